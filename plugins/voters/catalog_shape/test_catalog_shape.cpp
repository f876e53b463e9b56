// voters.catalog_shape with proposals.clusters on rooms simulated by sensors.simulated_laser:
// a table (a top on four legs) and a cabinet (a closed box) are trained from their own views
// and found, each as its class, in a room where they stand beside each other on a floor that
// is not at z = 0.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>
#include <set>

#include "furnihost/host/ground_estimation.hpp"
#include "furnihost/stage.hpp"
#include "shape/shape.hpp"
#include "size_index.hpp"
#include "test_stages.hpp"

namespace furnihost {
namespace {

using nlohmann::json;

using testing::AddBox;

template <class T>
std::shared_ptr<T> Make(const std::string& type, const json& params = json::object()) {
  return testing::MakeStage<T>(type, params);
}

// Catalog models stand with their bounding-box bottom centre at the origin.
CatalogModel Table() { return testing::BoxTable(); }

CatalogModel Cabinet() { return testing::BoxCabinet(); }

std::vector<TrainingView> Views(const std::vector<const CatalogModel*>& models) {
  return testing::SimulatedTrainingViews(models);
}

// A room with `objects` on a floor at `floor_z`, scanned from four sides 3 m around (1, 0) at
// 1.5 m above the floor, with its ground estimated.
Scan ScanRoom(const std::vector<PlacedObject>& objects, float floor_z,
              RunContext& ctx) {
  SensorRequest req;
  req.objects = objects;
  AddBox(req.extra, {-3.f, -3.f, floor_z - 0.02f}, {5.f, 3.f, floor_z});  // the floor
  for (float a : {0.f, 1.57f, 3.14f, 4.71f}) {
    Eigen::Isometry3f s = Eigen::Isometry3f::Identity();
    s.linear() = Eigen::AngleAxisf(a + 3.14159f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    s.translation() = Eigen::Vector3f(1.f + 3.f * std::cos(a), 3.f * std::sin(a), floor_z + 1.5f);
    req.poses.push_back(s);
  }
  auto sensor = Make<Sensor>("sensors.simulated_laser", {{"voxel_m", 0.015}});
  Scan scan;
  for (auto& s : sensor->Acquire(req, ctx)) scan.points.insert(scan.points.end(), s.points.begin(), s.points.end());
  scan.ground = EstimateGround(scan.points, GroundOptions{});
  return scan;
}

// What one sensor at `pose` sees of `req`'s objects, with its ground estimated and the sensor's
// position as the scan's origin.
Scan ScanOneView(SensorRequest req, const Eigen::Isometry3f& pose, const json& sensor, RunContext& ctx) {
  req.poses = {pose};
  Scan scan;
  for (auto& v : Make<Sensor>("sensors.simulated_laser", sensor)->Acquire(req, ctx))
    scan.points.insert(scan.points.end(), v.points.begin(), v.points.end());
  scan.ground = EstimateGround(scan.points, GroundOptions{});
  scan.origin = pose.translation();
  return scan;
}

// max_top_m bounds where a class's objects end: the 0.75 m table is a table under a bound of
// 1.0 m, and no table at all (at any score) under a bound of 0.6 m, while the cabinet beside it
// keeps its score whatever the table's bound.
TEST(CatalogShape, MaxTopKeepsAClassOffProposalsWhoseTopStandsHigher) {
  const CatalogModel table = Table(), cabinet = Cabinet();
  RunContext ctx;
  const json model = Make<Voter>("voters.catalog_shape")->Train(Views({&table, &cabinet}), ctx);
  Eigen::Isometry3f tp = Eigen::Isometry3f::Identity(), cp = Eigen::Isometry3f::Identity();
  cp.translation() = Eigen::Vector3f(2.0f, 0.3f, 0.f);
  const Scan scan = ScanRoom({{&table, tp}, {&cabinet, cp}}, 0.f, ctx);
  const Proposals props = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  SceneParts parts;
  parts.scan = &scan;
  parts.proposals = &props;
  auto best = [&](double max_top, const std::string& cls) {
    auto voter = Make<Voter>("voters.catalog_shape",
                             {{"min_score", 1e-9}, {"class_params", {{"table", {{"max_top_m", max_top}}}}}});
    voter->Load(model);
    std::optional<Hypothesis> b;
    for (const auto& h : voter->Vote({parts}, ctx).hypotheses)
      if (h.cls == cls && (!b || h.score > b->score)) b = h;
    return b;
  };
  const auto kept = best(1.0, "table");
  ASSERT_TRUE(kept.has_value());
  EXPECT_LT(kept->center.head<2>().norm(), 0.1f);
  EXPECT_FALSE(best(0.6, "table").has_value());
  const auto c_low = best(0.6, "cabinet"), c_high = best(1.0, "cabinet");
  ASSERT_TRUE(c_low && c_high);
  EXPECT_FLOAT_EQ(c_low->score, c_high->score);
  EXPECT_THROW(Make<Voter>("voters.catalog_shape", {{"class_params", {{"table", {{"max_top_m", -1}}}}}}), std::exception);
}

TEST(CatalogShape, TrainsSizesProfilesAndOpenFloor) {
  const CatalogModel table = Table(), cabinet = Cabinet();
  auto voter = Make<Voter>("voters.catalog_shape");
  RunContext ctx;
  const json model = voter->Train(Views({&table, &cabinet}), ctx);
  ASSERT_EQ(model.at("models").size(), 2u);
  const json& t = model["models"][0];
  const json& c = model["models"][1];
  EXPECT_EQ(t.at("class"), "table");
  // The floor under a table shows between its legs; under a closed cabinet it never does.
  EXPECT_GT(t.at("open").get<float>(), 0.8f);
  EXPECT_LT(c.at("open").get<float>(), 0.05f);
  // A table puts its whole top in the profile's highest bins, a box too (its top is flat).
  const auto tp = t.at("profile").get<std::vector<float>>();
  EXPECT_GT(tp.back() + tp[tp.size() - 2], 0.8f);
  EXPECT_NO_THROW(voter->Load(model));
}

// The voter says that it learns a model with a mesh from the mesh alone (StageNeeds), and so
// it does: one view of no points per model gives the model its simulated views give. Without
// the mesh the same views are learned from their points, and the model differs.
TEST(CatalogShape, LearnsAModelWithAMeshFromTheMeshAlone) {
  const CatalogModel table = Table(), cabinet = Cabinet();
  auto voter = Make<Voter>("voters.catalog_shape");
  EXPECT_FALSE(voter->Needs().training_scans);
  RunContext ctx;
  std::vector<TrainingView> scanned = Views({&table, &cabinet});  // as the host gives them: with their model
  for (TrainingView& tv : scanned) tv.model = tv.model_id == table.id ? &table : &cabinet;
  std::vector<TrainingView> meshes;
  for (const CatalogModel* m : {&table, &cabinet}) {
    TrainingView tv;
    tv.cls = m->cls;
    tv.model_id = m->id;
    tv.view = -1;
    tv.object_size = m->size;
    tv.model = m;
    meshes.push_back(tv);
  }
  const json from_scans = voter->Train(scanned, ctx);
  EXPECT_EQ(voter->Train(meshes, ctx), from_scans);

  CatalogModel bare_table = table, bare_cabinet = cabinet;
  bare_table.mesh.triangles.clear();
  bare_cabinet.mesh.triangles.clear();
  std::vector<TrainingView> bare = scanned;
  for (TrainingView& tv : bare) tv.model = tv.model_id == table.id ? &bare_table : &bare_cabinet;
  EXPECT_NE(voter->Train(bare, ctx), from_scans) << "vacuous: the views' points give the mesh's model";
}

// The room: both objects on a floor 1.2 m below the origin (a camera's frame), scanned from
// four sides. Proposals and recognition find the table as a table and the cabinet as a cabinet,
// each with its box, and neither as the other class first.
TEST(CatalogShape, FindsEachObjectAsItsClass) {
  const CatalogModel table = Table(), cabinet = Cabinet();
  auto voter = Make<Voter>("voters.catalog_shape", {{"thresholds", {{"table", 0.05}, {"cabinet", 0.05}}}});
  RunContext ctx;
  voter->Load(voter->Train(Views({&table, &cabinet}), ctx));

  const float floor_z = -1.2f;
  Eigen::Isometry3f tp = Eigen::Isometry3f::Identity(), cp = Eigen::Isometry3f::Identity();
  tp.translation() = Eigen::Vector3f(0.f, 0.f, floor_z);
  cp.translation() = Eigen::Vector3f(2.0f, 0.3f, floor_z);
  cp.linear() = Eigen::AngleAxisf(0.6f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  const Scan scan = ScanRoom({{&table, tp}, {&cabinet, cp}}, floor_z, ctx);
  EXPECT_NEAR(scan.ground->HeightAt(1.f, 0.f), floor_z, 0.02f);

  auto proposer = Make<Proposer>("proposals.clusters");
  const Proposals props = proposer->Propose(scan, nullptr, ctx);
  ASSERT_FALSE(props.items.empty());
  SceneParts parts;
  parts.scan = &scan;
  parts.proposals = &props;
  const VoteResult r = voter->Vote({parts}, ctx);
  auto best = [&](const std::string& cls) {
    const Hypothesis* b = nullptr;
    for (const auto& h : r.hypotheses)
      if (h.cls == cls && (!b || h.score > b->score)) b = &h;
    return b;
  };
  const Hypothesis* t = best("table");
  const Hypothesis* c = best("cabinet");
  ASSERT_TRUE(t && c);
  EXPECT_LT((t->center.head<2>() - Eigen::Vector2f(0.f, 0.f)).norm(), 0.1f);
  EXPECT_LT((c->center.head<2>() - Eigen::Vector2f(2.0f, 0.3f)).norm(), 0.1f);
  EXPECT_TRUE(t->accepted.value_or(false));
  EXPECT_TRUE(c->accepted.value_or(false));
  EXPECT_EQ(t->model, "test_table");
  // Boxes: the table's reaches the floor (its legs), the cabinet's is 1.2 m tall.
  ASSERT_TRUE(t->box && c->box);
  EXPECT_NEAR(t->box->center.z() - 0.5f * t->box->size.z(), floor_z, 0.06f);
  EXPECT_NEAR(c->box->size.z(), 1.2f, 0.06f);
  // The evidence says what was measured: the cabinet's top 1.2 m, its best model's terms.
  ASSERT_TRUE(c->evidence.count("top_m") && c->evidence.count("e_length"));
  EXPECT_NEAR(c->evidence.at("top_m"), 1.2f, 0.06f);
  EXPECT_GE(c->evidence.at("e_length"), 0.f);
  // Each object scores its own class above the other one.
  auto score_at = [&](const std::string& cls, const Eigen::Vector2f& at) {
    float s = 0.f;
    for (const auto& h : r.hypotheses)
      if (h.cls == cls && (h.center.head<2>() - at).norm() < 0.2f) s = std::max(s, h.score);
    return s;
  };
  EXPECT_GT(score_at("table", {0.f, 0.f}), score_at("cabinet", {0.f, 0.f}));
  EXPECT_GT(score_at("cabinet", {2.0f, 0.3f}), score_at("table", {2.0f, 0.3f}));
}

// A proposal with exactly the points, box, ground and surround of an earlier one is scored once
// and copied: each copy (its own group) gets the original's score, evidence and box; a copy whose
// surround differs is scored on its own.
TEST(CatalogShape, CopiesOfAProposalScoreAsTheOriginal) {
  const CatalogModel table = Table(), cabinet = Cabinet();
  auto voter = Make<Voter>("voters.catalog_shape", {{"min_score", 1e-6}, {"nms_iou", 1.0}});
  RunContext ctx;
  voter->Load(voter->Train(Views({&table, &cabinet}), ctx));
  Eigen::Isometry3f tp = Eigen::Isometry3f::Identity(), cp = Eigen::Isometry3f::Identity();
  cp.translation() = Eigen::Vector3f(2.0f, 0.3f, 0.f);
  const Scan scan = ScanRoom({{&table, tp}, {&cabinet, cp}}, 0.f, ctx);
  const Proposals props = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  const size_t n = props.items.size();
  ASSERT_GT(n, 0u);
  Proposals twice = props;
  int groups = 0;
  for (const auto& p : props.items) groups = std::max(groups, p.group + 1);
  for (size_t i = 0; i < n; ++i) {
    Proposal c = props.items[i];
    c.group += groups;
    if (i == 0) c.surround += 0.5f;  // not a copy any more
    twice.items.push_back(c);
  }
  auto vote = [&](const Proposals& ps) {
    SceneParts parts;
    parts.scan = &scan;
    parts.proposals = &ps;
    std::map<std::pair<std::string, int>, Hypothesis> by;  // (class, proposal) -> hypothesis
    for (const auto& h : voter->Vote({parts}, ctx).hypotheses) by[{h.cls, h.proposal}] = h;
    return by;
  };
  const auto once = vote(props), both = vote(twice);
  size_t compared = 0;
  for (const auto& [key, h] : once) {
    const auto copy = both.find({key.first, key.second + int(n)});
    if (key.second == 0) {
      if (copy != both.end()) {
        EXPECT_LT(copy->second.score, h.score);  // its surround costs
      }
      continue;
    }
    ASSERT_NE(copy, both.end()) << key.first << " " << key.second;
    EXPECT_EQ(copy->second.score, h.score);
    EXPECT_EQ(copy->second.model, h.model);
    EXPECT_EQ(copy->second.evidence, h.evidence);
    ASSERT_TRUE(copy->second.box && h.box);
    EXPECT_EQ(copy->second.box->center, h.box->center);
    ++compared;
  }
  EXPECT_GT(compared, 0u);
}

// 'source' picks the proposer rules a class is scored on: one name, a comma-separated list
// (whole names only), or "any".
TEST(CatalogShape, SourceListsTheRulesAClassIsScoredOn) {
  const CatalogModel table = Table();
  RunContext ctx;
  Eigen::Isometry3f tp = Eigen::Isometry3f::Identity();
  const Scan scan = ScanRoom({{&table, tp}}, 0.f, ctx);
  const Proposals props = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  SceneParts parts;
  parts.scan = &scan;
  parts.proposals = &props;
  auto tables_from = [&](const std::string& source) {
    auto voter = Make<Voter>("voters.catalog_shape", {{"class_params", {{"table", {{"source", source}}}}},
                                                      {"min_score", 1e-4}, {"nms_iou", 1.0}});
    voter->Load(voter->Train(Views({&table}), ctx));
    std::multiset<std::string> rules;
    for (const auto& h : voter->Vote({parts}, ctx).hypotheses)
      if (h.cls == "table") rules.insert(props.items.at(size_t(h.proposal)).source);
    return rules;
  };
  const auto all = tables_from("all"), segs = tables_from("segs"), both = tables_from("segs,all");
  ASSERT_FALSE(all.empty());
  ASSERT_FALSE(segs.empty());
  EXPECT_EQ(all.count("segs"), 0u);
  EXPECT_EQ(segs.count("all"), 0u);
  EXPECT_EQ(both.size(), all.size() + segs.size());
  EXPECT_GE(tables_from("any").size(), both.size());
  EXPECT_TRUE(tables_from("al").empty());  // a name, not a prefix
  EXPECT_TRUE(tables_from("al,seg").empty());
  EXPECT_THROW(tables_from(""), InputError);
  EXPECT_THROW(tables_from("all,"), InputError);
}

// A kitchen wall cabinet (0.8 x 0.36 x 0.7 m) hanging 1.3 m above the floor: with its class
// standing on the floor (wall_mount 0) the gap under it rules it out; with wall_mount > 0 it is
// found, as the model lifted to its bottom, at about exp(-wall_mount) of a perfect fit's score.
TEST(CatalogShape, WallMountFindsAHangingCabinet) {
  CatalogModel cabinet;
  cabinet.id = "test_wall_cabinet";
  cabinet.cls = "cabinet";
  AddBox(cabinet.mesh, {-0.4f, -0.18f, 0.f}, {0.4f, 0.18f, 0.7f});
  cabinet.size = cabinet.mesh.Bounds().sizes();
  const float floor_z = 0.f, lift = 1.3f;
  RunContext ctx;
  Eigen::Isometry3f cp = Eigen::Isometry3f::Identity();
  cp.translation() = Eigen::Vector3f(1.0f, 0.2f, floor_z + lift);
  const Scan scan = ScanRoom({{&cabinet, cp}}, floor_z, ctx);
  auto proposer = Make<Proposer>("proposals.clusters");
  const Proposals props = proposer->Propose(scan, nullptr, ctx);
  SceneParts parts;
  parts.scan = &scan;
  parts.proposals = &props;
  auto cabinet_at = [&](float wall_mount, float lowest = 0.f) {
    auto voter = Make<Voter>(
        "voters.catalog_shape",
        {{"class_params", {{"cabinet", {{"wall_mount", wall_mount}, {"wall_mount_bottom_m", lowest}}}}}, {"min_score", 1e-4}});
    voter->Load(voter->Train(Views({&cabinet}), ctx));
    std::optional<Hypothesis> best;
    for (const auto& h : voter->Vote({parts}, ctx).hypotheses)
      if (h.cls == "cabinet" && (h.center.head<2>() - Eigen::Vector2f(1.0f, 0.2f)).norm() < 0.15f &&
          (!best || h.score > best->score))
        best = h;
    return best;
  };
  EXPECT_FALSE(cabinet_at(0.f).has_value());
  const auto h = cabinet_at(2.f);
  ASSERT_TRUE(h.has_value());
  EXPECT_NEAR(h->evidence.at("bottom_m"), lift, 0.05f);
  EXPECT_FLOAT_EQ(h->evidence.at("e_bottom"), 2.f);  // the wall_mount cost in place of the gap's
  EXPECT_GT(h->score, 0.5f * std::exp(-2.f));
  EXPECT_LE(h->score, std::exp(-2.f) + 1e-6f);
  ASSERT_TRUE(h->box);
  EXPECT_NEAR(h->box->size.z(), 0.7f, 0.06f);
  // Hung above the lowest mount (wall_mount_bottom_m) it costs nothing more; hung lower by d it
  // costs (d / sig_bottom)^2 / 2 more (sig_bottom 0.15 m).
  const auto high = cabinet_at(2.f, 1.2f);
  ASSERT_TRUE(high.has_value());
  EXPECT_FLOAT_EQ(high->evidence.at("e_bottom"), 2.f);
  EXPECT_FLOAT_EQ(high->score, h->score);
  const auto low = cabinet_at(2.f, 1.6f);
  ASSERT_TRUE(low.has_value());
  const float d = (1.6f - low->evidence.at("bottom_m")) / 0.15f;
  EXPECT_GT(d, 1.5f);
  EXPECT_NEAR(low->evidence.at("e_bottom"), 2.f + 0.5f * d * d, 1e-3f);
  EXPECT_NEAR(low->score, h->score * std::exp(-0.5f * d * d), 1e-4f);
}

// An armchair (a closed seat, a back and two armrests) seen by one sensor from its side: the near
// armrest hides most of the seat, so the view's top-view profile holds the armrests and the back
// and little seat. Training keeps the profile each training view saw alone; on a scan with a
// sensor origin, view_profiles compares with the closest of those as well as with all views
// fused (measured: the profile term falls from 2.5 to 0.35, the score rises from 0.08 to 0.66).
// A scan without an origin (a reconstruction) is scored as before.
TEST(CatalogShape, ViewProfilesScoreAnArmchairSeenFromItsSide) {
  CatalogModel chair;
  chair.id = "test_armchair";
  chair.cls = "chair";
  AddBox(chair.mesh, {-0.35f, -0.35f, 0.f}, {0.25f, 0.35f, 0.45f});   // seat
  AddBox(chair.mesh, {0.25f, -0.35f, 0.f}, {0.35f, 0.35f, 0.85f});    // back (+x side)
  AddBox(chair.mesh, {-0.35f, -0.35f, 0.45f}, {0.25f, -0.27f, 0.65f});  // armrests
  AddBox(chair.mesh, {-0.35f, 0.27f, 0.45f}, {0.25f, 0.35f, 0.65f});
  chair.size = chair.mesh.Bounds().sizes();
  RunContext ctx;
  auto train = [&](bool views) {
    auto voter = Make<Voter>("voters.catalog_shape", {{"view_profiles", views}, {"min_score", 1e-6}, {"nms_iou", 1.0}});
    const json model = voter->Train(Views({&chair}), ctx);
    voter->Load(model);
    return std::make_pair(voter, model);
  };
  const auto [with, model] = train(true);
  const auto without = train(false).first;
  // One profile per eye around the model, each a distribution; they differ from the fused one.
  const auto fused = model["models"][0].at("profile").get<std::vector<float>>();
  const json& vp = model["models"][0].at("view_profiles");
  ASSERT_EQ(vp.size(), 8u);
  float most = 0.f;
  for (const auto& v : vp) {
    const auto p = v.get<std::vector<float>>();
    ASSERT_EQ(p.size(), fused.size());
    float sum = 0.f, diff = 0.f;
    for (size_t k = 0; k < p.size(); ++k) sum += p[k], diff += std::abs(p[k] - fused[k]);
    EXPECT_NEAR(sum, 1.f, 1e-4f);
    most = std::max(most, diff);
  }
  EXPECT_GT(most, 0.2f);
  // A model whose view profiles are not profiles is refused with an input error.
  for (const json& bad : {json("x"), json::array({"x"}), json::array({json::array({1, 2})}),
                          json::array({json(std::vector<float>(fused.size(), -1.f))})}) {
    json m = model;
    m["models"][0]["view_profiles"] = bad;
    EXPECT_THROW(Make<Voter>("voters.catalog_shape")->Load(m), InputError) << bad.dump();
  }

  // One sensor 2.5 m to the chair's side, 1.5 m above the floor, looking at it.
  SensorRequest req;
  req.objects = {{&chair, Eigen::Isometry3f::Identity()}};
  AddBox(req.extra, {-3.f, -3.f, -0.02f}, {5.f, 3.f, 0.f});
  Eigen::Isometry3f s = Eigen::Isometry3f::Identity();
  s.linear() = Eigen::AngleAxisf(-1.5708f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  s.translation() = Eigen::Vector3f(0.f, 2.5f, 1.5f);
  Scan scan = ScanOneView(req, s, {{"voxel_m", 0.015}}, ctx);
  const Proposals props = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  SceneParts parts;
  parts.scan = &scan;
  parts.proposals = &props;
  auto best = [&](Voter& voter) {
    std::optional<Hypothesis> b;
    for (const auto& h : voter.Vote({parts}, ctx).hypotheses)
      if (h.cls == "chair" && h.center.head<2>().norm() < 0.25f && (!b || h.score > b->score)) b = h;
    return b;
  };
  const auto a = best(*without), b = best(*with);
  ASSERT_TRUE(a && b);
  EXPECT_LT(b->evidence.at("e_profile"), 0.5f * a->evidence.at("e_profile"));
  EXPECT_GT(b->score, a->score);
  // Without a sensor origin the fused profile alone, as before.
  scan.origin.reset();
  const auto c = best(*without), d = best(*with);
  ASSERT_TRUE(c && d);
  EXPECT_FLOAT_EQ(c->score, d->score);
}

// A depth camera's single view (640 x 480 px, 525 px focal length: 62 deg wide; 8 m range) of an
// armchair in the middle of the image and of a sofa of the same section, 2.4 m long, that the
// image's left edge cuts 0.8 m into: what the camera saw of the sofa is armchair-sized. With
// view_edge, the chair hypotheses on the cut proposal pay its cost (score x exp(-1)); the armchair
// in the middle pays nothing (its rows go on to the wall behind it). A scan whose points surround
// its origin (four sensors around) has no view edge, and a scan without an origin is scored as
// before.
TEST(CatalogShape, ViewEdgeCostsProposalsTheViewCuts) {
  auto seat_back_arms = [](CatalogModel& m, float half) {
    AddBox(m.mesh, {-0.35f, -half, 0.f}, {0.25f, half, 0.45f});              // seat
    AddBox(m.mesh, {0.25f, -half, 0.f}, {0.35f, half, 0.85f});               // back (+x side)
    AddBox(m.mesh, {-0.35f, -half, 0.45f}, {0.25f, -half + 0.08f, 0.65f});  // armrests
    AddBox(m.mesh, {-0.35f, half - 0.08f, 0.45f}, {0.25f, half, 0.65f});
    m.size = m.mesh.Bounds().sizes();
  };
  CatalogModel chair, sofa;
  chair.id = "test_armchair", chair.cls = "chair";
  seat_back_arms(chair, 0.35f);
  sofa.id = "test_long_sofa", sofa.cls = "sofa";
  seat_back_arms(sofa, 1.2f);
  RunContext ctx;
  // One model (training does not depend on the cost), loaded by a voter per cost.
  const json model = Make<Voter>("voters.catalog_shape")->Train(Views({&chair}), ctx);
  auto voter = [&](float cost) {
    auto v = Make<Voter>("voters.catalog_shape", {{"class_params", {{"chair", {{"view_edge", cost}}}}},
                                                  {"min_score", 1e-9}, {"nms_iou", 1.0}});
    v->Load(model);
    return v;
  };
  const auto with = voter(1.f), without = voter(0.f);

  // Both face the camera (backs away from it, at +x); the camera 1.3 m above the floor, looking
  // along +x, 15 deg down. At x = 3 m the image spans y = -1.8 .. 1.8 m (+y on its left).
  Eigen::Isometry3f cp = Eigen::Isometry3f::Identity(), sp = Eigen::Isometry3f::Identity();
  cp.translation() = Eigen::Vector3f(3.f, 0.f, 0.f);
  sp.translation() = Eigen::Vector3f(3.f, 2.2f, 0.f);
  SensorRequest req;
  req.objects = {{&chair, cp}, {&sofa, sp}};
  AddBox(req.extra, {-1.f, -6.f, -0.02f}, {8.f, 6.f, 0.f});   // the floor
  AddBox(req.extra, {6.f, -6.f, 0.f}, {6.1f, 6.f, 2.6f});     // the wall behind: rows end at the image's edges
  Eigen::Isometry3f cam = Eigen::Isometry3f::Identity();
  cam.linear() = Eigen::AngleAxisf(0.2618f, Eigen::Vector3f::UnitY()).toRotationMatrix();
  cam.translation() = Eigen::Vector3f(0.f, 0.f, 1.3f);
  const json camera = {{"pattern", "depth_camera"}, {"camera_max_range_m", 8.0}, {"voxel_m", 0.015}};
  Scan scan = ScanOneView(req, cam, camera, ctx);
  ASSERT_GT(scan.points.size(), 1000u);
  const Proposals props = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  SceneParts parts;
  parts.scan = &scan;
  parts.proposals = &props;
  // The best chair hypothesis centred within 0.3 m of `at` (x, y), and the same proposal's
  // hypothesis from `other` (same box).
  auto best_at = [&](const VoteResult& r, const Eigen::Vector2f& at) {
    std::optional<Hypothesis> b;
    for (const auto& h : r.hypotheses)
      if (h.cls == "chair" && (h.center.head<2>() - at).norm() < 0.3f && (!b || h.score > b->score)) b = h;
    return b;
  };
  auto same_box = [&](const VoteResult& r, const Hypothesis& h) {
    std::optional<Hypothesis> b;
    for (const auto& g : r.hypotheses)
      if (g.cls == "chair" && g.box && h.box && (g.box->center - h.box->center).norm() < 1e-5f &&
          (g.box->size - h.box->size).norm() < 1e-5f)
        b = g;
    return b;
  };
  const VoteResult rw = with->Vote({parts}, ctx), ro = without->Vote({parts}, ctx);
  const auto middle = best_at(rw, {3.f, 0.f});
  ASSERT_TRUE(middle);
  EXPECT_EQ(middle->evidence.at("view_edge_points"), 0.f);
  EXPECT_EQ(middle->evidence.at("e_view_edge"), 0.f);
  const auto middle_without = same_box(ro, *middle);
  ASSERT_TRUE(middle_without);
  EXPECT_FLOAT_EQ(middle->score, middle_without->score);
  EXPECT_EQ(middle_without->evidence.count("view_edge_points"), 0u);  // off: not measured
  // The sofa's visible end: cut by the edge, at exp(-1) of its score without the cost.
  const auto cut = best_at(ro, {3.f, 1.4f});
  ASSERT_TRUE(cut);
  const auto cut_with = same_box(rw, *cut);
  ASSERT_TRUE(cut_with);
  EXPECT_GE(cut_with->evidence.at("view_edge_points"), 3.f);
  EXPECT_EQ(cut_with->evidence.at("e_view_edge"), 1.f);
  EXPECT_NEAR(cut_with->score, cut->score * std::exp(-1.f), 1e-6f + 1e-4f * cut->score);

  // Points all around the origin (a panoramic scan): no view edge. No origin: no measure.
  Scan around = ScanRoom({{&chair, cp}}, 0.f, ctx);
  around.origin = Eigen::Vector3f(1.f, 0.f, 1.5f);
  const Proposals around_props = Make<Proposer>("proposals.clusters")->Propose(around, nullptr, ctx);
  SceneParts around_parts;
  around_parts.scan = &around;
  around_parts.proposals = &around_props;
  int measured = 0;
  for (const auto& h : with->Vote({around_parts}, ctx).hypotheses)
    if (h.cls == "chair") {
      ++measured;
      EXPECT_EQ(h.evidence.at("view_edge_points"), 0.f);
    }
  EXPECT_GT(measured, 0);
  scan.origin.reset();
  for (const auto& h : with->Vote({parts}, ctx).hypotheses) EXPECT_EQ(h.evidence.count("e_view_edge"), 0u);
}


// SizeIndex alone: a best-first search bounded by the squared distance from a query to a node's
// box finds the nearest of many points (ties: the lowest index), as a scan of all points does,
// and visits a small share of them.
TEST(CatalogShapeSizeIndex, FindsTheNearestPointAsAScanOfAll) {
  using Index = catalog_shape::SizeIndex;
  constexpr size_t K = Index::kDims;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<std::array<double, K>> pts;
  std::vector<Index::Box> boxes;
  std::vector<int> ids;
  for (int i = 0; i < 2000; ++i) {
    std::array<double, K> p;
    for (size_t a = 0; a < K; ++a) p[a] = (a < 2 ? 1.0 : 0.1) * u(rng);
    // A few exact duplicates, so ties must go to the earlier point.
    pts.push_back(i % 50 == 49 ? pts[size_t(i - 17)] : p);
    Index::Box b;
    for (size_t a = 0; a < K; ++a) b[a] = b[a + K] = pts.back()[a];
    boxes.push_back(b);
    ids.push_back(i);
  }
  std::array<double, K> scale;
  scale.fill(1.0);
  const Index index(ids, boxes, scale, 4);
  ASSERT_EQ(index.size(), pts.size());
  size_t visited = 0;
  for (int q = 0; q < 200; ++q) {
    std::array<double, K> x = pts[size_t(q * 7)];
    if (q % 4 != 0)
      for (auto& v : x) v = u(rng);
    auto d2 = [&](const std::array<double, K>& p) {
      double s = 0;
      for (size_t a = 0; a < K; ++a) s += (p[a] - x[a]) * (p[a] - x[a]);
      return s;
    };
    int want = -1;
    double want_d = INFINITY;
    for (size_t i = 0; i < pts.size(); ++i)
      if (d2(pts[i]) < want_d) want_d = d2(pts[i]), want = int(i);
    int got = -1;
    double got_d = INFINITY;
    index.Search(
        [&](const Index::Box& b) {
          double s = 0;
          for (size_t a = 0; a < K; ++a) {
            const double g = std::max({b[a] - x[a], x[a] - b[a + K], 0.0});
            s += g * g;
          }
          return s;
        },
        [&] { return got_d; },
        [&](size_t m) {
          ++visited;
          const double d = d2(pts[m]);
          if (d < got_d || (d == got_d && int(m) < got)) got_d = d, got = int(m);
        });
    EXPECT_EQ(got, want) << "query " << q;
    EXPECT_EQ(got_d, want_d) << "query " << q;
  }
  EXPECT_LT(visited, 200u * pts.size() / 10);  // on average under 10 % of the points per query
}

// A catalog of many models of varied sizes (profiles and open floor drawn at random, a few
// profiles with a negative share, exact copies of half of them, one class hanging on walls too): the size index gives every proposal
// the model, score and evidence that scoring every model gives, hypothesis for hypothesis.
TEST(CatalogShape, ModelIndexChoosesAsScoringEveryModel) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  json models = json::array();
  for (int i = 0; i < 600; ++i) {
    const std::string cls = i % 3 == 0 ? "table" : i % 3 == 1 ? "cabinet" : "chair";
    std::vector<float> prof(size_t(shape::kProfileBins));
    float sum = 0.f;
    for (auto& p : prof) sum += p = std::pow(u(rng), 3.f);
    for (auto& p : prof) p /= sum;
    if (i % 97 == 0) prof[0] -= 0.3f, prof[5] += 0.3f;  // a hand-made profile, not a histogram
    const float x = 0.3f * std::exp(2.f * u(rng)), y = 0.3f * std::exp(1.5f * u(rng)), z = 0.4f * std::exp(1.3f * u(rng));
    models.push_back({{"id", "m" + std::to_string(i)}, {"class", cls}, {"size", {x, y, z}}, {"profile", prof},
                      {"open", u(rng)}, {"top_offset", {0.f, 0.f}}});
  }
  // An exact copy of every other model after them all: equal energies, the earlier model wins.
  for (size_t i = 0; i < 600; i += 2) {
    json dup = models[i];
    dup["id"] = "copy_of_m" + std::to_string(i);
    models.push_back(dup);
  }
  const json model = {{"format", "catalog_shape/1"}, {"profile_cell_m", 0.05}, {"models", models}};

  RunContext ctx;
  const CatalogModel table = Table(), cabinet = Cabinet();
  Eigen::Isometry3f tp = Eigen::Isometry3f::Identity(), cp = Eigen::Isometry3f::Identity(),
                    hp = Eigen::Isometry3f::Identity();
  cp.translation() = Eigen::Vector3f(2.0f, 0.3f, 0.f);
  cp.linear() = Eigen::AngleAxisf(0.6f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  hp.translation() = Eigen::Vector3f(0.5f, -1.6f, 1.3f);  // a cabinet hung on a wall
  const Scan scan = ScanRoom({{&table, tp}, {&cabinet, cp}, {&cabinet, hp}}, 0.f, ctx);
  const Proposals props = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  ASSERT_GT(props.items.size(), 3u);
  SceneParts parts;
  parts.scan = &scan;
  parts.proposals = &props;
  auto vote = [&](bool index) {
    auto voter = Make<Voter>("voters.catalog_shape",
                             {{"model_index", index}, {"min_score", 1e-30}, {"nms_iou", 1.0},
                              {"class_params", {{"cabinet", {{"wall_mount", 1.0}, {"wall_mount_bottom_m", 1.0}, {"source", "any"}}},
                                                {"table", {{"source", "any"}}}, {"chair", {{"source", "any"}}}}}});
    voter->Load(model);
    return voter->Vote({parts}, ctx).hypotheses;
  };
  const auto all = vote(false), indexed = vote(true);
  ASSERT_EQ(indexed.size(), all.size());
  ASSERT_GE(all.size(), 3 * props.items.size() / 2);
  std::set<std::string> chosen;
  for (size_t k = 0; k < all.size(); ++k) {
    EXPECT_EQ(indexed[k].cls, all[k].cls);
    EXPECT_EQ(indexed[k].proposal, all[k].proposal);
    EXPECT_EQ(indexed[k].model, all[k].model) << all[k].cls << " proposal " << all[k].proposal;
    EXPECT_EQ(indexed[k].score, all[k].score);
    EXPECT_EQ(indexed[k].evidence, all[k].evidence);
    chosen.insert(all[k].model);
  }
  EXPECT_GT(chosen.size(), 5u);  // many models chosen, not one per class
  for (const auto& m : chosen) EXPECT_EQ(m.rfind("copy_of_", 0), std::string::npos) << m;
}

}  // namespace
}  // namespace furnihost
