// The furnihost binary: exit codes and one-line errors on bad input.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <fstream>
#include <sstream>

#include "furnihost/host/io.hpp"
#include "furnihost/host/model_file.hpp"
#include "furnihost/scan_reader.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

using Run = furnihost::testing::CommandRun;
Run Furnihost(const std::string& args) { return furnihost::testing::RunFurnihost(args); }

using furnihost::testing::ErrorLines;

const char* kGraph = R"({"stages": {"input": {"type": "sensors.scan_file"},
  "feat_unused": {"type": "features.centroid", "inputs": ["seg"]},
  "seg": {"type": "segmenters.throws", "inputs": ["input"]}}})";

std::string PluginArgs() {
  return "--plugin-path " + (fs::path(furnihost::testing::PluginDir()).parent_path() / "test_plugins" / "bad").string();
}

}  // namespace

TEST(Cli, HelpAndVersion) {
  auto r = Furnihost("--help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("furnihost train"), std::string::npos);
  EXPECT_EQ(Furnihost("plugins --help").code, 0);
  EXPECT_EQ(Furnihost("detect --help").code, 0);
  EXPECT_EQ(Furnihost("").code, 2);
  EXPECT_EQ(Furnihost("frobnicate").code, 2);
}

TEST(Cli, PluginsListsEveryKindFound) {
  auto r = Furnihost("plugins");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("sensors.scan_file"), std::string::npos);
  EXPECT_NE(r.out.find("features.centroid"), std::string::npos);
  auto j = Furnihost("plugins --json");
  ASSERT_EQ(j.code, 0);
  auto parsed = nlohmann::json::parse(j.out);
  EXPECT_GE(parsed["plugins"].size(), 2u);
  // Every plugin found is listed in the text too, whatever its kind (proposers were left out once).
  for (const auto& p : parsed["plugins"])
    EXPECT_NE(r.out.find("\n" + p["type"].get<std::string>() + "  ["), std::string::npos) << p["type"];
}

TEST(Cli, BadInputsExitTwoWithOneLine) {
  auto dir = furnihost::testing::TempDir("cli_bad");
  furnihost::AtomicWriteText(dir + "/g.json", kGraph);
  furnihost::AtomicWriteText(dir + "/empty.pcd", "");
  {
    std::ofstream(dir + "/empty.pcd").close();
  }
  furnihost::AtomicWriteText(dir + "/corrupt.pcd", "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                                                    "WIDTH 99\nHEIGHT 1\nPOINTS 99\nDATA binary\nxx");
  furnihost::AtomicWriteText(dir + "/unknown_param.json",
                             R"({"stages": {"input": {"type": "sensors.scan_file", "params": {"voxel": 1}}}})");
  // A base config whose name is too long for the file system (found by fuzz_graph_config).
  furnihost::AtomicWriteText(dir + "/long_extends.json", "{\"extends\": \"" + std::string(5000, 'a') + ".json\"}");
  const std::string g = "--graph " + dir + "/g.json " + PluginArgs() + " ";
  struct Case {
    std::string args, needle;
  } cases[] = {
      {g + dir + "/missing.pcd", "missing.pcd: no such scan file"},
      {g + dir, "is a directory"},
      {g + dir + "/empty.pcd", "empty.pcd: is empty"},
      {g + dir + "/corrupt.pcd", "corrupt.pcd"},
      {"--graph " + dir + "/unknown_param.json " + dir + "/corrupt.pcd", "/stages/input/params/voxel: unknown parameter"},
      {"--graph " + dir + "/nothere.json x.pcd", "nothere.json: no such JSON file"},
      {"validate --graph " + dir + "/unknown_param.json", "unknown parameter"},
      {"validate --graph " + dir + "/long_extends.json", "long_extends.json:/extends: unknown base config"},
      {g + "--up auto --level " + dir + "/corrupt.pcd", "--level: levels an --up AXIS"},
      {g + "--transform 0,0,0,0,0.3,0 --level " + dir + "/corrupt.pcd", "--level: levels an --up AXIS"},
      {"detect --graph", "--graph"},
      // Issue 18's frame options name themselves.
      {g + "--up q " + dir + "/corrupt.pcd", "--up: 'q' is not an axis"},
      {g + "--transform 0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,1 " + dir + "/corrupt.pcd", "--transform: the matrix is singular"},
      {g + "--transform 1,2,3 " + dir + "/corrupt.pcd", "--transform: expected 16 numbers"},
      {g + "--shift nan,0,0 " + dir + "/corrupt.pcd", "--shift: expected 3 comma-separated numbers"},
      {g + "--ground wobbly " + dir + "/corrupt.pcd", "--ground"},
      {g + "--set nope " + dir + "/corrupt.pcd", "--set"},
  };
  for (const auto& c : cases) {
    auto r = Furnihost(c.args);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    auto lines = ErrorLines(r.err);
    ASSERT_EQ(lines.size(), 1u) << c.args << "\n" << r.err;
    EXPECT_NE(lines[0].find(c.needle), std::string::npos) << lines[0];
  }
}

// `validate` constructs every stage, so rules between parameters (ParamBinding::Rule) and
// per-value checks (a NumberMap's numbers) fail there: exit 2, one line naming the parameter.
TEST(Cli, ValidateRunsCrossFieldRules) {
  auto dir = furnihost::testing::TempDir("cli_rules");
  struct Case {
    std::string graph, needle;
  } cases[] = {
      {R"({"stages": {"input": {"type": "sensors.scan_file", "params": {"origin": [1, 2]}}}})",
       "origin: expected 3 numbers, got 2"},
      {R"({"stages": {"input": {"type": "sensors.scan_file"},
          "seg": {"type": "segmenters.pcl_region_growing", "inputs": ["input"],
                  "params": {"min_points": 50, "max_points": 20}}}})",
       "max_points must be 0 (no limit) or >= min_points"},
      {R"({"stages": {"input": {"type": "sensors.simulated_laser", "params": {"tilt_min_deg": 40}}}})",
       "tilt_min_deg (40.000000) > tilt_max_deg (30.000000)"},
      {R"({"stages": {"input": {"type": "sensors.scan_file"},
          "prop": {"type": "proposals.clusters", "inputs": ["input"], "params": {"radii": []}}}})",
       "radii: give at least one clustering radius"},
      {R"({"stages": {"input": {"type": "sensors.scan_file"},
          "prop": {"type": "proposals.clusters", "inputs": ["input"]},
          "vote": {"type": "voters.catalog_shape", "inputs": ["prop"], "params": {"thresholds": {"chair": -1}}}}})",
       "/stages/vote/params/thresholds/chair: expected a number in [0, inf], got -1"},
  };
  int i = 0;
  for (const auto& c : cases) {
    const std::string path = dir + "/g" + std::to_string(i++) + ".json";
    furnihost::AtomicWriteText(path, c.graph);
    auto r = Furnihost("validate --graph " + path);
    EXPECT_EQ(r.code, 2) << c.graph << "\n" << r.err;
    auto lines = ErrorLines(r.err);
    ASSERT_EQ(lines.size(), 1u) << c.graph << "\n" << r.err;
    EXPECT_NE(lines[0].find(c.needle), std::string::npos) << lines[0];
  }
}

TEST(Cli, StageExceptionNamesTagAndType) {
  auto dir = furnihost::testing::TempDir("cli_throw");
  furnihost::AtomicWriteText(dir + "/g.json", kGraph);
  furnihost::Scan s;
  s.points = {{0, 0, 0}, {1, 1, 1}};
  furnihost::WriteScan(dir + "/s.ply", s);
  auto r = Furnihost("--graph " + dir + "/g.json " + PluginArgs() + " --out " + dir + "/out " + dir + "/s.ply");
  EXPECT_EQ(r.code, 1) << r.err;
  auto lines = ErrorLines(r.err);
  ASSERT_EQ(lines.size(), 1u) << r.err;
  EXPECT_NE(lines[0].find("stage 'seg' (segmenters.throws): segment always throws"), std::string::npos) << lines[0];
  EXPECT_FALSE(fs::exists(dir + "/out/detections.json"));
}

TEST(Cli, DetectWithoutVoterWritesPartsAndSaysSo) {
  auto dir = furnihost::testing::TempDir("cli_partial");
  furnihost::AtomicWriteText(dir + "/g.json", R"({"stages": {"input": {"type": "sensors.scan_file"}}})");
  furnihost::Scan s;
  s.points = {{0, 0, 0}, {1, 1, 1}};
  furnihost::WriteScan(dir + "/s.pcd", s);
  auto r = Furnihost("--graph " + dir + "/g.json --out " + dir + "/out " + dir + "/s.pcd");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("no segmenter"), std::string::npos);
  auto j = furnihost::ReadJson(dir + "/out/detections.json");
  EXPECT_EQ(j["points"], 2);
  EXPECT_TRUE(j["detections"].empty());
  EXPECT_FALSE(j["missing_stages"].empty());
}

// Every shipped graph config (configs/*.json; names starting with '_' are local experiments)
// passes `furnihost validate` against the plugins built here, so a renamed or retired
// parameter cannot leave a config behind. Configs naming a plugin this build lacks (the
// sanitizer pass builds a few plugins only) are skipped, and said so.
TEST(Cli, EveryShippedConfigValidates) {
  const fs::path configs = fs::path(furnihost::testing::SourceDir()) / "configs";
  const auto reg = furnihost::testing::MakeRegistry();
  // The stage types of a config after its `extends` chain (RFC 7386 merge patches).
  std::function<nlohmann::json(const fs::path&)> resolve = [&](const fs::path& p) {
    nlohmann::json j = furnihost::ReadJson(p.string());
    if (j.contains("extends")) {
      nlohmann::json base = resolve(p.parent_path() / j.at("extends").get<std::string>());
      base.merge_patch(j);
      return base;
    }
    return j;
  };
  int validated = 0;
  std::vector<std::string> skipped;
  for (const auto& e : fs::directory_iterator(configs)) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() != ".json" || name[0] == '_') continue;
    std::string missing;
    const nlohmann::json graph = resolve(e.path());  // named: a temporary would die before the loop body
    for (const auto& [tag, st] : graph.at("stages").items())
      if (st.is_object() && st.contains("type") && !reg->Find(st.at("type").get<std::string>()))
        missing = st.at("type").get<std::string>();
    if (!missing.empty()) {
      skipped.push_back(name + " (" + missing + ")");
      continue;
    }
    const auto r = Furnihost("validate --graph " + e.path().string());
    EXPECT_EQ(r.code, 0) << name << ": " << r.err;
    ++validated;
  }
  for (const auto& s : skipped) std::printf("[ configs ] skipped %s: plugin not built\n", s.c_str());
  std::printf("[ configs ] %d validated, %zu skipped\n", validated, skipped.size());
  EXPECT_GE(validated + skipped.size(), 10u);  // the folder was found and read
}

// One scan per sensor: the ground truth counts each object's returns, leaves out what the
// sensor barely sees (--min-visible) and comes in the sensor's upright frame (--sensor-frame),
// where the object's points lie inside its box and the floor lies at minus the sensor's height.
TEST(Cli, SimulatePerSensorGroundTruthInTheSensorsFrame) {
  const std::string dir = furnihost::testing::TempDir("cli_sim_frame");
  const std::string corpus = furnihost::testing::SourceDir() + "/tests/hostile/corpus/catalogs";
  // The sensor at x = 3.2 looks towards -x (180 deg field of view, down to 50 deg below the
  // horizon): the cube at x = 1.5 is in view, the one at (3.6, 3.5) is behind it.
  furnihost::AtomicWriteText(dir + "/scene.json", R"({"room": {"size_m": [4, 4], "height_m": 2.5},
    "objects": [{"model": "cube", "x": 1.5, "y": 2}, {"model": "cube", "x": 3.6, "y": 3.5}],
    "sensors": [{"position": [3.2, 2, 1.2], "yaw_deg": 180}],
    "sensor_params": {"angular_resolution_deg": 1, "tilt_resolution_deg": 1, "tilt_min_deg": -50, "noise_a": 0,
                      "noise_b": 0}})");
  const std::string sim = "simulate -q --catalog " + corpus + "/tiny/catalog.json --scene " + dir + "/scene.json";
  {
    const auto r = Furnihost(sim + " --out " + dir + "/world.ply --per-sensor");
    ASSERT_EQ(r.code, 0) << r.err;
    const auto objects = furnihost::ReadJson(dir + "/world.gt.json").at("objects");
    ASSERT_EQ(objects.size(), 2u);  // every object, the hidden one with no return
    EXPECT_GT(objects[0].at("n_points").get<int>(), 20);
    EXPECT_EQ(objects[1].at("n_points").get<int>(), 0);
  }
  const auto r = Furnihost(sim + " --out " + dir + "/view.ply --per-sensor --min-visible 20 --sensor-frame");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto gt = furnihost::ReadJson(dir + "/view.gt.json");
  ASSERT_EQ(gt.at("objects").size(), 1u) << gt.dump();
  const auto& o = gt.at("objects")[0];
  // World (1.5, 2, 0.3) seen from (3.2, 2, 1.2) heading -x: 1.7 m ahead, 0.9 m below.
  const auto c = o.at("center").get<std::vector<float>>();
  EXPECT_NEAR(c[0], 1.7f, 1e-3f);
  EXPECT_NEAR(c[1], 0.f, 1e-3f);
  EXPECT_NEAR(c[2], -0.9f, 1e-3f);
  // The way the cube faces seen from the sensor: its front (-y of the model: a cube has no open
  // side, so the estimate falls back on the catalog frame's depth axis) turned by the sensor's
  // heading -x: +y.
  EXPECT_NEAR(o.at("yaw").get<float>(), 1.5708f, 1e-3f);
  const auto s = o.at("size").get<std::vector<float>>();
  const furnihost::Scan scan = furnihost::ReadScan(dir + "/view.ply");
  int inside = 0, floor = 0;
  for (const auto& p : scan.points) {
    bool in = true;
    for (int k = 0; k < 3; ++k) in = in && std::abs(p[k] - c[size_t(k)]) <= 0.5f * s[size_t(k)] + 1e-3f;
    inside += in;
    floor += std::abs(p.z() + 1.2f) < 1e-3f;
  }
  EXPECT_EQ(inside, o.at("n_points").get<int>());
  EXPECT_GT(floor, 100);
  // Both options need one scan per sensor.
  const auto bad = Furnihost(sim + " --out " + dir + "/x.ply --sensor-frame");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--per-sensor"), std::string::npos) << bad.err;
}

// Objects may not overlap on a scene's floor plan, unless one is marked "under" (a chair pushed
// under a table): then both are placed and scanned. A bad "under" is an error naming it.
TEST(Cli, SimulateRefusesOverlapsUnlessAnObjectIsUnder) {
  const std::string dir = furnihost::testing::TempDir("cli_sim_under");
  const std::string corpus = furnihost::testing::SourceDir() + "/tests/hostile/corpus/catalogs";
  auto scene = [&](const std::string& under) {
    furnihost::AtomicWriteText(dir + "/scene.json", R"({"room": {"size_m": [4, 4], "height_m": 2.5},
      "objects": [{"model": "cube", "x": 1.5, "y": 2}, {"model": "cube", "x": 1.6, "y": 2.1)" + under + R"(}],
      "sensor_params": {"angular_resolution_deg": 2, "tilt_resolution_deg": 2, "noise_a": 0, "noise_b": 0}})");
    return Furnihost("simulate -q --catalog " + corpus + "/tiny/catalog.json --scene " + dir + "/scene.json --out " + dir +
                     "/room.ply");
  };
  auto r = scene("");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("overlap (footprints intersect"), std::string::npos) << r.err;
  r = scene(R"(, "under": true)");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(furnihost::ReadJson(dir + "/room.gt.json").at("objects").size(), 2u);
  r = scene(R"(, "under": "yes")");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("/objects/1/under: expected true or false"), std::string::npos) << r.err;
}

// detect loads the catalog and the model on a worker while the scan is read, framed and
// grounded: an unreadable catalog still ends the run with exit 2 and one line naming it, with
// one thread or two, whether the scan is good or bad too, and nothing is written.
TEST(Cli, CatalogErrorsWhileTheScanLoadsExitTwoWithOneLine) {
  const std::string dir = furnihost::testing::TempDir("cli_catalog_overlap");
  const std::string corpus = furnihost::testing::SourceDir() + "/tests/hostile/corpus/catalogs";
  furnihost::AtomicWriteText(dir + "/g.json", R"({"catalog": ")" + corpus + R"(/not_json/catalog.json",
    "training": {"sensor": "sim"},
    "stages": {"sim": {"type": "sensors.simulated_laser"}, "input": {"type": "sensors.scan_file"},
               "prop": {"type": "proposals.clusters", "inputs": ["input"]},
               "vote": {"type": "voters.catalog_shape", "inputs": ["prop"]}}})");
  furnihost::Scan s;  // a floor and a box: a scan every stage before the voter accepts
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) {
      s.points.emplace_back(0.05f * float(i), 0.05f * float(j), 0.f);
      if (i > 20 && i < 30 && j > 20 && j < 30) s.points.emplace_back(0.05f * float(i), 0.05f * float(j), 0.5f);
    }
  furnihost::WriteScan(dir + "/good.ply", s);
  furnihost::AtomicWriteText(dir + "/bad.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n1\n2\n");
  for (const std::string threads : {"1", "2"})
    for (const std::string scan : {"good", "bad"}) {
      const std::string out = dir + "/out_" + scan + threads;
      const auto r = Furnihost("--graph " + dir + "/g.json --threads " + threads + " --out " + out + " " + dir + "/" + scan + ".ply");
      EXPECT_EQ(r.code, 2) << scan << " " << threads << "\n" << r.err;
      const auto lines = ErrorLines(r.err);
      ASSERT_EQ(lines.size(), 1u) << r.err;
      if (scan == "good") {
        EXPECT_NE(lines[0].find("not_json/catalog.json"), std::string::npos) << lines[0];
      }
      EXPECT_FALSE(fs::exists(out + "/detections.json")) << out;
    }
  // A scan failing at once races the catalog failing on the worker: whichever comes first, the
  // run ends with exit 2 and one line, never std::terminate from the loading's error rethrown
  // while the scan's unwinds (it did in 2-15 % of such runs).
  for (int i = 0; i < 20; ++i) {
    const auto r = Furnihost("--graph " + dir + "/g.json --threads 2 --out " + dir + "/out_race " + dir + "/bad.ply");
    ASSERT_EQ(r.code, 2) << "run " << i << "\n" << r.err;
    ASSERT_EQ(ErrorLines(r.err).size(), 1u) << r.err;
  }
}

// `furnihost SCAN` without --graph picks the graph by what the scan says, in one log line: with
// a sensor origin (a PCD's VIEWPOINT, or --origin) the one-spot laser route, laser_room.json;
// without, the room-reconstruction route, room.json. Scans that disagree are refused. (A file
// given as --out stops each run right after the choice; the installed binary's whole run is
// tests/sdk/install_test.sh's.)
TEST(Cli, WithoutAGraphTheScanPicksOne) {
  const std::string dir = furnihost::testing::TempDir("cli_default_graph");
  const std::string src = furnihost::testing::SourceDir();
  furnihost::AtomicWriteText(dir + "/not_a_folder", "");
  furnihost::AtomicWriteText(dir + "/room.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                                "property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n");
  const std::string stop = " --out " + dir + "/not_a_folder";
  struct Case {
    std::string args, graph, why;
  } cases[] = {
      {src + "/data/demo/room.pcd", "/configs/laser_room.json", "room.pcd has a sensor origin (VIEWPOINT 3 2.5 1.5)"},
      {dir + "/room.ply", "/configs/room.json", "room.ply has no sensor origin"},
      {dir + "/room.ply --origin 0,0,1", "/configs/laser_room.json", "--origin gives a sensor origin"},
  };
  for (const auto& c : cases) {
    const auto r = Furnihost(c.args + stop);
    EXPECT_EQ(r.code, 2) << c.args << "\n" << r.err;
    int said = 0;
    std::istringstream err(r.err);
    for (std::string line; std::getline(err, line);)
      if (line.find("no --graph") != std::string::npos) {
        ++said;
        EXPECT_NE(line.find("--graph " + src + c.graph), std::string::npos) << line;
        EXPECT_NE(line.find(c.why), std::string::npos) << line;
      }
    EXPECT_EQ(said, 1) << r.err;
    const auto lines = ErrorLines(r.err);
    ASSERT_EQ(lines.size(), 1u) << r.err;
    EXPECT_NE(lines[0].find("exists and is not a folder"), std::string::npos) << lines[0];
  }
  const auto mixed = Furnihost(src + "/data/demo/room.pcd " + dir + "/room.ply" + stop);
  EXPECT_EQ(mixed.code, 2);
  const auto lines = ErrorLines(mixed.err);
  ASSERT_EQ(lines.size(), 1u) << mixed.err;
  EXPECT_NE(lines[0].find("1 of the 2 scans have a sensor origin"), std::string::npos) << lines[0];
}

// `furnihost gap`: the part features of the training views against those of the objects in a
// dataset's scans. The "real" scan here is simulated by the same kind of laser as the graph's
// training views, at their distance, so those are nearer to it than views of a noisy, holed
// variant. Six cubes at several turns give the real parts a spread of every feature: with two
// cubes seen from 2.5 m at 0.5 deg (2.2 cm between returns, under the 3 cm of the boundary test)
// nearly every real part had boundary ratio 1, and the last bits of the ray tracer's hits decided
// whether the graph's views were 7 or 30 of that column's deviations away.
TEST(Cli, GapPutsTheMatchingTrainingViewsNearest) {
  const std::string dir = furnihost::testing::TempDir("cli_gap");
  const std::string catalog = furnihost::testing::SourceDir() + "/tests/hostile/corpus/catalogs/tiny/catalog.json";
  furnihost::AtomicWriteText(dir + "/scene.json", R"({"room": {"size_m": [6, 5], "height_m": 2.5},
    "objects": [{"model": "cube", "x": 1.59, "y": 2.41, "yaw_deg": 10}, {"model": "cube", "x": 2.48, "y": 2.93, "yaw_deg": 40},
                {"model": "cube", "x": 3.52, "y": 2.93, "yaw_deg": 70}, {"model": "cube", "x": 4.41, "y": 2.41, "yaw_deg": 25},
                {"model": "cube", "x": 2.2, "y": 4.0, "yaw_deg": 55}, {"model": "cube", "x": 3.8, "y": 4.0, "yaw_deg": 5}],
    "sensors": [{"position": [3.0, 1.0, 1.5], "yaw_deg": 90}],
    "sensor_params": {"angular_resolution_deg": 0.25, "tilt_resolution_deg": 0.25, "tilt_min_deg": -60, "noise_a": 0.003,
                      "noise_b": 0}})");
  furnihost::AtomicWriteText(dir + "/data.json", R"({"scenes": [{"scan": "room.ply", "gt": "room.gt.json"}], "classes": ["cube"]})");
  const std::string stages = R"("input": {"type": "sensors.scan_file"},
      "sim": {"type": "sensors.simulated_laser", "params": {"angular_resolution_deg": 0.25, "tilt_resolution_deg": 0.25,
              "views": 4, "noise_a": 0.003, "noise_b": 0}},
      "seg": {"type": "segmenters.region_growing", "inputs": ["input"]})";
  furnihost::AtomicWriteText(dir + "/g.json", R"({"catalog": ")" + catalog + R"(", "training": {"sensor": "sim"}, "stages": {)" +
                                                  stages + R"(, "feat": {"type": "features.paper24", "inputs": ["seg"]}}})");
  const std::string gap = "gap -q --graph " + dir + "/g.json --dataset " + dir + "/data.json --out " + dir + "/out";
  const std::string rough = R"( --sensor 'rough={"views": 4, "noise_a": 0.03, "holes": 0.5, "hole_size_m": 0.05}')";
  // The noise of the real scan and of both variants' views is drawn from the seed.
  for (const std::string seed : {"1", "42"}) {
    SCOPED_TRACE("seed " + seed);
    ASSERT_EQ(Furnihost("simulate -q --seed " + seed + " --catalog " + catalog + " --scene " + dir + "/scene.json --out " + dir +
                        "/room.ply")
                  .code,
              0);
    const auto r = Furnihost(gap + " --seed " + seed + rough);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.out, "") << "-q prints nothing";
    const auto j = furnihost::ReadJson(dir + "/out/gap.json");
    EXPECT_EQ(j.at("real_objects"), 6);
    EXPECT_GT(j.at("real_parts").get<int>(), 12);
    ASSERT_EQ(j.at("variants").size(), 2u);
    EXPECT_EQ(j.at("variants")[0].at("name"), "graph");
    EXPECT_EQ(j.at("variants")[1].at("name"), "rough");
    const double same = j.at("variants")[0].at("w1_over_sd_mean").get<double>();
    const double far = j.at("variants")[1].at("w1_over_sd_mean").get<double>();
    EXPECT_GE(same, 0.0);
    EXPECT_LT(same, far);
    // Not by one column: the matching views are nearer on most of them.
    int nearer = 0;
    for (const auto& [col, w] : j.at("variants")[0].at("w1_over_sd").items())
      nearer += w.get<double>() < j.at("variants")[1].at("w1_over_sd").at(col).get<double>();
    EXPECT_GT(nearer, int(j.at("features").size()) / 2);
    // One class here: its mean is the whole set's.
    EXPECT_DOUBLE_EQ(j.at("variants")[0].at("w1_over_sd_mean_per_class").at("cube").get<double>(), same);
    EXPECT_LT(j.at("variants")[0].at("nearest_median").get<double>(), j.at("variants")[1].at("nearest_median").get<double>());
  }
  EXPECT_TRUE(fs::exists(dir + "/out/gap.md"));
  EXPECT_TRUE(fs::exists(dir + "/out/hist/points.svg"));
  EXPECT_TRUE(fs::exists(dir + "/out/hist/boundary_ratio.png"));
  // Bad input: exit 2, one line naming what is wrong.
  for (const auto& [args, says] : std::vector<std::pair<std::string, std::string>>{
           {" --sensor nope", "--sensor nope: expected NAME=PARAMS"},
           {" --sensor 'graph={}'", "'graph' is taken"},
           {" --sensor 'x=[1]'", "--sensor x: PARAMS must be a JSON object"},
           {R"( --sensor 'x={"holes": 2}')", "--sensor x/holes"}}) {
    const auto bad = Furnihost(gap + args);
    EXPECT_EQ(bad.code, 2) << args;
    const auto lines = ErrorLines(bad.err);
    ASSERT_EQ(lines.size(), 1u) << bad.err;
    EXPECT_NE(lines[0].find(says), std::string::npos) << lines[0];
  }
  furnihost::AtomicWriteText(dir + "/nofeat.json", R"({"catalog": ")" + catalog + R"(", "training": {"sensor": "sim"}, "stages": {)" +
                                                       stages + "}}");
  const auto nofeat = Furnihost("gap -q --graph " + dir + "/nofeat.json --dataset " + dir + "/data.json --out " + dir + "/o2");
  EXPECT_EQ(nofeat.code, 2);
  EXPECT_NE(nofeat.err.find("a features stage fed by a segmenter"), std::string::npos) << nofeat.err;
  furnihost::AtomicWriteText(dir + "/nocat.json", R"({"training": {"sensor": "sim"}, "stages": {)" + stages +
                                                      R"(, "feat": {"type": "features.paper24", "inputs": ["seg"]}}})");
  const auto nocat = Furnihost("gap -q --graph " + dir + "/nocat.json --dataset " + dir + "/data.json --out " + dir + "/o3");
  EXPECT_EQ(nocat.code, 2);
  EXPECT_NE(nocat.err.find("nocat.json:/catalog: missing"), std::string::npos) << nocat.err;
}

// A graph whose one voter learns from meshes (configs/room.json: voters.catalog_shape, the
// bundled catalog of 6 meshes): training scans no model. The model file counts each model as
// learned from its mesh and no view, and the training sensor spent no time.
TEST(Cli, TrainingARecogniserOfMeshesScansNoModel) {
  const std::string dir = furnihost::testing::TempDir("cli_train_meshes");
  const auto r = Furnihost("train --graph " + furnihost::testing::SourceDir() + "/configs/room.json --out " + dir +
                           "/m.fhm");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto m = furnihost::LoadModel(dir + "/m.fhm");
  const nlohmann::json& v = m.summary.at("voters").at("recognise");
  EXPECT_EQ(v.at("views"), 0) << m.summary.dump();
  EXPECT_EQ(v.value("meshes", 0), m.summary.at("models").get<int>()) << m.summary.dump();
  EXPECT_GE(m.summary.at("models").get<int>(), 6);
  const size_t at = r.out.find("time per step [ms] ");
  ASSERT_NE(at, std::string::npos) << r.out;
  const nlohmann::json times = nlohmann::json::parse(r.out.substr(at + 19));
  EXPECT_TRUE(times.contains("recognise")) << times.dump();
  EXPECT_FALSE(times.contains("simulate")) << "the training sensor ran: " << times.dump();
  fs::remove_all(dir);
}
