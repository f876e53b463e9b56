#include "cli_common.hpp"

#include <tbb/global_control.h>

#include <iostream>
#include <sstream>

#include "furnihost/log.hpp"

namespace furnihost::app {

void CommonOptions::Add(CLI::App& app, bool with_run_options) {
  // One folder per --plugin-path, so `--plugin-path DIR scan.pcd` leaves the scan alone.
  app.add_option("--plugin-path", plugin_paths,
                 "extra folder(s) searched for plugins first (then $FURNIHOST_PLUGIN_PATH, the build tree, the install prefix)")
      ->allow_extra_args(false);
  app.add_flag("-v,--verbose", verbose, "more log output (-vv for debug, -vvv for trace)");
  app.add_flag("-q,--quiet", quiet, "only warnings and errors");
  if (with_run_options) {
    app.add_option("--threads", threads, "worker threads (0 = all cores)")->check(CLI::Range(0, 1024));
    app.add_option("--seed", seed, "random seed (default: the graph's \"seed\")");
  }
}

void CommonOptions::Apply() const {
  SetupLogging(quiet ? 0 : 1 + verbose);
  static std::unique_ptr<tbb::global_control> control;
  if (threads > 0)
    control = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
}

std::unique_ptr<Registry> CommonOptions::MakeRegistry() const {
  return std::make_unique<Registry>(Registry::DefaultSearchPath(plugin_paths));
}

RunContext CommonOptions::Context(uint64_t graph_seed) const {
  RunContext c;
  c.seed = seed.value_or(graph_seed);
  c.threads = threads;
  c.verbose = verbose > 0;
  return c;
}

std::optional<int> Parse(CLI::App& app, std::vector<std::string> args) {
  std::reverse(args.begin(), args.end());  // CLI11 takes the vector back to front
  try {
    app.parse(args);
  } catch (const CLI::CallForHelp& e) {
    std::cout << app.help();
    return 0;
  } catch (const CLI::ParseError& e) {
    std::cerr << "furnihost " << app.get_name() << ": error: " << e.what() << " (see --help)\n";
    return 2;
  }
  return std::nullopt;
}

std::vector<double> ParseNumbers(const std::string& text, size_t count, const std::string& option) {
  std::vector<double> v;
  std::string t = text;
  for (auto& c : t)
    if (c == ',') c = ' ';
  std::istringstream in(t);
  double x;
  while (in >> x) v.push_back(x);
  if (!in.eof() || v.size() != count || std::any_of(v.begin(), v.end(), [](double d) { return !std::isfinite(d); }))
    throw InputError(option + ": expected " + std::to_string(count) + " comma-separated numbers, got '" + text + "'");
  return v;
}

}  // namespace furnihost::app
