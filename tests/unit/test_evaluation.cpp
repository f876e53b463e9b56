// Evaluation: the matcher (paper Sect. VII-A) on hand-made scenes, AP on a hand-computed
// curve, dataset manifest errors, the Markdown report of two configs, and `furnihost eval`
// / `furnihost compare` end to end on a tiny generated dataset.
#include "furnihost/host/config.hpp"
#include "furnihost/host/evaluation.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "furnihost/host/io.hpp"
#include "report.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace furnihost;
using furnihost::app::RenderReport;  // the app's (framework/app/report.hpp)
using furnihost::app::ReportInfo;
using nlohmann::json;

namespace {

Detection Det(const std::string& cls, float x, float y, float score, float z = 0.5f) {
  Detection d;
  d.cls = cls;
  d.center = {x, y, z};
  d.score = score;
  return d;
}

GroundTruthObject Gt(const std::string& cls, float x, float y, float sx, float sy) {
  GroundTruthObject g;
  g.cls = cls;
  g.center = {x, y, 0.4f};
  g.size = {sx, sy, 0.8f};
  return g;
}

ClassMap Classes() {
  ClassMap c;
  c.classes = {"chair", "table", "cabinet"};
  c.map = {{"armchair", "chair"}, {"desk", "table"}, {"sofa", std::nullopt}};
  return c;
}

void WriteText(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path) << text;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// The message of the InputError `f` throws ("" when it throws none).
template <class F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// ---- matcher ---------------------------------------------------------------------------------

TEST(Matcher, DoubleDetectionOnOneObjectIsOneTpOneFp) {
  const std::vector<GroundTruthObject> gt = {Gt("chair", 1, 1, 0.6f, 0.5f)};
  // The lower-scored detection comes first in the list and is closer: score order still wins.
  const std::vector<Detection> dets = {Det("chair", 1.0f, 1.02f, 0.4f), Det("chair", 1.1f, 1.0f, 0.9f)};
  const SceneMatch m = MatchScene(dets, gt, Classes(), WidthConvention::Max);
  EXPECT_EQ(m.det_to_gt[1], 0);
  EXPECT_EQ(m.det_to_gt[0], SceneMatch::kUnmatched);
  EXPECT_EQ(m.gt_to_det[0], 1);
}

TEST(Matcher, ClassMismatchIsFalsePositiveAndMiss) {
  const std::vector<GroundTruthObject> gt = {Gt("table", 0, 0, 1.2f, 0.8f)};
  const std::vector<Detection> dets = {Det("chair", 0, 0, 0.9f)};
  const SceneMatch m = MatchScene(dets, gt, Classes(), WidthConvention::Max);
  EXPECT_EQ(m.det_to_gt[0], SceneMatch::kUnmatched);
  EXPECT_EQ(m.gt_to_det[0], SceneMatch::kUnmatched);
}

TEST(Matcher, BoundaryDistancesForBothWidthConventions) {
  // 0.8 x 0.4 m footprint: radius 0.4 m (max) or 0.2 m (min). Distances 1 mm either side;
  // the detection height (z = 3 m) must not matter, matching is on the floor plane.
  const std::vector<GroundTruthObject> gt = {Gt("table", 2, 3, 0.8f, 0.4f)};
  auto matched = [&](float dx, float dy, WidthConvention w) {
    const std::vector<Detection> d = {Det("table", 2 + dx, 3 + dy, 0.5f, 3.0f)};
    return MatchScene(d, gt, Classes(), w).det_to_gt[0] == 0;
  };
  EXPECT_TRUE(matched(0.399f, 0, WidthConvention::Max));
  EXPECT_FALSE(matched(0.401f, 0, WidthConvention::Max));
  EXPECT_TRUE(matched(0, -0.399f, WidthConvention::Max));  // the radius is the same in every direction
  EXPECT_TRUE(matched(0.199f, 0, WidthConvention::Min));
  EXPECT_FALSE(matched(0.201f, 0, WidthConvention::Min));
  EXPECT_TRUE(matched(0.14f, 0.14f, WidthConvention::Min));   // 0.198 m diagonally
  EXPECT_FALSE(matched(0.143f, 0.143f, WidthConvention::Min));  // 0.2022 m
  EXPECT_NEAR(MatchRadius(gt[0], WidthConvention::Max), 0.4f, 1e-6f);
  EXPECT_NEAR(MatchRadius(gt[0], WidthConvention::Min), 0.2f, 1e-6f);
}

TEST(Matcher, ClassMapAppliesToTruthAndDetections) {
  const std::vector<GroundTruthObject> gt = {Gt("desk", 0, 0, 1.4f, 0.7f), Gt("chair", 3, 0, 0.5f, 0.5f),
                                             Gt("sofa", 6, 0, 2.0f, 0.9f), Gt("lamp", 9, 0, 0.3f, 0.3f)};
  const std::vector<Detection> dets = {Det("table", 0.1f, 0, 0.9f), Det("armchair", 3, 0.1f, 0.8f),
                                       Det("sofa", 6, 0, 0.7f), Det("lamp", 9, 0, 0.6f)};
  const SceneMatch m = MatchScene(dets, gt, Classes(), WidthConvention::Max);
  EXPECT_EQ(m.det_to_gt[0], 0);  // table detection on a desk (desk -> table)
  EXPECT_EQ(m.det_to_gt[1], 1);  // armchair detection on a chair (armchair -> chair)
  EXPECT_EQ(m.det_to_gt[2], SceneMatch::kIgnored);  // sofa -> null
  EXPECT_EQ(m.det_to_gt[3], SceneMatch::kIgnored);  // not an evaluated class
  EXPECT_EQ(m.gt_to_det[2], SceneMatch::kIgnored);
  EXPECT_EQ(m.gt_to_det[3], SceneMatch::kIgnored);
  EXPECT_EQ(m.gt_class[0], "table");
  EXPECT_EQ(m.det_class[1], "chair");
  // Ignored classes are neither false positives nor misses.
  const EvalMetrics e = Evaluate({{dets, gt, false, "", {}}}, Classes(), WidthConvention::Max);
  EXPECT_EQ(e.hypotheses.tp, 2);
  EXPECT_EQ(e.hypotheses.fp, 0);
  EXPECT_EQ(e.hypotheses.fn, 0);
  EXPECT_EQ(e.ignored_gt.at("sofa"), 1);
  EXPECT_EQ(e.ignored_detections.at("lamp"), 1);
}

TEST(Matcher, TakesTheNearestUnmatchedObject) {
  const std::vector<GroundTruthObject> gt = {Gt("chair", 0, 0, 0.6f, 0.6f), Gt("chair", 0.4f, 0, 0.6f, 0.6f)};
  const std::vector<Detection> dets = {Det("chair", 0.3f, 0, 0.9f), Det("chair", 0.1f, 0, 0.8f)};
  const SceneMatch m = MatchScene(dets, gt, Classes(), WidthConvention::Max);
  EXPECT_EQ(m.det_to_gt[0], 1);  // 0.1 m from gt 1, 0.3 m from gt 0
  EXPECT_EQ(m.det_to_gt[1], 0);  // gt 1 is taken; gt 0 is 0.1 m away
}

// ---- metrics ---------------------------------------------------------------------------------

TEST(Metrics, AveragePrecisionOfAHandComputedCurve) {
  // 3 objects; detections by score: TP FP TP FP TP.
  // points (r, p): (1/3, 1) (1/3, 1/2) (2/3, 2/3) (2/3, 1/2) (1, 3/5)
  // envelope at the recall steps: 1, 2/3, 3/5  ->  AP = (1 + 2/3 + 3/5) / 3 = 0.755556
  const std::vector<double> r = {1 / 3.0, 1 / 3.0, 2 / 3.0, 2 / 3.0, 1.0};
  const std::vector<double> p = {1.0, 0.5, 2 / 3.0, 0.5, 0.6};
  EXPECT_NEAR(AveragePrecision(r, p), (1 + 2 / 3.0 + 0.6) / 3, 1e-12);
  EXPECT_EQ(AveragePrecision({}, {}), 0.0);
  // A curve that never reaches full recall only integrates up to where it stops.
  EXPECT_NEAR(AveragePrecision({0.5}, {1.0}), 0.5, 1e-12);

  // The same curve through Evaluate: 3 chairs 2 m apart, FPs far from everything.
  std::vector<GroundTruthObject> gt = {Gt("chair", 0, 0, 0.5f, 0.5f), Gt("chair", 2, 0, 0.5f, 0.5f),
                                       Gt("chair", 4, 0, 0.5f, 0.5f)};
  std::vector<Detection> dets = {Det("chair", 0, 0, 0.9f), Det("chair", 10, 10, 0.8f), Det("chair", 2, 0, 0.7f),
                                 Det("chair", 20, 10, 0.6f), Det("chair", 4, 0, 0.5f)};
  const EvalMetrics e = Evaluate({{dets, gt, false, "", {}}}, Classes(), WidthConvention::Max);
  const ClassMetrics& c = e.classes[0];
  ASSERT_EQ(c.cls, "chair");
  ASSERT_EQ(c.curve.size(), 5u);
  EXPECT_NEAR(c.curve[2].precision, 2 / 3.0, 1e-12);
  EXPECT_NEAR(c.curve[2].recall, 2 / 3.0, 1e-12);
  EXPECT_FLOAT_EQ(c.curve[2].score, 0.7f);
  EXPECT_NEAR(c.ap, 0.755556, 1e-6);
  EXPECT_NEAR(e.map, 0.755556, 1e-6);  // the other classes have no gt and are left out of the mean
  EXPECT_TRUE(std::isnan(e.classes[1].ap));
  EXPECT_NEAR(c.hypotheses.precision, 0.6, 1e-12);
  EXPECT_NEAR(c.hypotheses.recall, 1.0, 1e-12);
  EXPECT_FALSE(c.verified.has_value());  // no fitter ran
}

TEST(Metrics, TiedScoresGiveOnePointAndScenesPool) {
  // Two scenes; the TP in scene 1 and the FP in scene 0 share a score: one threshold, one point.
  const std::vector<GroundTruthObject> gt = {Gt("table", 0, 0, 1, 1)};
  const std::vector<SceneEval> scenes = {{{Det("table", 5, 5, 0.7f)}, gt, false, "", {}},
                                         {{Det("table", 0, 0, 0.7f), Det("table", 0.1f, 0, 0.2f)}, gt, false, "", {}}};
  const EvalMetrics e = Evaluate(scenes, Classes(), WidthConvention::Max);
  const ClassMetrics& t = e.classes[1];
  ASSERT_EQ(t.curve.size(), 2u);
  EXPECT_EQ(t.curve[0].tp, 1);
  EXPECT_EQ(t.curve[0].fp, 1);
  EXPECT_NEAR(t.curve[0].recall, 0.5, 1e-12);
  EXPECT_EQ(t.curve[1].fp, 2);  // the second detection on the scene-1 table
  EXPECT_EQ(t.gt, 2);
  EXPECT_NEAR(t.ap, 0.25, 1e-12);
}

TEST(Metrics, VerifiedDetectionsAreMatchedOnTheirOwnAndErrorsMeasured) {
  GroundTruthObject g = Gt("chair", 1, 1, 0.6f, 0.6f);
  g.yaw = 10.f * float(M_PI) / 180.f;
  Detection rejected = Det("chair", 1.0f, 1.0f, 0.9f);
  rejected.verified = false;
  rejected.model = "m1";
  Detection kept = Det("chair", 1.06f, 1.08f, 0.8f);  // 0.1 m off
  kept.verified = true;
  kept.model = "m2";
  kept.yaw = 350.f * float(M_PI) / 180.f;  // 20 deg from the gt across 0
  const EvalMetrics e = Evaluate({{{rejected, kept}, {g}, true, "", {}}}, Classes(), WidthConvention::Max);
  const ClassMetrics& c = e.classes[0];
  EXPECT_EQ(c.hypotheses.tp, 1);
  EXPECT_EQ(c.hypotheses.fp, 1);
  EXPECT_NEAR(c.hypotheses.centre_error_m.median, 0.0, 1e-6);  // the rejected one took the gt
  ASSERT_TRUE(c.verified.has_value());
  EXPECT_EQ(c.verified->tp, 1);
  EXPECT_EQ(c.verified->fp, 0);
  EXPECT_NEAR(c.verified->precision, 1.0, 1e-12);
  EXPECT_NEAR(c.verified->centre_error_m.median, 0.1, 1e-5);
  EXPECT_EQ(c.verified->yaw_error_deg.n, 1);
  EXPECT_NEAR(c.verified->yaw_error_deg.median, 20.0, 1e-3);
  EXPECT_TRUE(e.fitted);
  EXPECT_EQ(e.verified.tp, 1);
}

// Verification figures count the voter's hypotheses where the voter put them; the per-object
// records show the verified detection, else the rejected hypothesis, else "missed".
TEST(Metrics, VerificationRemovalRatesAndObjectRecords) {
  GroundTruthObject a = Gt("chair", 1, 1, 0.6f, 0.6f), b = Gt("chair", 4, 4, 0.6f, 0.6f), c = Gt("table", 8, 8, 1, 1);
  a.yaw = 0.f;
  a.model = "chair_a";
  // Hypothesis 0: true at the voter's centre, moved 0.12 m by the fitter, kept.
  Detection d0 = Det("chair", 1.12f, 1.0f, 0.9f);
  d0.verified = true;
  d0.model = "chair_a";
  d0.yaw = 170.f * float(M_PI) / 180.f;
  d0.coverage = 0.8f;
  // Hypothesis 1: true (on b), rejected.
  Detection d1 = Det("chair", 4.1f, 4.0f, 0.8f);
  d1.verified = false;
  d1.model = "chair_b";
  d1.checks = {Check::AtLeast("coverage", 0.3, 0.5)};
  // Hypotheses 2 and 3: false; the fitter moved 2 onto object a (it is still a false
  // hypothesis), 2 is removed, 3 is kept.
  Detection d2 = Det("chair", 1.0f, 1.0f, 0.7f);
  d2.verified = false;
  Detection d3 = Det("chair", 6.0f, 6.0f, 0.6f);
  d3.verified = true;
  SceneEval se{{d0, d1, d2, d3}, {a, b, c}, true, "room", {{1.0f, 1.0f, 0.5f}, {4.1f, 4.0f, 0.5f}, {2.5f, 2.5f, 0.5f}, {6.0f, 6.0f, 0.5f}}};
  const EvalMetrics e = Evaluate({se}, Classes(), WidthConvention::Max);
  ASSERT_TRUE(e.classes[0].verification.has_value());
  const VerificationFigures& v = *e.classes[0].verification;
  EXPECT_EQ(v.tp, 2);
  EXPECT_EQ(v.tp_kept, 1);
  EXPECT_EQ(v.fp, 2);
  EXPECT_EQ(v.fp_removed, 1);
  EXPECT_NEAR(v.fp_removal_rate, 0.5, 1e-12);
  EXPECT_NEAR(v.tp_kept_rate, 0.5, 1e-12);
  EXPECT_EQ(e.verification.fp, 2);
  EXPECT_TRUE(std::isnan(e.classes[1].verification->fp_removal_rate));  // no table hypotheses

  ASSERT_EQ(e.objects.size(), 3u);
  EXPECT_EQ(e.objects[0].scene, "room");
  EXPECT_EQ(e.objects[0].status, "verified");
  EXPECT_EQ(e.objects[0].model, "chair_a");
  EXPECT_EQ(e.objects[0].gt_model, "chair_a");
  EXPECT_NEAR(e.objects[0].centre_error_m, 0.12, 1e-5);
  EXPECT_NEAR(e.objects[0].yaw_error_deg, 170.0, 1e-3);  // raw: no symmetry folding
  EXPECT_NEAR(e.objects[0].coverage, 0.8, 1e-6);
  EXPECT_EQ(e.objects[1].status, "rejected");
  EXPECT_EQ(e.objects[1].rejection, "coverage 0.3 < 0.5");
  EXPECT_EQ(e.objects[2].status, "missed");
  EXPECT_EQ(e.objects[2].cls, "table");
  EXPECT_TRUE(std::isnan(e.objects[2].centre_error_m));

  // The records survive the run record round trip and reach the report.
  RunFigures f;
  f.metrics = e;
  const RunFigures back = RunFiguresFromJson(ToJson(f), "test");
  ASSERT_EQ(back.metrics.objects.size(), 3u);
  EXPECT_EQ(back.metrics.objects[1].rejection, "coverage 0.3 < 0.5");
  EXPECT_EQ(back.metrics.verification.fp_removed, 1);
  const std::string md = RenderReport({{"A", "a.json", {back}}}, ReportInfo{});
  EXPECT_NE(md.find("share of false hypotheses removed | 0.500"), std::string::npos) << md;
  EXPECT_NE(md.find("| room | 1 | chair | ? | rejected | chair_b |"), std::string::npos) << md;
}

// A yaw error is folded by the turns that map the gt object onto itself: a table (2-fold)
// fitted the other way round is right, a chair (1-fold) or an undeclared object is not.
TEST(Metrics, YawErrorsFoldByTheGroundTruthsSymmetry) {
  EXPECT_NEAR(FoldYawErrorDeg(170.0, std::nullopt), 170.0, 1e-12);
  EXPECT_NEAR(FoldYawErrorDeg(170.0, 1), 170.0, 1e-12);
  EXPECT_NEAR(FoldYawErrorDeg(170.0, 2), 10.0, 1e-9);
  EXPECT_NEAR(FoldYawErrorDeg(100.0, 4), 10.0, 1e-9);
  EXPECT_NEAR(FoldYawErrorDeg(50.0, 4), 40.0, 1e-9);
  EXPECT_NEAR(FoldYawErrorDeg(123.0, 0), 0.0, 1e-12);
  EXPECT_TRUE(std::isnan(FoldYawErrorDeg(NAN, 2)));

  GroundTruthObject table = Gt("table", 1, 1, 1.2f, 0.8f), chair = Gt("chair", 4, 4, 0.6f, 0.6f);
  table.yaw = chair.yaw = 0.f;
  table.yaw_symmetry = 2;
  chair.yaw_symmetry = 1;
  Detection t = Det("table", 1.f, 1.f, 0.9f), c = Det("chair", 4.f, 4.f, 0.9f);
  t.verified = c.verified = true;
  t.model = c.model = "m";
  t.yaw = c.yaw = 175.f * float(M_PI) / 180.f;
  const EvalMetrics e = Evaluate({{{t, c}, {table, chair}, true, "room", {}}}, Classes(), WidthConvention::Max);
  EXPECT_NEAR(e.classes[0].verified->yaw_error_deg.median, 175.0, 1e-3);  // chair
  EXPECT_NEAR(e.classes[1].verified->yaw_error_deg.median, 5.0, 1e-3);    // table
  ASSERT_EQ(e.objects.size(), 2u);
  EXPECT_NEAR(e.objects[0].yaw_error_deg, 175.0, 1e-3);
  EXPECT_NEAR(e.objects[0].yaw_error_folded_deg, 5.0, 1e-3);
  EXPECT_EQ(e.objects[0].yaw_symmetry, 2);
  RunFigures f;
  f.metrics = e;
  const RunFigures back = RunFiguresFromJson(ToJson(f), "test");
  EXPECT_EQ(back.metrics.objects[0].yaw_symmetry, 2);
  EXPECT_NEAR(back.metrics.objects[0].yaw_error_folded_deg, 5.0, 1e-3);
  const std::string md = RenderReport({{"A", "a.json", {back}}}, ReportInfo{});
  EXPECT_NE(md.find("| 175.0 | 2 | 5.0 |"), std::string::npos) << md;
}

TEST(Metrics, SummariseInterpolatesBetweenOrderStatistics) {
  const ErrorStats s = Summarise({10, 1, 9, 2, 8, 3, 7, 4, 6, 5});
  EXPECT_EQ(s.n, 10);
  EXPECT_NEAR(s.median, 5.5, 1e-12);
  EXPECT_NEAR(s.p90, 9.1, 1e-12);  // position 0.9 * 9 = 8.1
  EXPECT_EQ(Summarise({}).n, 0);
  EXPECT_TRUE(std::isnan(Summarise({}).median));
  const MeanStd m = MeanAndStd({1, 2, 3, NAN});
  EXPECT_EQ(m.n, 3);
  EXPECT_NEAR(m.mean, 2.0, 1e-12);
  EXPECT_NEAR(m.std, 1.0, 1e-12);
}

// ---- dataset manifests ---------------------------------------------------------------------

TEST(Dataset, LoadsPathsRelativeToTheManifest) {
  const std::string dir = furnihost::testing::TempDir("eval_manifest_ok");
  WriteText(dir + "/scans/a.xyz", "0 0 0\n1 0 0\n");
  WriteText(dir + "/scans/a.gt.json", R"({"objects": [{"class": "chair", "center": [0,0,0.4], "size": [0.5,0.5,0.8]}]})");
  WriteText(dir + "/sets/D.json", R"({"scenes": [{"scan": "../scans/a.xyz", "gt": "../scans/a.gt.json", "origin": [1, 2, 1.5]}],
    "class_map": {"desk": "table", "sofa": null}, "classes": ["chair", "table"]})");
  const Dataset d = LoadDataset(dir + "/sets/D.json");
  ASSERT_EQ(d.scenes.size(), 1u);
  EXPECT_EQ(fs::path(d.scenes[0].scan), fs::path(dir) / "scans" / "a.xyz");
  ASSERT_TRUE(d.scenes[0].origin.has_value());
  EXPECT_FLOAT_EQ(d.scenes[0].origin->y(), 2.f);
  EXPECT_EQ(d.classes.Map("desk").value_or(""), "table");
  EXPECT_FALSE(d.classes.Map("sofa").has_value());
  EXPECT_FALSE(d.classes.Map("bed").has_value());
  EXPECT_EQ(d.classes.Map("chair").value_or(""), "chair");

  const std::string h1 = HashDataset(d);
  EXPECT_EQ(h1.rfind("fnv1a64:", 0), 0u);
  EXPECT_EQ(h1.size(), 8u + 16u);
  EXPECT_EQ(HashDataset(d), h1);
  WriteText(dir + "/scans/a.gt.json", R"({"objects": []})");
  EXPECT_NE(HashDataset(d), h1);  // a changed ground truth changes the hash
  // FNV-1a 64 reference value of "a".
  EXPECT_EQ(Fnv1a("a", 1), 0xaf63dc4c8601ec8cull);
  fs::remove_all(dir);
}

// The graphs shipped for real data output the classes their benchmarks evaluate: every catalog
// class name a benchmark maps onto an evaluated class (ScanNet's nightstand, dresser and bookshelf
// are its cabinets) is mapped the same way by the graph's recogniser. A catalog that names its
// cabinets by kind (held-out models, a user's own catalog) then still gives one cabinet class,
// scored with the cabinet spreads and suppressed as one class, as if the catalog used one name.
TEST(Dataset, RealDataGraphsMapTheirBenchmarksClassNames) {
  const std::string src = furnihost::testing::SourceDir();
  const std::pair<const char*, const char*> pairs[] = {{"configs/scannet.json", "benchmarks/scannet_dev.json"},
                                                       {"configs/rgbd_view.json", "benchmarks/sunrgbd_dev.json"},
                                                       {"configs/rgbd_view.json", "benchmarks/synthetic_views.json"}};
  for (const auto& [graph, dataset] : pairs) {
    const nlohmann::json g = LoadConfigJson(src + "/" + graph);
    const nlohmann::json& map = g.at("stages").at("recognise").at("params").at("class_map");
    std::ifstream in(src + "/" + dataset);
    const nlohmann::json d = nlohmann::json::parse(in);
    size_t mapped = 0;
    for (const auto& [name, to] : d.at("class_map").items()) {
      if (to.is_null()) continue;  // not evaluated (SUN RGB-D's beds)
      ++mapped;
      ASSERT_TRUE(map.contains(name)) << graph << " does not map " << name << " (" << dataset << ")";
      EXPECT_EQ(map[name], to) << graph << " " << name;
    }
    EXPECT_GE(mapped, 6u) << dataset;
  }
}

TEST(Dataset, BadManifestsNameFileAndPointer) {
  const std::string dir = furnihost::testing::TempDir("eval_manifest_bad");
  WriteText(dir + "/a.xyz", "0 0 0\n");
  WriteText(dir + "/a.gt.json", R"({"objects": []})");
  const std::string m = dir + "/D.json";
  auto error = [&](const std::string& text) {
    WriteText(m, text);
    return ErrorOf([&] { LoadDataset(m); });
  };
  const std::string scene = R"({"scan": "a.xyz", "gt": "a.gt.json"})";
  EXPECT_NE(error(R"({"scenes": [)" + scene + "]}").find(m + ":/classes: missing"), std::string::npos);
  EXPECT_NE(error(R"({"scenes": [], "classes": ["chair"]})").find(m + ":/scenes: expected a non-empty"), std::string::npos);
  EXPECT_NE(error(R"({"scenes": [{"scan": "missing.xyz", "gt": "a.gt.json"}], "classes": ["chair"]})").find(m + ":/scenes/0/scan:"),
            std::string::npos);
  EXPECT_NE(error(R"({"scenes": [{"scan": "a.xyz"}], "classes": ["chair"]})").find(m + ":/scenes/0/gt: missing"),
            std::string::npos);
  EXPECT_NE(error(R"({"scenes": [{"scna": "a.xyz", "gt": "a.gt.json"}], "classes": ["chair"]})").find(m + ":/scenes/0/scna: unknown key"),
            std::string::npos);
  EXPECT_NE(error(R"({"scenes": [{"scan": "a.xyz", "gt": "a.gt.json", "origin": [1, 2]}], "classes": ["chair"]})")
                .find(m + ":/scenes/0/origin: expected [x, y, z]"),
            std::string::npos);
  EXPECT_NE(error(R"({"scenes": [)" + scene + R"(], "classes": ["chair"], "class_map": {"desk": "table"}})")
                .find(m + ":/class_map/desk: \"table\" is not one of the evaluated classes"),
            std::string::npos);
  EXPECT_NE(error(R"({"scenes": [)" + scene + R"(], "classes": ["chair", "chair"]})").find(m + ":/classes/1: duplicate"),
            std::string::npos);
  EXPECT_NE(error(R"({"scenes": [)" + scene + R"(], "classes": ["chair"], "clases": []})").find(m + ":/clases: unknown key"),
            std::string::npos);
  EXPECT_NE(error("[1, 2]").find(m + ": expected a JSON object"), std::string::npos);
  EXPECT_EQ(error(R"({"scenes": [)" + scene + R"(], "classes": ["chair"]})"), "");
  fs::remove_all(dir);
}

// ---- report ----------------------------------------------------------------------------------

namespace {

// A config whose chair results are `dets` against two chairs.
RunFigures Figures(uint64_t seed, const std::vector<Detection>& dets) {
  const std::vector<GroundTruthObject> gt = {Gt("chair", 0, 0, 0.5f, 0.5f), Gt("chair", 2, 0, 0.5f, 0.5f)};
  RunFigures f;
  f.seed = seed;
  f.metrics = Evaluate({{dets, gt, false, "", {}}}, Classes(), WidthConvention::Max);
  f.scenes = {{"a.ply", 100.0, static_cast<int>(dets.size()), {{"input", 10.0}, {"segment", 90.0}}}};
  f.stage_ms = {{"input", 10.0}, {"segment", 90.0}};
  f.wall_ms = 100;
  f.peak_rss_mb = 50;
  return f;
}

// The table row starting with "| <label> |" in `md` after the heading containing `section`.
std::string RowOf(const std::string& md, const std::string& section, const std::string& label) {
  const size_t s = md.find(section);
  if (s == std::string::npos) return "(no section " + section + ")";
  const size_t r = md.find("\n| " + label + " |", s);
  if (r == std::string::npos) return "(no row " + label + ")";
  return md.substr(r + 1, md.find('\n', r + 1) - r - 1);
}

}  // namespace

TEST(Report, RendersTwoConfigsWithDifferences) {
  ConfigSummary a{"paper", "configs/paper.json", {Figures(42, {Det("chair", 0, 0, 0.9f), Det("chair", 2, 0, 0.8f)})}};
  ConfigSummary b{"paper_nn", "configs/paper_nn.json", {Figures(42, {Det("chair", 0, 0, 0.9f), Det("chair", 9, 9, 0.8f)})}};
  ReportInfo info;
  info.dataset = "benchmarks/x.json";
  info.dataset_hash = "fnv1a64:0123456789abcdef";
  info.scenes = 1;
  info.width = WidthConvention::Min;
  info.plots = {"pr_chair.png"};
  const std::string md = RenderReport({a, b}, info);
  EXPECT_NE(md.find("width convention **min**"), std::string::npos) << md;
  EXPECT_NE(md.find("fnv1a64:0123456789abcdef"), std::string::npos);
  EXPECT_NE(md.find("| metric | A: paper | B: paper_nn | B − A |"), std::string::npos) << md;
  EXPECT_EQ(RowOf(md, "### chair (2 ground-truth objects)", "AP"), "| AP | 1.000 | 0.500 | -0.500 |") << md;
  EXPECT_EQ(RowOf(md, "### chair", "precision (hypotheses)"), "| precision (hypotheses) | 1.000 | 0.500 | -0.500 |");
  EXPECT_EQ(RowOf(md, "### chair", "FP (hypotheses)"), "| FP (hypotheses) | 0 | 1 | +1 |");
  EXPECT_EQ(RowOf(md, "### all classes", "mAP (mean AP over classes with ground truth)"),
            "| mAP (mean AP over classes with ground truth) | 1.000 | 0.500 | -0.500 |");
  EXPECT_EQ(RowOf(md, "## Time and memory", "stage segment [ms per scene]"), "| stage segment [ms per scene] | 90.0 | 90.0 | 0.0 |");
  // No fitter ran and no gt has a yaw: those rows are left out rather than filled with n/a.
  EXPECT_EQ(md.find("(verified)"), std::string::npos);
  EXPECT_EQ(md.find("yaw error"), std::string::npos);
  EXPECT_NE(md.find("![pr_chair](pr_chair.png)"), std::string::npos);
  // A class without ground truth or detections gets one line, not a table of n/a.
  EXPECT_NE(md.find("### table\n\nno ground-truth objects and no detections in any config"), std::string::npos);
  // A difference that rounds to zero has no sign.
  EXPECT_EQ(RowOf(md, "### chair", "TP (hypotheses)"), "| TP (hypotheses) | 2 | 1 | -1 |");
  EXPECT_EQ(RowOf(md, "## Time and memory", "peak resident memory [MB]"), "| peak resident memory [MB] | 50.0 | 50.0 | 0.0 |");

  // Several seeds: mean ± sample std, difference of the means.
  b.runs.push_back(Figures(43, {Det("chair", 0, 0, 0.9f), Det("chair", 2, 0, 0.8f)}));
  a.runs.push_back(a.runs[0]);
  a.runs[1].seed = 43;
  const std::string md2 = RenderReport({a, b}, info);
  EXPECT_EQ(RowOf(md2, "### chair", "AP"), "| AP | 1.000 ± 0.000 | 0.750 ± 0.354 | -0.250 |") << md2;
  EXPECT_EQ(RowOf(md2, "### chair", "FP (hypotheses)"), "| FP (hypotheses) | 0.0 ± 0.0 | 0.5 ± 0.7 | +0.5 |");
  EXPECT_NE(md2.find("B = **paper_nn** (`configs/paper_nn.json`), seeds 42 43"), std::string::npos);

  // The run-record round trip used by `furnihost compare` renders the same text.
  const ConfigSummary a2 = ConfigSummaryFromJson(json::parse(ToJson(a).dump()), "a");
  const ConfigSummary b2 = ConfigSummaryFromJson(json::parse(ToJson(b).dump()), "b");
  EXPECT_EQ(RenderReport({a2, b2}, info), md2);
  EXPECT_NE(ErrorOf([] { ConfigSummaryFromJson(json{{"name", "x"}, {"runs", json::array()}}, "rec.json:/figures"); })
                .find("rec.json:/figures/runs: expected a non-empty list"),
            std::string::npos);
}

// ---- the command line ------------------------------------------------------------------------

namespace {

int Furnihost(const std::string& args, std::string* out) {
  const std::string cmd = std::string(FURNIHOST_TEST_BINARY) + " " + args + " 2>&1 </dev/null";
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) out->append(buf.data(), n);
  const int status = pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

}  // namespace

TEST(EvalCommand, WritesEveryOutputAndComparesRunRecords) {
  // Two scenes and a graph that only reads scans: no detector, so every object is a miss.
  // This checks the command's plumbing (outputs, records, compare), not detection quality.
  const std::string dir = furnihost::testing::TempDir("eval_cli");
  for (const char* s : {"r1", "r2"}) {
    WriteText(dir + "/data/" + s + ".xyz", "0 0 0\n1 0 0\n0 1 0\n1 1 1\n");
    WriteText(dir + "/data/" + s + ".gt.json",
              R"({"objects": [{"class": "chair", "center": [0.5, 0.5, 0.4], "size": [0.5, 0.5, 0.8]},
                              {"class": "sofa", "center": [2, 2, 0.4], "size": [2, 1, 0.8]}]})");
  }
  WriteText(dir + "/D.json", R"({"scenes": [{"scan": "data/r1.xyz", "gt": "data/r1.gt.json"},
    {"scan": "data/r2.xyz", "gt": "data/r2.gt.json"}], "class_map": {"sofa": null}, "classes": ["chair", "table"]})");
  WriteText(dir + "/a.json", R"({"stages": {"input": {"type": "sensors.scan_file"}}})");
  WriteText(dir + "/b.json", R"({"seed": 7, "stages": {"input": {"type": "sensors.scan_file"}}})");
  std::string out;
  const int rc = Furnihost("eval -q --graph " + dir + "/a.json --graph " + dir + "/b.json --dataset " + dir +
                         "/D.json --out " + dir + "/out --seeds 2 --width min --jobs 2",
                     &out);
  ASSERT_EQ(rc, 0) << out;
  for (const char* f : {"summary.json", "report.md", "pr_chair.svg", "pr_chair.png", "pr_table.svg", "run_a.json", "run_b.json"})
    EXPECT_TRUE(fs::is_regular_file(dir + "/out/" + f)) << f;
  EXPECT_EQ(ReadText(dir + "/out/pr_chair.png").substr(1, 3), "PNG");
  EXPECT_NE(ReadText(dir + "/out/pr_chair.svg").find("<svg"), std::string::npos);

  const json summary = json::parse(ReadText(dir + "/out/summary.json"));
  EXPECT_EQ(summary["width_convention"], "min");
  EXPECT_EQ(summary["dataset"]["scenes"], 2);
  ASSERT_EQ(summary["configs"].size(), 2u);
  const json& runs = summary["configs"][1]["runs"];
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0]["seed"], 7);
  EXPECT_EQ(runs[1]["seed"], 8);
  const json& chair = runs[0]["metrics"]["classes"][0];
  EXPECT_EQ(chair["class"], "chair");
  EXPECT_EQ(chair["gt"], 2);
  EXPECT_EQ(chair["hypotheses"]["fn"], 2);
  EXPECT_EQ(runs[0]["metrics"]["ignored_gt"]["sofa"], 2);
  EXPECT_EQ(runs[0]["scenes"].size(), 2u);

  const json record = json::parse(ReadText(dir + "/out/run_b.json"));
  EXPECT_EQ(record["format"], "furnihost-run-record");
  EXPECT_EQ(record["seed"], 7);
  EXPECT_EQ(record["config"]["stages"]["input"]["type"], "sensors.scan_file");
  EXPECT_EQ(record["plugins"][0]["type"], "sensors.scan_file");
  EXPECT_FALSE(record["plugins"][0]["version"].get<std::string>().empty());
  EXPECT_EQ(record["dataset"]["hash"], summary["dataset"]["hash"]);
  EXPECT_TRUE(record["git"].contains("revision"));
  EXPECT_TRUE(record["machine"].contains("nproc"));

  const std::string report = ReadText(dir + "/out/report.md");
  EXPECT_NE(report.find("| metric | A: a | B: b | B − A |"), std::string::npos) << report;
  EXPECT_EQ(RowOf(report, "### chair", "recall (hypotheses)"), "| recall (hypotheses) | 0.000 ± 0.000 | 0.000 ± 0.000 | 0.000 |");

  std::string cmp;
  ASSERT_EQ(Furnihost("compare " + dir + "/out/run_a.json " + dir + "/out/run_b.json", &cmp), 0) << cmp;
  EXPECT_NE(cmp.find("| metric | A: a | B: b | B − A |"), std::string::npos) << cmp;
  // --jitter: recorded, named in the report, and a comparison with an unjittered run warns.
  std::string jit;
  ASSERT_EQ(Furnihost("eval -q --graph " + dir + "/a.json --dataset " + dir + "/D.json --out " + dir +
                          "/out_j --seeds 2 --jitter 0.0005",
                      &jit),
            0)
      << jit;
  EXPECT_DOUBLE_EQ(json::parse(ReadText(dir + "/out_j/run_a.json"))["jitter_m"].get<double>(), 0.0005);
  EXPECT_EQ(json::parse(ReadText(dir + "/out/run_a.json"))["jitter_m"].get<double>(), 0.0);
  EXPECT_NE(ReadText(dir + "/out_j/report.md").find("scans jittered: Gaussian noise of 0.50 mm"), std::string::npos);
  std::string cmp_j;
  ASSERT_EQ(Furnihost("compare " + dir + "/out/run_a.json " + dir + "/out_j/run_a.json", &cmp_j), 0) << cmp_j;
  EXPECT_NE(cmp_j.find("WARNING: the runs jittered their scans differently (A: 0.00 mm, B: 0.50 mm"), std::string::npos)
      << cmp_j;
  std::string bad_jit;
  EXPECT_EQ(Furnihost("eval --graph " + dir + "/a.json --dataset " + dir + "/D.json --out " + dir + "/out3 --jitter -1",
                      &bad_jit),
            2);
  EXPECT_NE(bad_jit.find("--jitter"), std::string::npos) << bad_jit;

  std::string bad;
  EXPECT_EQ(Furnihost("compare " + dir + "/D.json " + dir + "/out/run_b.json", &bad), 2);
  EXPECT_NE(bad.find("not a furnihost run record"), std::string::npos) << bad;
  std::string bad_ds;
  WriteText(dir + "/bad.json", R"({"scenes": [{"scan": "nope.xyz", "gt": "data/r1.gt.json"}], "classes": ["chair"]})");
  EXPECT_EQ(Furnihost("eval --graph " + dir + "/a.json --dataset " + dir + "/bad.json --out " + dir + "/out2", &bad_ds), 2);
  EXPECT_NE(bad_ds.find(dir + "/bad.json:/scenes/0/scan:"), std::string::npos) << bad_ds;
  fs::remove_all(dir);
}
