// SDK geometry: ConvexHull2D drops the points well inside the outline before its sort
// (Akl-Toussaint); its hulls must equal those of the plain monotone chain over every point,
// bit for bit, including on grids and edges full of collinear points.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <thread>

#include "furnihost/geometry.hpp"
#include "furnihost/host/ground_estimation.hpp"

namespace {

using V2 = Eigen::Vector2f;

// The plain algorithm, as ConvexHull2D was before the filter: the reference.
std::vector<V2> PlainHull(std::vector<V2> p) {
  auto cross = [](const V2& o, const V2& a, const V2& b) {
    return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
  };
  std::sort(p.begin(), p.end(), [](const V2& a, const V2& b) { return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y(); });
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() < 3) return p;
  std::vector<V2> h(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}

TEST(Geometry, ConvexHullEqualsThePlainMonotoneChain) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  int cases = 0;
  for (int n : {3, 10, 63, 64, 65, 200, 5000}) {
    for (int kind = 0; kind < 6; ++kind) {
      for (int rep = 0; rep < 8; ++rep, ++cases) {
        std::vector<V2> p;
        const float yaw = u(rng) * 3.14159f, c = std::cos(yaw), s = std::sin(yaw);
        const V2 shift(3.f * u(rng) + 4.f, 3.f * u(rng) - 2.f);  // away from the origin, as scans are
        for (int i = 0; i < n; ++i) {
          V2 q;
          switch (kind) {
            case 0: q = V2(u(rng), u(rng)); break;                                      // square
            case 1: q = V2(u(rng), 0.02f * u(rng)); break;                              // thin strip
            case 2: q = V2(std::round(8 * u(rng)) / 8, std::round(8 * u(rng)) / 8); break;  // grid: collinear
            case 3: {                                                                    // rectangle outline
              const float t = u(rng);
              q = (i % 4 == 0) ? V2(t, -0.5f) : (i % 4 == 1) ? V2(t, 0.5f) : (i % 4 == 2) ? V2(-1.f, t / 2) : V2(1.f, t / 2);
              break;
            }
            case 4: q = V2(0.3f * std::round(u(rng)), 0.3f * std::round(u(rng))); break;  // heavy duplicates
            default: {                                                                   // disc
              const float a = 3.14159f * u(rng), r = std::sqrt(0.5f * (u(rng) + 1.f));
              q = V2(r * std::cos(a), r * std::sin(a));
            }
          }
          p.emplace_back(c * q.x() - s * q.y() + shift.x(), s * q.x() + c * q.y() + shift.y());
        }
        const std::vector<V2> want = PlainHull(p), got = furnihost::ConvexHull2D(p);
        ASSERT_EQ(got.size(), want.size()) << "n " << n << " kind " << kind << " rep " << rep;
        for (size_t i = 0; i < got.size(); ++i)
          ASSERT_TRUE(got[i] == want[i]) << "n " << n << " kind " << kind << " rep " << rep << " vertex " << i;
      }
    }
  }
  EXPECT_EQ(cases, 7 * 6 * 8);
}


// A RangeFor as a thread pool would run it: small chunks, on two threads, in no fixed order.
void TwoThreadsInChunks(size_t begin, size_t end, const std::function<void(size_t, size_t)>& body) {
  constexpr size_t kChunk = 37;
  std::thread other([&] {
    for (size_t b = begin + kChunk; b < end; b += 2 * kChunk) body(b, std::min(end, b + kChunk));
  });
  for (size_t b = begin; b < end; b += 2 * kChunk) body(b, std::min(end, b + kChunk));
  other.join();
}

// The voxel normals and the ground (a warped floor under furniture and walls) are the same bit for
// bit whether their per-voxel fits run in one pass or spread over threads.
TEST(Geometry, VoxelNormalsAndGroundDoNotDependOnThePartition) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  furnihost::Points cloud;
  for (int i = 0; i < 40000; ++i) {  // floor 6 x 5 m, 3 cm bend
    const float x = 6 * u(rng), y = 5 * u(rng);
    cloud.emplace_back(x, y, 0.03f * std::sin(x) + 0.002f * u(rng));
  }
  for (int i = 0; i < 10000; ++i) cloud.emplace_back(6 * u(rng), 0.f, 2.5f * u(rng));           // wall
  for (int i = 0; i < 5000; ++i) cloud.emplace_back(2 + u(rng), 2 + 0.6f * u(rng), 0.75f);       // table top
  const furnihost::VoxelNormals a = furnihost::EstimateVoxelNormals(cloud, 0.05f);
  const furnihost::VoxelNormals b = furnihost::EstimateVoxelNormals(cloud, 0.05f, TwoThreadsInChunks);
  ASSERT_EQ(a.normals.size(), b.normals.size());
  ASSERT_GT(a.normals.size(), 1000u);
  EXPECT_TRUE(a.normals == b.normals);
  EXPECT_TRUE(a.centroids == b.centroids);
  EXPECT_EQ(a.flat, b.flat);
  EXPECT_EQ(a.voxel_of, b.voxel_of);
  furnihost::GroundOptions o;
  o.kind = "height_map";
  const furnihost::GroundModel g1 = furnihost::EstimateGround(cloud, o);
  const furnihost::GroundModel g2 = furnihost::EstimateGround(cloud, o, TwoThreadsInChunks);
  ASSERT_EQ(g1.kind, furnihost::GroundKind::HeightMap);
  EXPECT_EQ(g1.kind, g2.kind);
  EXPECT_EQ(g1.heights, g2.heights);
  EXPECT_EQ(g1.observed, g2.observed);
  EXPECT_EQ(g1.plane.a, g2.plane.a);
  EXPECT_EQ(g1.plane.b, g2.plane.b);
  EXPECT_EQ(g1.plane.c, g2.plane.c);
  EXPECT_GT(g1.heights.size(), 100u);
}

}  // namespace

// Exact copies only (-0 equal to +0), first appearance kept in order, each point mapped to its
// position; a flood of one position stays one position.
TEST(Geometry, GroupEqualPointsKeepsFirstAppearances) {
  const furnihost::Points p = {{1, 2, 3}, {0, 0, 0}, {1, 2, 3}, {-0.f, 0, -0.f}, {1, 2, 3.0000005f}, {0, 0, 0}};
  std::vector<uint32_t> of;
  const furnihost::Points d = furnihost::GroupEqualPoints(p, &of);
  ASSERT_EQ(d.size(), 3u);
  EXPECT_EQ(d[0], p[0]);
  EXPECT_EQ(d[1], p[1]);
  EXPECT_EQ(d[2], p[4]);
  EXPECT_EQ(of, (std::vector<uint32_t>{0, 1, 0, 1, 2, 1}));
  const furnihost::Points flood(100000, Eigen::Vector3f::Zero());
  EXPECT_EQ(furnihost::GroupEqualPoints(flood).size(), 1u);
  EXPECT_TRUE(furnihost::GroupEqualPoints(furnihost::Points()).empty());
}

// JitterPoints: Gaussian noise of the given spread on each coordinate, uncorrelated, the same
// for a seed, other for another seed; NaN and a driver's (0, 0, 0) left as they are.
TEST(JitterPoints, GaussianPerCoordinateDeterministicPerSeed) {
  const size_t n = 20000;
  furnihost::Points pts(n, Eigen::Vector3f(1.f, -2.f, 3.f));
  pts[5] = Eigen::Vector3f::Zero();
  pts[6] = Eigen::Vector3f(NAN, 0.f, 0.f);
  const float sigma = 0.01f;
  furnihost::Points a = pts, b = pts, c = pts, d = pts;
  furnihost::JitterPoints(a, sigma, 42);
  furnihost::JitterPoints(b, sigma, 42);
  furnihost::JitterPoints(c, sigma, 43);
  furnihost::JitterPoints(d, 0.f, 42);
  EXPECT_TRUE(a[5].isZero());
  EXPECT_TRUE(std::isnan(a[6].x()));
  EXPECT_EQ(a[6].y(), 0.f);
  size_t same_b = 0, same_c = 0, same_d = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  size_t m = 0;
  for (size_t i = 0; i < n; ++i) {
    if (i == 5 || i == 6) continue;
    same_b += a[i] == b[i];
    same_c += a[i] == c[i];
    same_d += d[i] == pts[i];
    const Eigen::Vector3d e = (a[i] - pts[i]).cast<double>();
    mean += e;
    cov += e * e.transpose();
    ++m;
  }
  EXPECT_EQ(same_b, m);  // the same seed: the same noise
  EXPECT_LT(same_c, 10u);  // another seed: other noise
  EXPECT_EQ(same_d, m);  // sigma 0: untouched
  mean /= double(m);
  cov /= double(m);
  for (int k = 0; k < 3; ++k) {
    EXPECT_LT(std::abs(mean[k]), 4 * sigma / std::sqrt(double(m))) << k;
    EXPECT_NEAR(std::sqrt(cov(k, k)), sigma, 0.03 * sigma) << k;
    for (int l = 0; l < k; ++l) EXPECT_LT(std::abs(cov(k, l)) / (sigma * sigma), 0.05) << k << l;
  }
}

// With `axes`, the noise is drawn along them: a cloud turned by R and jittered along R's columns
// gets the turned noise, point by point (an ensemble's runs jitter a scan the same way in the
// scene whatever frame its file is in).
TEST(JitterPoints, NoiseAlongGivenAxesTurnsWithTheCloud) {
  const Eigen::Matrix3f r = (Eigen::AngleAxisf(0.6f, Eigen::Vector3f::UnitZ()) *
                             Eigen::AngleAxisf(float(M_PI / 2), Eigen::Vector3f::UnitX())).toRotationMatrix();
  furnihost::Points a, b;
  for (int i = 0; i < 500; ++i) {
    a.emplace_back(0.002f * float(i), 1.f, -0.5f);
    b.push_back(r * a.back());
  }
  const furnihost::Points a0 = a, b0 = b;
  furnihost::JitterPoints(a, 0.002f, 7);
  furnihost::JitterPoints(b, 0.002f, 7, r);
  double moved = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const Eigen::Vector3f na = a[i] - a0[i], nb = b[i] - b0[i];
    EXPECT_LT((r * na - nb).norm(), 1e-6f) << i;
    moved += na.norm();
  }
  EXPECT_GT(moved / double(a.size()), 0.002);  // it did move them (mean |n| = 1.6 sigma)
}
