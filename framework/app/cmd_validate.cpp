#include <iostream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/pipeline.hpp"

namespace furnihost::app {

int RunValidate(const std::vector<std::string>& args) {
  CLI::App app{"Validate a graph config against the plugins found and construct its stages (nothing runs).", "validate"};
  CommonOptions common;
  std::string graph;
  bool print = false;
  common.Add(app, false);
  app.add_option("--graph,-g", graph, "graph config (JSON)")->required();
  app.add_flag("--print", print, "print the resolved config (extends applied, every default filled)");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  auto reg = common.MakeRegistry();
  GraphConfig g = common.LoadGraph(graph, *reg);
  // Every stage is constructed too: rules between parameters (a plugin's Check) fail here, not
  // after training. A constructor's InputError is the graph's fault (exit 2).
  try {
    Pipeline pipeline(g, *reg);
  } catch (const StageError& e) {
    throw InputError(graph + ": " + e.what());
  }
  if (print) std::cout << DumpJson(g.resolved, 2) << "\n";
  else std::cout << graph << ": valid (" << g.stages.size() << " stages)\n";
  return 0;
}

}  // namespace furnihost::app
