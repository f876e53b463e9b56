// Single views with objects in contact, through the shipped single-view graph (configs/rgbd_view.json
// on the bundled catalog), as a user runs it: `furnihost simulate` makes a depth camera's view of
// a table with a chair, the chair pushed under the table (its seat below the top, its back
// against the top's edge) or pulled out; the view is detected with its sensor origin.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "furnihost/host/io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

// The accepted detections of a view of a table (sh3d_table) and a chair (sh3d_chair) standing at
// `chair_y` (the table's centre at y = 2.7, its near edge at 2.325), facing the camera.
std::vector<nlohmann::json> AcceptedInView(const std::string& name, float chair_y, nlohmann::json* truth) {
  const std::string src = furnihost::testing::SourceDir();
  const std::string dir = furnihost::testing::TempDir("single_views_" + name);
  nlohmann::json scene = nlohmann::json::parse(R"({"room": {"size_m": [5, 4.5], "height_m": 2.6},
    "objects": [{"model": "sh3d_table", "x": 2.5, "y": 2.7},
                {"model": "sh3d_chair", "x": 2.5, "y": 0, "yaw_deg": 180, "under": true}],
    "sensors": [{"position": [2.2, 0.4, 1.3], "yaw_deg": 80, "pitch_deg": 20}],
    "sensor_params": {"pattern": "depth_camera", "width": 320, "height": 240, "focal_px": 262.5, "noise_a": 0.002,
                      "noise_b": 0.0015, "dropout": 0.05, "camera_max_range_m": 6.0}})");
  scene["objects"][1]["y"] = chair_y;
  furnihost::AtomicWriteText(dir + "/scene.json", scene.dump());
  auto r = furnihost::testing::RunFurnihost("simulate -q --catalog " + src + "/data/catalog/catalog.json --scene " + dir +
                                            "/scene.json --out " + dir + "/view.ply --per-sensor --sensor-frame --min-visible 200");
  if (r.code != 0) {
    ADD_FAILURE() << r.err;
    return {};
  }
  furnihost::AtomicWriteText(dir + "/g.json", nlohmann::json({{"extends", src + "/configs/rgbd_view.json"},
                                                              {"catalog", src + "/data/catalog/catalog.json"},
                                                              {"model_cache", dir + "/model.fhm"}})
                                                  .dump());
  r = furnihost::testing::RunFurnihost("-q --graph " + dir + "/g.json " + dir + "/view.ply --origin 0,0,0 --out " + dir +
                                       "/out");
  if (r.code != 0) {
    ADD_FAILURE() << r.err;
    return {};
  }
  *truth = furnihost::ReadJson(dir + "/view.gt.json").at("objects");
  std::vector<nlohmann::json> a;
  const nlohmann::json j = furnihost::ReadJson(dir + "/out/detections.json");
  for (const auto& d : j.at("detections"))
    if (d.value("verified", false)) a.push_back(d);
  fs::remove_all(dir);
  return a;
}

// Exactly one accepted detection per ground-truth object, of its class, within half its width
// of its centre on the floor plane (the paper's rule), and nothing else accepted.
void ExpectTheTableAndTheChair(const std::vector<nlohmann::json>& accepted, const nlohmann::json& truth) {
  ASSERT_EQ(truth.size(), 2u);
  EXPECT_EQ(accepted.size(), 2u);
  std::vector<char> used(accepted.size(), 0);
  for (const auto& o : truth) {
    const float radius = 0.5f * std::max(o.at("size")[0].get<float>(), o.at("size")[1].get<float>());
    bool found = false;
    for (size_t i = 0; i < accepted.size() && !found; ++i) {
      const auto& d = accepted[i];
      if (used[i] || d.at("class") != o.at("class")) continue;
      const float dx = d.at("center")[0].get<float>() - o.at("center")[0].get<float>();
      const float dy = d.at("center")[1].get<float>() - o.at("center")[1].get<float>();
      if (std::hypot(dx, dy) > radius) continue;
      used[i] = found = true;
    }
    EXPECT_TRUE(found) << "no accepted " << o.at("class") << " at " << o.at("center");
  }
  for (size_t i = 0; i < accepted.size(); ++i)
    EXPECT_TRUE(used[i]) << "false positive: " << accepted[i].at("class") << " at " << accepted[i].at("center");
}

}  // namespace

// The chair pushed under the table touches it: one cluster. The table top's plane separates
// what stands under it (proposals.clusters support_splits), and the analysis by synthesis keeps
// the table and the chair that explain the view together: two detections, not one.
TEST(SingleViews, AChairPushedUnderATableIsTwoObjects) {
  nlohmann::json truth;
  const auto accepted = AcceptedInView("under", 2.42f, &truth);
  if (HasFatalFailure()) return;
  ExpectTheTableAndTheChair(accepted, truth);
}

// The same view with the chair pulled out gives the same two.
TEST(SingleViews, TheChairPulledOutIsTheSameTwoObjects) {
  nlohmann::json truth;
  const auto accepted = AcceptedInView("out", 1.7f, &truth);
  if (HasFatalFailure()) return;
  ExpectTheTableAndTheChair(accepted, truth);
}
