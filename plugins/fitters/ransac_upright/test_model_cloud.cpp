// ModelCloud's coverage grid against its kd-tree: Covered(q) must give the exact answer
// (CoveredExact) for every query, the grid only decides the cells where it is sure. Queries:
// uniform in the grid's box (mostly far cells), and the model's own points jittered by up to
// 1.5x the inlier distance (the cells near the surface, where covered / ambiguous / outside
// meet).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include <octomap/OcTree.h>

#include "model_cloud.hpp"
#include "occupancy.hpp"
#include "synthetic_scene.hpp"
#include "test_support.hpp"

namespace {

using namespace furnihost;
using namespace furnihost::ransac_upright;
using namespace furnihost::synthetic;

void ExpectGridIsExact(const CatalogModel& m, float inlier, uint64_t seed) {
  SamplingOptions so;
  so.inlier_distance = inlier;
  const ModelCloud c(m, so, seed);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const Eigen::Vector3f lo = c.Bounds().min() - Eigen::Vector3f::Constant(2 * inlier);
  const Eigen::Vector3f ext = c.Bounds().sizes() + Eigen::Vector3f::Constant(4 * inlier);
  int covered = 0, wrong = 0, n = 0;
  auto check = [&](const Eigen::Vector3f& q) {
    const bool exact = c.CoveredExact(q);
    covered += exact;
    wrong += c.Covered(q) != exact;
    ++n;
  };
  for (int i = 0; i < 100000; ++i) check(lo + Eigen::Vector3f(u(rng), u(rng), u(rng)).cwiseProduct(ext));
  for (size_t i = 0; i < c.Cloud().size(); ++i)
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3f d(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f);
      check(c.Cloud()[i] + 3.f * inlier * u(rng) * d);
    }
  EXPECT_EQ(wrong, 0) << m.id << " inlier " << inlier << ": " << wrong << " of " << n << " queries";
  EXPECT_GT(covered, n / 4);      // the near-surface queries are mostly covered ...
  EXPECT_LT(covered, n - n / 10); // ... and not all of them
  EXPECT_GT(c.GridBytes(), 0u);
}

TEST(ModelCloud, CoverageGridAgreesWithTheKdTree) {
  const CatalogModel chair = Model("chair_b", "chair", Chair(0.56f, 0.50f, 0.40f, 0.62f, 0.05f).mesh);
  const CatalogModel table = Model("table", "table", Table(1.2f, 0.8f, 0.75f).mesh);
  for (float inlier : {0.02f, 0.04f, 0.013f}) {
    ExpectGridIsExact(chair, inlier, 3);
    ExpectGridIsExact(table, inlier, 4);
  }
}

// The disk cache gives back the sampled cloud bit for bit (points, normals, figures and the
// coverage grid's answers) under its key, and nothing under another key or from a damaged file.
TEST(ModelCloud, CacheRoundTripAndDamagedFiles) {
  namespace fs = std::filesystem;
  const CatalogModel chair = Model("chair_b", "chair", Chair(0.56f, 0.50f, 0.40f, 0.62f, 0.05f).mesh);
  SamplingOptions so;
  const ModelCloud c(chair, so, 5);
  const uint64_t key = ModelCloud::CacheKey(chair, so, 5);
  const std::string dir = furnihost::testing::TempDir("model_cloud_cache");
  const std::string path = dir + "/chair.fhmc";
  c.Save(path, key);
  auto l = ModelCloud::Load(path, key, chair.id);
  ASSERT_TRUE(l);
  EXPECT_EQ(l->Id(), chair.id);
  ASSERT_EQ(l->Cloud().size(), c.Cloud().size());
  for (size_t i = 0; i < c.Cloud().size(); ++i) {
    ASSERT_EQ(l->Cloud()[i], c.Cloud()[i]);
    ASSERT_EQ(l->Normals()[i], c.Normals()[i]);
  }
  EXPECT_EQ(l->Bounds().min(), c.Bounds().min());
  EXPECT_EQ(l->Bounds().max(), c.Bounds().max());
  EXPECT_EQ(l->Area(), c.Area());
  EXPECT_EQ(l->OuterArea(), c.OuterArea());
  EXPECT_EQ(l->Spacing(), c.Spacing());
  EXPECT_EQ(l->InlierDistance(), c.InlierDistance());
  EXPECT_EQ(l->GridBytes(), c.GridBytes());
  std::vector<int> a, b;
  c.HeightBand(0.4f, 0.01f, false, &a);
  l->HeightBand(0.4f, 0.01f, false, &b);
  EXPECT_EQ(a, b);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<float> u(-0.1f, 0.1f);
  int differ = 0;
  for (size_t i = 0; i < c.Cloud().size(); i += 7) {
    const Eigen::Vector3f q = c.Cloud()[i] + Eigen::Vector3f(u(rng), u(rng), u(rng));
    differ += c.Covered(q) != l->Covered(q);
    float d1 = 0, d2 = 0;
    differ += c.Nearest(q, &d1) != l->Nearest(q, &d2) || d1 != d2;
  }
  EXPECT_EQ(differ, 0);

  // Another key (other mesh, options or seed) finds nothing.
  EXPECT_FALSE(ModelCloud::Load(path, key + 1, chair.id));
  SamplingOptions denser = so;
  denser.density_per_m2 *= 2;
  EXPECT_NE(ModelCloud::CacheKey(chair, denser, 5), key);
  EXPECT_NE(ModelCloud::CacheKey(chair, so, 6), key);
  const CatalogModel other = Model("chair_b", "chair", Chair(0.56f, 0.50f, 0.41f, 0.62f, 0.05f).mesh);
  EXPECT_NE(ModelCloud::CacheKey(other, so, 5), key);
  EXPECT_FALSE(ModelCloud::Load(dir + "/missing.fhmc", key, chair.id));

  // Truncated at several places, and a corrupt point count: null, never a crash.
  const auto size = fs::file_size(path);
  std::string bytes(size, '\0');
  std::ifstream(path, std::ios::binary).read(bytes.data(), static_cast<std::streamsize>(size));
  for (size_t cut : {size_t(4), size_t(20), size / 2, size - 1}) {
    std::ofstream(dir + "/cut.fhmc", std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(cut));
    EXPECT_FALSE(ModelCloud::Load(dir + "/cut.fhmc", key, chair.id)) << "cut at " << cut;
  }
  std::string bad = bytes;
  const uint64_t huge = ~0ull;
  std::memcpy(bad.data() + 16, &huge, sizeof(huge));  // the point count follows magic and key
  std::ofstream(dir + "/bad.fhmc", std::ios::binary | std::ios::trunc).write(bad.data(), static_cast<std::streamsize>(bad.size()));
  EXPECT_FALSE(ModelCloud::Load(dir + "/bad.fhmc", key, chair.id));
  bad = bytes;  // a NaN in the first point
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(bad.data() + 24, &nan, sizeof(nan));
  std::ofstream(dir + "/nan.fhmc", std::ios::binary | std::ios::trunc).write(bad.data(), static_cast<std::streamsize>(bad.size()));
  EXPECT_FALSE(ModelCloud::Load(dir + "/nan.fhmc", key, chair.id));
  fs::remove_all(dir);
}

}  // namespace

// RadiusGrid (CoveredExact's look-up) answers as the kd-tree does for every query: points of a
// plane, a cluster of copies of one point and scattered points; queries jittered around them at
// about the radius (both sides of it), exactly at it along an axis (the strict comparison), far
// away, and on cell borders. Sets whose box needs too many cells take the kd-tree itself.
TEST(RadiusGrid, SameAnswersAsTheKdTree) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Points pts;
  for (int i = 0; i < 3000; ++i) pts.emplace_back(u(rng), u(rng), 0.25f);             // a plane
  for (int i = 0; i < 500; ++i) pts.emplace_back(0.3f, -0.2f, 0.7f);                   // copies
  for (int i = 0; i < 1000; ++i) pts.emplace_back(u(rng), u(rng), 0.5f + 0.5f * u(rng));  // scatter
  for (const float r : {0.005f, 0.02f, 0.1f}) {
    const PointIndex kd(&pts);
    const RadiusGrid grid(&pts, r);
    int hits = 0, misses = 0;
    for (int i = 0; i < 40000; ++i) {
      const Eigen::Vector3f& p = pts[size_t(i) % pts.size()];
      Eigen::Vector3f q;
      switch (i % 4) {
        case 0: q = p + Eigen::Vector3f(u(rng), u(rng), u(rng)) * (1.5f * r); break;
        case 1: q = p + Eigen::Vector3f::Unit(i % 3) * (u(rng) > 0 ? r : -r); break;  // exactly r away
        case 2: q = Eigen::Vector3f(u(rng), u(rng), u(rng)) * 3.f; break;             // also outside the box
        default: q = Eigen::Vector3f(std::round(p.x() / r) * r * 1.01f, p.y(), p.z());  // near cell borders
      }
      const bool want = kd.AnyWithin(q, r);
      ASSERT_EQ(grid.AnyWithin(q), want) << "r " << r << " query " << q.transpose();
      (want ? hits : misses)++;
    }
    EXPECT_GT(hits, 5000);  // both answers are exercised
    EXPECT_GT(misses, 5000);
  }
  const Points none;
  EXPECT_FALSE(RadiusGrid(&none, 0.02f).AnyWithin(Eigen::Vector3f::Zero()));
  const Points wide{{0.f, 0.f, 0.f}, {1000.f, 1000.f, 1000.f}};  // 5e4^3 cells: the kd-tree answers
  const RadiusGrid sparse(&wide, 0.02f);
  EXPECT_TRUE(sparse.AnyWithin({1000.f, 1000.f, 1000.01f}));
  EXPECT_FALSE(sparse.AnyWithin({500.f, 500.f, 500.f}));
}

// The occupancy grid of a sensor origin far outside the scan (1.3 km, or 5 km past OctoMap's
// range) spans the scan, not the way to the origin: its rays start where they enter the
// points' box grown by 2 m. The free space in front of the wall the far sensor sees is there;
// an origin inside the room gives whole rays.
TEST(Occupancy, FarSensorOriginCostsWhatTheScanSpans) {
  Points room;  // a floor of 4 x 4 m and a wall at x = 4
  for (int i = 0; i <= 80; ++i)
    for (int j = 0; j <= 80; ++j) {
      room.emplace_back(0.05f * float(i), 0.05f * float(j), 0.f);
      room.emplace_back(4.f, 0.05f * float(i), 0.05f * float(j) * 0.6f);
    }
  OccupancyOptions opt;
  for (const Eigen::Vector3f& origin : {Eigen::Vector3f(1300.f, 2.f, 1.5f), Eigen::Vector3f(2.f, -5000.f, 1.5f),
                                       Eigen::Vector3f(2.f, 2.f, 1.5f)}) {
    OccupancyStats st;
    const auto tree = BuildOccupancy(room, origin, opt, &st);
    double x0, y0, z0, x1, y1, z1;
    tree->getMetricMin(x0, y0, z0);
    tree->getMetricMax(x1, y1, z1);
    EXPECT_GE(x0, -2.1) << origin.transpose();
    EXPECT_LE(x1, 6.1) << origin.transpose();
    EXPECT_GE(y0, -2.1) << origin.transpose();
    EXPECT_LE(y1, 6.1) << origin.transpose();
    EXPECT_GT(st.free, 0u) << origin.transpose();
  }
  // Seen from x = 1300 m, the space just in front of the wall (x = 4.5) is free, behind it
  // unknown; seen from inside, the other way round.
  const auto far = BuildOccupancy(room, Eigen::Vector3f(1300.f, 2.f, 1.5f), opt);
  const octomap::OcTreeNode* front = far->search(4.5, 2.0, 1.0);
  ASSERT_NE(front, nullptr);
  EXPECT_FALSE(far->isNodeOccupied(front));
  EXPECT_EQ(far->search(3.5, 2.0, 1.0), nullptr);
  const auto inside = BuildOccupancy(room, Eigen::Vector3f(2.f, 2.f, 1.5f), opt);
  ASSERT_NE(inside->search(3.5, 2.0, 1.0), nullptr);
  EXPECT_EQ(inside->search(4.5, 2.0, 1.0), nullptr);
}
