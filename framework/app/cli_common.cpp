#include "cli_common.hpp"

#include <fmt/format.h>
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
  app.add_option("--set", sets,
                 "override a stage parameter: TAG.PARAM=VALUE (JSON value; repeatable), e.g. --set "
                 "vote.height_tolerance_m=0.2; ground.kind=plane sets the ground; recorded in the run record")
      ->allow_extra_args(false);
  app.add_flag("-v,--verbose", verbose, "more log output: -v debug, -vv trace");
  app.add_flag("-q,--quiet", quiet, "only warnings and errors");
  if (with_run_options) {
    app.add_option("--threads", threads, "worker threads (0 = all cores)")->check(CLI::Range(0, 1024));
    app.add_option("--seed", seed, "random seed (default: the graph's \"seed\")");
  }
}

void CommonOptions::AddMinConfidence(CLI::App& app) {
  app.add_option("--min-confidence", min_confidence,
                 "accept detections of calibrated classes at this confidence in [0, 1] (default: the graph's "
                 "calibration.min_confidence, 0.5; docs/calibration.md)")
      ->check(CLI::Range(0.0, 1.0));
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

GraphConfig CommonOptions::LoadGraph(const std::string& path, const Registry& registry) const {
  std::vector<std::string> all = sets;
  if (min_confidence) all.push_back(fmt::format("calibration.min_confidence={}", *min_confidence));
  return furnihost::LoadGraph(path, registry, all);
}

void FrameCli::Add(CLI::App& app) {
  app.add_option("--up", up,
                 "which axis of the scan's coordinates points up: +z (default), -y (a camera's optical frame: x right, "
                 "y down, z forward), +y, ..., or auto (the normal of the dominant plane with the scene above it)");
  app.add_flag("--level", level,
               "after --up AXIS: level the frame on the floor when it is tilted 8-35 deg from that axis (a camera "
               "pitched down, read in its optical frame with --up -y); the graph's \"frame\": {\"level\": true} does "
               "the same");
  app.add_option("--transform", transform,
                 "scan -> z-up frame as 16 numbers (4x4, row-major) or x,y,z,roll,pitch,yaw (metres, radians; as a ROS "
                 "static transform); instead of --up");
  app.add_option("--shift", shift,
                 "global shift x,y,z subtracted from the coordinates at read time (default: automatic for files whose "
                 "first point lies 100 m or more from the origin); outputs are written back in the file's coordinates");
  app.add_option("--ground", ground,
                 "the floor: auto (default of the graph), level, plane, height_map, or a number: a fixed floor height "
                 "[m] in the z-up frame");
}

FrameOptions FrameCli::Frame() const {
  FrameOptions f;
  f.up = up;
  if (up != "auto") UpAxisRotation(up, "--up");  // validates
  f.level = level;
  if (level && up == "auto") throw InputError("--level: levels an --up AXIS; --up auto finds the floor itself");
  if (!transform.empty()) {
    if (up != "+z") throw InputError("--transform: give either --up or --transform, not both");
    if (level) throw InputError("--level: levels an --up AXIS, not a --transform (give the sensor's full pose)");
    f.transform = ParseTransform(transform, "--transform");
  }
  if (!shift.empty()) {
    const auto v = ParseNumbers(shift, 3, "--shift");
    f.shift.shift = Eigen::Vector3d(v[0], v[1], v[2]);
    CheckShift(*f.shift.shift, "--shift");
  }
  return f;
}

void FrameCli::ApplyGround(GraphConfig& g) const {
  if (ground.empty()) return;
  GroundOptions o = g.ground;
  char* end = nullptr;
  const double z = std::strtod(ground.c_str(), &end);
  if (end != ground.c_str() && *end == '\0') {
    if (!std::isfinite(z) || std::abs(z) > 1e4)
      throw InputError("--ground: a fixed floor height must be finite and within 10 km, got '" + ground + "'");
    o.kind = "fixed";
    o.z_m = static_cast<float>(z);
  } else {
    o.kind = ground;
  }
  o.Check("--ground: ");
  g.ground = o;
  g.resolved["ground"] = ToJson(o);
}

}  // namespace furnihost::app
