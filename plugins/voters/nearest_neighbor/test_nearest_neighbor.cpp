// voters.nearest_neighbor on the hand-built views of the hough tests, and side by side with
// voters.hough_vocabulary on the same scene.
#include <gtest/gtest.h>

#include <algorithm>

#include "test_support.hpp"
#include "synthetic_views.hpp"

namespace furnihost {
namespace {

using nlohmann::json;
using synth::Chair;
using synth::MakeScene;
using synth::MakeViews;
using synth::Pose;
using synth::Table;

Registry& Reg() {
  static auto reg = testing::MakeRegistry();
  return *reg;
}

std::shared_ptr<Voter> MakeVoter(const std::string& type, const json& params) {
  const auto* entry = Reg().Find(type);
  if (!entry) throw std::runtime_error("plugin not found: " + type);
  return Reg().CreateAs<Voter>(type, entry->params.Resolve(params, "test"));
}

const json kThresholds = {{"chair", 1.5}, {"table", 1.5}};

std::vector<TrainingView> Views() { return MakeViews({Chair(), Table()}, 2, 4, 0.02f, 7); }

float Dist2D(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return (a.head<2>() - b.head<2>()).norm();
}

TEST(NearestNeighbor, EachPartCastsOneUnitVoteAndObjectsAreFound) {
  RunContext ctx;
  auto voter = MakeVoter("voters.nearest_neighbor", {{"thresholds", kThresholds}});
  const json model = voter->Train(Views(), ctx);
  EXPECT_EQ(model.at("format"), "voters.nearest_neighbor/3");
  // One word per training part.
  EXPECT_EQ(model.at("words").size(), model.at("class").size() * synth::kDim);

  const std::vector<synth::SceneObject> objects = {{Chair(), {1.f, 1.f, 0.45f}, {}},
                                                   {Chair(), {2.5f, 1.2f, 0.45f}, {}},
                                                   {Table(), {2.f, 3.f, 0.45f}, {}}};
  const auto scene = MakeScene(objects, Pose(-1.f, 0.5f, 2.0f), 0.02f, 3);
  const VoteResult r = voter->Vote({scene.Parts()}, ctx);
  ASSERT_EQ(r.votes.size(), scene.seg.parts.size());
  for (const auto& v : r.votes) EXPECT_EQ(v.w(), 1.f);

  // A chair's seat and back vote exactly at its centre (mass 2 >= 1.5 wherever its legs'
  // nearest training legs send their votes), so every chair is found within half its width.
  // The table is clutter here: its legs' nearest training legs point to any of four offsets.
  for (const auto& o : objects) {
    if (o.spec.cls != "chair") continue;
    bool found = false;
    for (const auto& h : r.hypotheses)
      found = found || (h.cls == "chair" && Dist2D(h.center, o.center) < 0.5f * 0.51f);
    EXPECT_TRUE(found) << "chair at " << o.center.transpose();
  }
  for (const auto& h : r.hypotheses) EXPECT_GE(h.score, 1.5f);

  // Round trip through CBOR votes identically.
  auto loaded = MakeVoter("voters.nearest_neighbor", {{"thresholds", kThresholds}});
  loaded->Load(json::from_cbor(json::to_cbor(model)));
  const VoteResult r2 = loaded->Vote({scene.Parts()}, ctx);
  ASSERT_EQ(r2.votes.size(), r.votes.size());
  for (size_t i = 0; i < r.votes.size(); ++i) EXPECT_EQ(r.votes[i], r2.votes[i]);
  ASSERT_EQ(r2.hypotheses.size(), r.hypotheses.size());
  for (size_t i = 0; i < r.hypotheses.size(); ++i) EXPECT_EQ(r.hypotheses[i].center, r2.hypotheses[i].center);
}

TEST(NearestNeighbor, InverseDistanceWeightsAreAtMostOne) {
  RunContext ctx;
  auto voter = MakeVoter("voters.nearest_neighbor",
                         {{"thresholds", kThresholds}, {"weighting", "inverse_distance"}});
  voter->Train(Views(), ctx);
  const auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}}, Eigen::Isometry3f::Identity(), 0.05f, 2);
  const VoteResult r = voter->Vote({scene.Parts()}, ctx);
  ASSERT_EQ(r.votes.size(), scene.seg.parts.size());
  for (const auto& v : r.votes) {
    EXPECT_LT(v.w(), 1.f);
    EXPECT_GT(v.w(), 0.8f);  // feature noise 0.05 per dimension: distance well below 0.25
  }
}

TEST(NearestNeighbor, MaxDistanceKeepsExactlyThePartsWithinIt) {
  // inverse_distance weights give each part's distance to its nearest training part
  // (w = 1 / (1 + d)); with max_distance at the median of those distances, exactly the parts
  // at or below it vote (the kd-tree search is bounded by it, the cut must stay exact).
  RunContext ctx;
  const json base = {{"thresholds", kThresholds}, {"weighting", "inverse_distance"}};
  auto all = MakeVoter("voters.nearest_neighbor", base);
  const json model = all->Train(Views(), ctx);
  const auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}, {Table(), {3.f, 2.5f, 0.45f}, {}}},
                               Pose(0.5f, 0.f, 0.3f), 0.15f, 4);
  const VoteResult r = all->Vote({scene.Parts()}, ctx);
  ASSERT_EQ(r.votes.size(), scene.seg.parts.size());
  std::vector<float> d;
  for (const auto& v : r.votes) d.push_back(1.f / v.w() - 1.f);
  std::sort(d.begin(), d.end());
  ASSERT_GT(d.back(), d.front() + 0.05f) << "the scene noise should spread the distances";
  const float cut = d[d.size() / 2];
  const auto within = std::count_if(d.begin(), d.end(), [&](float x) { return x <= cut + 1e-4f; });
  const auto beyond = std::count_if(d.begin(), d.end(), [&](float x) { return x > cut + 1e-4f; });
  ASSERT_GT(beyond, 0);

  json cut_params = base;
  cut_params["max_distance"] = cut + 1e-4f;
  auto bounded = MakeVoter("voters.nearest_neighbor", cut_params);
  bounded->Load(model);
  const VoteResult rb = bounded->Vote({scene.Parts()}, ctx);
  EXPECT_EQ(static_cast<long>(rb.votes.size()), within);
  for (const auto& v : rb.votes) EXPECT_LE(1.f / v.w() - 1.f, cut + 2e-4f);
}

TEST(NearestNeighbor, AgreesWithHoughVocabularyOnACleanScene) {
  // Both voters see the same synthetic room; on clean parts both put the chair at its centre.
  RunContext ctx;
  auto nn = MakeVoter("voters.nearest_neighbor", {{"thresholds", kThresholds}});
  auto hough = MakeVoter("voters.hough_vocabulary", {{"k", 8}, {"thresholds", kThresholds}});
  const auto views = Views();
  nn->Train(views, ctx);
  hough->Train(views, ctx);
  const auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}, {Table(), {3.f, 2.5f, 0.45f}, {}}},
                               Pose(0.f, 0.f, 0.7f), 0.01f, 8);
  const VoteResult a = nn->Vote({scene.Parts()}, ctx);
  const VoteResult b = hough->Vote({scene.Parts()}, ctx);
  const Eigen::Vector3f chair(1.f, 1.f, 0.45f);
  for (const VoteResult* r : {&a, &b}) {
    int near = 0;
    for (const auto& h : r->hypotheses) near += h.cls == "chair" && Dist2D(h.center, chair) < 0.05f;
    EXPECT_EQ(near, 1);
  }
}

TEST(NearestNeighbor, RefusesAHoughModel) {
  RunContext ctx;
  auto hough = MakeVoter("voters.hough_vocabulary", {{"k", 8}});
  const json model = hough->Train(Views(), ctx);
  auto nn = MakeVoter("voters.nearest_neighbor", json::object());
  EXPECT_THROW(nn->Load(model), StageError);
}

}  // namespace
}  // namespace furnihost
