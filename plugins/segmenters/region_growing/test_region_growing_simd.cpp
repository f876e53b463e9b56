// segmenters.region_growing's vector paths against the scalar ones, bit for bit: paired 6x6
// solves, AVX2 neighbourhoods and paired fits.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <random>
#include <set>

#include "simd/left_pack.hpp"
#include "test_region_growing_scenes.hpp"

namespace {

using namespace rg_test;

// The normals solve their 6x6 systems two at a time: each lane must give the single solve's
// coefficients bit for bit, and its answer, also when the other lane's system is degenerate.
TEST(RegionGrowing, PairedSolvesAreTheSingleSolves) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // A = B^T B (+ a ridge), with B 8 x 6; rank-deficient when some columns of B repeat.
  auto system = [&](int kind, double A[6][6], double y[6]) {
    double B[8][6];
    for (auto& row : B)
      for (double& v : row) v = u(rng);
    if (kind == 1)
      for (auto& row : B) row[5] = row[4];  // singular
    if (kind == 2)
      for (auto& row : B) row[3] = 1e-7 * row[3];  // badly scaled
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) {
        double s = 0;
        for (const auto& row : B) s += row[i] * row[j];
        A[i][j] = i <= j ? s : 0.0;  // upper triangle only
      }
    for (int i = 0; i < 6; ++i) y[i] = u(rng);
  };
  int solved = 0, refused = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    double A0[6][6], A1[6][6], y0[6], y1[6];
    system(trial % 3, A0, y0);
    system((trial / 3) % 3, A1, y1);
    double s0[6], s1[6], p0[6], p1[6];
    const bool ok0 = rg::detail::SolveSpd6(A0, y0, s0), ok1 = rg::detail::SolveSpd6(A1, y1, s1);
    bool ok[2];
    rg::detail::SolveSpd6Pair(A0, y0, A1, y1, p0, p1, ok);
    ASSERT_EQ(ok[0], ok0) << trial;
    ASSERT_EQ(ok[1], ok1) << trial;
    if (ok0) {
      ASSERT_EQ(std::memcmp(s0, p0, sizeof s0), 0) << trial;
    }
    if (ok1) {
      ASSERT_EQ(std::memcmp(s1, p1, sizeof s1), 0) << trial;
    }
    solved += ok0 + ok1;
    refused += !ok0 + !ok1;
  }
  EXPECT_GT(solved, 2000);
  EXPECT_GT(refused, 1000);  // the singular systems
}

// The neighbourhoods are gathered 8 candidates at a time where the CPU has AVX2: the normals,
// the curvatures and the parts must be those of the scalar loops bit for bit (sparse noisy
// surfaces, so the growth runs from the neighbour lists).
TEST(RegionGrowing, AvxNeighbourhoodsGiveTheScalarResults) {
  // Without AVX2 both runs take the scalar loops (the dispatch is tested in test_simd).
  std::mt19937_64 rng(11);
  Scan scan;
  scan.points = Sphere({0, 0, 0.4f}, 0.3f, 3000.f, rng);
  AddQuad(scan.points, nullptr, 0, Eigen::Vector3f(-1, -1, 0), Eigen::Vector3f(2, 0, 0), Eigen::Vector3f(0, 2, 0), 1500.f,
          rng);
  std::normal_distribution<float> g(0.f, 0.004f);
  for (auto& p : scan.points) p += Eigen::Vector3f(g(rng), g(rng), g(rng));
  rg::RegionGrowingOptions o;
  o.normal_radius_m = 0.08;
  o.distance_m = 0.05;
  rg::SegmentTimings ta, tb;
  furnihost::simd::SetAvx2(false);
  const auto a = rg::Segment(scan, o, &ta);
  furnihost::simd::SetAvx2(true);
  const auto b = rg::Segment(scan, o, &tb);
  EXPECT_STREQ(ta.growth, "lists");
  EXPECT_STREQ(tb.growth, "lists");
  ASSERT_EQ(a.normals.size(), b.normals.size());
  EXPECT_EQ(std::memcmp(a.normals.data(), b.normals.data(), sizeof(a.normals[0]) * a.normals.size()), 0);
  EXPECT_EQ(std::memcmp(a.curvature.data(), b.curvature.data(), sizeof(float) * a.curvature.size()), 0);
  ASSERT_EQ(a.parts.size(), b.parts.size());
  ASSERT_GT(a.parts.size(), 2u);
  for (size_t p = 0; p < a.parts.size(); ++p) EXPECT_EQ(a.parts[p].indices, b.parts[p].indices);
}

// The exact normals fit two points' neighbourhoods side by side in AVX2 vectors (FitSystemPair):
// each point's normal and curvature must be the single fit's bit for bit, whatever the pair:
// neighbourhoods of different sizes (a sphere's, a plane's, a sparse clump's), too few points
// for the height function (fewer than min_fit_points) or for a normal (fewer than 3), and
// neighbourhoods without 2-D extent (a line). Without AVX2 both runs take the 4-lane loops.
TEST(RegionGrowing, PairedFitsAreTheSingleFits) {
  std::mt19937_64 rng(23);
  Points pts = Sphere({0, 0, 0.5f}, 0.25f, 4000.f, rng);
  AddQuad(pts, nullptr, 0, Eigen::Vector3f(-1, -1, 0), Eigen::Vector3f(2, 0, 0), Eigen::Vector3f(0, 1.3f, 0), 900.f, rng);
  std::normal_distribution<float> g(0.f, 0.003f);
  for (auto& p : pts) p += Eigen::Vector3f(g(rng), g(rng), g(rng));
  for (int i = 0; i < 40; ++i) pts.emplace_back(2.f + 0.01f * float(i), 2.f, 0.3f);  // a line
  std::uniform_real_distribution<float> far(3.f, 9.f);
  for (int i = 0; i < 30; ++i) pts.emplace_back(far(rng), far(rng), far(rng));  // isolated points
  for (int c = 0; c < 12; ++c) {  // clumps of 4: fewer than min_fit_points
    const Eigen::Vector3f at(-3.f - float(c), -3.f, 1.f);
    for (int i = 0; i < 4; ++i) pts.push_back(at + Eigen::Vector3f(0.01f * float(i), 0.013f * float(i % 2), 0.f));
  }
  rg::RegionGrowingOptions o;
  o.normal_radius_m = 0.06;
  furnihost::simd::SetAvx2(false);
  const auto a = rg::EstimateNormals(pts, std::nullopt, o);
  furnihost::simd::SetAvx2(true);
  const auto b = rg::EstimateNormals(pts, std::nullopt, o);
  ASSERT_EQ(a.normals.size(), pts.size());
  ASSERT_EQ(b.normals.size(), pts.size());
  EXPECT_EQ(std::memcmp(a.normals.data(), b.normals.data(), sizeof(a.normals[0]) * a.normals.size()), 0);
  EXPECT_EQ(std::memcmp(a.curvature.data(), b.curvature.data(), sizeof(float) * a.curvature.size()), 0);
  // Every kind of neighbourhood occurred: NaN normals (isolated points), and finite ones.
  size_t nan = 0;
  for (const auto& n : a.normals) nan += !n.allFinite();
  EXPECT_GE(nan, 30u);
  EXPECT_LT(nan, pts.size() / 10);
}

}  // namespace
