// FuseDetections (the graph's "ensemble"): runs' detections of one object joined by box IoU,
// scored by the runs that found it, boxes averaged, the score check re-decided, and the first
// run's detection speaking for its object.
#include <gtest/gtest.h>

#include <cmath>

#include "furnihost/geometry.hpp"
#include "furnihost/host/pipeline.hpp"

using namespace furnihost;

namespace {

// A detection whose box is centred at (x, y, size.z / 2), accepted by a score check at `limit`.
Detection Boxed(const std::string& cls, float x, float y, Eigen::Vector3f size, float score, float limit = 0.2f,
                float yaw = 0.f, int proposal = 0) {
  Detection d;
  d.cls = cls;
  d.score = score;
  d.center = {x, y, 0.5f * size.z()};
  OrientedBox b;
  b.center = d.center;
  b.size = size;
  b.yaw = yaw;
  d.box = b;
  d.model_pose = UprightPose(x, y, 0.f, yaw);
  d.proposal = proposal;
  d.support = {{0, proposal, 1.f}};
  d.checks.push_back(Check::AtLeast("score", score, limit));
  d.verified = d.checks.back().passed;
  return d;
}

const Detection* Near(const std::vector<Detection>& ds, const std::string& cls, float x, float y) {
  for (const auto& d : ds)
    if (d.cls == cls && std::hypot(d.center.x() - x, d.center.y() - y) < 0.2f) return &d;
  return nullptr;
}

}  // namespace

TEST(FuseDetections, JoinsOneObjectAcrossRunsAndScoresItByTheRunsThatFoundIt) {
  const Eigen::Vector3f chair(0.6f, 0.5f, 0.9f);
  std::vector<std::vector<Detection>> runs(4);
  // A chair every run finds, a few cm apart; run 2 gives it a quarter turn (length and width swapped).
  runs[0].push_back(Boxed("chair", 1.00f, 2.00f, chair, 0.40f, 0.2f, 0.f, 7));
  runs[1].push_back(Boxed("chair", 1.04f, 2.00f, chair, 0.50f, 0.2f, 0.f, 3));
  runs[2].push_back(Boxed("chair", 1.00f, 2.04f, {0.5f, 0.6f, 0.9f}, 0.30f, 0.2f, float(M_PI / 2), 4));
  runs[3].push_back(Boxed("chair", 0.96f, 1.96f, chair, 0.20f, 0.2f, 0.f, 5));
  // A second chair in run 1 over the first: one run gives an object one member only.
  runs[1].push_back(Boxed("chair", 1.02f, 2.02f, chair, 0.45f, 0.2f, 0.f, 9));
  // A table where the chair is: another class, never joined with it.
  runs[0].push_back(Boxed("table", 1.00f, 2.00f, {1.2f, 0.8f, 0.75f}, 0.30f, 0.1f));
  // A chair one run of four accepts: fused, it falls below its threshold (0.36 / 4 < 0.2).
  runs[3].push_back(Boxed("chair", 5.00f, 5.00f, chair, 0.36f, 0.2f, 0.f, 11));
  // A table the first run rejected (0.12 < 0.15) and the other three found higher: fused 0.16, accepted.
  runs[0].push_back(Boxed("table", 3.00f, 0.00f, {1.2f, 0.8f, 0.75f}, 0.12f, 0.15f));
  for (int r = 1; r < 4; ++r) runs[size_t(r)].push_back(Boxed("table", 3.02f, 0.00f, {1.2f, 0.8f, 0.75f}, 0.18f, 0.15f));
  // Boxes 0.3 m apart along 0.6 m: IoU 1/3 joins at 0.3, not at 0.5.
  runs[0].push_back(Boxed("sofa", 8.0f, 0.0f, {0.6f, 0.6f, 0.8f}, 0.2f, 0.1f));
  runs[1].push_back(Boxed("sofa", 8.3f, 0.0f, {0.6f, 0.6f, 0.8f}, 0.2f, 0.1f));

  const auto fused = FuseDetections(runs, 0.3);
  ASSERT_EQ(fused.size(), 6u);  // chair, its second run-1 copy, two tables, the lone chair, sofa
  for (size_t i = 1; i < fused.size(); ++i) EXPECT_GE(fused[i - 1].score, fused[i].score);  // by score

  const Detection* c = Near(fused, "chair", 1.f, 2.f);
  ASSERT_NE(c, nullptr);
  // Members: 0.50 (run 1, the top), 0.40, 0.30, 0.20; run 1's 0.45 is left alone.
  EXPECT_NEAR(c->score, (0.5f + 0.4f + 0.3f + 0.2f) / 4.f, 1e-6f);
  EXPECT_EQ(c->evidence.at("ensemble_runs"), 4.f);
  EXPECT_EQ(c->proposal, 7);  // the first run's member speaks for the object
  ASSERT_TRUE(c->box.has_value());
  EXPECT_NEAR(c->box->center.x(), 1.0f, 1e-5f);
  EXPECT_NEAR(c->box->center.y(), 2.0f, 1e-5f);
  EXPECT_NEAR(c->box->size.x(), 0.6f, 1e-5f);  // run 2's turned box counted as 0.6 x 0.5
  EXPECT_NEAR(c->box->size.y(), 0.5f, 1e-5f);
  EXPECT_NEAR((c->center - c->box->center).norm(), 0.f, 1e-5f);
  EXPECT_NEAR(c->model_pose.translation().x(), 1.0f, 1e-5f);
  EXPECT_TRUE(c->verified.value_or(false));
  ASSERT_EQ(c->checks.size(), 1u);
  EXPECT_NEAR(c->checks[0].value, c->score, 1e-6);

  int chairs_near = 0;
  for (const auto& d : fused) chairs_near += d.cls == "chair" && d.center.x() < 2.f;
  EXPECT_EQ(chairs_near, 2);
  const Detection* t = Near(fused, "table", 1.f, 2.f);
  ASSERT_NE(t, nullptr);
  EXPECT_NEAR(t->score, 0.30f / 4.f, 1e-6f);

  const Detection* lone = Near(fused, "chair", 5.f, 5.f);
  ASSERT_NE(lone, nullptr);
  EXPECT_NEAR(lone->score, 0.09f, 1e-6f);
  EXPECT_FALSE(lone->verified.value_or(true));  // accepted by one run, rejected fused
  EXPECT_NE(lone->Rejection(), "");
  EXPECT_FALSE(lone->checks[0].passed);
  EXPECT_EQ(lone->proposal, -1);  // not the first run's: its proposal index would name another run's proposal
  EXPECT_TRUE(lone->support.empty());

  const Detection* late = Near(fused, "table", 3.f, 0.f);
  ASSERT_NE(late, nullptr);
  EXPECT_NEAR(late->score, (0.12f + 3 * 0.18f) / 4.f, 1e-6f);
  EXPECT_TRUE(late->verified.value_or(false));
  EXPECT_EQ(late->Rejection(), "");
  EXPECT_EQ(late->proposal, 0);  // the first run's, though it was not the top

  EXPECT_EQ(FuseDetections(runs, 0.5).size(), 7u);  // the sofas stay apart at 0.5
}

TEST(FuseDetections, OneRunIsItselfAndTheOrderOfTiesIsFixed) {
  std::vector<std::vector<Detection>> one(1);
  one[0].push_back(Boxed("chair", 0.f, 0.f, {0.5f, 0.5f, 0.9f}, 0.3f));
  one[0].push_back(Boxed("chair", 3.f, 0.f, {0.5f, 0.5f, 0.9f}, 0.3f));
  Detection boxless = Boxed("table", 9.f, 9.f, {1.f, 1.f, 1.f}, 0.5f);
  boxless.box.reset();
  one[0].push_back(boxless);
  const auto f = FuseDetections(one, 0.3);
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0].cls, "table");
  EXPECT_FLOAT_EQ(f[0].score, 0.5f);
  EXPECT_FLOAT_EQ(f[1].center.x(), 0.f);  // tied scores keep their order
  EXPECT_FLOAT_EQ(f[2].center.x(), 3.f);
  EXPECT_TRUE(FuseDetections({}, 0.3).empty());
}
