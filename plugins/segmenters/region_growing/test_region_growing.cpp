// segmenters.region_growing through the registry: normal accuracy on analytic surfaces,
// the parts of a box and a cylinder, the small-part rule, and scans in map coordinates.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <cstdio>
#include <cstring>
#include <random>
#include <set>

#include "furnihost/stage.hpp"
#include "furnihost/voxel_index.hpp"
#include "parallel/tbb_for.hpp"
#include "region_growing_core.hpp"
#include "simd/left_pack.hpp"
#include "test_support.hpp"

namespace {

using furnihost::Points;
using furnihost::Scan;
using furnihost::Segmentation;
using furnihost::Segmenter;
namespace rg = furnihost::rg;

constexpr double kPi = 3.14159265358979323846;

std::shared_ptr<Segmenter> MakeSegmenter(const nlohmann::json& params = nlohmann::json::object()) {
  static auto reg = furnihost::testing::MakeRegistry();
  const auto* entry = reg->Find("segmenters.region_growing");
  EXPECT_NE(entry, nullptr) << "plugin not found in " << furnihost::testing::PluginDir();
  return reg->CreateAs<Segmenter>("segmenters.region_growing", entry->params.Resolve(params, "test"));
}

Segmentation RunSeg(const Scan& scan, const nlohmann::json& params = nlohmann::json::object()) {
  furnihost::RunContext ctx;
  ctx.threads = 2;
  return MakeSegmenter(params)->Segment(scan, ctx);
}

// In double and via atan2: acos of a float dot product near 1 is off by ~0.02 deg.
double AngleDeg(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  const Eigen::Vector3d x = a.cast<double>(), y = b.cast<double>();
  return std::atan2(x.cross(y).norm(), x.dot(y)) * 180.0 / kPi;
}

// Uniform random points on a sphere of radius r around c, about `density` points per m^2.
Points Sphere(const Eigen::Vector3f& c, float r, float density, std::mt19937_64& rng) {
  std::normal_distribution<float> g(0.f, 1.f);
  const int n = int(4 * kPi * r * r * density);
  Points pts;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3f d(g(rng), g(rng), g(rng));
    pts.push_back(c + r * d.normalized());
  }
  return pts;
}

// Uniform random points on the parallelogram o + s a + t b, s, t in [0, 1].
void AddQuad(Points& pts, std::vector<int>* face, int id, const Eigen::Vector3f& o, const Eigen::Vector3f& a,
             const Eigen::Vector3f& b, float density, std::mt19937_64& rng) {
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const int n = int(a.cross(b).norm() * density);
  for (int i = 0; i < n; ++i) {
    pts.push_back(o + u(rng) * a + u(rng) * b);
    if (face) face->push_back(id);
  }
}

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

// The index behind every neighbourhood (segmenters and features) against brute force, on
// clustered, sparse and coincident points spanning several metres, for both anchors; built
// serially and with TBB it must be the same index.
TEST(VoxelIndex, RadiusNeighboursMatchBruteForce) {
  using furnihost::VoxelIndex;
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Points pts;
  for (int i = 0; i < 1500; ++i) pts.emplace_back(0.3f * u(rng), 0.3f * u(rng), 0.3f * u(rng));  // dense blob
  for (int i = 0; i < 300; ++i) pts.emplace_back(5.f * u(rng), 3.f * u(rng), 2.f * u(rng));      // sparse
  for (int i = 0; i < 20; ++i) pts.emplace_back(1.f, 1.f, 1.f);                                    // duplicates
  for (int i = 0; i < 200; ++i) pts.emplace_back(-2.f * u(rng), -0.05f * u(rng), 0.1f * u(rng));  // negative side
  for (VoxelIndex::Anchor anchor : {VoxelIndex::Anchor::kBoundingBox, VoxelIndex::Anchor::kWorld})
    for (float r : {0.03f, 0.05f, 0.2f}) {
      SCOPED_TRACE(::testing::Message() << "r " << r << " world anchor " << (anchor == VoxelIndex::Anchor::kWorld));
      VoxelIndex grid, serial;
      grid.Build(pts, r, anchor, furnihost::TbbFor());
      serial.Build(pts, r, anchor);
      ASSERT_EQ(grid.size(), pts.size());
      EXPECT_EQ(grid.order, serial.order);
      EXPECT_EQ(grid.cell_start, serial.cell_start);
      EXPECT_EQ(grid.nb_start, serial.nb_start);
      EXPECT_EQ(grid.nb, serial.nb);
      const std::vector<uint32_t> slot_of = grid.SlotOfInput();
      std::vector<int> seen(pts.size(), 0);
      for (int c = 0; c < grid.NumCells(); ++c) {
        const Eigen::Vector3i cc = grid.CellCoords(c);
        for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k)
          ASSERT_LE((grid.CellCoords(grid.nb[k]) - cc).cwiseAbs().maxCoeff(), 1);
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
          ASSERT_EQ(grid.cell_of[s], c);
          if (s > grid.cell_start[c]) {
            ASSERT_LT(grid.order[s - 1], grid.order[s]) << "input order inside a cell";
          }
          const Eigen::Vector3f& p = pts[grid.order[s]];
          if (anchor == VoxelIndex::Anchor::kWorld) {
            // Cells at multiples of r: points of one cell share floor(p / r).
            const Eigen::Vector3f f = (p * (1.f / r)).array().floor();
            const Eigen::Vector3f f0 = (pts[grid.order[grid.cell_start[c]]] * (1.f / r)).array().floor();
            ASSERT_EQ(f, f0);
          }
          ++seen[grid.order[s]];
          ASSERT_EQ(slot_of[grid.order[s]], uint32_t(s));
          std::vector<int> got, want;
          grid.ForEachWithin(c, grid.x[s], grid.y[s], grid.z[s], r,
                             [&](int q, float, float, float, float) { got.push_back(int(grid.order[q])); });
          for (size_t j = 0; j < pts.size(); ++j)
            if ((pts[j] - p).squaredNorm() < r * r) want.push_back(int(j));
          std::sort(got.begin(), got.end());
          ASSERT_EQ(got, want) << "point " << grid.order[s];
        }
      }
      for (int v : seen) ASSERT_EQ(v, 1);
    }
  VoxelIndex empty;
  empty.Build({}, 0.1f);
  EXPECT_EQ(empty.NumCells(), 0);
  VoxelIndex bad;
  EXPECT_THROW(bad.Build(pts, 0.f), furnihost::StageError);
  EXPECT_THROW(bad.Build({{0.f, 0.f, 0.f}, {1e4f, 0.f, 0.f}}, 0.001f), furnihost::StageError);  // > 2^20 cells
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

// The first `faces` of a box's bottom, top, front and back faces (corner lo, edges X, Y, Z) and
// a ball, `d` points per m2, with Gaussian noise of `sigma` on every coordinate.
Scan FacesAndBall(uint64_t seed, const Eigen::Vector3f& lo, const Eigen::Vector3f& X, const Eigen::Vector3f& Y,
                  const Eigen::Vector3f& Z, int faces, const Eigen::Vector3f& centre, float radius, float d,
                  float sigma) {
  std::mt19937_64 rng(seed);
  Scan scan;
  const Eigen::Vector3f o[4] = {lo, lo + Z, lo, lo + Y}, a[4] = {X, X, X, X}, b[4] = {Y, Y, Z, Z};
  for (int f = 0; f < faces; ++f) AddQuad(scan.points, nullptr, 0, o[f], a[f], b[f], d, rng);
  const Points ball = Sphere(centre, radius, d, rng);
  scan.points.insert(scan.points.end(), ball.begin(), ball.end());
  std::normal_distribution<float> noise(0.f, sigma);
  for (auto& p : scan.points) p += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
  return scan;
}

// The same parts, point for point, with the same centroids, and the same discarded points.
void ExpectSameParts(const Segmentation& a, const Segmentation& b) {
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t k = 0; k < a.parts.size(); ++k) {
    EXPECT_EQ(a.parts[k].indices, b.parts[k].indices) << "part " << k;
    EXPECT_EQ(a.parts[k].centroid, b.parts[k].centroid) << "part " << k;
  }
  EXPECT_EQ(a.discarded_points, b.discarded_points);
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
