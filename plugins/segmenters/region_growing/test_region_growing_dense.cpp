// segmenters.region_growing on dense and repeated points: copies of one point, the density-
// adaptive normals (voxel centroids) and the growth by sub-cells and by neighbour lists give
// what the exact, point-by-point paths give.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <random>
#include <set>

#include "test_region_growing_scenes.hpp"

namespace {

using namespace rg_test;

// Copies of one point share a neighbourhood, so one fit serves them all: a million copies
// (a driver's (0, 0, 0) for every invalid return) are one part, in linear time (with a fit
// per copy over every copy, 10^12 steps, this test would not end within ctest's timeout).
TEST(RegionGrowing, AMillionCopiesOfOnePointAreOnePart) {
  Scan scan;
  scan.points.assign(1000000, Eigen::Vector3f(0.f, 0.f, 0.f));
  const auto seg = RunSeg(scan);
  ASSERT_EQ(seg.parts.size(), 1u);
  EXPECT_EQ(seg.parts[0].indices.size(), scan.points.size());
  ASSERT_EQ(seg.normals.size(), scan.points.size());
  EXPECT_EQ(seg.normals.front(), seg.normals.back());
}

// A sphere whose every point is stored 40 times, the copies scattered through the cloud: each
// copy gets the normal and curvature the single point gets (the fit's weights scale alike; the
// sphere is dense enough that every neighbourhood has min_fit_points without its copies).
TEST(RegionGrowing, CopiesGetTheNormalOfTheirPoint) {
  std::mt19937_64 rng(4);
  Scan once;
  once.points = Sphere(Eigen::Vector3f(0.f, 0.f, 1.f), 0.3f, 10000.f, rng);
  once.origin = Eigen::Vector3f(0.f, 0.f, 1.f);
  Scan copies = once;
  copies.points.clear();
  for (int c = 0; c < 40; ++c) copies.points.insert(copies.points.end(), once.points.begin(), once.points.end());
  // Exact balls: 40 copies make the neighbourhoods 40 times denser, which would switch on the
  // voxel centroids (DenseNormals* below); here the copies must weigh alike in the exact fit.
  const nlohmann::json exact = {{"max_normal_points", 0}};
  const auto a = RunSeg(once, exact), b = RunSeg(copies, exact);
  ASSERT_EQ(b.normals.size(), copies.points.size());
  const size_t n = once.points.size();
  for (size_t i = 0; i < copies.points.size(); ++i) {
    ASSERT_TRUE(b.normals[i].allFinite()) << i;
    EXPECT_LT(AngleDeg(b.normals[i], a.normals[i % n]), 0.05) << i;
    EXPECT_NEAR(b.curvature[i], a.curvature[i % n], 1e-4f) << i;
  }
  // With the centroids (the default) every copy still gets exactly its point's normal, and
  // it stays close to the exact one.
  const auto c = RunSeg(copies);
  for (size_t i = 0; i < copies.points.size(); ++i) {
    ASSERT_TRUE(c.normals[i].allFinite()) << i;
    EXPECT_EQ(c.normals[i], c.normals[i % n]) << i;
    EXPECT_EQ(c.curvature[i], c.curvature[i % n]) << i;
    EXPECT_LT(AngleDeg(c.normals[i], a.normals[i % n]), 1.0) << i;
  }
}

// Density-adaptive normals (max_normal_points): at normal density nothing changes, bit for
// bit; at 1-2 mm spacing the voxel centroids keep the normals accurate and the parts the same.
TEST(RegionGrowing, DenseNormalsOffAtNormalDensity) {
  std::mt19937_64 rng(8);
  Scan scan;
  scan.points = Sphere({0.1f, 0.2f, 1.f}, 0.3f, 10000.f, rng);  // ~1 cm spacing: ~28 in a 3 cm ball
  AddQuad(scan.points, nullptr, 0, Eigen::Vector3f(-1, -1, 0.5f), Eigen::Vector3f(2, 0, 0),
          Eigen::Vector3f(0, 2, 0), 15000.f, rng);  // ~42 in a 3 cm ball, ~130 in 3x3x3 cells
  scan.origin = Eigen::Vector3f(0, 0, 2);
  const auto a = RunSeg(scan), b = RunSeg(scan, {{"max_normal_points", 0}});
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t p = 0; p < a.parts.size(); ++p) EXPECT_EQ(a.parts[p].indices, b.parts[p].indices);
  for (size_t i = 0; i < scan.points.size(); ++i) {
    EXPECT_EQ(std::memcmp(a.normals[i].data(), b.normals[i].data(), sizeof(float) * 3), 0) << i;
    EXPECT_EQ(std::memcmp(&a.curvature[i], &b.curvature[i], sizeof(float)), 0) << i;
  }
}

TEST(RegionGrowing, DenseNormalsAccurateOnASphereAndAPlane) {
  std::mt19937_64 rng(9);
  const Eigen::Vector3f c(0.3f, -0.2f, 1.0f);
  Scan scan;
  scan.points = Sphere(c, 0.2f, 400000.f, rng);  // ~1.6 mm spacing: ~1100 points in a 3 cm ball
  scan.origin = c;
  const size_t on_sphere = scan.points.size();
  const Eigen::Vector3f n_true = Eigen::Vector3f(0.3f, -0.2f, 1.f).normalized();
  const Eigen::Vector3f a = n_true.unitOrthogonal(), b = n_true.cross(a);
  const Eigen::Vector3f o(1, 2, 0.5f);
  std::normal_distribution<float> g(0.f, 0.001f);
  AddQuad(scan.points, nullptr, 0, o, 0.4f * a, 0.4f * b, 400000.f, rng);  // 1 mm noise
  for (size_t i = on_sphere; i < scan.points.size(); ++i) scan.points[i] += g(rng) * n_true;
  const auto seg = RunSeg(scan);
  double sum_s = 0, worst_s = 0, sum_p = 0, worst_p = 0;
  int inner = 0;
  for (size_t i = 0; i < scan.points.size(); ++i) {
    ASSERT_TRUE(seg.normals[i].allFinite()) << i;
    if (i < on_sphere) {
      const double e = AngleDeg(seg.normals[i], (c - scan.points[i]).normalized());
      sum_s += e, worst_s = std::max(worst_s, e);
    } else {
      const Eigen::Vector3f d = scan.points[i] - o;
      const float border = std::min({d.dot(a), d.dot(b), 0.4f - d.dot(a), 0.4f - d.dot(b)});
      if (border <= 0.03f) continue;
      const double e = std::min(AngleDeg(seg.normals[i], n_true), AngleDeg(seg.normals[i], -n_true));
      sum_p += e, worst_p = std::max(worst_p, e), ++inner;
    }
  }
  EXPECT_LT(sum_s / double(on_sphere), 0.3);
  EXPECT_LT(worst_s, 1.5);
  EXPECT_LT(sum_p / inner, 0.5);
  EXPECT_LT(worst_p, 2.0);
}

// In dense cells the points of one voxel (edge normal_radius_m / 4) share one fit, centred on the
// voxel's centroid, and each takes the normal of the fitted surface at its own position. On a
// small sphere the true normal turns by up to ~3 deg across a voxel of 7.5 mm: one normal per
// voxel would be off by that much at the voxel's corners; the surface's normal is not.
TEST(RegionGrowing, DenseNormalsFollowTheSurfaceInsideAVoxel) {
  std::mt19937_64 rng(12);
  const Eigen::Vector3f c(-0.4f, 0.1f, 1.2f);
  Scan scan;
  scan.points = Sphere(c, 0.12f, 600000.f, rng);  // ~1.3 mm spacing: ~30 points per voxel
  scan.origin = c;
  const auto seg = RunSeg(scan);
  double worst = 0, sum = 0;
  for (size_t i = 0; i < scan.points.size(); ++i) {
    ASSERT_TRUE(seg.normals[i].allFinite()) << i;
    const double e = AngleDeg(seg.normals[i], (c - scan.points[i]).normalized());
    sum += e, worst = std::max(worst, e);
  }
  EXPECT_LT(sum / double(scan.points.size()), 0.2);
  EXPECT_LT(worst, 1.0);
}

// Equal quality at density: a furniture-like scene (floor, a chair's seat box, back and legs,
// a ball) at ~2.6 mm spacing with 1 mm noise, segmented with the density-adaptive normals (the
// default: voxel centroids, one fit per voxel) and with every point of every ball
// (max_normal_points 0). Every part holding >= 1 % of the points in the exact result (>= 80 %
// of the points are in such parts) has a part in the adaptive one that shares >= 85 % of their
// union, and the counts of such parts differ by at most one.
TEST(RegionGrowing, DenseSegmentationAgreesWithEveryPointSegmentation) {
  std::mt19937_64 rng(31);
  const float d = 150000.f;
  Scan scan;
  const Eigen::Vector3f X(1, 0, 0), Y(0, 1, 0), Z(0, 0, 1);
  AddQuad(scan.points, nullptr, 0, Eigen::Vector3f(-0.5f, -0.5f, 0.f), 1.2f * X, 1.2f * Y, d, rng);  // floor
  const Eigen::Vector3f s0(0.f, 0.f, 0.40f);                                                      // seat box
  AddQuad(scan.points, nullptr, 0, s0 + 0.05f * Z, 0.45f * X, 0.45f * Y, d, rng);
  AddQuad(scan.points, nullptr, 0, s0, 0.45f * X, 0.05f * Z, d, rng);
  AddQuad(scan.points, nullptr, 0, s0 + 0.45f * Y, 0.45f * X, 0.05f * Z, d, rng);
  AddQuad(scan.points, nullptr, 0, s0 + 0.45f * X, 0.45f * Y, 0.05f * Z, d, rng);
  AddQuad(scan.points, nullptr, 0, s0 + 0.45f * Y + 0.05f * Z, 0.45f * X, 0.45f * Z, d, rng);  // back
  for (const Eigen::Vector3f& corner : {Eigen::Vector3f(0.02f, 0.02f, 0.f), Eigen::Vector3f(0.40f, 0.02f, 0.f),
                                       Eigen::Vector3f(0.02f, 0.40f, 0.f), Eigen::Vector3f(0.40f, 0.40f, 0.f)}) {
    AddQuad(scan.points, nullptr, 0, corner, 0.03f * X, 0.40f * Z, d, rng);  // legs: two faces each
    AddQuad(scan.points, nullptr, 0, corner, 0.03f * Y, 0.40f * Z, d, rng);
  }
  const Points ball = Sphere(Eigen::Vector3f(-0.25f, 0.45f, 0.2f), 0.12f, d, rng);
  for (const auto& p : ball)
    if (p.z() > 0.02f) scan.points.push_back(p);
  std::normal_distribution<float> noise(0.f, 0.001f);
  for (auto& p : scan.points) p += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
  scan.origin = Eigen::Vector3f(1.5f, -1.0f, 1.5f);
  const nlohmann::json paper_radius = {{"normal_radius_m", 0.03}};
  const auto exact = RunSeg(scan, {{"normal_radius_m", 0.03}, {"max_normal_points", 0}});
  const auto fast = RunSeg(scan, paper_radius);
  const size_t n = scan.points.size(), big = n / 100;
  std::vector<int> label(n, -1);
  for (size_t k = 0; k < fast.parts.size(); ++k)
    for (int i : fast.parts[k].indices) label[size_t(i)] = int(k);
  int big_exact = 0, big_fast = 0;
  size_t agreeing = 0, in_big = 0;
  double worst = 1.0;
  for (const auto& part : fast.parts) big_fast += part.indices.size() >= big;
  for (const auto& part : exact.parts) {
    if (part.indices.size() < big) continue;
    ++big_exact;
    in_big += part.indices.size();
    std::map<int, size_t> shared;
    for (int i : part.indices) ++shared[label[size_t(i)]];
    const auto best = std::max_element(shared.begin(), shared.end(), [](auto& a, auto& b) { return a.second < b.second; });
    const size_t other = best->first >= 0 ? fast.parts[size_t(best->first)].indices.size() : 0;
    const double iou = double(best->second) / double(part.indices.size() + other - best->second);
    worst = std::min(worst, iou);
    if (iou >= 0.85) agreeing += part.indices.size();
  }
  std::printf("%zu points; parts of >= 1 %%: %d exact, %d adaptive, holding %.3f of the points; worst IoU %.3f\n", n,
              big_exact, big_fast, double(in_big) / double(n), worst);
  EXPECT_GE(big_exact, 4);
  EXPECT_LE(std::abs(big_exact - big_fast), 1);
  EXPECT_GE(worst, 0.85);
  EXPECT_GE(double(in_big), 0.8 * double(n));
  EXPECT_EQ(agreeing, in_big);
}

TEST(RegionGrowing, DenseNormalsGiveTheBoxTheSamePartsAsSparse) {
  auto box = [](float density) {
    std::mt19937_64 rng(3);
    Scan scan;
    std::vector<int> face;
    const Eigen::Vector3f lo(0.2f, 0.1f, 0.3f);
    const Eigen::Vector3f X(0.6f, 0, 0), Y(0, 0.4f, 0), Z(0, 0, 0.5f);  // BoxSurfaceGivesSixPlanarParts'
    AddQuad(scan.points, &face, 0, lo, X, Y, density, rng);
    AddQuad(scan.points, &face, 1, lo + Z, X, Y, density, rng);
    AddQuad(scan.points, &face, 2, lo, X, Z, density, rng);
    AddQuad(scan.points, &face, 3, lo + Y, X, Z, density, rng);
    AddQuad(scan.points, &face, 4, lo, Y, Z, density, rng);
    AddQuad(scan.points, &face, 5, lo + X, Y, Z, density, rng);
    return std::make_pair(scan, face);
  };
  // Faces found: parts holding >= 90 % of a face with >= 98 % purity.
  auto faces = [](const Segmentation& seg, const std::vector<int>& face) {
    std::vector<int> size(6, 0);
    for (int f : face) ++size[f];
    std::set<int> found;
    for (const auto& part : seg.parts) {
      std::map<int, int> hist;
      for (int i : part.indices) ++hist[face[i]];
      const auto best = std::max_element(hist.begin(), hist.end(), [](auto& l, auto& r) { return l.second < r.second; });
      if (best->second >= 0.9 * size[best->first] && best->second >= 0.98 * double(part.indices.size()))
        found.insert(best->first);
    }
    return found.size();
  };
  const auto [sparse, sparse_face] = box(10000.f);
  const auto [dense, dense_face] = box(250000.f);  // 2 mm spacing: ~700 points in a 3 cm ball
  const auto a = RunSeg(sparse), b = RunSeg(dense);
  EXPECT_EQ(faces(a, sparse_face), 6u);
  EXPECT_EQ(faces(b, dense_face), 6u);
  // Big parts: the six faces in both (the edge strips are small or regrouped).
  auto big = [](const Segmentation& seg, size_t n) {
    return std::count_if(seg.parts.begin(), seg.parts.end(), [&](const auto& p) { return p.indices.size() > n / 20; });
  };
  EXPECT_EQ(big(a, sparse.points.size()), 6);
  EXPECT_EQ(big(b, dense.points.size()), 6);
}

// A dense scan (3 mm spacing: ~60 points per 2.5 cm sub-cell) grows sub-cell by sub-cell: the
// same parts, point for point, and the same centroids as growing point by point.
TEST(RegionGrowing, GrowthBySubCellsGivesThePartsOfGrowthByPoints) {
  const Scan scan = FacesAndBall(5, Eigen::Vector3f(0.2f, 0.1f, 0.3f), Eigen::Vector3f(0.6f, 0, 0),
                                 Eigen::Vector3f(0, 0.4f, 0), Eigen::Vector3f(0, 0, 0.5f), 4,
                                 Eigen::Vector3f(0.5f, 0.3f, 1.2f), 0.15f, 100000.f, 0.002f);
  const nlohmann::json base = {{"normal_radius_m", 0.03}, {"angle_deg", 20}};
  nlohmann::json points = base;
  points["growth_by_sub_cells"] = false;
  const auto a = RunSeg(scan, base), b = RunSeg(scan, points);
  ASSERT_GT(a.parts.size(), 6u);
  ExpectSameParts(a, b);
}

// A sparse scan (2 cm spacing, 5 cm distance: about one point per sub-cell) grows from
// per-point neighbour lists: the same parts, point for point, as scanning the cells
// (max_list_candidates 0). A clump of 20 000 copies of one point would make the lists
// quadratic: that scan grows over the cells (point by point, without sub-cells, which it
// would otherwise take for its density).
TEST(RegionGrowing, NeighbourListsGiveThePartsOfTheCellScan) {
  const Scan scan = FacesAndBall(9, Eigen::Vector3f(0.2f, 0.1f, 0.3f), Eigen::Vector3f(1.2f, 0, 0),
                                 Eigen::Vector3f(0, 0.8f, 0), Eigen::Vector3f(0, 0, 0.7f), 3,
                                 Eigen::Vector3f(0.8f, 0.5f, 1.5f), 0.3f, 2500.f, 0.004f);
  rg::RegionGrowingOptions listed, cells;
  listed.normal_radius_m = cells.normal_radius_m = 0.08;
  listed.angle_deg = cells.angle_deg = 20;
  cells.max_list_candidates = 0;
  auto compare = [&](const Scan& s, const char* expected_growth) {
    rg::SegmentTimings ta, tb;
    const auto a = rg::Segment(s, listed, &ta), b = rg::Segment(s, cells, &tb);
    EXPECT_STREQ(ta.growth, expected_growth);
    EXPECT_STREQ(tb.growth, "cells");
    ASSERT_GT(a.parts.size(), 4u);
    ExpectSameParts(a, b);
  };
  compare(scan, "lists");
  listed.growth_by_sub_cells = cells.growth_by_sub_cells = false;
  Scan clump = scan;
  clump.points.insert(clump.points.end(), 20000, Eigen::Vector3f(0.5f, 0.5f, 0.3f));
  compare(clump, "cells");
}

}  // namespace
