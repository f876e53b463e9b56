// fitters.ransac_upright's determinism (threads, the rest of the list) and its accuracy over random
// placements. Tolerances: pose recovery within 3 cm (bounding-box centre, world frame) and 5° (yaw).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "furnihost/geometry.hpp"
#include "furnihost/host/ground_estimation.hpp"
#include "furnihost/stage.hpp"
#include "test_ransac_upright_scenes.hpp"

namespace {

using namespace ransac_test;
using ransac_test::Hypothesis;  // the helper, not furnihost::Hypothesis

// One scan of a room with a chair (object 0) and a table (object 1); each object's parts are
// a scene of their own (the same scan twice).
struct ChairAndTableRoom {
  Scenes sc;
  std::vector<int> chair_parts, table_parts;
  int chair_scene = 0, table_scene = 0;
};
ChairAndTableRoom MakeChairAndTableRoom() {
  ChairAndTableRoom r;
  World w;
  w.AddRoom(5.f, 2.5f);
  const Furniture chair = Chair(0.45f, 0.45f, 0.45f, 0.45f), table = Table(1.2f, 0.8f, 0.75f);
  w.Add(chair.mesh, Upright(1.8f, 0.9f, 2.2f), 0, &chair.component);
  w.Add(table.mesh, Upright(1.2f, -1.4f, 0.3f), 1, &table.component);
  const SimScan room = Simulate(w, kSensor, -1.6f, 1.0f, 200, -0.9f, 0.1f, 60, 0.003f, 0.05f, 9, kScanPose);
  r.chair_scene = r.sc.Add(room, 0, &r.chair_parts);
  r.table_scene = r.sc.Add(room, 1, &r.table_parts);
  return r;
}

TEST(RansacUpright, DeterministicForASeedWhateverTheThreads) {
  const Catalog cat = FurnitureCatalog();
  const ChairAndTableRoom room = MakeChairAndTableRoom();
  const Scenes& sc = room.sc;
  const std::vector<Detection> in = {Hypothesis(sc, "chair", room.chair_scene, room.chair_parts),
                                     Hypothesis(sc, "table", room.table_scene, room.table_parts),
                                     Hypothesis(sc, "chair", room.table_scene, room.table_parts)};
  auto run = [&](int threads, uint64_t seed) { return MakeFitter()->Fit(in, sc.Ctx(cat, threads, seed)); };
  const auto a = run(1, 11), b = run(2, 11);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE("detection " + std::to_string(i));
    ExpectSameFit(a[i], b[i]);
    EXPECT_EQ(a[i].notes, b[i].notes);
  }
  EXPECT_TRUE(a[0].verified.value_or(false)) << a[0].Rejection();
  EXPECT_TRUE(a[1].verified.value_or(false)) << a[1].Rejection();
  EXPECT_FALSE(a[2].verified.value_or(true));  // chair models on the table's points
  // Another seed samples differently (the iteration counts are the seed's footprint).
  const auto c = run(2, 12);
  int differs = 0;
  for (size_t i = 0; i < a.size(); ++i) differs += a[i].iterations != c[i].iterations || a[i].yaw != c[i].yaw;
  EXPECT_GT(differs, 0);
}

// A hypothesis's RANSAC seed comes from the hypothesis, not its place in the list: fitted alone,
// behind others or in reverse order it gives the same pose (A/B runs that change one class's
// hypotheses leave the other classes' fits alone).
TEST(RansacUpright, AHypothesisFitsTheSameWhateverElseIsInTheList) {
  const Catalog cat = FurnitureCatalog();
  const ChairAndTableRoom room = MakeChairAndTableRoom();
  const Scenes& sc = room.sc;
  const Detection c = Hypothesis(sc, "chair", room.chair_scene, room.chair_parts),
                  t = Hypothesis(sc, "table", room.table_scene, room.table_parts);
  const auto fit = [&](const std::vector<Detection>& in) { return MakeFitter()->Fit(in, sc.Ctx(cat, 1, 5)); };
  const auto both = fit({c, t}), reversed = fit({t, c}), alone = fit({t});
  ASSERT_EQ(both.size(), 2u);
  ASSERT_EQ(reversed.size(), 2u);
  ASSERT_EQ(alone.size(), 1u);
  ExpectSameFit(reversed[0], both[1]);
  ExpectSameFit(alone[0], both[1]);
  EXPECT_EQ(reversed[1].yaw, both[0].yaw);
  EXPECT_EQ(reversed[1].iterations, both[0].iterations);
  EXPECT_TRUE(both[1].verified.value_or(false)) << both[1].Rejection();
}

// Accuracy over random placements (both chair models, random x, y, yaw): prints median and
// 90th percentile of the centre and yaw errors, for RANSAC alone (the paper) and with the
// optional upright ICP steps. Both: p90 within the tolerance, no placement off by more than
// twice the centre tolerance; the refinement lowers the median centre error by 30 % and halves
// the median yaw error at least. (Some placements of chair_b end a few cm off with or without
// the refinement, whichever the seed: the ICP steps do not leave that local minimum.)
// 20 random placements of the two chairs, fitted without refinement, with 5 point-to-point
// ICP steps and with 5 point-to-plane steps. Every fit must pick the right model and land
// within tolerance at p90 (one placement in ~20 lands 3.5-4 cm off whatever the seed: a
// RANSAC pose in a neighbouring basin that neither refinement leaves, hence the looser max).
// Each refinement must sharpen the median: point-to-point by 30 % (centre) and 50 % (yaw),
// point-to-plane at least twice as much again.
TEST(RansacUpright, AccuracyOverRandomPlacements) {
  const Catalog cat = FurnitureCatalog();
  struct Variant {
    int refine;
    const char* metric;
  };
  const Variant variants[] = {{0, "point"}, {5, "point"}, {5, "plane"}};
  float median_centre[3] = {0.f, 0.f, 0.f}, median_yaw[3] = {0.f, 0.f, 0.f};
  for (int v = 0; v < 3; ++v) {
    const Variant& var = variants[v];
    std::mt19937_64 rng(2024);
    std::uniform_real_distribution<float> uni(0.f, 1.f);
    std::vector<float> ce, ye;
    int right_model = 0;
    const int kRuns = 20;
    auto fitter = MakeFitter({{"refine_iterations", var.refine}, {"refine_metric", var.metric}});
    for (int r = 0; r < kRuns; ++r) {
      const std::string id = r % 2 ? "chair_b" : "chair_a";
      const float rad = 1.5f + 1.5f * uni(rng), az = 2 * kPi * uni(rng), yaw = 2 * kPi * uni(rng) - kPi;
      const Eigen::Isometry3f truth = Upright(rad * std::cos(az), rad * std::sin(az), yaw);
      Scenes sc;
      std::vector<int> parts;
      const int s = sc.Add(ScanOf(cat.Get(id), truth, 100 + r), 0, &parts);
      const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat, 0, 500 + r));
      ASSERT_EQ(out.size(), 1u);
      right_model += out[0].model == id;
      const PoseError e = ErrorOf(out[0], cat.Get(id), truth);
      ce.push_back(e.centre);
      ye.push_back(e.yaw);
    }
    auto quantile = [](std::vector<float> x, double q) {
      std::sort(x.begin(), x.end());
      return x[std::min(x.size() - 1, static_cast<size_t>(q * (x.size() - 1) + 0.5))];
    };
    std::printf("[ accuracy ] refine_iterations %d (%s), %d placements: right model %d; centre error median %.4f m, "
                "p90 %.4f m, max %.4f m; yaw error median %.2f deg, p90 %.2f deg, max %.2f deg\n",
                var.refine, var.metric, kRuns, right_model, quantile(ce, 0.5), quantile(ce, 0.9), quantile(ce, 1.0),
                quantile(ye, 0.5) * 180 / kPi, quantile(ye, 0.9) * 180 / kPi, quantile(ye, 1.0) * 180 / kPi);
    const std::string what = std::to_string(var.refine) + " " + var.metric;
    EXPECT_EQ(right_model, kRuns) << what;
    EXPECT_LT(quantile(ce, 0.9), kCentreTol) << what;
    EXPECT_LT(quantile(ye, 0.9), kYawTol) << what;
    EXPECT_LT(quantile(ce, 1.0), 2 * kCentreTol) << what;
    median_centre[v] = quantile(ce, 0.5);
    median_yaw[v] = quantile(ye, 0.5);
  }
  EXPECT_LT(median_centre[1], 0.7f * median_centre[0]);
  EXPECT_LT(median_yaw[1], 0.5f * median_yaw[0]);
  EXPECT_LT(median_centre[2], 0.5f * median_centre[1]);
  EXPECT_LT(median_yaw[2], 0.5f * median_yaw[1]);
}

}  // namespace
