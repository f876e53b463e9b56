// The example plugins of docs/writing-a-plugin.md, loaded through the host: each one is listed by
// `furnihost plugins`, constructed through the registry from its declared defaults and given a
// small input; the examples' graph runs `furnihost detect` on the demo room; and the doc's code
// blocks are the files that are built here.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "furnihost/host/registry.hpp"
#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace furnihost {
namespace {

const std::vector<std::string> kExamples = {"features.centroid", "segmenters.example_grid",
                                            "voters.example_class_mean", "fitters.example_score"};

Registry& Reg() {
  static Registry reg({FURNIHOST_EXAMPLE_PLUGIN_DIR, testing::PluginDir()});
  return reg;
}

template <class T>
std::shared_ptr<T> Make(const std::string& type, const json& params = json::object()) {
  const auto* entry = Reg().Find(type);
  if (!entry) throw std::runtime_error("plugin not found: " + type);
  return Reg().CreateAs<T>(type, entry->params.Resolve(params, "test"));
}

// out: stdout then stderr (for failure messages and the plugin list).
struct CliRun {
  int code = -1;
  std::string out;
};
CliRun Furnihost(const std::string& args) {
  const testing::CommandRun r = testing::RunFurnihost(args);
  return {r.code, r.out + r.err};
}

std::string ReadText(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(Examples, ListedByTheHost) {
  const CliRun r = Furnihost(std::string("plugins --plugin-path ") + FURNIHOST_EXAMPLE_PLUGIN_DIR);
  ASSERT_EQ(r.code, 0) << r.out;
  for (const auto& type : kExamples) EXPECT_NE(r.out.find(type + "  ["), std::string::npos) << type << "\n" << r.out;
  EXPECT_TRUE(Reg().Refusals().empty());
}

TEST(Examples, EachConstructsFromItsDefaults) {
  for (const auto& type : kExamples) {
    SCOPED_TRACE(type);
    const auto* entry = Reg().Find(type);
    ASSERT_NE(entry, nullptr);
    EXPECT_NE(Reg().Create(type, entry->params.Resolve(json::object(), type)), nullptr);
  }
  EXPECT_THROW(Make<Segmenter>("segmenters.example_grid", {{"cell_m", 0}}), InputError);
}

// Two clumps of 4 points in different 0.5 m cubes and one stray point.
Scan TwoClumps() {
  Scan scan;
  for (float x0 : {0.1f, 2.1f})
    for (int i = 0; i < 4; ++i) scan.points.emplace_back(x0 + 0.01f * i, 0.1f, 0.1f + 0.1f * x0);
  scan.points.emplace_back(5.f, 5.f, 5.f);
  return scan;
}

TEST(Examples, GridSegmenterMakesOnePartPerCube) {
  const Scan scan = TwoClumps();
  const Segmentation seg = Make<Segmenter>("segmenters.example_grid", {{"cell_m", 0.5}, {"min_points", 2}})
                               ->Segment(scan, RunContext{});
  ASSERT_EQ(seg.parts.size(), 2u);
  EXPECT_EQ(seg.parts[0].indices, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_NEAR(seg.parts[1].centroid.x(), 2.115f, 1e-5f);
  EXPECT_EQ(seg.discarded_points, 1);
  EXPECT_EQ(seg.normals.size(), scan.points.size());
}

TEST(Examples, CentroidFeatures) {
  const Scan scan = TwoClumps();
  Segmentation seg;
  seg.parts.push_back({{0, 1, 2, 3}, Eigen::Vector3f(0.115f, 0.1f, 0.11f)});
  const FeatureMatrix f = Make<Features>("features.centroid", {{"log_count", false}})->Compute(scan, seg, RunContext{});
  ASSERT_EQ(f.values.rows(), 1);
  EXPECT_EQ(f.names[1], "count");
  EXPECT_FLOAT_EQ(f.values(0, 0), 0.11f);
  EXPECT_FLOAT_EQ(f.values(0, 1), 4.f);
  EXPECT_NEAR(f.values(0, 2), 0.03f, 1e-6f);
}

TrainingView View(const std::string& cls, std::vector<std::array<float, 2>> rows) {
  TrainingView v;
  v.cls = cls;
  v.features.names = {"a", "b"};
  v.features.values.resize(Eigen::Index(rows.size()), 2);
  for (size_t r = 0; r < rows.size(); ++r) v.features.values.row(Eigen::Index(r)) << rows[r][0], rows[r][1];
  return v;
}

TEST(Examples, ClassMeanVoterTrainsLoadsAndVotes) {
  RunContext ctx;
  auto trained = Make<Voter>("voters.example_class_mean");
  EXPECT_THROW(trained->Vote({}, ctx), StageError);  // no model yet
  const json model = trained->Train({View("chair", {{0.25f, 0.125f}, {0.75f, 0.125f}}), View("table", {{0.875f, 0.875f}})}, ctx);
  EXPECT_EQ(model["format"], "voters.example_class_mean/1");
  EXPECT_EQ(model["classes"]["chair"], json({0.5, 0.125}));

  auto voter = Make<Voter>("voters.example_class_mean", {{"max_distance", 0.3}});
  EXPECT_THROW(voter->Load({{"format", "voters.example_class_mean/0"}}), StageError);
  voter->Load(json::parse(model.dump()));  // as read back from the model file
  Scan scan = TwoClumps();
  scan.pose.translation() = Eigen::Vector3f(10.f, 0.f, 0.f);
  Segmentation seg;
  seg.parts = {{{0}, Eigen::Vector3f(1, 2, 0)}, {{1}, Eigen::Vector3f(3, 4, 0)}, {{2}, Eigen::Vector3f(5, 6, 0)}};
  FeatureMatrix f;
  f.names = {"a", "b"};
  f.values.resize(3, 2);
  f.values << 0.5f, 0.125f,  // a chair's part
      0.75f, 0.875f,          // a table's, 0.125 from its mean
      0.5f, 0.6f;             // farther than 0.3 from both
  SceneParts scene;
  scene.scan = &scan;
  scene.segmentation = &seg;
  scene.features = &f;
  const VoteResult r = voter->Vote({scene}, ctx);
  EXPECT_EQ(r.classes, (std::vector<std::string>{"chair", "table"}));
  ASSERT_EQ(r.hypotheses.size(), 2u);
  EXPECT_EQ(r.hypotheses[0].cls, "chair");
  EXPECT_FLOAT_EQ(r.hypotheses[0].score, 1.f);
  EXPECT_TRUE(r.hypotheses[0].center.isApprox(Eigen::Vector3f(11, 2, 0)));  // world frame
  EXPECT_EQ(r.hypotheses[1].cls, "table");
  EXPECT_FLOAT_EQ(r.hypotheses[1].score, 1.f / 1.125f);
  ASSERT_EQ(r.hypotheses[1].support.size(), 1u);
  EXPECT_EQ(r.hypotheses[1].support[0].part, 1);
}

TEST(Examples, ScoreFitterVerifiesByScore) {
  std::vector<Detection> in(2);
  in[0].score = 0.5f;
  in[1].score = 2.f;
  const auto out = Make<Fitter>("fitters.example_score", {{"min_score", 1.0}})->Fit(in, FitContext{});
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].verified, false);
  EXPECT_EQ(out[0].Rejection(), "min_score 0.5 < 1");
  EXPECT_EQ(out[1].verified, true);
}

// The examples' graph: trains on the bundled catalog (2 simulated views per model) and detects in
// the demo room with every example stage.
TEST(Examples, GraphOfTheExamplesDetects) {
  const fs::path src = testing::SourceDir();
  const std::string out = testing::TempDir("examples_detect");
  const CliRun r = Furnihost("--graph " + (src / "examples/plugins/examples.json").string() + " --plugin-path " +
                          FURNIHOST_EXAMPLE_PLUGIN_DIR + " --threads 2 -q --out " + out + " " +
                          (src / "data/demo/room.pcd").string());
  ASSERT_EQ(r.code, 0) << r.out;
  // The voter's hypotheses went through the fitter: some accepted, some rejected by min_score.
  const json d = json::parse(ReadText(fs::path(out) / "detections.json"));
  int accepted = 0, rejected = 0;
  for (const auto& det : d.at("detections")) {
    EXPECT_GE(det.at("score").get<double>(), 1 / 1.8 - 1e-6);  // vote.max_distance 0.8
    (det.at("verified").get<bool>() ? accepted : rejected) += 1;
  }
  EXPECT_GT(accepted, 0) << r.out;
  EXPECT_GT(rejected, 0) << r.out;
  EXPECT_EQ(Furnihost("validate --graph " + (src / "examples/plugins/examples.json").string() + " --plugin-path " +
                      FURNIHOST_EXAMPLE_PLUGIN_DIR + " --set vote.max_distance=11")
                .code,
            2);
}

// docs/writing-a-plugin.md shows each example file in full: a code block right after a line
// `<!-- file: PATH -->` must be that file, byte for byte, and every example file must be shown.
TEST(Examples, DocCodeBlocksAreTheBuiltFiles) {
  const fs::path src = testing::SourceDir();
  const std::string doc = ReadText(src / "docs/writing-a-plugin.md");
  std::set<std::string> shown;
  const std::string marker = "<!-- file: ";
  for (size_t at = doc.find(marker); at != std::string::npos; at = doc.find(marker, at + 1)) {
    const size_t name_end = doc.find(" -->\n", at);
    ASSERT_NE(name_end, std::string::npos);
    const std::string path = doc.substr(at + marker.size(), name_end - at - marker.size());
    SCOPED_TRACE(path);
    const size_t fence = name_end + 5;  // the next line opens the code block: ```lang
    ASSERT_EQ(doc.compare(fence, 3, "```"), 0) << "no code block right after the marker";
    const size_t body = doc.find('\n', fence) + 1;
    const size_t close = doc.find("\n```\n", body - 1);
    ASSERT_NE(close, std::string::npos);
    ASSERT_TRUE(fs::is_regular_file(src / path));
    EXPECT_EQ(doc.substr(body, close + 1 - body), ReadText(src / path))
        << "docs/writing-a-plugin.md's copy differs from the file";
    shown.insert(path);
  }
  std::vector<std::string> files = {"plugins/features/centroid/centroid.cpp", "plugins/features/centroid/CMakeLists.txt"};
  for (const auto& e : fs::recursive_directory_iterator(src / "examples/plugins")) {
    const std::string rel = fs::relative(e.path(), src).string();
    if (e.is_regular_file() && e.path().filename() != "test_examples.cpp") files.push_back(rel);
  }
  for (const auto& f : files) EXPECT_TRUE(shown.count(f)) << f << " is not shown in docs/writing-a-plugin.md";
}

}  // namespace
}  // namespace furnihost
