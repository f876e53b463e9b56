// segmenters.region_growing through the registry: normal accuracy on analytic surfaces,
// the parts of a box and a cylinder, the small-part rule, scans in map coordinates, bad input.
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

TEST(RegionGrowing, SphereNormalsWithinOneDegree) {
  std::mt19937_64 rng(1);
  Scan scan;
  const Eigen::Vector3f c(0.3f, -0.2f, 1.0f);
  scan.points = Sphere(c, 0.5f, 10000.f, rng);  // ~1 cm spacing, ~28 neighbours in 3 cm
  scan.origin = c;                              // normals must point inwards
  const auto seg = RunSeg(scan);
  ASSERT_EQ(seg.normals.size(), scan.points.size());
  double sum = 0, worst = 0;
  for (size_t i = 0; i < scan.points.size(); ++i) {
    const Eigen::Vector3f truth = (c - scan.points[i]).normalized();
    ASSERT_TRUE(seg.normals[i].allFinite()) << "point " << i;
    EXPECT_NEAR(seg.normals[i].norm(), 1.f, 1e-4f);
    const double e = AngleDeg(seg.normals[i], truth);  // signed: orientation towards the origin
    sum += e;
    worst = std::max(worst, e);
  }
  // Tolerance: mean 0.2 deg, worst 1 deg (the order-2 fit is exact up to O((r/R)^3) on a sphere;
  // the rest is irregular random sampling).
  EXPECT_LT(sum / double(scan.points.size()), 0.2);
  EXPECT_LT(worst, 1.0);
  // Curvature lambda0/sum of a spherical cap of radius 3 cm on R = 0.5 m is tiny but > 0.
  for (float k : seg.curvature) EXPECT_LT(k, 0.01f);
}

TEST(RegionGrowing, PlaneNormalsExactWithoutNoiseAndWithinTwoDegreesWithNoise) {
  const Eigen::Vector3f n_true = Eigen::Vector3f(0.3f, -0.2f, 1.f).normalized();
  const Eigen::Vector3f a = n_true.unitOrthogonal(), b = n_true.cross(a);
  const Eigen::Vector3f o(1, 2, 0.5f);
  for (float sigma : {0.f, 0.001f}) {
    SCOPED_TRACE(sigma);
    std::mt19937_64 rng(2);
    std::normal_distribution<float> g(0.f, sigma > 0 ? sigma : 1.f);
    Scan scan;
    AddQuad(scan.points, nullptr, 0, o, a, b, 10000.f, rng);  // 1 m x 1 m, ~1 cm spacing
    if (sigma > 0)
      for (auto& p : scan.points) p += g(rng) * n_true;
    scan.origin = o + 0.5f * (a + b) + 2.f * n_true;
    const auto seg = RunSeg(scan);
    double sum = 0, worst = 0, sum_inner = 0, worst_inner = 0;
    int inner = 0;
    for (size_t i = 0; i < scan.points.size(); ++i) {
      const double e = AngleDeg(seg.normals[i], n_true);  // signed: towards the origin
      sum += e;
      worst = std::max(worst, e);
      const Eigen::Vector3f d = scan.points[i] - o;
      const float border = std::min({d.dot(a), d.dot(b), 1.f - d.dot(a), 1.f - d.dot(b)});
      if (border > 0.03f) {  // a full neighbourhood
        sum_inner += e;
        worst_inner = std::max(worst_inner, e);
        ++inner;
      }
    }
    const double mean = sum / double(scan.points.size());
    if (sigma == 0) {
      EXPECT_LT(worst, 0.05);  // float rounding only
    } else {
      // 1 mm noise over a 3 cm radius: ~1 deg on average. Near the border and above all in
      // the corners the quadratic extrapolates from a one-sided neighbourhood (up to ~25 deg
      // there), hence the bound on the inner points only for the worst case.
      EXPECT_LT(sum_inner / inner, 1.5);
      EXPECT_LT(worst_inner, 10.0);
      EXPECT_LT(mean, 2.0);
    }
    // A plane is one part.
    ASSERT_EQ(seg.parts.size(), 1u);
    EXPECT_EQ(seg.parts[0].indices.size(), scan.points.size());
  }
}

TEST(RegionGrowing, BoxSurfaceGivesSixPlanarParts) {
  std::mt19937_64 rng(3);
  Scan scan;
  std::vector<int> face;
  const Eigen::Vector3f lo(0.2f, 0.1f, 0.3f);
  const Eigen::Vector3f X(0.6f, 0, 0), Y(0, 0.4f, 0), Z(0, 0, 0.5f);
  const float d = 10000.f;
  AddQuad(scan.points, &face, 0, lo, X, Y, d, rng);
  AddQuad(scan.points, &face, 1, lo + Z, X, Y, d, rng);
  AddQuad(scan.points, &face, 2, lo, X, Z, d, rng);
  AddQuad(scan.points, &face, 3, lo + Y, X, Z, d, rng);
  AddQuad(scan.points, &face, 4, lo, Y, Z, d, rng);
  AddQuad(scan.points, &face, 5, lo + X, Y, Z, d, rng);
  std::vector<int> face_size(6, 0);
  for (int f : face) ++face_size[f];
  const auto seg = RunSeg(scan);

  // Each face must be one part holding >= 90 % of it with >= 98 % purity; anything else
  // is the thin strip along the 12 edges, where the 3 cm neighbourhoods straddle two faces
  // and normals bend by ~45 deg (more than alpha from both faces).
  std::set<int> faces_found;
  size_t in_face_parts = 0;
  for (const auto& part : seg.parts) {
    std::map<int, int> hist;
    for (int i : part.indices) ++hist[face[i]];
    const auto best = std::max_element(hist.begin(), hist.end(),
                                       [](auto& l, auto& r) { return l.second < r.second; });
    const double purity = double(best->second) / double(part.indices.size());
    const double coverage = double(best->second) / double(face_size[best->first]);
    if (coverage >= 0.9) {
      EXPECT_GE(purity, 0.98) << "face " << best->first;
      EXPECT_TRUE(faces_found.insert(best->first).second) << "face " << best->first << " found twice";
      in_face_parts += part.indices.size();
    } else {
      EXPECT_LT(coverage, 0.1) << "a face split into big pieces";
    }
  }
  EXPECT_EQ(faces_found.size(), 6u);
  EXPECT_GE(double(in_face_parts), 0.93 * double(scan.points.size()));
}

TEST(RegionGrowing, CylinderPartsSpanAtMostTwiceAlpha) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Scan scan;
  const float R = 0.25f, H = 0.6f;
  const int n = int(2 * kPi * R * H * 10000.f);
  for (int i = 0; i < n; ++i) {
    const float t = float(2 * kPi) * u(rng);
    scan.points.emplace_back(R * std::cos(t), R * std::sin(t), H * u(rng));
  }
  for (double alpha : {40.0, 25.0}) {
    SCOPED_TRACE(alpha);
    const auto seg = RunSeg(scan, {{"angle_deg", alpha}});
    size_t covered = 0;
    for (const auto& part : seg.parts) {
      std::vector<double> az;
      for (int i : part.indices) az.push_back(std::atan2(scan.points[i].y(), scan.points[i].x()) * 180.0 / kPi);
      std::sort(az.begin(), az.end());
      double gap = az.front() + 360.0 - az.back();
      for (size_t k = 1; k < az.size(); ++k) gap = std::max(gap, az[k] - az[k - 1]);
      const double span = 360.0 - gap;  // azimuth range = normal range on a cylinder
      // Tolerance 3 deg: normal errors at the part's edges (random sampling).
      EXPECT_LE(span, 2 * alpha + 3.0);
      covered += part.indices.size();
    }
    EXPECT_GE(seg.parts.size(), size_t(std::ceil(360.0 / (2 * alpha))));
    EXPECT_EQ(covered + size_t(seg.discarded_points), scan.points.size());
  }
}

// Two parallel sheets 4 cm apart (within delta = 5 cm, outside each other's 3 cm normal
// neighbourhoods), no sensor origin: both sheets' normals point to the bounding-box centre
// between them, i.e. opposite ways. Unsigned angles (default) make one part, signed two.
TEST(RegionGrowing, SignedNormalsSeparateOppositeSheets) {
  Scan scan;
  for (int face = 0; face < 2; ++face)
    for (int i = 0; i <= 40; ++i)
      for (int j = 0; j <= 40; ++j) scan.points.emplace_back(0.01f * i, 0.01f * j, 0.04f * face);
  const auto one = RunSeg(scan);
  ASSERT_EQ(one.parts.size(), 1u);
  const auto two = RunSeg(scan, {{"signed_normals", true}});
  ASSERT_EQ(two.parts.size(), 2u);
  for (const auto& part : two.parts) {
    ASSERT_EQ(part.indices.size(), 41u * 41u);
    const float z = scan.points[part.indices.front()].z();
    for (int i : part.indices) ASSERT_EQ(scan.points[i].z(), z);
  }
  EXPECT_GT(one.normals.front().z(), 0.99f);  // the lower sheet looks up to the centre
  EXPECT_LT(one.normals.back().z(), -0.99f);
}

// Two tiny clusters within delta of each other merge into one part; isolated tiny clusters
// are discarded and counted.
TEST(RegionGrowing, SmallPartsRegroupedByDistanceOrDiscarded) {
  Scan scan;
  for (int i = 0; i <= 50; ++i)
    for (int j = 0; j <= 50; ++j) scan.points.emplace_back(0.01f * i, 0.01f * j, 0.f);
  const int plane = int(scan.points.size());
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<float> u(-0.005f, 0.005f);
  auto cluster = [&](const Eigen::Vector3f& c, int k) {
    std::vector<int> idx;
    for (int i = 0; i < k; ++i) {
      idx.push_back(int(scan.points.size()));
      scan.points.push_back(c + Eigen::Vector3f(u(rng), u(rng), u(rng)));
    }
    return idx;
  };
  auto a = cluster({0.2f, 0.2f, 1.f}, 5);   // a and b: 3-5 cm apart
  auto b = cluster({0.24f, 0.2f, 1.f}, 6);
  cluster({2.f, 0.f, 1.f}, 4);             // isolated: discarded
  cluster({-2.f, 0.f, 1.f}, 9);            // isolated, one short of min_points: discarded
  const auto seg = RunSeg(scan);
  ASSERT_EQ(seg.parts.size(), 2u);
  EXPECT_EQ(int(seg.parts[0].indices.size()), plane);
  std::vector<int> ab = a;
  ab.insert(ab.end(), b.begin(), b.end());
  std::sort(ab.begin(), ab.end());
  EXPECT_EQ(seg.parts[1].indices, ab);
  EXPECT_EQ(seg.discarded_points, 13);
  Eigen::Vector3f mean = Eigen::Vector3f::Zero();
  for (int i : ab) mean += scan.points[i];
  EXPECT_LT((seg.parts[1].centroid - mean / float(ab.size())).norm(), 1e-5f);

  // min_points = 1 keeps every cluster.
  const auto all = RunSeg(scan, {{"min_points", 1}});
  EXPECT_EQ(all.discarded_points, 0);
  size_t total = 0;
  for (const auto& p : all.parts) total += p.indices.size();
  EXPECT_EQ(total, scan.points.size());
}

TEST(RegionGrowing, SparsePointsGetNaNNormalsAndStillJoinByDistance) {
  Scan scan;
  for (int i = 0; i < 20; ++i) scan.points.emplace_back(0.04f * i, 0.f, 0.f);  // 4 cm apart > 3 cm radius
  const auto seg = RunSeg(scan);
  for (size_t i = 0; i < scan.points.size(); ++i) {
    EXPECT_FALSE(seg.normals[i].allFinite());
    EXPECT_TRUE(std::isnan(seg.curvature[i]));
  }
  // Every point is its own normal-less part, regrouped by distance (4 cm < 5 cm) into one.
  ASSERT_EQ(seg.parts.size(), 1u);
  EXPECT_EQ(seg.parts[0].indices.size(), 20u);
}

// The same geometry in map coordinates (1e5 m away) gives the same normals and parts. The far
// scan is built first and the near one derived from it by an exact subtraction, so both hold
// exactly the same shape (float resolution at 1e5 m is ~8 mm).
TEST(RegionGrowing, FarFromOriginSameNormals) {
  std::mt19937_64 rng(6);
  const double offset = 1e5;
  Points shape = Sphere({0, 0, 1.f}, 0.4f, 10000.f, rng);
  AddQuad(shape, nullptr, 0, Eigen::Vector3f(-1, -1, 0), Eigen::Vector3f(2, 0, 0), Eigen::Vector3f(0, 2, 0.2f),
          3000.f, rng);
  Scan far, near;
  for (const auto& p : shape) {
    const Eigen::Vector3f f = (p.cast<double>() + Eigen::Vector3d::Constant(offset)).cast<float>();
    far.points.push_back(f);
    near.points.push_back((f.cast<double>() - Eigen::Vector3d::Constant(offset)).cast<float>());
  }
  near.origin = Eigen::Vector3f(0.5f, 0.5f, 2.f);
  far.origin = (near.origin->cast<double>() + Eigen::Vector3d::Constant(offset)).cast<float>();
  const auto sn = RunSeg(near), sf = RunSeg(far);
  double worst = 0;
  int finite = 0;
  for (size_t i = 0; i < shape.size(); ++i) {
    ASSERT_EQ(sn.normals[i].allFinite(), sf.normals[i].allFinite());
    if (!sn.normals[i].allFinite()) continue;
    ++finite;
    worst = std::max(worst, AngleDeg(sn.normals[i], sf.normals[i]));
  }
  EXPECT_GT(finite, int(shape.size()) * 9 / 10);
  EXPECT_LT(worst, 1e-3);
  ASSERT_EQ(sn.parts.size(), sf.parts.size());
  for (size_t p = 0; p < sn.parts.size(); ++p) {
    EXPECT_EQ(sn.parts[p].indices, sf.parts[p].indices);
    const Eigen::Vector3d back = sf.parts[p].centroid.cast<double>() - Eigen::Vector3d::Constant(offset);
    EXPECT_LT((back - sn.parts[p].centroid.cast<double>()).norm(), 0.01);  // float resolution at 1e5 m
  }
}

TEST(RegionGrowing, DeterministicAcrossThreadCounts) {
  std::mt19937_64 rng(7);
  Scan scan;
  scan.points = Sphere({0, 0, 0}, 0.3f, 8000.f, rng);
  AddQuad(scan.points, nullptr, 0, Eigen::Vector3f(-1, -1, -0.5f), Eigen::Vector3f(2, 0, 0),
          Eigen::Vector3f(0, 2, 0), 5000.f, rng);
  auto seg = MakeSegmenter();
  furnihost::RunContext one, two;
  one.threads = 1;
  two.threads = 2;
  const auto a = seg->Segment(scan, one), b = seg->Segment(scan, two);
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t p = 0; p < a.parts.size(); ++p) EXPECT_EQ(a.parts[p].indices, b.parts[p].indices);
  for (size_t i = 0; i < scan.points.size(); ++i) {
    ASSERT_EQ(a.normals[i].allFinite(), b.normals[i].allFinite());
    if (a.normals[i].allFinite()) {
      EXPECT_EQ(a.normals[i], b.normals[i]);
    }
  }
}

TEST(RegionGrowing, RejectsBadParameters) {
  auto reg = furnihost::testing::MakeRegistry();
  const auto* entry = reg->Find("segmenters.region_growing");
  ASSERT_NE(entry, nullptr);
  EXPECT_THROW(entry->params.Resolve({{"angle_deg", 200}}, "test"), furnihost::InputError);
  EXPECT_THROW(entry->params.Resolve({{"normal_radius_m", "three"}}, "test"), furnihost::InputError);
  EXPECT_THROW(entry->params.Resolve({{"min_points", 0}}, "test"), furnihost::InputError);
}

TEST(RegionGrowing, EmptyAndNonFiniteScans) {
  Scan empty;
  const auto s0 = RunSeg(empty);
  EXPECT_TRUE(s0.parts.empty());
  Scan scan;
  for (int i = 0; i <= 20; ++i)
    for (int j = 0; j <= 20; ++j) scan.points.emplace_back(0.01f * i, 0.01f * j, 0.f);
  scan.points.emplace_back(NAN, 0.f, 0.f);
  const auto s1 = RunSeg(scan);
  ASSERT_EQ(s1.parts.size(), 1u);
  EXPECT_EQ(s1.parts[0].indices.size(), scan.points.size() - 1);
  EXPECT_EQ(s1.discarded_points, 1);
  EXPECT_FALSE(s1.normals.back().allFinite());
}

}  // namespace
