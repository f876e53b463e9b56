// furnihost — learn furniture from CAD catalogs, find it in 3D scans.
#include <malloc.h>

#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "commands.hpp"
#include "mpi_world.hpp"
#include "furnihost/error.hpp"
#include "furnihost/host/detector.hpp"
#include "furnihost/log.hpp"

namespace {

const char* kUsage = R"(furnihost — locate and categorise furniture in 3D scans with models learned from CAD catalogs

usage:
  furnihost SCAN [SCAN ...] [--graph G.json] [--out DIR]
                                                         detect (trains and caches the model if needed);
                                                         no --graph: laser_room.json for a scan with a sensor
                                                         origin, room.json for one without
  furnihost train    --graph G.json                      build the model from the graph's catalog
  furnihost simulate --catalog C.json --scene S.json --out room.pcd
                                                         synthetic room scan with ground truth
  furnihost validate --graph G.json [--print]            validate a graph config
  furnihost eval --graph A.json [--graph B.json ...] --dataset D.json [--out DIR] [--seeds N]
                                                         A/B evaluation: PR curves, AP, timings, report
  furnihost compare RUN_A.json RUN_B.json                A | B | B - A table of two eval run records
  furnihost gap --graph G.json --dataset D.json [--sensor NAME=PARAMS ...]
                                                         training views against real scans: part feature gap
  furnihost catalog CATALOG.json [--out DIR]             each model's class, size and front, with a picture
  furnihost plugins  [--json]                            list the plugins found

Run `furnihost <command> --help` (or `furnihost detect --help`) for the options of each.
Exit codes: 0 success, 2 usage/config/input error, 1 internal error.
)";

}  // namespace

int main(int argc, char** argv) {
  using namespace furnihost;
  // Working buffers of a scan (a few hundred kB to a few hundred MB, allocated and freed stage
  // after stage) come from the heap and stay there between stages: glibc's defaults map each
  // one afresh and give it back on free, and the page faults of touching it again were ~8 % of
  // a 50k-point detection. Beyond 64 MB of free heap top the memory goes back to the system.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 64 << 20);
  furnihost::SetupLogging(1);
  // Every rank of an MPI run ends its world before exiting, whatever the path out of main.
  struct CloseWorld {
    ~CloseWorld() { app::World::Close(); }
  } close_world;
  std::vector<std::string> args(argv + 1, argv + argc);
  const std::map<std::string, int (*)(const std::vector<std::string>&)> commands = {
      {"detect", app::RunDetect},     {"train", app::RunTrain},       {"simulate", app::RunSimulate},
      {"validate", app::RunValidate}, {"plugins", app::RunPlugins},   {"eval", app::RunEval},
      {"compare", app::RunCompare},   {"gap", app::RunGap},           {"catalog", app::RunCatalog}};
  try {
    if (args.empty() || args[0] == "-h" || args[0] == "--help" || args[0] == "help") {
      std::cout << kUsage;
      return args.empty() ? 2 : 0;
    }
    if (args[0] == "--version") {
      std::cout << "furnihost " << FURNIHOST_APP_VERSION << "\n";
      return 0;
    }
    auto it = commands.find(args[0]);
    // eval and train share their work among the ranks of an MPI launch (mpi_jobs.hpp); the
    // other commands run on rank 0 alone.
    const std::string command = it != commands.end() ? args[0] : "detect";
    if (command != "eval" && command != "train" && !app::RunsOnThisRank(command)) return 0;
    if (it != commands.end()) return it->second(std::vector<std::string>(args.begin() + 1, args.end()));
    if (args[0].rfind("-", 0) != 0 && args[0].find('.') == std::string::npos && args[0].find('/') == std::string::npos) {
      std::cerr << "furnihost: error: unknown command '" << args[0]
                << "' (commands: detect, train, simulate, validate, eval, compare, gap, plugins; see --help)\n";
      return 2;
    }
    return app::RunDetect(args);
  } catch (const app::RankStopped& e) {
    return e.code;  // another rank failed and rank 0 said why
  } catch (const InputError& e) {
    std::cerr << "furnihost: error: " << OneLine(e.what()) << "\n";
    return 2;
  } catch (const StageError& e) {
    std::cerr << "furnihost: error: " << OneLine(e.what()) << "\n";
    return e.IsInputError() ? 2 : 1;
  } catch (const std::filesystem::filesystem_error& e) {
    // Output folders that are files, permissions, a full disk: the user's environment.
    std::cerr << "furnihost: error: " << OneLine(e.what()) << "\n";
    return 2;
  } catch (const std::bad_alloc&) {
    std::cerr << "furnihost: internal error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "furnihost: internal error: " << OneLine(e.what()) << "\n";
    return 1;
  }
}
