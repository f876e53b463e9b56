// fitters.ransac_upright's verification: coverage, tied models, observed free space, proposal
// hypotheses, one class per object, the recogniser's accepted detections, bad support.
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

// A scanned chair whose class has one catalog model, a table mesh filed as a chair: no pose of it
// covers the chair's points.
struct WrongShapeScene {
  Catalog cat;
  Scenes sc;
  std::vector<int> parts;
  int scene = 0;
};
WrongShapeScene MakeWrongShapeScene() {
  WrongShapeScene w;
  w.cat.models.push_back(Model("table_as_chair", "chair", Table(1.2f, 0.8f, 0.75f).mesh));
  const CatalogModel chair = Model("real_chair", "chair", Chair(0.45f, 0.45f, 0.45f, 0.45f).mesh);
  w.scene = w.sc.Add(ScanOf(chair, Upright(1.8f, 0.9f, 2.2f), 3), 0, &w.parts);
  return w;
}

TEST(RansacUpright, WrongShapeIsRejectedByCoverage) {
  const WrongShapeScene w = MakeWrongShapeScene();
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(w.sc, "chair", w.scene, w.parts)}, w.sc.Ctx(w.cat));
  ASSERT_EQ(out.size(), 1u);
  const Detection& d = out[0];
  ASSERT_TRUE(d.verified.has_value());
  EXPECT_FALSE(*d.verified);
  // The checks say what was measured and why it failed: coverage below min_coverage.
  ASSERT_EQ(d.checks.size(), 1u);
  EXPECT_EQ(d.checks[0].name, "coverage");
  EXPECT_FALSE(d.checks[0].passed);
  EXPECT_TRUE(d.checks[0].at_least);
  EXPECT_DOUBLE_EQ(d.checks[0].limit, 0.5);
  ASSERT_TRUE(d.coverage);
  EXPECT_FLOAT_EQ(float(d.checks[0].value), *d.coverage);
  EXPECT_EQ(d.Rejection().rfind("coverage ", 0), 0u) << d.Rejection();
  EXPECT_NE(d.Rejection().find(" < 0.5"), std::string::npos) << d.Rejection();
  EXPECT_GE(*d.coverage, 0.f);
  EXPECT_LT(*d.coverage, 0.5f);
  EXPECT_EQ(d.model, "table_as_chair");  // the pose that was rejected is still reported
}

// Seen from the front, a small cabinet's points are covered just as well by a wider cabinet of
// the same depth and height: the tie is broken by the share of each model explained.
TEST(RansacUpright, TiedModelsAreRankedByTheShareOfThemselvesExplained) {
  Catalog cat;
  Mesh wide, narrow;
  AddBox(&wide, nullptr, 0, {-0.6f, -0.25f, 0.f}, {0.6f, 0.25f, 0.6f});
  AddBox(&narrow, nullptr, 0, {-0.2f, -0.25f, 0.f}, {0.2f, 0.25f, 0.6f});
  cat.models.push_back(Model("wide_cabinet", "cabinet", wide));
  cat.models.push_back(Model("narrow_cabinet", "cabinet", narrow));
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = Upright(0.f, 2.5f, 0.f);  // front face towards the sensor
  const int s = sc.Add(ScanOf(cat.Get("narrow_cabinet"), truth, 8), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "cabinet", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "narrow_cabinet");
  ASSERT_FALSE(out[0].notes.empty());
  // Both models reached (about) full coverage: the choice was the tie-break, not coverage.
  EXPECT_EQ(out[0].notes[0].find("abandoned"), std::string::npos) << out[0].notes[0];
  const PoseError e = ErrorOf(out[0], cat.Get("narrow_cabinet"), truth, kPi);  // a box: 180° symmetric
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
}

// The chair's points come from a reconstruction without origin; a second scan with a sensor
// origin saw the room without the chair, so its rays cross where the chair would stand.
TEST(RansacUpright, ModelInObservedFreeSpaceIsRejected) {
  const Catalog cat = FurnitureCatalog();
  const CatalogModel& chair = cat.Get("chair_a");
  const Eigen::Isometry3f where = Upright(1.8f, 0.9f, 2.2f);
  for (bool chair_in_laser_scan : {false, true}) {
    Scenes sc;
    std::vector<int> parts;
    sc.Add(ScanOf(chair, where, 4, true, chair_in_laser_scan), -2, nullptr);  // laser scan, origin known
    const int s = sc.Add(ScanOf(chair, where, 5, false), 0, &parts);            // chair points, no origin
    auto fitter = MakeFitter();
    const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat));
    ASSERT_EQ(out.size(), 1u);
    const Detection& d = out[0];
    EXPECT_EQ(d.model, "chair_a");
    ASSERT_TRUE(d.coverage && d.free_space_ratio);
    EXPECT_GE(*d.coverage, 0.5f);
    // Two checks, in order: coverage (passed), then free space.
    ASSERT_EQ(d.checks.size(), 2u);
    EXPECT_EQ(d.checks[0].name, "coverage");
    EXPECT_TRUE(d.checks[0].passed);
    EXPECT_EQ(d.checks[1].name, "free_space_ratio");
    EXPECT_FALSE(d.checks[1].at_least);
    EXPECT_EQ(d.checks[1].passed, chair_in_laser_scan);
    if (chair_in_laser_scan) {
      EXPECT_TRUE(d.verified.value_or(false)) << d.Rejection();
      EXPECT_LT(*d.free_space_ratio, 0.2f);
    } else {
      EXPECT_FALSE(d.verified.value_or(true));
      EXPECT_GT(*d.free_space_ratio, 0.5f);
      EXPECT_EQ(d.Rejection().rfind("free_space_ratio ", 0), 0u) << d.Rejection();
    }
    EXPECT_GE(*d.free_space_ratio, 0.f);
    std::printf("[ free space ] chair %s the laser scan: free_space_ratio %.3f, coverage %.3f\n",
                chair_in_laser_scan ? "in" : "missing from", *d.free_space_ratio, *d.coverage);
  }
}

TEST(RansacUpright, ScanWithoutOriginSkipsTheFreeSpaceTest) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = sc.Add(ScanOf(cat.Get("chair_b"), Upright(-1.2f, -1.9f, -0.8f), 6, false), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "chair_b");
  EXPECT_TRUE(out[0].verified.value_or(false)) << out[0].Rejection();
  EXPECT_FALSE(out[0].free_space_ratio.has_value());
  EXPECT_NE(std::find(out[0].notes.begin(), out[0].notes.end(), "free-space test skipped: scan has no sensor origin"),
            out[0].notes.end());
}

// A recogniser of object proposals (voters.catalog_shape) names a proposal, not parts, and the
// graph has no segmentation: the fitter takes the proposal's points and estimates their normals
// itself (without them every sample would draw a random yaw, and 10 samples rarely find the
// pose).
TEST(RansacUpright, ProposalHypothesesFitTheProposalsPointsAndFreeSpaceChoosesAmongTiedPoses) {
  const Catalog cat = FurnitureCatalog();
  const CatalogModel& chair = cat.Get("chair_b");
  const SimScan sim = ScanOf(chair, kChairPose, 11);
  Proposals props;
  Proposal prop;
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  for (size_t i = 0; i < sim.scan.points.size(); ++i)
    if (sim.object[i] == 0) {
      prop.indices.push_back(static_cast<int>(i));
      sum += sim.scan.pose * sim.scan.points[i];
    }
  ASSERT_GT(prop.indices.size(), 1000u);
  props.items.push_back(prop);
  FitContext ctx;
  ctx.scenes.push_back({&sim.scan, nullptr, nullptr, &props});  // no segmentation: no normals
  ctx.catalog = cat.Ptrs();
  ctx.run.seed = 3;
  Detection h;
  h.cls = "chair";
  h.score = 0.3f;
  h.center = sum / float(prop.indices.size());
  h.proposal = 0;
  // Seen from one side, the chair is covered as well by its turn by 180 degrees pushed back,
  // which free space refuses: free_space_alternatives then takes the near-tied right pose.
  int refused_by_free_space = 0;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    ctx.run.seed = seed;
    const auto plain = MakeFitter()->Fit({h}, ctx);
    ASSERT_EQ(plain.size(), 1u);
    EXPECT_EQ(plain[0].model, "chair_b") << "seed " << seed;
    EXPECT_GT(plain[0].coverage.value_or(0.f), 0.95f) << "seed " << seed;
    refused_by_free_space += !plain[0].verified.value_or(false);
    const auto out = MakeFitter({{"free_space_alternatives", true}})->Fit({h}, ctx);
    const PoseError e = ErrorOf(out[0], chair, kChairPose);
    EXPECT_TRUE(out[0].verified.value_or(false)) << "seed " << seed << ": " << out[0].Rejection();
    EXPECT_LT(e.centre, kCentreTol) << "seed " << seed;
    EXPECT_LT(e.yaw, kYawTol) << "seed " << seed;
    if (!plain[0].verified.value_or(false)) {
      EXPECT_EQ(plain[0].Rejection().rfind("free_space_ratio ", 0), 0u) << plain[0].Rejection();
      EXPECT_NE(out[0].notes.back().find("a near-tied pose passes"), std::string::npos) << out[0].notes.back();
    }
  }
  EXPECT_GT(refused_by_free_space, 0);  // the case the option is for occurred
  // A proposal the scene does not have is refused.
  h.proposal = 1;
  EXPECT_THROW(MakeFitter()->Fit({h}, ctx), StageError);
}

// one_class_per_object: two accepted readings of one proposal (its box overlapping another's by
// more than object_iou) keep only the higher-scored class; a proposal elsewhere is untouched.
TEST(RansacUpright, OneClassPerObjectRefusesTheWeakerReadingOfAProposal) {
  const Catalog cat = FurnitureCatalog();
  const SimScan sim = ScanOf(cat.Get("chair_b"), kChairPose, 12);
  Proposals props;
  Proposal chair_points, background;
  for (size_t i = 0; i < sim.scan.points.size(); ++i) {
    Proposal& p = sim.object[i] == 0 ? chair_points : background;
    p.indices.push_back(static_cast<int>(i));
    p.box.extend(sim.scan.points[i]);
  }
  ASSERT_FALSE(background.indices.empty());
  props.items = {chair_points, chair_points, background};
  FitContext ctx;
  ctx.scenes.push_back({&sim.scan, nullptr, nullptr, &props});
  ctx.catalog = cat.Ptrs();
  // Each accepted by its recogniser; keep_accepted with floor 0 keeps them whatever the fit says.
  auto accepted = [&](const std::string& cls, float score, int proposal) {
    Detection d;
    d.cls = cls;
    d.score = score;
    d.proposal = proposal;
    d.center = sim.scan.pose * props.items[size_t(proposal)].box.center();
    d.verified = true;
    d.checks = {Check::AtLeast("score", score, 0.1)};
    return d;
  };
  const std::vector<Detection> in = {accepted("table", 0.3f, 1), accepted("chair", 0.6f, 0),
                                     accepted("table", 0.2f, 2)};
  const nlohmann::json keep = {{"keep_accepted", true}, {"keep_min_coverage", 0.0}};
  nlohmann::json exclusive = keep;
  exclusive["one_class_per_object"] = true;
  const auto both = MakeFitter(keep)->Fit(in, ctx);
  const auto one = MakeFitter(exclusive)->Fit(in, ctx);
  ASSERT_EQ(both.size(), 3u);
  ASSERT_EQ(one.size(), 3u);
  for (const Detection& d : both) EXPECT_TRUE(d.verified.value_or(false)) << d.cls << ": " << d.Rejection();
  EXPECT_FALSE(one[0].verified.value_or(true));  // the table reading of the chair's points
  EXPECT_EQ(one[0].Rejection(), "iou_with_stronger_class 1 > 0.5");
  EXPECT_NE(one[0].notes.back().find("the same object as an accepted chair"), std::string::npos) << one[0].notes.back();
  EXPECT_TRUE(one[1].verified.value_or(false)) << one[1].Rejection();
  EXPECT_TRUE(one[2].verified.value_or(false)) << one[2].Rejection();  // the room around: another object
}

// keep_accepted: what the recogniser accepted on its own stays accepted, with its checks and box,
// when the fit fails, unless the fit covers less than keep_min_coverage (it contradicts it).
TEST(RansacUpright, KeepAcceptedTrustsTheRecogniserUnlessTheFitContradictsIt) {
  const WrongShapeScene w = MakeWrongShapeScene();
  const Catalog& cat = w.cat;
  const Scenes& sc = w.sc;
  Detection h = Hypothesis(sc, "chair", w.scene, w.parts);
  const auto plain = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_TRUE(plain[0].coverage.has_value());
  const float c = *plain[0].coverage;
  ASSERT_FALSE(plain[0].verified.value_or(true));
  ASSERT_GT(c, 0.02f);
  h.verified = true;  // as voters.catalog_shape leaves an accepted proposal
  h.checks = {Check::AtLeast("score", 0.3, 0.2)};
  h.box = OrientedBox{h.center, Eigen::Vector3f(0.45f, 0.45f, 0.9f), 0.f};
  h.box_source = "proposal";
  for (const float floor : {c - 0.01f, c + 0.01f}) {
    const auto out = MakeFitter({{"keep_accepted", true}, {"keep_min_coverage", floor}})->Fit({h}, sc.Ctx(cat));
    ASSERT_EQ(out.size(), 1u);
    const Detection& d = out[0];
    if (floor < c) {
      EXPECT_TRUE(d.verified.value_or(false));
      ASSERT_EQ(d.checks.size(), 1u);
      EXPECT_EQ(d.checks[0].name, "score");
      EXPECT_EQ(d.Rejection(), "");
      EXPECT_EQ(d.box_source, "proposal");
      EXPECT_EQ(d.center, h.center);
      ASSERT_TRUE(d.evidence.count("fit_coverage"));
      EXPECT_FLOAT_EQ(d.evidence.at("fit_coverage"), c);
      EXPECT_NE(d.notes.back().find("kept, its recogniser accepted it"), std::string::npos) << d.notes.back();
    } else {
      EXPECT_FALSE(d.verified.value_or(true));
      EXPECT_EQ(d.Rejection().rfind("coverage ", 0), 0u) << d.Rejection();
    }
  }
  // A hypothesis its recogniser left undecided (or refused) is the fit's to decide.
  h.verified.reset();
  EXPECT_FALSE(MakeFitter({{"keep_accepted", true}, {"keep_min_coverage", 0.0}})
                   ->Fit({h}, sc.Ctx(cat))[0]
                   .verified.value_or(true));
}

// free_space_alternatives consults the near-tied poses only when free space refuses the best:
// a fit that passes is unchanged bit for bit, and a chair the laser saw through stays refused
// (no near-tied pose of it escapes the free space).
TEST(RansacUpright, FreeSpaceAlternativesOnlyReplaceARefusedPose) {
  const Catalog cat = FurnitureCatalog();
  const CatalogModel& chair = cat.Get("chair_a");
  for (bool chair_in_laser_scan : {false, true}) {
    Scenes sc;
    std::vector<int> parts;
    sc.Add(ScanOf(chair, kChairPose, 4, true, chair_in_laser_scan), -2, nullptr);
    const int s = sc.Add(ScanOf(chair, kChairPose, 5, false), 0, &parts);
    const Detection h = Hypothesis(sc, "chair", s, parts);
    const auto base = MakeFitter()->Fit({h}, sc.Ctx(cat));
    const auto alt = MakeFitter({{"free_space_alternatives", true}})->Fit({h}, sc.Ctx(cat));
    ASSERT_EQ(alt.size(), 1u);
    EXPECT_EQ(alt[0].verified.value_or(false), chair_in_laser_scan) << alt[0].Rejection();
    if (chair_in_laser_scan) ExpectSameFit(base[0], alt[0]);
  }
}

TEST(RansacUpright, ClassWithoutModelsAndBadSupport) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = sc.Add(ScanOf(cat.Get("chair_a"), Upright(1.8f, 0.9f, 2.2f), 7), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "sofa", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_FALSE(out[0].verified.value_or(true));
  ASSERT_EQ(out[0].checks.size(), 1u);
  EXPECT_EQ(out[0].checks[0].name, "catalog_models");
  EXPECT_EQ(out[0].Rejection(), "catalog_models 0 < 1");
  EXPECT_NE(std::find(out[0].notes.begin(), out[0].notes.end(), "no catalog model of class 'sofa'"), out[0].notes.end());
  EXPECT_THROW(fitter->Fit({Hypothesis(sc, "chair", s, {999})}, sc.Ctx(cat)), StageError);
  EXPECT_THROW(fitter->Fit({Hypothesis(sc, "chair", 3, parts)}, sc.Ctx(cat)), StageError);
}

}  // namespace
