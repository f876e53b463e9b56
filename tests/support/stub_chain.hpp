// The stub detection chain of tests/hostile/corpus/graphs/stub_chain.json (sensor, the test-only
// stub segmenter and voter of tests/hostile/plugins, features.centroid) on a room simulated from
// the hostile corpus's tiny catalog: a whole detection through the furnihost binary in a second,
// for tests of what the host does around the stages.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "furnihost/host/io.hpp"
#include "test_support.hpp"

namespace furnihost::testing {

// The folder of a test plugin set built beside the plugins ("hostile", "outside", "bad").
inline std::string TestPlugins(const std::string& name) {
  return (std::filesystem::path(PluginDir()).parent_path() / "test_plugins" / name).string();
}

inline std::string HostileCorpus() { return SourceDir() + "/tests/hostile/corpus"; }

// A simulated room with the tiny catalog's cube, made once per test binary.
inline const std::string& StubRoom() {
  static const std::string room = [] {
    const std::string dir = TempDir("stub_chain_room");
    std::filesystem::create_directories(dir);
    const std::string out = dir + "/room.pcd";
    const auto r = RunFurnihost("simulate -q --catalog " + HostileCorpus() + "/catalogs/tiny/catalog.json --scene " +
                                HostileCorpus() + "/catalogs/scene.json --out " + out);
    if (r.code != 0) throw std::runtime_error("simulating the stub room failed: " + r.err);
    return out;
  }();
  return room;
}

// The stub chain's graph, its model cached in `dir`; `stages` is merged in (null removes a stage).
inline nlohmann::json StubGraph(const std::string& dir, const nlohmann::json& stages) {
  nlohmann::json g = {
      {"seed", 7},
      {"catalog", HostileCorpus() + "/catalogs/tiny/catalog.json"},
      {"model_cache", dir + "/model.fhm"},
      {"training", {{"sensor", "sim"}}},
      {"stages",
       {{"sim",
         {{"type", "sensors.simulated_laser"},
          {"params", {{"views", 2}, {"angular_resolution_deg", 2}, {"tilt_resolution_deg", 2}}}}},
        {"input", {{"type", "sensors.scan_file"}}},
        {"seg", {{"type", "segmenters.hostile_stub"}, {"inputs", {"input"}}}},
        {"feat", {{"type", "features.centroid"}, {"inputs", {"seg"}}}},
        {"vote", {{"type", "voters.hostile_stub"}, {"inputs", {"feat"}}}}}}};
  g["stages"].merge_patch(stages);
  return g;
}

// Writes `graph` to DIR/g.json and runs detection on the stub room with the test plugins and
// `extra` arguments; the command's run (detections in DIR/out/detections.json).
inline CommandRun DetectStubRoom(const std::string& dir, const nlohmann::json& graph, const std::string& extra = "") {
  std::filesystem::create_directories(dir);
  AtomicWriteText(dir + "/g.json", graph.dump(1));
  return RunFurnihost("--graph " + dir + "/g.json " + StubRoom() + " --plugin-path " + TestPlugins("hostile") +
                      " --plugin-path " + TestPlugins("outside") + " --out " + dir + "/out " + extra);
}

}  // namespace furnihost::testing
