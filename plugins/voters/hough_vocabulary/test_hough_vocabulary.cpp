// voters.hough_vocabulary on hand-built views (synthetic_views.hpp): known part offsets, so
// the vote geometry is known exactly. Tolerances: "within half a class width" is the paper's
// true-positive rule (Sect. VII-A); exact reproductions are checked to 1e-4 m (float sums).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "furnihost/host/ground_estimation.hpp"
#include "test_support.hpp"
#include "synthetic_views.hpp"
#include "voting/voting.hpp"

namespace furnihost {
namespace {

using nlohmann::json;
using synth::Chair;
using synth::MakeScene;
using synth::MakeViews;
using synth::Pose;
using synth::SceneObject;
using synth::Table;

constexpr const char* kType = "voters.hough_vocabulary";

Registry& Reg() {
  static auto reg = testing::MakeRegistry();
  return *reg;
}

std::shared_ptr<Voter> MakeVoter(const json& params, const char* type = kType) {
  const auto* entry = Reg().Find(type);
  if (!entry) throw std::runtime_error(std::string("plugin not found: ") + type);
  return Reg().CreateAs<Voter>(type, entry->params.Resolve(params, "test"));
}

json BaseParams() {
  return {{"k", 8}, {"thresholds", {{"chair", 1.5}, {"table", 1.5}}}};
}

std::vector<TrainingView> TwoClassViews() {
  return MakeViews({Chair(), Table()}, /*models=*/2, /*views=*/4, /*noise=*/0.02f, /*seed=*/7);
}

std::vector<const Hypothesis*> OfClass(const VoteResult& r, const std::string& cls) {
  std::vector<const Hypothesis*> out;
  for (const auto& h : r.hypotheses)
    if (h.cls == cls) out.push_back(&h);
  return out;
}

float Dist2D(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return (a.head<2>() - b.head<2>()).norm();
}

// Class width as the voter learns it: median over the models of max(size x, y).
constexpr float kChairWidth = 0.5f * 1.02f;  // models scaled 1.00 and 1.04
constexpr float kTableWidth = 1.2f * 1.02f;

TEST(HoughVocabulary, RecoversObjectsOfTwoClassesInARotatedScan) {
  auto voter = MakeVoter(BaseParams());
  RunContext ctx;
  voter->Train(TwoClassViews(), ctx);

  const std::vector<SceneObject> objects = {{Chair(), {1.f, 1.f, 0.45f}, {}},
                                            {Chair(), {2.5f, 1.2f, 0.45f}, {}},
                                            {Table(), {2.f, 3.f, 0.45f}, {}}};
  const auto scene = MakeScene(objects, Pose(0.5f, -0.3f, 0.5236f), 0.02f, 3);
  const VoteResult r = voter->Vote({scene.Parts()}, ctx);

  ASSERT_EQ(r.classes, (std::vector<std::string>{"chair", "table"}));
  ASSERT_EQ(r.grids.size(), 2u);
  EXPECT_GT(r.votes.size(), scene.seg.parts.size());
  // One hypothesis per object, each within half a class width of the truth; no extra ones.
  const auto chairs = OfClass(r, "chair");
  const auto tables = OfClass(r, "table");
  ASSERT_EQ(chairs.size(), 2u);
  ASSERT_EQ(tables.size(), 1u);
  for (size_t o = 0; o < objects.size(); ++o) {
    const auto& list = objects[o].spec.cls == "chair" ? chairs : tables;
    const float half = 0.5f * (objects[o].spec.cls == "chair" ? kChairWidth : kTableWidth);
    const Hypothesis* best = nullptr;
    for (const auto* h : list)
      if (!best || Dist2D(h->center, objects[o].center) < Dist2D(best->center, objects[o].center)) best = h;
    ASSERT_NE(best, nullptr);
    EXPECT_LT(Dist2D(best->center, objects[o].center), half) << "object " << o;
    // The heaviest supporting part belongs to this object, and the support adds up to the
    // score (every vote in the window comes from some part).
    ASSERT_FALSE(best->support.empty());
    EXPECT_EQ(scene.object_of_part.at(best->support.front().part), static_cast<int>(o));
    double sum = 0.0;
    for (const auto& s : best->support) {
      EXPECT_EQ(s.scene, 0);
      sum += s.weight;
    }
    EXPECT_NEAR(sum, best->score, 1e-3 * best->score);
    EXPECT_NEAR(best->center.z(), 0.45f, 0.05f);
  }
  // Hypotheses come sorted by score; each grid has the density of its class only.
  for (size_t i = 1; i < r.hypotheses.size(); ++i)
    EXPECT_GE(r.hypotheses[i - 1].score, r.hypotheses[i].score);
  for (const auto& g : r.grids) {
    EXPECT_EQ(g.values.size(), static_cast<size_t>(g.width) * g.height);
    EXPECT_GT(g.width, 0);
  }
}

TEST(HoughVocabulary, SingleTrainingViewVotesReproduceItsCentroid) {
  // One view, one model, parts with distinct features and one word per part: every word
  // element points from its part to the same centroid, so the view itself, seen through any
  // pose, votes exactly at the centroid (one activation: a second word would be another part's).
  synth::ClassSpec chair = Chair();
  for (size_t p = 0; p < chair.parts.size(); ++p) chair.parts[p].feature = synth::Proto(static_cast<int>(p), static_cast<int>(p + 3) % synth::kDim);
  auto views = MakeViews({chair}, 1, 1, 0.f, 1);
  auto voter = MakeVoter({{"k", 6}, {"activations", 1}, {"thresholds", {{"chair", 0.5}}}});
  RunContext ctx;
  voter->Train(views, ctx);
  for (const auto& pose : {Eigen::Isometry3f::Identity(), Pose(1.5f, -2.f, 1.1f)}) {
    synth::Scene s;
    s.scan = views[0].scan;
    s.scan.pose = pose;
    s.seg = views[0].segmentation;
    s.features = views[0].features;
    const Eigen::Vector3f truth = pose * views[0].object_centroid;
    // The centroid in world = pose * (part + d) = pose * part + R d; pose rotates about z only.
    const VoteResult r = voter->Vote({{&s.scan, &s.seg, &s.features}}, ctx);
    ASSERT_FALSE(r.votes.empty());
    for (const auto& v : r.votes) {
      EXPECT_NEAR(v.x(), truth.x(), 1e-4f);
      EXPECT_NEAR(v.y(), truth.y(), 1e-4f);
    }
    ASSERT_EQ(r.hypotheses.size(), 1u);
    EXPECT_NEAR((r.hypotheses[0].center - truth).norm(), 0.f, 1e-4f);
    // Each part has mass 1 for its class (eq. 4-5), all inside the window.
    EXPECT_NEAR(r.hypotheses[0].score, static_cast<float>(views[0].segmentation.parts.size()), 1e-3f);
    EXPECT_EQ(r.hypotheses[0].support.size(), views[0].segmentation.parts.size());
  }
}

TEST(HoughVocabulary, ShapeVectorsAreLearnedInTheViewingFrame) {
  // The sensor of the single training view stands at -y looking +y (a simulator circling a
  // model returns views in the model frame). The voter stores d turned by -90 deg, so the
  // view reproduces its centroid when presented in its viewing frame (x towards the object),
  // and not in the model frame.
  synth::ClassSpec chair = Chair();
  for (size_t p = 0; p < chair.parts.size(); ++p)
    chair.parts[p].feature = synth::Proto(static_cast<int>(p), static_cast<int>(p + 3) % synth::kDim);
  auto views = MakeViews({chair}, 1, 1, 0.f, 1);
  views[0].scan.origin = Eigen::Vector3f(0.f, -2.f, 1.5f);
  auto voter = MakeVoter({{"k", 6}, {"activations", 1}, {"thresholds", {{"chair", 0.5}}}});
  RunContext ctx;
  voter->Train(views, ctx);
  const Eigen::Vector3f truth = views[0].object_centroid;

  synth::Scene in_view;  // scan frame = viewing frame: model frame turned by -90 deg
  const Eigen::Isometry3f view_to_model(Eigen::AngleAxisf(1.5707963f, Eigen::Vector3f::UnitZ()));
  in_view.scan.pose = view_to_model;
  in_view.seg = views[0].segmentation;
  for (auto& part : in_view.seg.parts) part.centroid = view_to_model.inverse() * part.centroid;
  in_view.features = views[0].features;
  const VoteResult r = voter->Vote({in_view.Parts()}, ctx);
  ASSERT_FALSE(r.votes.empty());
  for (const auto& v : r.votes) EXPECT_LT((v.head<2>() - truth.head<2>()).norm(), 1e-4f);

  synth::Scene in_model;  // the training scan as it is: off-centre parts vote elsewhere
  in_model.seg = views[0].segmentation;
  in_model.features = views[0].features;
  const VoteResult m = voter->Vote({in_model.Parts()}, ctx);
  int off = 0;
  for (const auto& v : m.votes) off += (v.head<2>() - truth.head<2>()).norm() > 0.1f;
  EXPECT_GE(off, 5);  // every part but the seat (d = 0 in xy)
}

TEST(HoughVocabulary, TrainingIsDeterministicForASeed) {
  RunContext ctx;
  ctx.seed = 1234;
  const auto views = TwoClassViews();
  const json a = MakeVoter(BaseParams())->Train(views, ctx);
  const json b = MakeVoter(BaseParams())->Train(views, ctx);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a.at("format"), "voters.hough_vocabulary/3");
  EXPECT_EQ(a.at("words").size(), 8u * synth::kDim);
  EXPECT_EQ(a.at("class").size(), 2u * 4u * (6u + 5u));  // every training part is an element
}

TEST(HoughVocabulary, LoadAfterCborRoundTripVotesIdentically) {
  RunContext ctx;
  auto trained = MakeVoter(BaseParams());
  const json model = trained->Train(TwoClassViews(), ctx);
  auto loaded = MakeVoter(BaseParams());
  loaded->Load(json::from_cbor(json::to_cbor(model)));

  const auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}, {Table(), {2.f, 3.f, 0.45f}, {1}}},
                               Pose(0.2f, 0.1f, -0.4f), 0.02f, 5);
  const VoteResult a = trained->Vote({scene.Parts()}, ctx);
  const VoteResult b = loaded->Vote({scene.Parts()}, ctx);
  ASSERT_EQ(a.votes.size(), b.votes.size());
  for (size_t i = 0; i < a.votes.size(); ++i) EXPECT_EQ(a.votes[i], b.votes[i]) << i;
  ASSERT_EQ(a.hypotheses.size(), b.hypotheses.size());
  ASSERT_FALSE(a.hypotheses.empty());
  for (size_t i = 0; i < a.hypotheses.size(); ++i) {
    EXPECT_EQ(a.hypotheses[i].cls, b.hypotheses[i].cls);
    EXPECT_EQ(a.hypotheses[i].center, b.hypotheses[i].center);
    EXPECT_EQ(a.hypotheses[i].score, b.hypotheses[i].score);
    ASSERT_EQ(a.hypotheses[i].support.size(), b.hypotheses[i].support.size());
  }
  ASSERT_EQ(a.grids.size(), b.grids.size());
  for (size_t i = 0; i < a.grids.size(); ++i) EXPECT_EQ(a.grids[i].values, b.grids[i].values);
}

// The score of the best hypothesis of class `cls` within half a class width of `at` (0 if none).
float ScoreNear(const VoteResult& r, const std::string& cls, const Eigen::Vector3f& at, float width) {
  float best = 0.f;
  for (const auto* h : OfClass(r, cls))
    if (Dist2D(h->center, at) < 0.5f * width) best = std::max(best, h->score);
  return best;
}

TEST(HoughVocabulary, PooledCopiesOfOneVocabularyVoteAsIt) {
  RunContext ctx;
  auto one = MakeVoter(BaseParams());
  const json model = one->Train(TwoClassViews(), ctx);
  const voting::Codebook book = voting::Codebook::FromJson(model, model.at("format").get<std::string>());
  const voting::Codebook pooled = voting::PoolCodebooks({book, book, book});
  ASSERT_EQ(pooled.Vocabularies(), 3);
  ASSERT_EQ(pooled.Words(), 3 * book.Words());
  auto three = MakeVoter(BaseParams());
  three->Load(json::from_cbor(json::to_cbor(pooled.ToJson(model.at("format").get<std::string>()))));

  const auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}, {Table(), {2.f, 3.f, 0.45f}, {1}}},
                               Pose(0.2f, 0.1f, -0.4f), 0.02f, 5);
  const VoteResult a = one->Vote({scene.Parts()}, ctx);
  const VoteResult b = three->Vote({scene.Parts()}, ctx);
  EXPECT_EQ(b.votes.size(), 3 * a.votes.size());  // every vote thrice, at a third of the weight
  ASSERT_EQ(a.hypotheses.size(), b.hypotheses.size());
  ASSERT_FALSE(a.hypotheses.empty());
  for (size_t i = 0; i < a.hypotheses.size(); ++i) {
    EXPECT_EQ(a.hypotheses[i].cls, b.hypotheses[i].cls);
    EXPECT_LT(Dist2D(a.hypotheses[i].center, b.hypotheses[i].center), 1e-3f);
    EXPECT_NEAR(a.hypotheses[i].score, b.hypotheses[i].score, 1e-4f * a.hypotheses[i].score);
  }
}

// Pooling vocabularies averages the k-means draw out of the votes: trained with other seeds on
// the same views, the objects' scores move far less than with one vocabulary.
TEST(HoughVocabulary, PooledVocabulariesAgreeAcrossSeeds) {
  const auto views = MakeViews({Chair(), Table()}, /*models=*/2, /*views=*/6, /*noise=*/0.03f, /*seed=*/11);
  const std::vector<SceneObject> objects = {{Chair(), {1.f, 1.f, 0.45f}, {}},
                                            {Chair(), {2.6f, 1.1f, 0.45f}, {}},
                                            {Table(), {2.f, 3.f, 0.45f}, {}}};
  const auto scene = MakeScene(objects, Pose(0.5f, -0.3f, 0.5236f), 0.03f, 3);
  // Largest relative difference of the objects' scores over training seeds 1..5.
  auto spread = [&](int vocabularies) {
    json p = BaseParams();
    p["vocabularies"] = vocabularies;
    p["restarts"] = 1;
    p["thresholds"] = {{"chair", 0.0}, {"table", 0.0}};
    std::vector<std::vector<float>> scores;
    for (uint64_t seed = 1; seed <= 5; ++seed) {
      RunContext ctx;
      ctx.seed = seed;
      auto voter = MakeVoter(p);
      voter->Train(views, ctx);
      const VoteResult r = voter->Vote({scene.Parts()}, ctx);
      std::vector<float> s;
      for (const auto& o : objects) {
        const bool chair = o.spec.cls == "chair";
        s.push_back(ScoreNear(r, o.spec.cls, o.center, chair ? kChairWidth : kTableWidth));
      }
      scores.push_back(s);
    }
    float worst = 0.f;
    for (size_t o = 0; o < objects.size(); ++o) {
      float lo = 1e30f, hi = 0.f;
      for (const auto& s : scores) lo = std::min(lo, s[o]), hi = std::max(hi, s[o]);
      EXPECT_GT(lo, 0.f) << vocabularies << " vocabularies: object " << o << " has no hypothesis";
      worst = std::max(worst, (hi - lo) / std::max(hi, 1e-6f));
    }
    return worst;
  };
  const float single = spread(1), pooled = spread(20);
  std::printf("relative score spread over 5 seeds: 1 vocabulary %.3f, 20 pooled %.3f\n", single, pooled);
  EXPECT_LT(pooled, 0.05f);
  EXPECT_LT(pooled, 0.5f * single);
}

TEST(HoughVocabulary, OverlappingSameClassHypothesisIsRemovedOtherClassKept) {
  RunContext ctx;
  const auto views = TwoClassViews();
  // Chair B lacks its back (weaker) and stands 0.75 widths from chair A: farther than the
  // search window (half a width), closer than the footprint (a width). A table overlaps B.
  const Eigen::Vector3f a(1.f, 1.f, 0.45f), b(1.f + 0.75f * kChairWidth, 1.f, 0.45f);
  const auto scene = MakeScene({{Chair(), a, {}}, {Chair(), b, {1}}, {Table(), b, {}}},
                               Eigen::Isometry3f::Identity(), 0.02f, 9);

  auto strict = MakeVoter(BaseParams());
  strict->Train(views, ctx);
  const VoteResult r = strict->Vote({scene.Parts()}, ctx);
  const auto chairs = OfClass(r, "chair");
  ASSERT_EQ(chairs.size(), 1u);
  EXPECT_LT(Dist2D(chairs[0]->center, a), 0.05f);
  const auto tables = OfClass(r, "table");
  ASSERT_EQ(tables.size(), 1u);
  EXPECT_LT(Dist2D(tables[0]->center, b), 0.5f * kTableWidth);

  // Control: with footprints smaller than the gap both chairs survive, so the removal above
  // is the footprint check and not the maxima search.
  json p = BaseParams();
  p["footprint_scale"] = 0.5;
  auto loose = MakeVoter(p);
  loose->Train(views, ctx);
  const auto both = OfClass(loose->Vote({scene.Parts()}, ctx), "chair");
  ASSERT_EQ(both.size(), 2u);
  EXPECT_GT(both[0]->score, both[1]->score);
  EXPECT_LT(Dist2D(both[0]->center, a), 0.05f);
  EXPECT_LT(Dist2D(both[1]->center, b), 0.05f);

  // Square footprints of a width overlap too.
  p["footprint_scale"] = 1.0;
  p["footprint"] = "square";
  auto square = MakeVoter(p);
  square->Train(views, ctx);
  EXPECT_EQ(OfClass(square->Vote({scene.Parts()}, ctx), "chair").size(), 1u);
}

TEST(HoughVocabulary, FusedViewsAccumulateEvidence) {
  // Scan 1 sees the chair's seat and back, scan 2 only its legs, from another position with
  // the same heading. Alone neither passes 2.5; fused (Sect. VII-C) they do, at the truth.
  RunContext ctx;
  json p = BaseParams();
  p["thresholds"]["chair"] = 2.5;
  auto voter = MakeVoter(p);
  voter->Train(TwoClassViews(), ctx);
  const Eigen::Vector3f truth(3.f, 2.f, 0.45f);
  const auto s1 = MakeScene({{Chair(), truth, {2, 3, 4, 5}}}, Pose(0.f, 0.f, 0.3f), 0.02f, 11);
  const auto s2 = MakeScene({{Chair(), truth, {0, 1}}}, Pose(2.f, 4.f, 0.3f), 0.02f, 12);
  EXPECT_TRUE(OfClass(voter->Vote({s1.Parts()}, ctx), "chair").empty());
  EXPECT_TRUE(OfClass(voter->Vote({s2.Parts()}, ctx), "chair").empty());
  const VoteResult fused = voter->Vote({s1.Parts(), s2.Parts()}, ctx);
  const auto chairs = OfClass(fused, "chair");
  ASSERT_EQ(chairs.size(), 1u);
  EXPECT_LT(Dist2D(chairs[0]->center, truth), 0.05f);
  bool from1 = false, from2 = false;
  for (const auto& s : chairs[0]->support) (s.scene == 0 ? from1 : from2) = true;
  EXPECT_TRUE(from1 && from2);
}

TEST(HoughVocabulary, HeightGateDropsPartsAtTheWrongHeight) {
  // Training objects stand on z = 0. The same chair floating 1 m up (its parts at heights no
  // training part had) is found without the gate and not with it; the chair on the floor is
  // found either way, at the same place.
  RunContext ctx;
  json p = BaseParams();
  auto plain = MakeVoter(p);
  p["height_tolerance_m"] = 0.1;
  auto gated = MakeVoter(p);
  plain->Train(TwoClassViews(), ctx);
  gated->Train(TwoClassViews(), ctx);
  const Eigen::Vector3f on_floor(1.f, 1.f, 0.45f), floating(3.f, 1.f, 1.45f);
  const auto scene = MakeScene({{Chair(), on_floor, {}}, {Chair(), floating, {}}}, Pose(0.f, 0.f, 0.2f), 0.02f, 5);
  const auto all = OfClass(plain->Vote({scene.Parts()}, ctx), "chair");
  const auto kept = OfClass(gated->Vote({scene.Parts()}, ctx), "chair");
  ASSERT_EQ(all.size(), 2u);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_LT(Dist2D(kept[0]->center, on_floor), 0.05f);
}

// Height gate (0.1 m) measured above the scan's ground (Scan::ground, which the pipeline
// estimates once per scan): the chair standing at `truth` on the floor z = floor_z(x) (a dense
// grid of points that belongs to no part, x from -1 m over nx cells of 5 cm, y from -1 m over
// 60) is found at its place with the ground of kind `keeps` estimated from the scan, and gated
// out with `drops` (a kind name, or "zero" for a level ground at z = 0).
void ExpectGroundDecides(const char* keeps, const char* drops, const Eigen::Vector3f& truth, int nx,
                         const std::function<float(float)>& floor_z) {
  RunContext ctx;
  json p = BaseParams();
  p["height_tolerance_m"] = 0.1;
  auto voter = MakeVoter(p);
  voter->Train(TwoClassViews(), ctx);
  auto scene = MakeScene({{Chair(), truth, {}}}, Eigen::Isometry3f::Identity(), 0.02f, 6);
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < 60; ++j) {
      const float x = -1.f + 0.05f * i;
      scene.scan.points.emplace_back(x, -1.f + 0.05f * j, floor_z(x));
    }
  auto ground = [&](const std::string& kind) {
    if (kind == "zero") return GroundModel::Level(0.f, "fixed");
    GroundOptions o;
    o.kind = kind;
    return EstimateGround(scene.scan.points, o);
  };
  scene.scan.ground = ground(keeps);
  const auto found = OfClass(voter->Vote({scene.Parts()}, ctx), "chair");
  ASSERT_EQ(found.size(), 1u) << keeps;
  EXPECT_LT(Dist2D(found[0]->center, truth), 0.05f) << keeps;
  scene.scan.ground = ground(drops);
  EXPECT_TRUE(OfClass(voter->Vote({scene.Parts()}, ctx), "chair").empty()) << drops;
}

TEST(HoughVocabulary, HeightGateMeasuresAboveTheScansGround) {
  // The room's floor is at z = -0.3: the estimated ground keeps the chair standing on it, a
  // ground at z = 0 gates it out.
  ExpectGroundDecides("auto", "zero", {1.f, 1.f, 0.15f}, 60, [](float) { return -0.3f; });
}

TEST(HoughVocabulary, HeightGateOnATiltedFloor) {
  // A drifted reconstruction: the floor rises 0.1 m per metre along x, and the chair stands on
  // it at x = 4, 0.4 m above the floor's low end. A plane (or the height map) measures its
  // parts' heights from the floor under them and keeps it; a level floor gates it out.
  for (const char* keeps : {"plane", "height_map"})
    ExpectGroundDecides(keeps, "level", {4.f, 1.f, -0.1f + 0.4f + 0.45f}, 120, [](float x) { return -0.1f + 0.1f * x; });
}

TEST(HoughVocabulary, PartsFarOutsideTheTrainingRangeDoNotVote) {
  // FeatureMatrix::excess (filled by the host's normaliser) says how far a part's raw
  // features lay outside the training range; beyond max_out_of_range the part is ignored.
  RunContext ctx;
  json p = BaseParams();
  p["max_out_of_range"] = 0.2;
  auto strict = MakeVoter(p);
  p["max_out_of_range"] = 0.6;
  auto loose = MakeVoter(p);
  auto off = MakeVoter(BaseParams());
  for (auto* v : {&strict, &loose, &off}) (*v)->Train(TwoClassViews(), ctx);
  auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}}, Eigen::Isometry3f::Identity(), 0.02f, 8);
  scene.features.excess = Eigen::VectorXf::Constant(scene.features.values.rows(), 0.5f);
  EXPECT_TRUE(strict->Vote({scene.Parts()}, ctx).votes.empty());
  EXPECT_EQ(OfClass(loose->Vote({scene.Parts()}, ctx), "chair").size(), 1u);
  EXPECT_EQ(OfClass(off->Vote({scene.Parts()}, ctx), "chair").size(), 1u);
}

TEST(HoughVocabulary, ColumnCheckDropsHypothesesUnderStructureOrOverEmptyFloor) {
  // Two chairs on the floor; a dense shelf (100 points) hangs 1.8 m up over the second one,
  // above the class height (tallest training chair 0.94 m) + margin. The clearance test drops
  // the chair under it, and only for the classes it is asked for; the existence test drops
  // hypotheses whose column holds fewer object points than asked (each seat has 20).
  RunContext ctx;
  json p = BaseParams();
  auto plain = MakeVoter(p);
  p["column_radius_m"] = 0.15;
  p["column_min_points"] = 10;
  auto checked = MakeVoter(p);
  p["column_clear_classes"] = "table";
  auto tables_only = MakeVoter(p);
  p["column_clear_classes"] = "";
  p["column_min_points"] = 30;
  auto needs_more = MakeVoter(p);
  for (auto* v : {&plain, &checked, &tables_only, &needs_more}) (*v)->Train(TwoClassViews(), ctx);
  const Eigen::Vector3f free_chair(1.f, 1.f, 0.45f), covered(3.f, 1.f, 0.45f);
  auto scene = MakeScene({{Chair(), free_chair, {}}, {Chair(), covered, {}}}, Eigen::Isometry3f::Identity(), 0.02f, 9);
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      scene.scan.points.emplace_back(covered.x() - 0.09f + 0.02f * i, covered.y() - 0.09f + 0.02f * j, 1.8f);
  EXPECT_EQ(OfClass(plain->Vote({scene.Parts()}, ctx), "chair").size(), 2u);
  const auto kept = OfClass(checked->Vote({scene.Parts()}, ctx), "chair");
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_LT(Dist2D(kept[0]->center, free_chair), 0.05f);
  EXPECT_EQ(OfClass(tables_only->Vote({scene.Parts()}, ctx), "chair").size(), 2u);
  EXPECT_TRUE(OfClass(needs_more->Vote({scene.Parts()}, ctx), "chair").empty());
}

TEST(HoughVocabulary, ClassesParameterRestrictsDetection) {
  RunContext ctx;
  json p = BaseParams();
  p["classes"] = " table ";
  auto voter = MakeVoter(p);
  voter->Train(TwoClassViews(), ctx);
  const auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}, {Table(), {2.f, 3.f, 0.45f}, {}}},
                               Eigen::Isometry3f::Identity(), 0.02f, 4);
  const VoteResult r = voter->Vote({scene.Parts()}, ctx);
  ASSERT_EQ(r.grids.size(), 1u);
  EXPECT_EQ(r.grids[0].cls, "table");
  ASSERT_EQ(r.hypotheses.size(), 1u);
  EXPECT_EQ(r.hypotheses[0].cls, "table");
  for (const auto& v : r.votes) EXPECT_EQ(r.classes.at(static_cast<size_t>(v.z())), "table");
}

TEST(HoughVocabulary, ClearErrors) {
  RunContext ctx;
  auto voter = MakeVoter(BaseParams());
  const auto scene = MakeScene({{Chair(), {1.f, 1.f, 0.45f}, {}}}, Eigen::Isometry3f::Identity(), 0.f, 1);
  EXPECT_THROW(voter->Vote({scene.Parts()}, ctx), StageError);  // no model yet
  EXPECT_THROW(voter->Load(json{{"format", "voters.nearest_neighbor/1"}}), StageError);
  EXPECT_THROW(voter->Train({}, ctx), StageError);
  voter->Train(TwoClassViews(), ctx);

  auto wrong = scene;
  wrong.features.values.conservativeResize(Eigen::NoChange, synth::kDim - 1);
  try {
    voter->Vote({wrong.Parts()}, ctx);
    FAIL() << "no error for a feature dimension mismatch";
  } catch (const StageError& e) {
    EXPECT_NE(std::string(e.what()).find("columns"), std::string::npos) << e.what();
  }
  json p = BaseParams();
  p["classes"] = "sofa";
  auto sofa = MakeVoter(p);
  sofa->Train(TwoClassViews(), ctx);
  EXPECT_THROW(sofa->Vote({scene.Parts()}, ctx), StageError);
  p = BaseParams();
  p["thresholds"]["chair"] = "high";
  EXPECT_THROW(MakeVoter(p), InputError);
}

}  // namespace
}  // namespace furnihost
