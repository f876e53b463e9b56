// proposals.clusters on a room simulated by sensors.simulated_laser (floor, two walls, objects
// built of boxes), its floor 0.8 m below z = 0: objects are proposed with their boxes, walls are
// not part of any "all" proposal, a cabinet against a wall survives in the "segs" proposals, a
// wardrobe's tall front in the "fronts" proposals,
// two objects that touch are split apart, and a top floating over its (disconnected) legs gets
// a variant that reaches the ground.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <string>
#include <tuple>

#include "furnihost/host/ground_estimation.hpp"
#include "furnihost/stage.hpp"
#include "test_stages.hpp"

namespace furnihost {
namespace {

using nlohmann::json;

using testing::AddBox;

template <class T>
std::shared_ptr<T> Make(const std::string& type, const json& params = json::object()) {
  return testing::MakeStage<T>(type, params);
}

float Iou(const Eigen::AlignedBox3f& a, const Eigen::AlignedBox3f& b) {
  const Eigen::AlignedBox3f i = a.intersection(b);
  if (i.isEmpty()) return 0.f;
  return i.volume() / (a.volume() + b.volume() - i.volume());
}

constexpr float kFloor = -0.8f;

Eigen::AlignedBox3f Box(Eigen::Vector3f lo, Eigen::Vector3f hi) {
  const Eigen::Vector3f up(0, 0, kFloor);
  return Eigen::AlignedBox3f(lo + up, hi + up);
}

struct Room {
  Scan scan;
  Eigen::AlignedBox3f low, high, cabinet, wardrobe, top, legs_and_top;
};

Room MakeRoom(const json& sensor_params = {{"voxel_m", 0.015}}) {
  Room r;
  CatalogModel m;  // everything is one mesh: the test is about what the points look like
  m.id = "room";
  m.cls = "room";
  const Eigen::Vector3f up(0, 0, kFloor);
  AddBox(m.mesh, Eigen::Vector3f(-3.f, -3.f, -0.02f) + up, Eigen::Vector3f(4.f, 3.f, 0.f) + up);   // floor
  AddBox(m.mesh, Eigen::Vector3f(-3.05f, -3.f, 0.f) + up, Eigen::Vector3f(-3.f, 3.f, 2.5f) + up);  // wall x = -3
  AddBox(m.mesh, Eigen::Vector3f(-3.f, 3.f, 0.f) + up, Eigen::Vector3f(4.f, 3.05f, 2.5f) + up);    // wall y = 3
  // Two boxes that touch (0.5 and 0.8 m tall, 0.6 m long each).
  r.low = Box({0.f, -1.f, 0.f}, {0.6f, -0.4f, 0.5f});
  r.high = Box({0.6f, -1.f, 0.f}, {1.2f, -0.4f, 0.8f});
  AddBox(m.mesh, r.low.min(), r.low.max());
  AddBox(m.mesh, r.high.min(), r.high.max());
  // A cabinet against the wall y = 3 (its back on the wall).
  r.cabinet = Box({-1.5f, 2.5f, 0.f}, {-0.6f, 3.f, 1.2f});
  AddBox(m.mesh, r.cabinet.min(), r.cabinet.max());
  // A wardrobe against the wall x = -3: its front is 2 m tall and 1 m long, a wall segment to
  // the "segs" rule, not to the "fronts" rule (shorter than 1.3 m).
  r.wardrobe = Box({-3.f, -2.5f, 0.f}, {-2.4f, -1.5f, 2.0f});
  AddBox(m.mesh, r.wardrobe.min(), r.wardrobe.max());
  // A table top whose legs end 20 cm under it (disconnected clusters).
  r.top = Box({1.5f, 1.f, 0.7f}, {2.5f, 1.6f, 0.75f});
  AddBox(m.mesh, r.top.min(), r.top.max());
  for (float x : {1.55f, 2.4f})
    for (float y : {1.05f, 1.5f}) AddBox(m.mesh, Eigen::Vector3f(x, y, 0.f) + up, Eigen::Vector3f(x + 0.05f, y + 0.05f, 0.5f) + up);
  r.legs_and_top = Box({1.5f, 1.f, 0.f}, {2.5f, 1.6f, 0.75f});

  SensorRequest req;
  req.objects.push_back({&m, Eigen::Isometry3f::Identity()});
  for (float a : {0.3f, 1.9f, 3.5f, 5.1f}) {
    Eigen::Isometry3f s = Eigen::Isometry3f::Identity();
    s.linear() = Eigen::AngleAxisf(a + 3.14159f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    s.translation() = Eigen::Vector3f(0.5f + 2.2f * std::cos(a), 2.2f * std::sin(a), kFloor + 1.5f);
    req.poses.push_back(s);
  }
  RunContext ctx;
  auto sensor = Make<Sensor>("sensors.simulated_laser", sensor_params);
  for (auto& s : sensor->Acquire(req, ctx)) r.scan.points.insert(r.scan.points.end(), s.points.begin(), s.points.end());
  r.scan.ground = EstimateGround(r.scan.points, GroundOptions{});
  return r;
}

float BestIou(const Proposals& p, const Eigen::AlignedBox3f& b, const std::string& source, const std::string& how = "") {
  float best = 0.f;
  for (const auto& q : p.items)
    if (q.source == source && q.how.find(how) != std::string::npos) best = std::max(best, Iou(q.box, b));
  return best;
}

TEST(Clusters, ProposesObjectsSplitsAndExtends) {
  const Room room = MakeRoom();
  EXPECT_NEAR(room.scan.ground->HeightAt(0.5f, 0.f), kFloor, 0.02f);
  RunContext ctx;
  const Proposals p = Make<Proposer>("proposals.clusters", {{"fronts_length_m", 1.3}})->Propose(room.scan, nullptr, ctx);
  EXPECT_GT(p.spacing, 0.002f);
  EXPECT_LT(p.spacing, 0.03f);
  ASSERT_FALSE(p.items.empty());
  for (const auto& q : p.items) {
    EXPECT_FALSE(q.indices.empty());
    EXPECT_GE(q.group, 0);
    EXPECT_GE(q.surround, 0.f);
  }
  // The touching boxes: one cluster, split where the profile steps from 0.5 to 0.8 m.
  EXPECT_GT(BestIou(p, room.low, "all", "split"), 0.6f);
  EXPECT_GT(BestIou(p, room.high, "all", "split"), 0.6f);
  Eigen::AlignedBox3f both = room.low;
  both.extend(room.high);
  EXPECT_GT(BestIou(p, both, "all"), 0.7f);
  // The cabinet's front is > 1 m tall and 0.9 m long: the "all" removal takes it for a wall;
  // "segs" keeps it (its top is below wall height), and its proposal is the cabinet.
  EXPECT_GT(BestIou(p, room.cabinet, "segs"), 0.6f);
  // The wardrobe's 2 m front is a wall to "segs"; "fronts" (on here) keeps it whole.
  EXPECT_LT(BestIou(p, room.wardrobe, "segs"), 0.5f);
  EXPECT_GT(BestIou(p, room.wardrobe, "fronts"), 0.7f);
  // The top alone, and extended down to its legs (the column under it): the table's box.
  EXPECT_GT(BestIou(p, room.top, "all"), 0.4f);  // a 5 cm slab: a centimetre of noise costs IoU
  EXPECT_GT(BestIou(p, room.legs_and_top, "all", "+ext"), 0.8f);
  // Walls are in no "all" proposal larger than a sliver (the last centimetres at a wall's ends,
  // beyond its inliers' 1-99 % extent, stay); the floor is in none at all.
  for (const auto& q : p.items) {
    int wall = 0, floor = 0;
    for (int i : q.indices) {
      const Eigen::Vector3f& x = room.scan.points[size_t(i)];
      wall += x.x() < -2.97f || x.y() > 2.97f;
      floor += x.z() < kFloor + 0.02f;
    }
    const Eigen::Vector3f e = q.box.sizes();
    if (q.source == "all" && wall > 0) {
      EXPECT_LT(std::min(e.x(), e.y()), 0.15f) << q.how << " " << q.box.min().transpose() << " / " << q.box.max().transpose();
    }
    EXPECT_EQ(floor, 0) << q.how;
  }
  ASSERT_EQ(p.removed.size(), room.scan.points.size());
}

// The share of the walls' points (30 cm and more above the floor) that the "all" removal took.
double WallRemoved(const Room& room, const Proposals& p) {
  size_t wall = 0, removed = 0;
  for (size_t i = 0; i < room.scan.points.size(); ++i) {
    const Eigen::Vector3f& x = room.scan.points[i];
    if (!(x.x() < -2.97f || x.y() > 2.97f) || x.z() < kFloor + 0.3f) continue;
    ++wall;
    removed += p.removed[i] == 1;
  }
  return wall ? double(removed) / double(wall) : 0.0;
}

// The room as a raw depth sensor sees it (range noise 2 mm + 4 mm/m^2: 10 cm at 5 m, far more
// than the 1.5 cm point spacing): the far walls' own k-NN normals scatter, a quarter of the walls
// is not found and joins the objects' clusters; with wall_normals "blocks" nearly all of them are.
TEST(Clusters, WallsOfANoisySensorAreFoundByBlockNormals) {
  const Room room = MakeRoom({{"voxel_m", 0.015}, {"noise_a", 0.002}, {"noise_b", 0.004}});
  RunContext ctx;
  const double points = WallRemoved(room, Make<Proposer>("proposals.clusters")->Propose(room.scan, nullptr, ctx));
  const json blocks = {{"wall_normals", "blocks"}, {"wall_voxel_m", 0.08}};
  const double block = WallRemoved(room, Make<Proposer>("proposals.clusters", blocks)->Propose(room.scan, nullptr, ctx));
  EXPECT_LT(points, 0.85);
  EXPECT_GT(block, 0.95);
  // "auto" is "blocks" for a scan with a sensor origin, "points" without.
  Scan with_origin = room.scan;
  with_origin.origin = Eigen::Vector3f(0.5f, 0.f, kFloor + 1.5f);
  const auto autop = Make<Proposer>("proposals.clusters", {{"wall_normals", "auto"}, {"wall_voxel_m", 0.08}});
  EXPECT_EQ(WallRemoved(room, autop->Propose(with_origin, nullptr, ctx)), block);
  EXPECT_EQ(WallRemoved(room, autop->Propose(room.scan, nullptr, ctx)), points);
}

// wall_normals "both": the proposals of "points" and those of "blocks", the latter's rules named
// all_blocks, segs_blocks and fronts_blocks, each with the same points, box and surround as in its
// own run (the noisy room, where the two sets of walls differ). The removed-points mask is the
// points' walls'. blocks_rules keeps only the listed rules of the blocks' walls.
TEST(Clusters, BothWallSetsGiveEachSetsProposalsUnderTheirOwnRules) {
  const Room room = MakeRoom({{"voxel_m", 0.015}, {"noise_a", 0.002}, {"noise_b", 0.004}});
  RunContext ctx;
  auto run = [&](const std::string& normals) {
    const json params = {{"wall_normals", normals}, {"wall_voxel_m", 0.08}, {"fronts_length_m", 1.3}};
    return Make<Proposer>("proposals.clusters", params)->Propose(room.scan, nullptr, ctx);
  };
  const Proposals points = run("points"), blocks = run("blocks"), both = run("both");
  // (rule, how, points) -> (box, surround) of a run, its rules renamed by `suffix`.
  using Key = std::tuple<std::string, std::string, std::vector<int>>;
  auto index = [](const Proposals& p, const std::string& suffix, std::map<Key, std::pair<Eigen::AlignedBox3f, float>>& out) {
    for (const auto& q : p.items) {
      std::vector<int> idx = q.indices;
      std::sort(idx.begin(), idx.end());
      std::string how = q.how;
      how.insert(q.source.size(), suffix);
      out.emplace(Key{q.source + suffix, how, idx}, std::make_pair(q.box, q.surround));
    }
  };
  std::map<Key, std::pair<Eigen::AlignedBox3f, float>> expected, got;
  index(points, "", expected);
  index(blocks, "_blocks", expected);
  index(both, "", got);
  std::set<std::string> rules;
  for (const auto& q : both.items) rules.insert(q.source);
  EXPECT_EQ(rules, (std::set<std::string>{"all", "segs", "fronts", "all_blocks", "segs_blocks", "fronts_blocks"}));
  // Every expected proposal once in `have`, with its box and surround.
  auto expect_same = [](const std::map<Key, std::pair<Eigen::AlignedBox3f, float>>& want,
                        const std::map<Key, std::pair<Eigen::AlignedBox3f, float>>& have) {
    ASSERT_EQ(have.size(), want.size());
    for (const auto& [key, value] : want) {
      const auto it = have.find(key);
      ASSERT_NE(it, have.end()) << std::get<1>(key);
      EXPECT_TRUE(it->second.first.isApprox(value.first)) << std::get<1>(key);
      EXPECT_FLOAT_EQ(it->second.second, value.second) << std::get<1>(key);
    }
  };
  expect_same(expected, got);
  EXPECT_EQ(both.removed, points.removed);
  EXPECT_NE(blocks.removed, points.removed);  // the two sets of walls differ in this room

  // blocks_rules "segs": of the blocks' walls only the segs_blocks proposals, the same as above.
  const json segs_only = {{"wall_normals", "both"}, {"wall_voxel_m", 0.08}, {"fronts_length_m", 1.3},
                          {"blocks_rules", "segs"}};
  std::map<Key, std::pair<Eigen::AlignedBox3f, float>> fewer, kept;
  index(Make<Proposer>("proposals.clusters", segs_only)->Propose(room.scan, nullptr, ctx), "", fewer);
  for (const auto& [key, value] : got)
    if (std::get<0>(key) != "all_blocks" && std::get<0>(key) != "fronts_blocks") kept.emplace(key, value);
  expect_same(kept, fewer);
  EXPECT_THROW(Make<Proposer>("proposals.clusters", {{"blocks_rules", "segs, walls"}}), std::exception);
}

// A scene named `id` holding a 6 x 6 m floor at kFloor, for the objects a test adds.
CatalogModel FloorScene(const std::string& id) {
  CatalogModel m;
  m.id = id;
  m.cls = id;
  const Eigen::Vector3f up(0, 0, kFloor);
  AddBox(m.mesh, Eigen::Vector3f(-3.f, -3.f, -0.02f) + up, Eigen::Vector3f(3.f, 3.f, 0.f) + up);
  return m;
}

// The scene `m` scanned by four laser scanners 2.6 m around its centre, 1.6 m above the floor,
// fused, voxelised to 1.5 cm, its ground estimated.
Scan ScanAround(const CatalogModel& m) {
  Scan scan;
  SensorRequest req;
  req.objects.push_back({&m, Eigen::Isometry3f::Identity()});
  for (float a : {0.3f, 1.9f, 3.5f, 5.1f}) {
    Eigen::Isometry3f s = Eigen::Isometry3f::Identity();
    s.linear() = Eigen::AngleAxisf(a + 3.14159f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    s.translation() = Eigen::Vector3f(2.6f * std::cos(a), 2.6f * std::sin(a), kFloor + 1.6f);
    req.poses.push_back(s);
  }
  RunContext ctx;
  auto sensor = Make<Sensor>("sensors.simulated_laser", {{"voxel_m", 0.015}});
  for (auto& v : sensor->Acquire(req, ctx)) scan.points.insert(scan.points.end(), v.points.begin(), v.points.end());
  scan.ground = EstimateGround(scan.points, GroundOptions{});
  return scan;
}

// A desk under a monitor: its cluster reaches the monitor's top, and a work-top variant gives the
// desk alone (its top and what is under it). A bare table (nothing over its top) and a counter at
// kitchen height (0.9 m, above work_top_max_m) get no such variant.
TEST(Clusters, WorkTopVariantDropsWhatStandsOnADesk) {
  CatalogModel m = FloorScene("office");
  const Eigen::Vector3f up(0, 0, kFloor);
  auto table = [&](float x0, float y0, float len, float dep, float h) {
    AddBox(m.mesh, Eigen::Vector3f(x0, y0, h - 0.04f) + up, Eigen::Vector3f(x0 + len, y0 + dep, h) + up);
    for (float x : {x0 + 0.02f, x0 + len - 0.07f})
      for (float y : {y0 + 0.02f, y0 + dep - 0.07f})
        AddBox(m.mesh, Eigen::Vector3f(x, y, 0.f) + up, Eigen::Vector3f(x + 0.05f, y + 0.05f, h - 0.04f) + up);
  };
  const Eigen::AlignedBox3f desk = Box({-1.5f, -1.5f, 0.f}, {-0.1f, -0.8f, 0.75f});
  table(-1.5f, -1.5f, 1.4f, 0.7f, 0.75f);
  // Two monitors on stands at the desk's back, 0.45 m over its top.
  for (float x : {-1.3f, -0.7f}) {
    AddBox(m.mesh, Eigen::Vector3f(x, -0.95f, 0.75f) + up, Eigen::Vector3f(x + 0.5f, -0.9f, 1.2f) + up);
  }
  const Eigen::AlignedBox3f bare = Box({0.8f, 0.5f, 0.f}, {2.0f, 1.3f, 0.74f});
  table(0.8f, 0.5f, 1.2f, 0.8f, 0.74f);
  const Eigen::AlignedBox3f counter = Box({-1.5f, 1.0f, 0.f}, {0.3f, 1.6f, 0.9f});
  AddBox(m.mesh, counter.min(), counter.max());
  AddBox(m.mesh, Eigen::Vector3f(-1.2f, 1.1f, 0.9f) + up, Eigen::Vector3f(-0.7f, 1.5f, 1.2f) + up);  // a microwave on it

  const Scan scan = ScanAround(m);
  RunContext ctx;

  const Proposals p = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  // The whole cluster is 1.2 m tall: its box is not the desk's.
  Eigen::AlignedBox3f with_monitors = desk;
  with_monitors.max().z() = kFloor + 1.2f;
  EXPECT_GT(BestIou(p, with_monitors, "all"), 0.8f);
  float cluster_only = 0.f;
  for (const auto& q : p.items)
    if (q.source == "all" && q.how.find("+top") == std::string::npos) cluster_only = std::max(cluster_only, Iou(q.box, desk));
  EXPECT_LT(cluster_only, 0.7f);
  EXPECT_GT(BestIou(p, desk, "all", "+top"), 0.8f);
  // No work top where nothing stands on the table, or on a counter at kitchen height.
  EXPECT_EQ(BestIou(p, bare, "all", "+top"), 0.f);
  EXPECT_EQ(BestIou(p, counter, "all", "+top"), 0.f);
  EXPECT_EQ(BestIou(p, counter, "segs", "+top"), 0.f);
  // A 'fronts' length the 'segs' rule already covers would add nothing: refused, naming it.
  try {
    Make<Proposer>("proposals.clusters", {{"fronts_length_m", 0.4}});
    ADD_FAILURE() << "fronts_length_m 0.4 accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("fronts_length_m"), std::string::npos) << e.what();
  }
  // Off: no variant at all.
  const Proposals off = Make<Proposer>("proposals.clusters", {{"work_top_variants", false}})->Propose(scan, nullptr, ctx);
  for (const auto& q : off.items) EXPECT_EQ(q.how.find("+top"), std::string::npos) << q.how;
}

// A nightstand under a lamp: its cluster reaches the lamp's top, and the low-top variant (rule
// all_low) gives the nightstand alone. A bare nightstand (nothing over its top), a bookcase (its
// top above low_top_max_m) and a block whose raised part covers most of its footprint (more than
// low_top_above_max: a taller object with a low shelf beside it, not a lamp on a top) get none;
// off by default.
TEST(Clusters, LowTopVariantDropsALampOffANightstand) {
  CatalogModel m = FloorScene("bedroom");
  const Eigen::Vector3f up(0, 0, kFloor);
  const Eigen::AlignedBox3f stand = Box({-1.5f, -1.5f, 0.f}, {-1.0f, -1.05f, 0.6f});
  AddBox(m.mesh, stand.min(), stand.max());
  AddBox(m.mesh, Eigen::Vector3f(-1.33f, -1.36f, 0.6f) + up, Eigen::Vector3f(-1.17f, -1.2f, 1.1f) + up);  // the lamp
  const Eigen::AlignedBox3f bare = Box({1.0f, -1.5f, 0.f}, {1.5f, -1.05f, 0.6f});
  AddBox(m.mesh, bare.min(), bare.max());
  const Eigen::AlignedBox3f bookcase = Box({-1.5f, 1.0f, 0.f}, {-0.7f, 1.35f, 1.8f});
  AddBox(m.mesh, bookcase.min(), bookcase.max());
  // A 1.0 x 0.5 m block 0.6 m tall with a box 0.4 m taller on 0.6 m of its length: 3/5 of its cells high.
  const Eigen::AlignedBox3f unit = Box({1.0f, 1.0f, 0.f}, {2.0f, 1.5f, 1.0f});
  AddBox(m.mesh, unit.min(), Eigen::Vector3f(2.0f, 1.5f, 0.6f) + up);
  AddBox(m.mesh, Eigen::Vector3f(1.4f, 1.0f, 0.6f) + up, unit.max());

  const Scan scan = ScanAround(m);
  RunContext ctx;

  const Proposals p = Make<Proposer>("proposals.clusters", {{"low_top_variants", true}})->Propose(scan, nullptr, ctx);
  Eigen::AlignedBox3f with_lamp = stand;
  with_lamp.max().z() = kFloor + 1.1f;
  EXPECT_GT(BestIou(p, with_lamp, "all"), 0.8f);
  EXPECT_GT(BestIou(p, stand, "all_low", "+low"), 0.7f);
  // The variant ends at the nightstand's top (a box cut at the lamp's top is 0.3 IoU above).
  for (const auto& q : p.items)
    if (q.source == "all_low" && Iou(q.box, stand) > 0.5f) {
      EXPECT_LT(q.box.max().z(), kFloor + 0.65f) << q.how;
    }
  EXPECT_EQ(BestIou(p, bare, "all_low"), 0.f);
  EXPECT_EQ(BestIou(p, bookcase, "all_low"), 0.f);
  EXPECT_EQ(BestIou(p, unit, "all_low"), 0.f);
  // Allowed to cover all of it, the tall part is cut off the unit too.
  const Proposals any = Make<Proposer>("proposals.clusters", {{"low_top_variants", true}, {"low_top_above_max", 1.0}})
                            ->Propose(scan, nullptr, ctx);
  EXPECT_GT(BestIou(any, Box({1.0f, 1.0f, 0.f}, {2.0f, 1.5f, 0.6f}), "all_low"), 0.7f);
  // Off (the default): no variant at all.
  const Proposals off = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  for (const auto& q : off.items) EXPECT_EQ(q.how.find("+low"), std::string::npos) << q.how;
  EXPECT_THROW(Make<Proposer>("proposals.clusters", {{"low_top_min_m", 0.6}, {"low_top_max_m", 0.62}}), std::exception);
}

// Points on the faces of a box (not its bottom) on a grid of `step` (a reconstruction's mesh
// vertices, without a sensor's shadows).
void SampleBox(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, float step, Points& out) {
  auto grid = [&](int a, int b, int c, float at) {  // the face where axis c = at
    for (float u = lo[a]; u <= hi[a] + 1e-4f; u += step)
      for (float v = lo[b]; v <= hi[b] + 1e-4f; v += step) {
        Eigen::Vector3f p;
        p[a] = u, p[b] = v, p[c] = at;
        out.push_back(p);
      }
  };
  grid(0, 1, 2, hi.z());
  grid(1, 2, 0, lo.x()), grid(1, 2, 0, hi.x());
  grid(0, 2, 1, lo.y()), grid(0, 2, 1, hi.y());
}

// Two armchairs side by side, touching at their armrests: one cluster, longer than any chair.
// In a reconstruction the armrests are dense (rounded, padded: many mesh vertices; here twice
// the density), so the sparsest slices lie in the seats, where the flat profile refuses a cut.
// The profile's ridge where the armrests meet gives the cut in two, and each chair.
TEST(Clusters, TouchingArmchairsAreCutAtTheirArmrests) {
  Scan scan;
  for (float x = -2.f; x <= 2.f; x += 0.02f)
    for (float y = -1.5f; y <= 2.f; y += 0.02f) scan.points.emplace_back(x, y, kFloor);
  const Eigen::Vector3f up(0, 0, kFloor);
  std::vector<Eigen::AlignedBox3f> chairs;
  for (float x0 : {-0.8f, 0.0f}) {
    SampleBox(Eigen::Vector3f(x0 + 0.12f, 0.f, 0.f) + up, Eigen::Vector3f(x0 + 0.68f, 0.65f, 0.42f) + up, 0.02f,
              scan.points);  // seat
    SampleBox(Eigen::Vector3f(x0, 0.f, 0.f) + up, Eigen::Vector3f(x0 + 0.12f, 0.8f, 0.62f) + up, 0.01f, scan.points);
    SampleBox(Eigen::Vector3f(x0 + 0.68f, 0.f, 0.f) + up, Eigen::Vector3f(x0 + 0.8f, 0.8f, 0.62f) + up, 0.01f,
              scan.points);  // arms
    SampleBox(Eigen::Vector3f(x0 + 0.12f, 0.65f, 0.f) + up, Eigen::Vector3f(x0 + 0.68f, 0.8f, 0.85f) + up, 0.02f,
              scan.points);  // back
    chairs.push_back(Box({x0, 0.f, 0.f}, {x0 + 0.8f, 0.8f, 0.85f}));
  }
  scan.ground = GroundModel::Level(kFloor, "fixed");
  RunContext ctx;
  Eigen::AlignedBox3f both = chairs[0];
  both.extend(chairs[1]);
  const Proposals with = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  // (The "all" removal takes the dense armrests' and backs' faces for walls: "segs" here.)
  EXPECT_GT(BestIou(with, both, "segs"), 0.9f);
  for (const auto& c : chairs) EXPECT_GT(BestIou(with, c, "segs", "split2"), 0.9f);
  const Proposals without = Make<Proposer>("proposals.clusters", {{"split_ridges", false}})->Propose(scan, nullptr, ctx);
  for (const auto& c : chairs) EXPECT_LT(BestIou(without, c, "segs", "split2"), 0.75f);
}

// Degenerate input: nothing to propose, a flood of identical points (10^6: linear time, else
// beyond ctest's timeout), a cloud without a ground.
TEST(Clusters, DegenerateScans) {
  RunContext ctx;
  auto proposer = Make<Proposer>("proposals.clusters");
  Scan empty;
  EXPECT_TRUE(proposer->Propose(empty, nullptr, ctx).items.empty());
  Scan same;
  same.points.assign(1000000, Eigen::Vector3f(1.f, 1.f, 0.5f));
  same.ground = GroundModel::Level(0.f, "fixed");
  Proposals p;
  EXPECT_NO_THROW(p = proposer->Propose(same, nullptr, ctx));
  EXPECT_EQ(p.removed.size(), same.points.size());
  Scan none;
  for (int i = 0; i < 1000; ++i) none.points.emplace_back(0.01f * i, 0.f, 0.3f + 0.0001f * i);
  EXPECT_NO_THROW(proposer->Propose(none, nullptr, ctx));
}

// A scan holding each point twice (duplicated vertices) proposes as the scan itself; one of two
// registered passes (a twin layer 2 mm off) still gives the objects whole (the spacing is not
// taken from the twins' 2 mm); past max_points a seeded random subset is proposed on.
TEST(Clusters, DuplicatesTwinLayersAndMaxPoints) {
  const Room room = MakeRoom();
  RunContext ctx;
  auto proposer = Make<Proposer>("proposals.clusters");
  const Proposals p0 = proposer->Propose(room.scan, nullptr, ctx);
  const size_t n = room.scan.points.size();
  Eigen::AlignedBox3f both = room.low;
  both.extend(room.high);
  ASSERT_GT(BestIou(p0, both, "all"), 0.7f);

  Scan doubled = room.scan;
  doubled.points.insert(doubled.points.end(), room.scan.points.begin(), room.scan.points.end());
  const Proposals p1 = proposer->Propose(doubled, nullptr, ctx);
  EXPECT_FLOAT_EQ(p1.spacing, p0.spacing);
  ASSERT_EQ(p1.items.size(), p0.items.size());
  for (size_t i = 0; i < p0.items.size(); ++i) {
    EXPECT_EQ(p1.items[i].indices, p0.items[i].indices);  // the first copies
    EXPECT_TRUE(p1.items[i].box.isApprox(p0.items[i].box));
  }
  EXPECT_EQ(p1.removed.size(), doubled.points.size());

  Scan twins = room.scan;
  std::mt19937 rng(5);
  std::normal_distribution<float> jitter(0.f, 0.002f);
  for (const auto& x : room.scan.points) twins.points.push_back(x + Eigen::Vector3f(jitter(rng), jitter(rng), jitter(rng)));
  // The twins' nearest neighbours are 2-4 mm away; the spacing stays near the grid's 1.5 cm
  // (0.45 x the 4th neighbour's distance: the twin of a grid neighbour).
  const Proposals p2 = proposer->Propose(twins, nullptr, ctx);
  EXPECT_GT(p2.spacing, 0.4f * p0.spacing);
  // On as many points as one pass has, most twins are apart: the objects come whole.
  const Proposals p2m = Make<Proposer>("proposals.clusters", {{"max_points", int(n)}})->Propose(twins, nullptr, ctx);
  EXPECT_GT(BestIou(p2m, both, "all"), 0.7f);
  EXPECT_GT(BestIou(p2m, room.legs_and_top, "all", "+ext"), 0.7f);

  const json half = {{"max_points", int(n / 2)}};
  const Proposals p3 = Make<Proposer>("proposals.clusters", half)->Propose(room.scan, nullptr, ctx);
  std::vector<int> used;
  for (const auto& q : p3.items) used.insert(used.end(), q.indices.begin(), q.indices.end());
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  EXPECT_LE(used.size(), n / 2);
  EXPECT_GT(BestIou(p3, both, "all"), 0.6f);
  EXPECT_EQ(p3.removed.size(), n);
  const Proposals again = Make<Proposer>("proposals.clusters", half)->Propose(room.scan, nullptr, ctx);
  ASSERT_EQ(again.items.size(), p3.items.size());
  for (size_t i = 0; i < p3.items.size(); ++i) EXPECT_EQ(again.items[i].indices, p3.items[i].indices);
  RunContext other;
  other.seed = 7;
  const Proposals reseeded = Make<Proposer>("proposals.clusters", half)->Propose(room.scan, nullptr, other);
  std::vector<int> used7;
  for (const auto& q : reseeded.items) used7.insert(used7.end(), q.indices.begin(), q.indices.end());
  std::sort(used7.begin(), used7.end());
  used7.erase(std::unique(used7.begin(), used7.end()), used7.end());
  EXPECT_NE(used7, used);
}

// A space of many rooms has more walls than one room: 48 wall segments (2.4 m long, 2 m high,
// each on a line of its own) over a 24 x 18 m floor are all found and removed, as the first 40
// were before the wall search ran past 40 planes.
TEST(Clusters, EveryWallOfALargeSpaceIsFound) {
  Scan scan;
  for (float x = -12.f; x < 12.f; x += 0.1f)
    for (float y = -9.f; y < 9.f; y += 0.1f) scan.points.emplace_back(x, y, 0.f);
  std::vector<std::pair<size_t, size_t>> walls;  // each wall's points [first, last)
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 6; ++j) {
      const float a = float(i * 6 + j) * 7.5f * 3.14159265f / 180.f;  // 48 directions 7.5 deg apart
      const Eigen::Vector3f c(-10.5f + 3.f * float(i), -7.5f + 3.f * float(j), 0.f), d(std::cos(a), std::sin(a), 0.f);
      const size_t first = scan.points.size();
      for (float t = -1.2f; t <= 1.2f; t += 0.03f)
        for (float h = 0.05f; h <= 2.05f; h += 0.03f) scan.points.push_back(c + t * d + Eigen::Vector3f(0.f, 0.f, h));
      walls.emplace_back(first, scan.points.size());
    }
  scan.ground = EstimateGround(scan.points, GroundOptions{});
  RunContext ctx;
  const Proposals p = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  ASSERT_EQ(p.removed.size(), scan.points.size());
  int found = 0;
  for (const auto& [first, last] : walls) {
    size_t removed = 0;
    for (size_t i = first; i < last; ++i) removed += p.removed[i] == 1;
    found += removed > 9 * (last - first) / 10;
  }
  EXPECT_EQ(found, 48);
}

// A wall's line runs on through the rest of a space: a sideboard 3 m further along it, its back
// on that line, is not wall (the "all" rule takes a plane's inliers in runs along the line, each
// a wall only if it is large itself).
TEST(Clusters, FurnitureOnAWallsLineFarAlongItIsNotWall) {
  Scan scan;
  const float g = 0.03f;
  for (float x = -1.f; x < 8.f; x += g)
    for (float y = -3.f; y < 1.f; y += g) scan.points.emplace_back(x, y, 0.f);
  for (float x = 0.f; x <= 2.f; x += g)  // a wall 2 m long, 2.5 m high, on y = 0
    for (float z = 0.05f; z <= 2.5f; z += g) scan.points.emplace_back(x, 0.f, z);
  const size_t first = scan.points.size();
  const Eigen::Vector3f lo(5.f, -0.5f, 0.f), hi(6.2f, 0.f, 0.8f);  // the sideboard, its back on y = 0
  for (float a = lo.x(); a <= hi.x(); a += g)
    for (float z = 0.05f; z <= hi.z(); z += g) scan.points.emplace_back(a, lo.y(), z), scan.points.emplace_back(a, hi.y(), z);
  for (float b = lo.y() + g; b < hi.y(); b += g)
    for (float z = 0.05f; z <= hi.z(); z += g) scan.points.emplace_back(lo.x(), b, z), scan.points.emplace_back(hi.x(), b, z);
  for (float a = lo.x(); a <= hi.x(); a += g)
    for (float b = lo.y(); b <= hi.y(); b += g) scan.points.emplace_back(a, b, hi.z());
  const size_t last = scan.points.size();
  scan.ground = EstimateGround(scan.points, GroundOptions{});
  RunContext ctx;
  const Proposals p = Make<Proposer>("proposals.clusters")->Propose(scan, nullptr, ctx);
  ASSERT_EQ(p.removed.size(), scan.points.size());
  size_t wall = 0, back = 0, back_wall = 0;
  for (size_t i = 0; i < first; ++i) wall += scan.points[i].y() == 0.f && p.removed[i] == 1;
  for (size_t i = first; i < last; ++i)
    if (std::abs(scan.points[i].y()) < 1e-4f) ++back, back_wall += p.removed[i] == 1;
  EXPECT_GT(wall, 3000u);  // the wall is removed
  ASSERT_GT(back, 500u);
  EXPECT_LT(back_wall, back / 10);  // the sideboard's back is not
  EXPECT_GT(BestIou(p, Eigen::AlignedBox3f(lo, hi), "all"), 0.8f);
}

// thin_spacing_m thins by density, not by count: a room sampled four times as densely is
// proposed on a subset about as sparse as the threshold, while two rooms side by side at the
// same density (twice the points) keep every point, where max_points would halve them.
TEST(Clusters, ThinSpacingThinsDenserScansNotLargerOnes) {
  const Room room = MakeRoom();
  RunContext ctx;
  const size_t n = room.scan.points.size();
  Eigen::AlignedBox3f both = room.low;
  both.extend(room.high);
  const Proposals p0 = Make<Proposer>("proposals.clusters")->Propose(room.scan, nullptr, ctx);
  ASSERT_GT(p0.spacing, 0.01f);
  auto used = [](const Proposals& p) {
    std::vector<int> u;
    for (const auto& q : p.items) u.insert(u.end(), q.indices.begin(), q.indices.end());
    std::sort(u.begin(), u.end());
    u.erase(std::unique(u.begin(), u.end()), u.end());
    return u.size();
  };
  const json thin = {{"thin_spacing_m", 0.9 * p0.spacing}};

  // Four passes, each point moved at random by 4 mm: four times the points on the same surfaces.
  Scan dense = room.scan;
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.f, 0.004f);
  for (int pass = 0; pass < 3; ++pass)
    for (const auto& x : room.scan.points) dense.points.push_back(x + Eigen::Vector3f(noise(rng), noise(rng), noise(rng)));
  const Proposals all = Make<Proposer>("proposals.clusters")->Propose(dense, nullptr, ctx);
  const Proposals thinned = Make<Proposer>("proposals.clusters", thin)->Propose(dense, nullptr, ctx);
  EXPECT_LT(all.spacing, 0.7f * p0.spacing);
  EXPECT_GT(thinned.spacing, 0.7f * p0.spacing);
  EXPECT_LT(used(thinned), 2 * n);
  EXPECT_EQ(thinned.removed.size(), dense.points.size());
  EXPECT_GT(BestIou(thinned, both, "all"), 0.6f);

  // The room and a copy of it 6 m away: the same density, twice the points.
  Scan two = room.scan;
  for (const auto& x : room.scan.points) two.points.push_back(x + Eigen::Vector3f(6.f, 0.f, 0.f));
  const Proposals kept = Make<Proposer>("proposals.clusters", thin)->Propose(two, nullptr, ctx);
  EXPECT_NEAR(kept.spacing, p0.spacing, 0.03f * p0.spacing);
  EXPECT_GT(used(kept), used(p0) + used(p0) / 2);  // both rooms' objects, all their points
  const Proposals counted = Make<Proposer>("proposals.clusters", {{"max_points", int(n)}})->Propose(two, nullptr, ctx);
  EXPECT_GT(counted.spacing, 1.2f * p0.spacing);  // max_points thins it to half
}

}  // namespace
}  // namespace furnihost
