// fitters.ransac_upright's recognition by analysis by synthesis (synthesis: true): its free-space check
// and the joint choice of readings.
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

// A view of `obj` (or of nothing there: `present` false) and a proposal of what the view sees of
// it, for a synthesis hypothesis of class `cls`; the scan has its sensor origin.
struct SynthesisView {
  SimScan sim;
  Proposals props;
  Detection Hypothesis(const std::string& cls, float score) const {
    Detection h;
    h.cls = cls;
    h.score = score;
    h.proposal = 0;
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (int i : props.items[0].indices) sum += sim.scan.pose * sim.scan.points[size_t(i)];
    h.center = sum / float(props.items[0].indices.size());
    return h;
  }
  FitContext Ctx(const Catalog& cat) const {
    FitContext ctx;
    ctx.scenes.push_back({&sim.scan, nullptr, nullptr, &props});
    ctx.catalog = cat.Ptrs();
    ctx.run.seed = 5;
    return ctx;
  }
};
SynthesisView ViewOf(const Mesh& mesh, const Eigen::Isometry3f& pose, uint64_t seed) {
  SynthesisView v;
  World w;
  w.AddRoom(5.f, 2.5f);
  w.Add(mesh, pose, 0);
  const Eigen::Vector3f centre = pose * BoundsOf(mesh).center();
  v.sim = SimulateObject(w, kSensor, centre, 1.2f, 160, 0.003f, 0.05f, seed, kScanPose, true);
  Proposal p;
  for (size_t i = 0; i < v.sim.scan.points.size(); ++i)
    if (v.sim.object[i] == 0) {
      p.indices.push_back(int(i));
      p.box.extend(v.sim.scan.points[i]);
    }
  v.props.items.push_back(p);
  return v;
}

const nlohmann::json kSynthesis = {{"synthesis", true}, {"default_threshold", 0.0}, {"cloud_cache", "off"}};

// The free-space check of the analysis by synthesis: a chair that the view sees is accepted
// where it stands, with little of its rendered surface where the sensor saw through; a thin
// post standing where the chair stood, read as a chair, is refused by the free-space check
// (free_space_ratio, the first check): every pose of a chair model that explains the post puts
// its seat and back where the sensor saw the floor and the wall behind.
TEST(Synthesis, AModelWhereTheSensorSawThroughIsRejectedByTheFreeSpaceCheck) {
  const Catalog cat = FurnitureCatalog();
  const Eigen::Isometry3f where = Upright(1.6f, 0.7f, 2.2f);
  const SynthesisView chair = ViewOf(cat.Get("chair_a").mesh, where, 21);
  const auto got = MakeFitter(kSynthesis)->Fit({chair.Hypothesis("chair", 0.3f)}, chair.Ctx(cat));
  ASSERT_EQ(got.size(), 1u);
  ASSERT_TRUE(got[0].free_space_ratio.has_value());
  EXPECT_TRUE(got[0].verified.value_or(false)) << got[0].Rejection();
  EXPECT_LT(*got[0].free_space_ratio, 0.1f);
  EXPECT_LT((got[0].center - where * BoundsOf(cat.Get("chair_a").mesh).center()).head<2>().norm(), 0.1f);
  ASSERT_FALSE(got[0].checks.empty());
  EXPECT_EQ(got[0].checks[0].name, "free_space_ratio");

  Mesh post;
  AddBox(&post, nullptr, 0, Eigen::Vector3f(-0.025f, -0.025f, 0.f), Eigen::Vector3f(0.025f, 0.025f, 0.8f));
  const SynthesisView thin = ViewOf(post, where, 22);
  ASSERT_GT(thin.props.items[0].indices.size(), 50u);
  const auto out = MakeFitter(kSynthesis)->Fit({thin.Hypothesis("chair", 0.3f)}, thin.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  const Detection& d = out[0];
  ASSERT_TRUE(d.free_space_ratio.has_value());
  EXPECT_GT(*d.free_space_ratio, 0.2f);
  EXPECT_FALSE(d.verified.value_or(true));
  EXPECT_EQ(d.Rejection().rfind("free_space_ratio ", 0), 0u) << d.Rejection();
  std::printf("[ synthesis ] chair: free_space_ratio %.3f; a post read as a chair: %.3f\n", *got[0].free_space_ratio,
              *d.free_space_ratio);
}

// The joint choice: two readings of one chair (as chair and as table) keep the better one; the
// other is explained away (its surface explained already, its box on the kept one's).
TEST(Synthesis, AnObjectReadAsTwoClassesKeepsTheBetterReading) {
  const Catalog cat = FurnitureCatalog();
  const SynthesisView chair = ViewOf(cat.Get("chair_b").mesh, Upright(1.5f, -0.4f, 0.7f), 23);
  const auto out = MakeFitter(kSynthesis)->Fit({chair.Hypothesis("chair", 0.3f), chair.Hypothesis("table", 0.05f)},
                                              chair.Ctx(cat));
  ASSERT_EQ(out.size(), 2u);
  const Detection& c = out[0].cls == "chair" ? out[0] : out[1];
  const Detection& t = out[0].cls == "chair" ? out[1] : out[0];
  EXPECT_TRUE(c.verified.value_or(false)) << c.Rejection();
  EXPECT_FALSE(t.verified.value_or(true));
  EXPECT_GT(c.score, t.score);
  EXPECT_NE(std::find(t.notes.begin(), t.notes.end(), "explained away by better-scored detections"), t.notes.end());
  EXPECT_TRUE(t.evidence.at("syn_new_share") < 0.5f ||
              std::any_of(t.checks.begin(), t.checks.end(),
                          [](const Check& k) { return k.name == "box_iou_with_kept" && !k.passed; }))
      << t.Rejection();
}

// The class competition (class_compete_exponent): a chair read as chair and as table with equal
// priors: the table's model explains less of the chair than the chair's (its pose objective is
// lower), so the table reading is weighed down by the ratio and the chair reading is not.
TEST(Synthesis, TheClassWhosePosedModelExplainsMoreOfAnObjectWins) {
  const Catalog cat = FurnitureCatalog();
  const SynthesisView chair = ViewOf(cat.Get("chair_b").mesh, Upright(1.5f, -0.4f, 0.7f), 23);
  nlohmann::json p = kSynthesis;
  p["class_compete_exponent"] = 2.0;
  const auto out = MakeFitter(p)->Fit({chair.Hypothesis("chair", 0.2f), chair.Hypothesis("table", 0.2f)}, chair.Ctx(cat));
  ASSERT_EQ(out.size(), 2u);
  const Detection& c = out[0].cls == "chair" ? out[0] : out[1];
  const Detection& t = out[0].cls == "chair" ? out[1] : out[0];
  ASSERT_TRUE(c.evidence.count("syn_compete") && t.evidence.count("syn_compete"));
  EXPECT_FLOAT_EQ(c.evidence.at("syn_compete"), 1.f);
  EXPECT_LT(t.evidence.at("syn_compete"), 0.8f);
  EXPECT_GT(c.score, t.score);
  EXPECT_TRUE(c.verified.value_or(false)) << c.Rejection();
  EXPECT_FALSE(t.verified.value_or(true));
  std::printf("[ synthesis ] a chair read as table: competition factor %.3f\n", t.evidence.at("syn_compete"));
}

// The view prior (view_prior_exponent): a chair model posed on a view of a chair is compared
// with what the sensor saw of it, part for part: the measured points about the posed model look
// like the part of the model the sensor should see (a high view prior); the same view read as a
// table gets a lower one.
TEST(Synthesis, AChairsViewLooksLikeThePartOfAChairModelTheSensorShouldSee) {
  const Catalog cat = FurnitureCatalog();
  const SynthesisView chair = ViewOf(cat.Get("chair_a").mesh, Upright(1.6f, 0.7f, 2.2f), 21);
  nlohmann::json p = kSynthesis;
  p["view_prior_exponent"] = 1.0;
  const auto c = MakeFitter(p)->Fit({chair.Hypothesis("chair", 0.3f)}, chair.Ctx(cat));
  const auto t = MakeFitter(p)->Fit({chair.Hypothesis("table", 0.3f)}, chair.Ctx(cat));
  ASSERT_EQ(c.size(), 1u);
  ASSERT_EQ(t.size(), 1u);
  ASSERT_TRUE(c[0].evidence.count("syn_view_prior") && t[0].evidence.count("syn_view_prior"));
  EXPECT_GT(c[0].evidence.at("syn_view_prior"), 0.3f);
  EXPECT_GT(c[0].evidence.at("syn_view_prior"), t[0].evidence.at("syn_view_prior"));
  std::printf("[ synthesis ] view prior of a chair's view: as chair %.3f, as table %.3f\n",
              c[0].evidence.at("syn_view_prior"), t[0].evidence.at("syn_view_prior"));
}

}  // namespace
