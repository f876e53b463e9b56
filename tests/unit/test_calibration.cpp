// Calibrated confidence (issue: a confidence that means a probability): the calibration file a
// graph names maps each detection's raw score to a confidence, and the graph's one working point
// (calibration.min_confidence, --min-confidence) decides; a graph without one says so and keeps
// its thresholds; eval measures how well confidences are calibrated (Reliability).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "furnihost/error.hpp"
#include "furnihost/host/calibration.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/host/io.hpp"
#include "stub_chain.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using furnihost::Calibration;
using furnihost::Check;
using furnihost::Detection;
using nlohmann::json;

namespace {

json ChairMap(double coef, double intercept) {
  return {{"furnihost_calibration", 1},
          {"method", "logistic"},
          {"fitted_on", {{"data", "test"}}},
          {"classes", {{"chair", {{"features", {"log_score"}}, {"coef", {coef}}, {"intercept", intercept}}}}}};
}

std::string Write(const std::string& name, const json& j) {
  const std::string dir = furnihost::testing::TempDir("calibration");
  fs::create_directories(dir);
  furnihost::AtomicWriteText(dir + "/" + name, j.dump());
  return dir + "/" + name;
}

Detection Chair(float score, double threshold) {
  Detection d;
  d.cls = "chair";
  d.score = score;
  d.checks = {Check::AtMost("free_space_ratio", 0.1, 0.3), Check::AtLeast("score", score, threshold)};
  d.verified = furnihost::FirstFailure(d.checks).empty();
  return d;
}

}  // namespace

TEST(Calibration, ConfidenceIsTheLogisticMapOfTheLogScore) {
  const Calibration c = Calibration::Load(Write("chair.json", ChairMap(1.5, 2.0)));
  const Detection d = Chair(0.2f, 0.1);
  ASSERT_TRUE(c.Confidence(d));
  EXPECT_NEAR(*c.Confidence(d), 1.0 / (1.0 + std::exp(-(2.0 + 1.5 * std::log(0.2)))), 1e-6);
  Detection table = d;
  table.cls = "table";
  EXPECT_FALSE(c.Confidence(table)) << "a class without a map has no confidence";
  EXPECT_EQ(c.FittedOn().value("data", ""), "test");
}

TEST(Calibration, TheConfidenceDecidesInsteadOfTheScoreThreshold) {
  // conf(s) = sigmoid(ln s): 0.5 at s = 1.
  const Calibration c = Calibration::Load(Write("unit.json", ChairMap(1.0, 0.0)));
  std::vector<Detection> d = {Chair(2.0f, 5.0), Chair(0.5f, 0.1), Chair(2.0f, 0.1)};
  d[2].checks.front() = Check::AtMost("free_space_ratio", 0.6, 0.3);  // a fitter's own verdict: rejected
  d[2].verified = false;
  Detection table = Chair(0.01f, 0.1);
  table.cls = "table";
  d.push_back(table);
  c.Apply(d, 0.5);
  // Below its score threshold, above the working point: accepted.
  EXPECT_EQ(d[0].verified, std::optional<bool>(true));
  EXPECT_NEAR(*d[0].confidence, 2.0 / 3.0, 1e-6);
  EXPECT_EQ(d[0].checks.back().name, "confidence");
  EXPECT_EQ(d[0].checks.size(), 2u) << "the score check is replaced, not kept beside";
  // Above its score threshold, below the working point: rejected, and the check says why.
  EXPECT_EQ(d[1].verified, std::optional<bool>(false));
  EXPECT_EQ(d[1].Rejection().rfind("confidence", 0), 0u) << d[1].Rejection();
  // The free-space check still rejects, whatever the confidence.
  EXPECT_EQ(d[2].verified, std::optional<bool>(false));
  EXPECT_EQ(d[2].Rejection().rfind("free_space_ratio", 0), 0u) << d[2].Rejection();
  // Uncalibrated class: its thresholds' verdict, no confidence.
  EXPECT_FALSE(d[3].confidence);
  EXPECT_EQ(d[3].verified, std::optional<bool>(false));
  EXPECT_EQ(d[3].checks.back().name, "score");
}

TEST(Calibration, MalformedFilesNameTheField) {
  struct Case {
    json file;
    std::string needle;
  } cases[] = {
      {json::array(), "expected a JSON object"},
      {{{"method", "logistic"}}, "/furnihost_calibration"},
      {{{"furnihost_calibration", 1}, {"method", "isotonic"}, {"classes", {{"chair", json::object()}}}}, "/method"},
      {{{"furnihost_calibration", 1}, {"method", "logistic"}, {"classes", json::object()}}, "/classes"},
      {{{"furnihost_calibration", 1}, {"method", "logistic"}, {"classes", {{"chair", {{"coef", {1, 2}}, {"intercept", 0}}}}}},
       "/classes/chair/coef"},
      {{{"furnihost_calibration", 1}, {"method", "logistic"},
        {"classes", {{"chair", {{"features", {"height"}}, {"coef", {1}}, {"intercept", 0}}}}}},
       "/classes/chair/features/0"},
      {{{"furnihost_calibration", 1}, {"method", "logistic"}, {"classes", {{"chair", {{"coef", {1}}, {"intercept", "x"}}}}}},
       "/classes/chair/intercept"},
  };
  for (const auto& c : cases) {
    const std::string path = Write("bad.json", c.file);
    try {
      Calibration::Load(path);
      ADD_FAILURE() << "accepted " << c.file.dump();
    } catch (const furnihost::InputError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_NE(what.find(c.needle), std::string::npos) << what;
    }
  }
}

TEST(Calibration, ReliabilityBinsAndExpectedCalibrationError) {
  // 0.15 x4 (1 true), 0.85 x4 (all true), 1.0 (true; the last bin holds 1).
  std::vector<std::pair<float, bool>> p = {{0.15f, true}, {0.15f, false}, {0.15f, false}, {0.15f, false},
                                           {0.85f, true}, {0.85f, true},  {0.85f, true},  {0.85f, true},
                                           {1.0f, true}};
  const furnihost::Reliability r = furnihost::MakeReliability(p);
  ASSERT_EQ(r.bins.size(), 10u);
  EXPECT_EQ(r.detections, 9);
  EXPECT_EQ(r.bins[1].n, 4);
  EXPECT_NEAR(r.bins[1].accuracy, 0.25, 1e-9);
  EXPECT_EQ(r.bins[8].n, 4);
  EXPECT_EQ(r.bins[9].n, 1);
  EXPECT_EQ(r.bins[0].n, 0);
  EXPECT_TRUE(std::isnan(r.bins[0].confidence));
  EXPECT_NEAR(r.ece, (4 * 0.1 + 4 * 0.15 + 1 * 0.0) / 9.0, 1e-6);
}

// A graph without a calibration runs, says so, and its detections carry no confidence; the same
// graph with one gives every detection its confidence and decides at min_confidence, which
// --min-confidence moves.
TEST(Calibration, AGraphWithoutACalibrationSaysSoAndOneWithItDecidesByConfidence) {
  const std::string dir = furnihost::testing::TempDir("calibration_cli");
  fs::remove_all(dir);
  const json plain = furnihost::testing::StubGraph(dir, json::object());
  auto r = furnihost::testing::DetectStubRoom(dir + "/plain", plain);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("no calibration in"), std::string::npos) << r.err;
  const json a = furnihost::ReadJson(dir + "/plain/out/detections.json");
  ASSERT_FALSE(a["detections"].empty()) << "vacuous: nothing detected";
  for (const auto& d : a["detections"]) EXPECT_TRUE(d["confidence"].is_null()) << d.dump();

  // The stub's class is "cube", its score a part count (>= 1): confidence sigmoid(-3) = 0.047.
  json map = ChairMap(0.0, -3.0);
  map["classes"]["cube"] = map["classes"]["chair"];
  fs::create_directories(dir + "/cal");
  furnihost::AtomicWriteText(dir + "/cal/map.json", map.dump());
  json calibrated = plain;
  calibrated["calibration"] = {{"file", "map.json"}};  // relative to the graph's file
  r = furnihost::testing::DetectStubRoom(dir + "/cal", calibrated);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("calibration: " + dir + "/cal/map.json"), std::string::npos) << r.err;
  const json b = furnihost::ReadJson(dir + "/cal/out/detections.json");
  ASSERT_EQ(b["detections"].size(), a["detections"].size());
  for (const auto& d : b["detections"]) {
    EXPECT_NEAR(d["confidence"].get<double>(), 1.0 / (1.0 + std::exp(3.0)), 1e-6) << d.dump();
    EXPECT_EQ(d["verified"], false) << d.dump();
  }
  r = furnihost::testing::DetectStubRoom(dir + "/cal", calibrated, "--min-confidence 0.04");
  ASSERT_EQ(r.code, 0) << r.err;
  const json c = furnihost::ReadJson(dir + "/cal/out/detections.json");
  for (const auto& d : c["detections"]) EXPECT_EQ(d["verified"], true) << d.dump();
  // A missing calibration file is a one-line error naming the config's key, exit 2.
  calibrated["calibration"]["file"] = "nothere.json";
  r = furnihost::testing::DetectStubRoom(dir + "/cal", calibrated);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("/calibration/file"), std::string::npos) << r.err;
  EXPECT_EQ(furnihost::testing::ErrorLines(r.err).size(), 1u) << r.err;
  r = furnihost::testing::DetectStubRoom(dir + "/cal", plain, "--min-confidence 2");
  EXPECT_EQ(r.code, 2) << r.err;
  if (!HasFailure()) fs::remove_all(dir);
}

namespace {
// A detection of `cls` with a box from `lo` to `hi` (axis-aligned), its confidence, accepted or not.
Detection Boxed(const std::string& cls, Eigen::Vector3f lo, Eigen::Vector3f hi, float confidence, bool accepted) {
  Detection d;
  d.cls = cls;
  d.score = confidence;
  d.confidence = confidence;
  d.verified = accepted;
  furnihost::OrientedBox b;
  b.center = 0.5f * (lo + hi);
  b.size = hi - lo;
  d.box = b;
  return d;
}
}  // namespace

// calibration.part_of "chair:sofa": an armchair reading of a sofa's seat, inside an accepted sofa
// more probable than it, is dropped; two chairs inside a sofa that together are more probable than
// the sofa stay (two armchairs side by side read as a sofa); a chair beside the sofa, or inside a
// sofa that is not accepted, stays; every other detection and the order stay.
TEST(Calibration, PartOfDropsASeatReadAsAChairInsideAMoreProbableSofa) {
  using V = Eigen::Vector3f;
  const auto pairs = furnihost::PartOfPairs({"chair : sofa"}, "part_of");
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0], std::make_pair(std::string("chair"), std::string("sofa")));
  std::vector<Detection> d = {
      Boxed("sofa", V(0, 0, 0), V(1.6, 0.9, 0.8), 0.9f, true),           // 0: a loveseat
      Boxed("chair", V(0.1, 0, 0), V(0.9, 0.8, 0.8), 0.45f, false),      // 1: its left seat, as an armchair
      Boxed("table", V(0.2, 0.1, 0), V(0.8, 0.6, 0.4), 0.3f, false),     // 2: another class inside: stays
      Boxed("chair", V(2.0, 0, 0), V(2.8, 0.8, 0.8), 0.7f, true),        // 3: a chair beside it
      Boxed("sofa", V(5, 0, 0), V(6.7, 0.9, 0.8), 0.6f, true),           // 4: two armchairs read as a sofa
      Boxed("chair", V(5, 0, 0), V(5.8, 0.85, 0.8), 0.5f, true),         // 5
      Boxed("chair", V(5.9, 0, 0), V(6.7, 0.85, 0.8), 0.45f, false),     // 6
      Boxed("sofa", V(9, 0, 0), V(10.6, 0.9, 0.8), 0.9f, false),         // 7: a sofa not accepted
      Boxed("chair", V(9.1, 0, 0), V(9.9, 0.8, 0.8), 0.2f, false),       // 8
      Boxed("chair", V(10.4, 0, 0), V(11.2, 0.8, 0.8), 0.1f, false)};    // 9: a quarter inside the sofa 7
  std::vector<Detection> kept = d;
  EXPECT_EQ(furnihost::DropParts(kept, pairs, 0.5), 1u);
  ASSERT_EQ(kept.size(), d.size() - 1);
  const std::vector<size_t> expect = {0, 2, 3, 4, 5, 6, 7, 8, 9};
  for (size_t k = 0; k < expect.size(); ++k) EXPECT_EQ(kept[k].box->center, d[expect[k]].box->center) << k;
  // The sofa 7 accepted: its seat goes too, the chair mostly outside it stays.
  d[7].verified = true;
  kept = d;
  EXPECT_EQ(furnihost::DropParts(kept, pairs, 0.5), 2u);
  EXPECT_EQ(kept.size(), d.size() - 2);
  // No pairs, nothing dropped; a malformed pair names the parameter.
  kept = d;
  EXPECT_EQ(furnihost::DropParts(kept, {}, 0.5), 0u);
  for (const char* bad : {"chair", "chair:", ":sofa", "chair:chair", "chair:sofa:bed"}) {
    try {
      furnihost::PartOfPairs({bad}, "g.json:/calibration/part_of");
      ADD_FAILURE() << bad << " accepted";
    } catch (const furnihost::InputError& e) {
      EXPECT_NE(std::string(e.what()).find("g.json:/calibration/part_of"), std::string::npos) << e.what();
    }
  }
}
