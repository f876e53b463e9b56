// furnihost::shape: nearest neighbours against brute force, PCA normals of a plane, the
// spacing of a grid, the footprint of a turned rectangle with outliers, profiles and their
// distance, visibility behind an occluder, suppression of overlapping proposals (and of a whole
// by its better-scored fragment only when asked); the neighbours the pipeline finds with the working
// frame give the shape a k-d tree of the working points gives.
#include "shape/shape.hpp"

#include "furnihost/host/frame.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace furnihost::shape {
namespace {

constexpr float kPi = 3.14159265358979f;

Points RandomCloud(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Points p;
  for (int i = 0; i < n; ++i) p.emplace_back(u(rng), u(rng), u(rng));
  return p;
}

TEST(KnnIndex, AgreesWithBruteForce) {
  const Points cloud = RandomCloud(2000, 3);
  KnnIndex index(cloud);
  std::vector<uint32_t> idx;
  std::vector<float> d2;
  for (int q = 0; q < 50; ++q) {
    const Eigen::Vector3f p = cloud[q * 37] + Eigen::Vector3f(0.01f, -0.02f, 0.005f);
    index.Query(p, 8, idx, d2);
    ASSERT_EQ(idx.size(), 8u);
    std::vector<float> all;
    for (const auto& c : cloud) all.push_back((c - p).squaredNorm());
    std::sort(all.begin(), all.end());
    for (int k = 0; k < 8; ++k) EXPECT_NEAR(d2[k], all[k], 1e-6f) << "query " << q << " rank " << k;
    EXPECT_TRUE(std::is_sorted(d2.begin(), d2.end()));
  }
}

// Copies of points (a driver's (0, 0, 0) for every invalid return) answer as the cloud would:
// the k nearest distances of brute force, each point once, copies counted.
TEST(KnnIndex, CopiesAgreeWithBruteForce) {
  Points cloud = RandomCloud(800, 5);
  for (int i = 0; i < 800; i += 5)
    for (int c = 0; c < 3; ++c) cloud.push_back(cloud[size_t(i)]);
  cloud.insert(cloud.end(), 3000, Eigen::Vector3f::Zero());
  KnnIndex index(cloud);
  std::vector<uint32_t> idx;
  std::vector<float> d2;
  for (int q = 0; q < 60; ++q) {
    const Eigen::Vector3f p = q < 50 ? cloud[size_t(q * 53)] : Eigen::Vector3f(0.01f * float(q - 50), 0.f, 0.f);
    index.Query(p, 20, idx, d2);
    ASSERT_EQ(idx.size(), 20u);
    std::vector<float> all;
    for (const auto& c : cloud) all.push_back((c - p).squaredNorm());
    std::sort(all.begin(), all.end());
    for (int k = 0; k < 20; ++k) {
      EXPECT_NEAR(d2[k], all[k], 1e-6f) << "query " << q << " rank " << k;
      EXPECT_NEAR(d2[k], (cloud[idx[k]] - p).squaredNorm(), 1e-6f);
    }
    std::vector<uint32_t> sorted = idx;
    std::sort(sorted.begin(), sorted.end());
    EXPECT_EQ(std::unique(sorted.begin(), sorted.end()), sorted.end()) << "a point returned twice";
  }
}

// A million copies of one point: spacing 0 and a unit normal for each, in linear time (a tree
// leaf holding all copies made this 10^12 steps, beyond ctest's timeout).
TEST(LocalShape, AMillionCopiesOfOnePoint) {
  const Points same(1000000, Eigen::Vector3f(1.f, 1.f, 0.5f));
  KnnIndex index(same);
  const LocalShape s = EstimateLocalShape(index, 16);
  ASSERT_EQ(s.nn.size(), same.size());
  EXPECT_EQ(*std::max_element(s.nn.begin(), s.nn.end()), 0.f);
  EXPECT_EQ(*std::max_element(s.nn4.begin(), s.nn4.end()), 0.f);
  for (size_t i = 0; i < same.size(); i += 9973) EXPECT_NEAR(s.normals[i].norm(), 1.f, 1e-5f);
  EXPECT_EQ(MedianSpacing(s.nn), 0.f);
}

// A (0, 0, 0) flood beside a view leaves the view's normals and spacing as they were.
TEST(LocalShape, ZeroFloodLeavesTheViewAlone) {
  Points view;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j) view.emplace_back(0.02f * float(i), 0.02f * float(j), 1.f);
  Points flooded(200000, Eigen::Vector3f::Zero());
  flooded.insert(flooded.end(), view.begin(), view.end());
  KnnIndex a(view), b(flooded);
  const LocalShape sa = EstimateLocalShape(a, 16), sb = EstimateLocalShape(b, 16);
  for (size_t i = 0; i < view.size(); ++i) {
    EXPECT_GT(std::abs(sb.normals[200000 + i].z()), 0.9999f) << i;
    EXPECT_EQ(sb.nn[200000 + i], sa.nn[i]) << i;
    EXPECT_EQ(sb.nn4[200000 + i], sa.nn4[i]) << i;
  }
  EXPECT_EQ(sb.nn[0], 0.f);
}

// The pipeline finds each point's 17 nearest positions while it estimates the canonical frame
// (in the z-up frame), and proposals.clusters takes its local shape from them instead of a k-d
// tree of the working points. A room-like cloud turned 0.7 rad: noisy walls and random points,
// copies of some points (a position of several points) and a regular grid (ties of distance).
// The frame is the same with and without the neighbours kept; the shapes agree (the distances
// are recomputed in the working frame; only near-ties may order differently).
TEST(LocalShape, TheFramesNeighboursGiveTheTreesShape) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::normal_distribution<float> noise(0.f, 0.004f);
  Points room;
  for (int i = 0; i < 6000; ++i) room.emplace_back(4.f * u(rng), noise(rng), 2.5f * u(rng));      // wall y = 0
  for (int i = 0; i < 4000; ++i) room.emplace_back(noise(rng), 3.f * u(rng), 2.5f * u(rng));      // wall x = 0
  for (int i = 0; i < 50; ++i)
    for (int j = 0; j < 50; ++j) room.emplace_back(1.f + 0.02f * float(i), 1.f + 0.02f * float(j), 0.f);  // grid floor
  for (int i = 0; i < 3000; ++i) room.emplace_back(4.f * u(rng), 3.f * u(rng), 2.5f * u(rng));
  for (int i = 0; i < 500; ++i) room.push_back(room[size_t(i * 7)]);  // copies
  const Eigen::Isometry3f turn(Eigen::AngleAxisf(0.7f, Eigen::Vector3f::UnitZ()));
  for (auto& p : room) p = turn * p;
  constexpr int kAsked = 17;  // what proposals.clusters asks for (StageNeeds): its 16 and itself
  ScanNeighbours nb;
  const Eigen::Isometry3d c = EstimateCanonicalFrame(room, &nb, kAsked);
  EXPECT_TRUE(c.isApprox(EstimateCanonicalFrame(room), 0.0)) << "the frame changed";
  ASSERT_TRUE(nb.Describes(room.size()));
  ASSERT_EQ(nb.k, kAsked);
  EXPECT_EQ(nb.Positions(), room.size() - 500);
  // Each position's list: itself first, then its nearest, as a brute-force search (distances).
  for (size_t v = 0; v < nb.Positions(); v += 97) {
    const Eigen::Vector3f& q = room[nb.members[nb.start[v]]];
    std::vector<float> all;
    for (size_t w = 0; w < nb.Positions(); ++w) all.push_back((room[nb.members[nb.start[w]]] - q).squaredNorm());
    std::sort(all.begin(), all.end());
    ASSERT_EQ(nb.count[v], kAsked);
    EXPECT_EQ(nb.nearest[v * size_t(nb.k)], v);
    for (int j = 0; j < nb.k; ++j)
      EXPECT_NEAR((room[nb.members[nb.start[nb.nearest[v * size_t(nb.k) + size_t(j)]]]] - q).squaredNorm(), all[size_t(j)], 1e-6f);
  }
  Points work(room.size());
  for (size_t i = 0; i < room.size(); ++i) work[i] = (c * room[i].cast<double>()).cast<float>();
  ASSERT_TRUE(CanUse(&nb, work, 16));
  EXPECT_FALSE(CanUse(&nb, work, 17));  // 18 points asked of 17 positions
  EXPECT_FALSE(CanUse(&nb, Points(work.begin(), work.end() - 1), 16));
  KnnIndex index(work);
  const LocalShape tree = EstimateLocalShape(index, 16), shared = EstimateLocalShape(work, nb, 16);
  ASSERT_EQ(shared.normals.size(), work.size());
  size_t exact = 0;
  for (size_t i = 0; i < work.size(); ++i) {
    exact += shared.normals[i] == tree.normals[i] && shared.nn[i] == tree.nn[i] && shared.nn4[i] == tree.nn4[i];
    EXPECT_GT(std::abs(shared.normals[i].dot(tree.normals[i])), 0.999f) << i;  // a tie at the grid: another 17th point
    EXPECT_NEAR(shared.nn[i], tree.nn[i], 1e-6f) << i;
    EXPECT_NEAR(shared.nn4[i], tree.nn4[i], 1e-6f) << i;
  }
  EXPECT_GT(double(exact), 0.98 * double(work.size()));  // the grid's ties
  // The frame keeps them with the scan only when asked (a stage of the graph needs them), as
  // many as asked, and never fewer than the 12 of its own plane fits.
  for (const int asked : {0, 5, kAsked, 30}) {
    Scan scan;
    scan.points = room;
    FrameOptions fo;
    fo.neighbours = asked;
    ToWorkingFrame(scan, fo);
    ASSERT_EQ(scan.neighbours != nullptr, asked > 0);
    if (asked > 0) {
      EXPECT_EQ(scan.neighbours->k, std::max(asked, 12));
      EXPECT_EQ(CanUse(scan.neighbours.get(), scan.points, 16), asked >= kAsked);
    }
  }
  // A cloud the frame samples (more than ~60k points) gets none.
  ScanNeighbours none;
  EstimateCanonicalFrame(RandomCloud(70000, 4), &none, kAsked);
  EXPECT_EQ(none.k, 0);
  EXPECT_FALSE(CanUse(&none, work, 16));
}

TEST(LocalShape, PlaneNormalsAndGridSpacing) {
  // A 2 cm grid on a plane tilted 30 degrees about x.
  const Eigen::Vector3f n(0.f, -std::sin(kPi / 6), std::cos(kPi / 6));
  const Eigen::Vector3f u(1.f, 0.f, 0.f), v = n.cross(u);
  Points plane;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) plane.push_back(0.02f * i * u + 0.02f * j * v);
  KnnIndex index(plane);
  const LocalShape s = EstimateLocalShape(index, 16);
  ASSERT_EQ(s.normals.size(), plane.size());
  for (size_t i = 0; i < plane.size(); i += 97) EXPECT_GT(std::abs(s.normals[i].dot(n)), 0.999f) << i;
  EXPECT_NEAR(MedianSpacing(s.nn), 0.02f, 1e-4f);
  for (size_t i = 0; i < plane.size(); i += 97) EXPECT_GE(s.nn4[i], s.nn[i]);
  // Duplicates are left out of the spacing; nothing to measure gives 0.
  EXPECT_NEAR(MedianSpacing(std::vector<float>{0.f, 0.f, 0.f, 0.03f, 0.03f}, 1), 0.03f, 1e-6f);
  EXPECT_EQ(MedianSpacing(std::vector<float>{0.f, 0.f}, 1), 0.f);
  EXPECT_EQ(MedianSpacing({}, 1), 0.f);
}

// A wall of a raw depth camera at a few metres: noise along its normal 1.5 times the point
// spacing. The points' own 16-neighbour normals scatter; the block normals (8 cm voxels) keep the
// wall's, also 10 km from the origin, and a million copies of one point take linear time.
TEST(BlockNormals, NoisyWallKeepsItsNormal) {
  const Eigen::Vector3f n = Eigen::Vector3f(std::cos(0.4f), std::sin(0.4f), 0.f);
  const Eigen::Vector3f u(-n.y(), n.x(), 0.f), v = Eigen::Vector3f::UnitZ();
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.f, 0.015f);
  Points wall;
  for (int i = 0; i < 150; ++i)
    for (int j = 0; j < 100; ++j) wall.push_back(0.01f * i * u + 0.01f * j * v + noise(rng) * n);
  auto share_within = [&](const Points& normals, float deg) {
    size_t ok = 0;
    for (const auto& m : normals) ok += std::abs(m.dot(n)) > std::cos(deg * kPi / 180.f);
    return double(ok) / double(normals.size());
  };
  KnnIndex index(wall);
  EXPECT_LT(share_within(EstimateLocalShape(index, 16).normals, 10.f), 0.5);
  const Points blocks = BlockNormals(wall, 0.08f);
  ASSERT_EQ(blocks.size(), wall.size());
  EXPECT_GT(share_within(blocks, 10.f), 0.95);
  Points far = wall;
  for (auto& p : far) p += Eigen::Vector3f(1e4f, -2e4f, 30.f);
  EXPECT_GT(share_within(BlockNormals(far, 0.08f), 10.f), 0.95);
  const Points same(1000000, Eigen::Vector3f(1.f, 2.f, 3.f));
  const Points one = BlockNormals(same, 0.08f);
  ASSERT_EQ(one.size(), same.size());
  EXPECT_TRUE(one.front().allFinite());
  EXPECT_TRUE(BlockNormals({}, 0.08f).empty());
}

TEST(Footprint, TurnedRectangleWithStrayPoints) {
  // A 1.2 x 0.5 m rectangle turned by 35 degrees about (2, -1), filled with points, plus 1 %
  // stray points 1 m away that must not set its size.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> ul(-0.6f, 0.6f), uw(-0.25f, 0.25f);
  const float yaw = 35.f * kPi / 180.f;
  const Eigen::Rotation2Df r(yaw);
  const Eigen::Vector2f c(2.f, -1.f);
  std::vector<Eigen::Vector2f> xy;
  for (int i = 0; i < 3000; ++i) xy.push_back(c + r * Eigen::Vector2f(ul(rng), uw(rng)));
  for (int i = 0; i < 20; ++i) xy.push_back(c + Eigen::Vector2f(1.5f, 1.5f));
  const Footprint f = OrientedFootprint(xy);
  EXPECT_NEAR(f.length, 1.2f, 0.06f);
  EXPECT_NEAR(f.width, 0.5f, 0.04f);
  EXPECT_NEAR(f.center.x(), c.x(), 0.05f);
  EXPECT_NEAR(f.center.y(), c.y(), 0.05f);
  // The yaw of the long side, up to its symmetry (pi).
  const float dy = std::remainder(f.yaw - yaw, kPi);
  EXPECT_LT(std::abs(dy), 3.f * kPi / 180.f) << f.yaw;
  // Too few points: their axis-aligned extents.
  const Footprint small = OrientedFootprint({{0.f, 0.f}, {0.4f, 0.1f}, {0.2f, 0.f}});
  EXPECT_NEAR(small.length, 0.4f, 1e-5f);
  EXPECT_NEAR(small.width, 0.1f, 1e-5f);
}

TEST(Footprint, SameWhateverThePointOrderAndQuarterTurnsOfTheFrame) {
  // An L-shaped cluster (a corner sofa: arms of 2.4 x 0.9 and 0.9 x 1.8 m) turned by 17 degrees,
  // 3000 points: its direction is chosen on a subsample, which must not depend on the order the
  // points come in (a cluster's order follows its search) nor on which of the frame's axes is x
  // (a canonical frame's axes come out in any quarter turn). Picking every k-th point of the
  // list, a shuffle moved the chosen direction by milliradians and the extents with it.
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const Eigen::Rotation2Df r(17.f * kPi / 180.f);
  std::vector<Eigen::Vector2f> xy;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector2f q = i % 2 ? Eigen::Vector2f(2.4f * u(rng), 0.9f * u(rng))
                                    : Eigen::Vector2f(0.9f * u(rng), 0.9f + 0.9f * u(rng));
    xy.push_back(Eigen::Vector2f(0.3f, -0.2f) + r * q);
  }
  const Footprint f = OrientedFootprint(xy);
  for (unsigned seed : {1u, 2u, 3u, 4u, 5u}) {
    std::vector<Eigen::Vector2f> shuffled = xy;
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(seed));
    const Footprint g = OrientedFootprint(shuffled);
    EXPECT_EQ(g.yaw, f.yaw) << "shuffle " << seed;
    EXPECT_EQ(g.length, f.length) << "shuffle " << seed;
    EXPECT_EQ(g.width, f.width) << "shuffle " << seed;
  }
  // A quarter turn and a mirror of the frame about its origin (exact in floating point).
  std::vector<Eigen::Vector2f> turned, mirrored;
  for (const auto& p : xy) turned.emplace_back(-p.y(), p.x()), mirrored.emplace_back(-p.x(), p.y());
  for (const auto& [name, pts] : {std::pair{"turned", &turned}, std::pair{"mirrored", &mirrored}}) {
    const Footprint g = OrientedFootprint(*pts);
    EXPECT_NEAR(g.length, f.length, 1e-5f) << name;
    EXPECT_NEAR(g.width, f.width, 1e-5f) << name;
  }
}

TEST(Profile, TableTopAndChairDifferAndTheDistanceIsAMetric) {
  // A table: a flat top at 0.75 m over the whole footprint. A chair: a seat at 0.45 m over
  // 3/4 of it and a back at 0.9 m over the last quarter. Heights as a share of top = 1 m.
  std::vector<Eigen::Vector2f> xy;
  std::vector<float> table_h, chair_h;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 40; ++j) {
      xy.emplace_back(0.0125f * i, 0.0125f * j);
      table_h.push_back(0.75f);
      chair_h.push_back(i < 30 ? 0.45f : 0.9f);
    }
  const Profile table = TopViewProfile(xy, table_h, 1.f);
  const Profile chair = TopViewProfile(xy, chair_h, 1.f);
  EXPECT_NEAR(std::accumulate(table.begin(), table.end(), 0.f), 1.f, 1e-5f);
  EXPECT_NEAR(std::accumulate(chair.begin(), chair.end(), 0.f), 1.f, 1e-5f);
  EXPECT_NEAR(table[15], 1.f, 1e-5f);                 // 0.75 of top: bin 15 of 20
  // 5 cm columns: the seat covers 7 of 10 columns across, the back the other 3.
  EXPECT_NEAR(chair[9], 0.7f, 0.06f);   // the seat
  EXPECT_NEAR(chair[18], 0.3f, 0.06f);  // the back
  EXPECT_NEAR(chair[9] + chair[18], 1.f, 1e-5f);
  EXPECT_EQ(ProfileDistance(table, table), 0.f);
  const float d = ProfileDistance(table, chair);
  EXPECT_NEAR(d, ProfileDistance(chair, table), 1e-6f);
  // EMD on [0, 1]: the seat's mass moves 0.30 (bin 9 to 15), the back's 0.15 (18 to 15).
  EXPECT_NEAR(d, chair[9] * 0.30f + chair[18] * 0.15f, 1e-4f);
  // Heights at or above the top fall into the last bin, not outside.
  const Profile over = TopViewProfile(xy, std::vector<float>(xy.size(), 2.f), 1.f);
  EXPECT_NEAR(over[kProfileBins - 1], 1.f, 1e-5f);
}

TEST(Visibility, AnOccluderHidesWhatIsBehindIt) {
  // Eye at the origin; a wall of samples at x = 2, a second one at x = 3 behind it but only
  // for |y| < 0.5 where the first wall stands, the rest of the back wall in the open.
  Points pts;
  for (int j = -20; j <= 20; ++j)
    for (int k = -10; k <= 10; ++k) {
      const float y = 0.025f * j, z = 0.025f * k;
      pts.emplace_back(2.f, y, z);
    }
  const size_t front = pts.size();
  for (int j = -60; j <= 60; ++j)
    for (int k = -10; k <= 10; ++k) pts.emplace_back(3.f, 0.025f * j, 0.025f * k);
  const std::vector<uint8_t> seen = VisibleFrom(pts, {Eigen::Vector3f::Zero()}, 0.02f, 0.03f);
  ASSERT_EQ(seen.size(), pts.size());
  int front_seen = 0, hidden_seen = 0, hidden = 0, open_seen = 0, open = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (i < front) {
      front_seen += seen[i];
      continue;
    }
    // Behind the front wall when its ray from the eye crosses x = 2 within |y| <= 0.5.
    const bool behind = std::abs(pts[i].y() * 2.f / 3.f) < 0.45f;
    const bool clear = std::abs(pts[i].y() * 2.f / 3.f) > 0.55f;
    if (behind) hidden += 1, hidden_seen += seen[i];
    if (clear) open += 1, open_seen += seen[i];
  }
  EXPECT_EQ(front_seen, static_cast<int>(front));
  EXPECT_EQ(hidden_seen, 0) << "of " << hidden;
  EXPECT_GT(open_seen, open * 9 / 10);
}

TEST(Visibility, EyesSurroundTheObjectAtTheirHeight) {
  const Points eyes = EyesAround(Eigen::Vector3f(1.f, 0.6f, 0.8f), 1.4f, 1.5f, 8);
  ASSERT_EQ(eyes.size(), 8u);
  const float half_diag = 0.5f * std::hypot(1.f, 0.6f);
  Eigen::Vector2f mean = Eigen::Vector2f::Zero();
  for (const auto& e : eyes) {
    EXPECT_NEAR(e.z(), 1.4f, 1e-5f);
    EXPECT_NEAR(e.head<2>().norm(), half_diag + 1.5f, 1e-4f);
    mean += e.head<2>() / 8.f;
  }
  EXPECT_LT(mean.norm(), 1e-4f);
}

TEST(SuppressOverlaps, AWholeSurvivesItsFragmentOnlyWhenAsked) {
  auto proposal = [](Eigen::Vector3f lo, Eigen::Vector3f hi) {
    Proposal p;
    p.box = Eigen::AlignedBox3f(lo, hi);
    return p;
  };
  // 0: a wall cabinet's lower half, scoring best; 1: the whole cabinet (2.2x the half's volume,
  // IoU 0.45 with it); 2: the half shifted by 2 cm, a true duplicate; 3: a box elsewhere.
  const std::vector<Proposal> items = {proposal({0, 0, 1.3f}, {1, 0.5f, 1.8f}),
                                       proposal({0, 0, 1.3f}, {1, 0.5f, 2.4f}),
                                       proposal({0.02f, 0, 1.3f}, {1.02f, 0.5f, 1.8f}),
                                       proposal({3, 0, 0}, {4, 1, 1})};
  const std::vector<float> score = {0.9f, 0.5f, 0.8f, 0.1f};
  EXPECT_EQ(SuppressOverlaps({0, 1, 2, 3}, score, items, 0.25f), (std::vector<size_t>{0, 3}));
  // At a ratio the whole reaches, it stays; the duplicate goes whatever the ratio.
  EXPECT_EQ(SuppressOverlaps({3, 2, 1, 0}, score, items, 0.25f, 2.f), (std::vector<size_t>{0, 1, 3}));
  // A whole smaller than the ratio asks is still a duplicate.
  EXPECT_EQ(SuppressOverlaps({0, 1, 2, 3}, score, items, 0.25f, 3.f), (std::vector<size_t>{0, 3}));
  // A larger box that does not hold the better one is judged by IoU alone.
  // (holds 80 % of it, IoU 0.33, 2.2x its volume)
  const std::vector<Proposal> apart = {items[0], proposal({0.2f, 0, 1.3f}, {1.2f, 0.5f, 2.4f})};
  EXPECT_EQ(SuppressOverlaps({0, 1}, {0.9f, 0.5f}, apart, 0.25f, 2.f), (std::vector<size_t>{0}));
}

}  // namespace
}  // namespace furnihost::shape

// A chair's back tells the model's way round: the model (its back at -y of its frame) turns a
// half turn when the points' back stands at +y, none when at -y; a table (its top quarter
// central) never turns; a near-square armchair may turn a quarter.
TEST(TopTurn, TheModelsBackGoesWhereThePointsBackIs) {
  using furnihost::shape::Footprint;
  // The turn for the points as they stand (their top quarter's centre, TopQuarterCentre).
  auto TurnToMatchTop = [](const Footprint& f, bool wide, const Eigen::Vector2f& top, const Eigen::Vector2f& size,
                           const std::vector<Eigen::Vector2f>& xy, const std::vector<float>& h, float height) {
    const auto centre = furnihost::shape::TopQuarterCentre(xy, h, height);
    return centre ? furnihost::shape::TurnToMatchTop(f, wide, top, size, *centre) : 0.f;
  };
  // A 0.5 x 0.5 seat at 0.45 m and a 0.95 m back along one side.
  auto chair = [](float back_y, float back_x, std::vector<Eigen::Vector2f>& xy, std::vector<float>& h) {
    for (int i = 0; i <= 10; ++i)
      for (int j = 0; j <= 10; ++j) {
        xy.emplace_back(-0.25f + 0.05f * float(i), -0.25f + 0.05f * float(j));
        h.push_back(0.45f);
      }
    for (int i = 0; i <= 10; ++i)
      for (int k = 0; k <= 10; ++k) {
        xy.emplace_back(back_x != 0.f ? back_x : -0.25f + 0.05f * float(i), back_y != 0.f ? back_y : -0.25f + 0.05f * float(i));
        h.push_back(0.5f + 0.045f * float(k));
      }
  };
  Footprint f;
  f.center = Eigen::Vector2f::Zero();
  f.yaw = 0.f;
  f.length = 0.6f;
  f.width = 0.5f;
  const Eigen::Vector2f back_at_minus_y(0.f, -0.4f), size(0.6f, 0.5f);
  std::vector<Eigen::Vector2f> xy;
  std::vector<float> h;
  chair(0.25f, 0.f, xy, h);  // back at +y
  EXPECT_NEAR(TurnToMatchTop(f, true, back_at_minus_y, size, xy, h, 0.95f), float(M_PI), 1e-6f);
  xy.clear(), h.clear();
  chair(-0.25f, 0.f, xy, h);  // back at -y: as the model stands
  EXPECT_EQ(TurnToMatchTop(f, true, back_at_minus_y, size, xy, h, 0.95f), 0.f);
  // A table's top quarter is central: no turn, wherever its points stand.
  xy.clear(), h.clear();
  chair(0.25f, 0.f, xy, h);
  EXPECT_EQ(TurnToMatchTop(f, true, Eigen::Vector2f(0.02f, 0.01f), size, xy, h, 0.95f), 0.f);
  // A near-square model (0.55 x 0.5) with its back at +x in the points: a quarter turn.
  xy.clear(), h.clear();
  chair(0.f, 0.25f, xy, h);
  const float q = TurnToMatchTop(f, true, back_at_minus_y, Eigen::Vector2f(0.55f, 0.5f), xy, h, 0.95f);
  EXPECT_NEAR(q, float(M_PI / 2), 1e-6f);
  // The model's -y turned by a quarter turn is +x: its back where the points' is.
  EXPECT_NEAR(std::cos(q) * back_at_minus_y.x() - std::sin(q) * back_at_minus_y.y(), 0.4f, 1e-5f);
  // A long model (0.9 x 0.5) never turns a quarter: the footprint's length decides its axis.
  EXPECT_EQ(std::fmod(TurnToMatchTop(f, true, back_at_minus_y, Eigen::Vector2f(0.9f, 0.5f), xy, h, 0.95f), float(M_PI)),
            0.f);
}
