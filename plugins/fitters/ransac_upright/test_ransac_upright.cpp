// fitters.ransac_upright through the registry, on ray-cast scans of box-built furniture: pose recovery,
// dense scans, the scan's ground, the points of the support, the voter's centre, the model-cloud cache.
// Tolerances: pose recovery within 3 cm (bounding-box centre, world frame) and 5° (yaw).
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

TEST(RansacUpright, RecoversChairPoseAndModel) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = kChairPose;
  const int s = AddChair(cat, &sc, &parts);
  ASSERT_GT(sc.scans[0]->scan.points.size(), 1500u);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  const Detection& d = out[0];
  EXPECT_EQ(d.model, "chair_a");
  const PoseError e = ErrorOf(d, cat.Get("chair_a"), truth);
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
  ASSERT_TRUE(d.verified.has_value());
  EXPECT_TRUE(*d.verified) << d.Rejection();
  ASSERT_TRUE(d.coverage && d.free_space_ratio && d.rms);  // the scan has an origin: the test ran
  EXPECT_GT(*d.coverage, 0.8f);
  EXPECT_GE(*d.free_space_ratio, 0.f);
  EXPECT_LT(*d.free_space_ratio, 0.2f);
  EXPECT_GT(*d.rms, 0.f);
  EXPECT_LT(*d.rms, 0.015f);
  EXPECT_GT(d.iterations, 0);
  // model_pose maps the model's bbox centre onto the reported centre.
  EXPECT_LT((d.model_pose * BoundsOf(cat.Get("chair_a").mesh).center() - d.center).norm(), 1e-4f);
}

// A dense scan (a tilting laser close by: ~10x the part points of the tests above): each
// candidate is scored on at most max_score_points of them and the final coverage on an even
// subset, which must find the same model and pose as scoring on all of them, and about the same
// coverage.
TEST(RansacUpright, DenseScanFitsOnASubsetAsOnAllPoints) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = sc.Add(ScanOf(cat.Get("chair_a"), kChairPose, 1, true, true, 300), 0, &parts);
  const Detection h = Hypothesis(sc, "chair", s, parts);
  const auto sub = MakeFitter()->Fit({h}, sc.Ctx(cat));  // default: max_score_points 2000
  const auto all = MakeFitter({{"max_score_points", 0}})->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(sub.size(), 1u);
  ASSERT_EQ(all.size(), 1u);
  ASSERT_TRUE(sub[0].coverage && all[0].coverage);
  size_t part_points = 0;
  for (int p : parts) part_points += sc.segs[0]->parts[p].indices.size();
  ASSERT_GT(part_points, 4u * 2000u);  // both caps bind
  for (const Detection* d : {&sub[0], &all[0]}) {
    EXPECT_EQ(d->model, "chair_a");
    const PoseError e = ErrorOf(*d, cat.Get("chair_a"), kChairPose);
    EXPECT_LT(e.centre, kCentreTol);
    EXPECT_LT(e.yaw, kYawTol);
    EXPECT_TRUE(d->verified.value_or(false)) << d->Rejection();
  }
  EXPECT_NEAR(*sub[0].coverage, *all[0].coverage, 0.03f);
}

// A scan whose floor is 0.6 m below z = 0 (a robot's sensor frame, say): the models stand on
// the scan's ground (Scan::ground, in the scan's frame, here posed 0.6 m down), never on z = 0.
// A ground put at world z = 0 leaves every model 0.6 m too high and nothing fits; the ground
// the pipeline estimates from the scan (the room's floor is in view) fits the chair, as a level
// ground fixed at the true height does.
TEST(RansacUpright, ModelsStandOnTheScansGround) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = Upright(1.8f, 0.9f, 2.2f);
  SimScan sim = ScanOf(cat.Get("chair_a"), truth, 1);
  const Eigen::Isometry3f down(Eigen::Translation3f(0.f, 0.f, -0.6f));
  sim.scan.pose = down * sim.scan.pose;
  const int s = sc.Add(std::move(sim), 0, &parts);
  const Detection h = Hypothesis(sc, "chair", s, parts);
  Scan& scan = sc.scans[0]->scan;
  const GroundModel estimated = EstimateGround(scan.points, GroundOptions{});
  EXPECT_NEAR(scan.pose.translation().z() + estimated.HeightAt(1.8f, 0.9f), -0.6f, 0.005f);
  scan.ground = GroundModel::Level(0.6f, "fixed");  // world z = 0
  const auto at_zero = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(at_zero.size(), 1u);
  EXPECT_FALSE(at_zero[0].verified.value_or(true));
  // One RANSAC draw each (the sampling path changes with any change of the floor height, so
  // the two fits differ by sampling; the statistical accuracy bound is AccuracyOverRandomPlacements').
  for (const GroundModel& g : {estimated, GroundModel::Level(0.f, "fixed")}) {
    scan.ground = g;
    const auto out = MakeFitter()->Fit({h}, sc.Ctx(cat));
    ASSERT_EQ(out.size(), 1u);
    const Detection& d = out[0];
    EXPECT_TRUE(d.verified.value_or(false)) << ToString(g.kind) << ": " << d.Rejection();
    EXPECT_EQ(d.model, "chair_a");
    const Eigen::Vector3f c = down * truth * BoundsOf(cat.Get("chair_a").mesh).center();
    EXPECT_NEAR(d.center.z(), c.z(), 0.006f);  // stands on the floor
    EXPECT_LT((d.center - c).head<2>().norm(), 2 * kCentreTol);
    EXPECT_LT(ErrorOf(d, cat.Get("chair_a"), down * truth).yaw, kYawTol);
    // The box is the fitted model's: its bottom on the ground, its size the model's.
    ASSERT_TRUE(d.box.has_value());
    EXPECT_EQ(d.box_source, "model");
    EXPECT_NEAR(d.box->center.z() - 0.5f * d.box->size.z(), -0.6f, 0.006f);
    EXPECT_TRUE(d.box->size.isApprox(BoundsOf(cat.Get("chair_a").mesh).sizes(), 1e-4f));
  }
}

// The voter's support holds every part with a vote near the maximum, background parts (floor,
// walls) included: they are left out of the fit, else they dilute the coverage.
TEST(RansacUpright, BackgroundPartsInTheSupportAreLeftOut) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = kChairPose;
  const int s = AddChair(cat, &sc, &parts);
  const int background = static_cast<int>(sc.segs[s]->parts.size()) - 1;  // PartsOf puts the rest last
  ASSERT_EQ(std::find(parts.begin(), parts.end(), background), parts.end());
  Detection h = Hypothesis(sc, "chair", s, parts);
  h.support.push_back({s, background, 1.f});
  const auto out = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "chair_a");
  const PoseError e = ErrorOf(out[0], cat.Get("chair_a"), truth);
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
  EXPECT_TRUE(out[0].verified.value_or(false)) << out[0].Rejection();
  const std::string note = "support: 1 of " + std::to_string(h.support.size()) + " parts out of the class' reach";
  EXPECT_TRUE(std::any_of(out[0].notes.begin(), out[0].notes.end(),
                          [&](const std::string& n) { return n.rfind(note, 0) == 0; }));
  // Left out rather than cropped: the same pose.
  const auto left_out = MakeFitter({{"crop_parts", false}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(left_out[0].model, "chair_a");
  EXPECT_LT(ErrorOf(left_out[0], cat.Get("chair_a"), truth).centre, kCentreTol);
  // Without the filter the background's points count against the chair.
  const auto all = MakeFitter({{"part_inside_fraction", 0.0}})->Fit({h}, sc.Ctx(cat));
  std::printf("[ support ] coverage %.3f with the background part cropped to the reach, %.3f with all of it\n", out[0].coverage.value_or(-1.f),
              all[0].coverage.value_or(-1.f));
  ASSERT_TRUE(out[0].coverage && all[0].coverage);
  EXPECT_LT(*all[0].coverage, *out[0].coverage - 0.1f);
}

// max_shift_m: a hypothesis whose centre is 0.3 m off the chair. Unlimited, the fit finds the
// chair; limited to 0.15 m, no pose may put the centre farther than that from the hypothesis
// (the fit then covers too little and is rejected); limited to 0.5 m, the chair again.
TEST(RansacUpright, MaxShiftKeepsTheFitNearTheVotersCentre) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = kChairPose;
  const int s = AddChair(cat, &sc, &parts);
  Detection h = Hypothesis(sc, "chair", s, parts);
  const Eigen::Vector3f true_centre = truth * BoundsOf(cat.Get("chair_a").mesh).center();
  h.center = true_centre + Eigen::Vector3f(0.3f, 0.f, 0.f);
  const auto free = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(free.size(), 1u);
  EXPECT_LT(ErrorOf(free[0], cat.Get("chair_a"), truth).centre, kCentreTol);
  EXPECT_TRUE(free[0].verified.value_or(false)) << free[0].Rejection();

  const auto tight = MakeFitter({{"max_shift_m", 0.15}})->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(tight.size(), 1u);
  if (!tight[0].model.empty()) {
    EXPECT_LE((tight[0].center - h.center).head<2>().norm(), 0.15f + 1e-4f);
  }
  EXPECT_FALSE(tight[0].verified.value_or(true));

  const auto loose = MakeFitter({{"max_shift_m", 0.5}})->Fit({h}, sc.Ctx(cat));
  EXPECT_LT(ErrorOf(loose[0], cat.Get("chair_a"), truth).centre, kCentreTol);
  EXPECT_TRUE(loose[0].verified.value_or(false)) << loose[0].Rejection();

  EXPECT_THROW(MakeFitter({{"max_shift_m", -0.1}}), std::exception);
}

// cloud_cache: the first fitter samples the class's models and writes one file per model; a
// new fitter (a new run) reads them and fits exactly as the sampling one did; 'off' writes
// nothing; an unwritable folder only warns.
TEST(RansacUpright, ModelCloudsAreCachedBetweenRuns) {
  namespace fs = std::filesystem;
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = AddChair(cat, &sc, &parts);
  const Detection h = Hypothesis(sc, "chair", s, parts);
  const std::string dir = furnihost::testing::TempDir("cloud_cache") + "/clouds";
  auto files = [&] {
    size_t n = 0;
    if (fs::exists(dir))
      for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ".fhmc";
    return n;
  };
  const auto off = MakeFitter({{"cloud_cache", "off"}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(files(), 0u);
  const auto first = MakeFitter({{"cloud_cache", dir}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(files(), 2u);  // chair_a and chair_b; the table is not of the class
  const auto again = MakeFitter({{"cloud_cache", dir}})->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(first.size(), 1u);
  ASSERT_EQ(again.size(), 1u);
  ExpectSameFit(first[0], off[0]);
  ExpectSameFit(again[0], off[0]);
  const auto unwritable = MakeFitter({{"cloud_cache", "/proc/furnihost_no_such_dir"}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(unwritable[0].center, off[0].center);
  fs::remove_all(fs::path(dir).parent_path());
}

TEST(RansacUpright, RecoversTablePoseUpToItsSymmetry) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = Upright(-1.6f, 1.4f, 0.3f);
  const int s = sc.Add(ScanOf(cat.Get("table_a"), truth, 2), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "table", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "table_a");
  const PoseError e = ErrorOf(out[0], cat.Get("table_a"), truth, kPi);  // a rectangle: 180° symmetric
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
  EXPECT_TRUE(out[0].verified.value_or(false)) << out[0].Rejection();
}

}  // namespace
