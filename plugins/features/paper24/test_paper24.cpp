// features.paper24 through the registry: closed-form values on rectangle patches.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace {

using furnihost::FeatureMatrix;
using furnihost::Scan;
using furnihost::Segmentation;

constexpr double kPi = 3.14159265358979323846;

std::shared_ptr<furnihost::Features> Make(const std::string& type, const nlohmann::json& params) {
  static auto reg = furnihost::testing::MakeRegistry();
  const auto* entry = reg->Find(type);
  EXPECT_NE(entry, nullptr) << type << " not found in " << furnihost::testing::PluginDir();
  return reg->CreateAs<furnihost::Features>(type, entry->params.Resolve(params, "test"));
}

FeatureMatrix Compute(const Scan& scan, const Segmentation& seg, const nlohmann::json& params) {
  furnihost::RunContext ctx;
  ctx.threads = 2;
  return Make("features.paper24", params)->Compute(scan, seg, ctx);
}

int Col(const FeatureMatrix& f, const std::string& name) {
  const auto it = std::find(f.names.begin(), f.names.end(), name);
  EXPECT_NE(it, f.names.end()) << name;
  return int(it - f.names.begin());
}

// A regular grid of na x nb points with spacing h, long side along `ua`, short along `ub`,
// centred at `c`; one part holding every point, normals set to ua x ub, curvature `curv`.
struct Patch {
  Scan scan;
  Segmentation seg;
};
Patch MakePatch(int na, int nb, float h, const Eigen::Vector3f& c, const Eigen::Vector3f& ua,
                const Eigen::Vector3f& ub, float curv) {
  Patch p;
  const Eigen::Vector3f n = ua.cross(ub).normalized();
  furnihost::Part part;
  for (int i = 0; i < na; ++i)
    for (int j = 0; j < nb; ++j) {
      const Eigen::Vector3d q = c.cast<double>() + double(h) * ((i - 0.5 * (na - 1)) * ua.cast<double>() +
                                                                 (j - 0.5 * (nb - 1)) * ub.cast<double>());
      part.indices.push_back(int(p.scan.points.size()));
      p.scan.points.push_back(q.cast<float>());
      p.seg.normals.push_back(n);
      p.seg.curvature.push_back(curv);
    }
  p.seg.parts.push_back(part);
  return p;
}

TEST(Paper24, TwentyFourNamedColumns) {
  const auto patch = MakePatch(5, 4, 0.01f, {0, 0, 0}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY(), 0.f);
  const auto f = Compute(patch.scan, patch.seg, nlohmann::json::object());
  ASSERT_EQ(f.values.cols(), 24);
  ASSERT_EQ(f.names.size(), 24u);
  EXPECT_EQ(f.values.rows(), 1);
  EXPECT_TRUE(f.values.allFinite());
}

// A 0.4 m x 0.2 m rectangle (41 x 21 points, 1 cm), its normal tilted 30 deg from +z about the
// x axis (the long side stays horizontal), away from the origin.
TEST(Paper24, TiltedRectangleMatchesClosedForm) {
  const float h = 0.01f;
  const int na = 41, nb = 21;
  const double tilt = 30.0 * kPi / 180.0;
  const Eigen::Vector3f ua = Eigen::Vector3f::UnitX();
  const Eigen::Vector3f ub(0.f, float(std::cos(tilt)), float(std::sin(tilt)));
  const auto patch = MakePatch(na, nb, h, {100.f, -200.f, 1.f}, ua, ub, 0.02f);
  const auto f = Compute(patch.scan, patch.seg, {{"boundary_radius_m", 0.025}, {"boundary_angle_deg", 90}});
  const auto v = f.values.row(0);
  // Variance of n evenly spaced values h apart: h^2 (n^2 - 1) / 12.
  const double va = double(h) * h * (na * na - 1) / 12.0, vb = double(h) * h * (nb * nb - 1) / 12.0;
  const double sum = va + vb;
  const double rel = 1e-3;  // float coordinates 200 m from the origin
  EXPECT_NEAR(v[Col(f, "ratio_e1_e2")], 0.0, 1e-4);
  EXPECT_NEAR(v[Col(f, "ratio_e2_e3")], vb / va, rel * vb / va);
  EXPECT_NEAR(v[Col(f, "ratio_e1_e3")], 0.0, 1e-4);
  EXPECT_NEAR(v[Col(f, "ratio_e1_sum")], 0.0, 1e-4);
  EXPECT_NEAR(v[Col(f, "ratio_e2_sum")], vb / sum, rel);
  EXPECT_NEAR(v[Col(f, "ratio_e3_sum")], va / sum, rel);
  EXPECT_NEAR(v[Col(f, "var_a1_m2")], 0.0, 1e-7);
  EXPECT_NEAR(v[Col(f, "var_a2_m2")], vb, rel * vb);
  EXPECT_NEAR(v[Col(f, "var_a3_m2")], va, rel * va);
  EXPECT_NEAR(v[Col(f, "tilt_a1_deg")], 30.0, 0.05);
  EXPECT_NEAR(v[Col(f, "tilt_a3_deg")], 90.0, 0.05);
  EXPECT_NEAR(v[Col(f, "extent_a1_far_m")], 0.0, 1e-4);
  EXPECT_NEAR(v[Col(f, "extent_a1_near_m")], 0.0, 1e-4);
  EXPECT_NEAR(v[Col(f, "extent_a2_far_m")], 0.1, 1e-4);
  EXPECT_NEAR(v[Col(f, "extent_a2_near_m")], 0.1, 1e-4);
  EXPECT_NEAR(v[Col(f, "extent_a3_far_m")], 0.2, 1e-4);
  EXPECT_NEAR(v[Col(f, "extent_a3_near_m")], 0.2, 1e-4);
  EXPECT_NEAR(v[Col(f, "var_extent_a1_m")], 0.0, 1e-4);
  EXPECT_NEAR(v[Col(f, "var_extent_a2_m")], vb / 0.2, rel * vb / 0.2);
  EXPECT_NEAR(v[Col(f, "var_extent_a3_m")], va / 0.4, rel * va / 0.4);
  EXPECT_NEAR(v[Col(f, "mean_curvature")], 0.02, 1e-6);
  // Boundary with radius 2.5 h: only the outer ring has a gap > 90 deg (the second ring sees
  // the first within 26.6 deg steps): 2 (41 + 21) - 4 = 120 of 861 points.
  EXPECT_NEAR(v[Col(f, "boundary_ratio")], 120.0 / 861.0, 1e-6);
}

// Voxel volume and occupancy on an axis-aligned rectangle with a voxel edge that puts no
// point on a voxel face: floor(0.4 / v) + 1 = 17 by floor(0.2 / v) + 1 = 9 voxels.
TEST(Paper24, VoxelVolumeAndOccupancy) {
  const double voxel = 0.0237;
  const auto patch = MakePatch(41, 21, 0.01f, {3.f, 4.f, 0.5f}, Eigen::Vector3f::UnitX(), Eigen::Vector3f::UnitY(), 0.f);
  const auto f = Compute(patch.scan, patch.seg, {{"voxel_m", voxel}});
  const double vol = 17 * 9 * voxel * voxel * voxel;
  EXPECT_NEAR(f.values(0, Col(f, "voxel_volume_m3")), vol, 1e-3 * vol);
  // OBB: 0.4 x 0.2 x (thickness 0 -> one voxel).
  EXPECT_NEAR(f.values(0, Col(f, "occupancy")), vol / (0.4 * 0.2 * voxel), 1e-3);
  EXPECT_NEAR(f.values(0, Col(f, "tilt_a1_deg")), 0.0, 0.05);
}

// Rotating a part about +z (a different yaw of the same furniture) changes no feature beyond
// the voxelisation (features 3 and 9 depend on the grid's alignment).
TEST(Paper24, InvariantToRotationAboutZ) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<float> u(-0.2f, 0.2f);
  Scan a;
  Segmentation seg;
  furnihost::Part part;
  for (int i = 0; i < 600; ++i) {  // a slanted, curved slab
    const float x = u(rng), y = u(rng) * 0.5f;
    a.points.emplace_back(x, y, 0.3f * x + 2.f * y * y + 0.1f * u(rng) * 0.05f);
    part.indices.push_back(i);
    seg.normals.emplace_back(NAN, NAN, NAN);
    seg.curvature.push_back(0.05f);
  }
  seg.parts.push_back(part);
  Scan b = a;
  const Eigen::Matrix3f rot = Eigen::AngleAxisf(1.1f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  for (auto& p : b.points) p = rot * p + Eigen::Vector3f(5, -3, 0);
  const auto fa = Compute(a, seg, {{"boundary_radius_m", 0.05}}), fb = Compute(b, seg, {{"boundary_radius_m", 0.05}});
  for (int c = 0; c < 24; ++c) {
    if (fa.names[c] == "voxel_volume_m3" || fa.names[c] == "occupancy") continue;
    EXPECT_NEAR(fa.values(0, c), fb.values(0, c), 1e-3 * std::max(1.f, std::fabs(fa.values(0, c)))) << fa.names[c];
  }
}

// The boundary test has two code paths: thresholds >= 90 deg look only at the gaps around
// empty 45 deg sectors, smaller ones sort all directions. On a random patch with a hole they
// must classify alike at (almost) the same threshold.
TEST(Paper24, BoundarySectorPathMatchesSortedPath) {
  std::mt19937_64 rng(10);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  Scan scan;
  Segmentation seg;
  furnihost::Part part;
  while (scan.points.size() < 3000) {
    const Eigen::Vector3f p(u(rng), u(rng), 0.01f * u(rng));
    if (p.head<2>().norm() < 0.08f) continue;  // a hole
    part.indices.push_back(int(scan.points.size()));
    scan.points.push_back(p);
    seg.normals.push_back(Eigen::Vector3f::UnitZ());
    seg.curvature.push_back(0.f);
  }
  seg.parts.push_back(part);
  const auto wide = Compute(scan, seg, {{"boundary_radius_m", 0.03}, {"boundary_angle_deg", 90.0}});
  const auto sorted = Compute(scan, seg, {{"boundary_radius_m", 0.03}, {"boundary_angle_deg", 89.999}});
  const double b = wide.values(0, Col(wide, "boundary_ratio"));
  EXPECT_NEAR(b, sorted.values(0, Col(sorted, "boundary_ratio")), 1.5 / 3000.0);
  // Outer square border and the hole's rim: a few percent of the points, not none, not most.
  EXPECT_GT(b, 0.02);
  EXPECT_LT(b, 0.3);
}

// Copies of points: every point of a holed square stored 40 times, the copies scattered
// through the part, gives the boundary ratio of the square itself (a copy is no neighbour
// direction, its neighbours' copies add none), and a million copies of one point are one
// boundary point each, in linear time (a test per copy over every copy: beyond ctest's timeout).
TEST(Paper24, CopiesKeepTheBoundaryRatioAndStayLinear) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  Scan once;
  while (once.points.size() < 2000) {
    const Eigen::Vector3f p(u(rng), u(rng), 0.f);
    if (p.head<2>().norm() > 0.08f) once.points.push_back(p);
  }
  auto part_of = [](const furnihost::Points& pts) {
    Segmentation seg;
    furnihost::Part part;
    for (size_t i = 0; i < pts.size(); ++i) part.indices.push_back(int(i));
    seg.parts.push_back(part);
    seg.normals.assign(pts.size(), Eigen::Vector3f::UnitZ());
    seg.curvature.assign(pts.size(), 0.f);
    return seg;
  };
  Scan copies;
  for (int c = 0; c < 40; ++c) copies.points.insert(copies.points.end(), once.points.begin(), once.points.end());
  for (double angle : {90.0, 60.0}) {
    const nlohmann::json params = {{"boundary_radius_m", 0.03}, {"boundary_angle_deg", angle}};
    const auto a = Compute(once, part_of(once.points), params), b = Compute(copies, part_of(copies.points), params);
    const double ratio = a.values(0, Col(a, "boundary_ratio"));
    EXPECT_GT(ratio, 0.02);
    EXPECT_FLOAT_EQ(b.values(0, Col(b, "boundary_ratio")), float(ratio)) << angle;
  }
  Scan same;
  same.points.assign(1000000, Eigen::Vector3f(1.f, 1.f, 1.f));
  const auto f = Compute(same, part_of(same.points), nlohmann::json::object());
  EXPECT_FLOAT_EQ(f.values(0, Col(f, "boundary_ratio")), 1.f);
}

// A scan much denser than the boundary radius needs: feature 1 tests an even sample of each
// cell's points (boundary_tests_per_cell), each standing for the points up to the next; the
// ratio stays that of testing every point (0), within the sampling's noise.
TEST(Paper24, DenseBoundaryRatioFromASampleMatchesEveryPoint) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<float> u(0.f, 0.5f);
  Scan scan;
  for (int i = 0; i < 60000; ++i) scan.points.emplace_back(u(rng), u(rng), 0.f);  // ~216 points per 3 cm cell
  Segmentation seg;
  furnihost::Part part;
  for (size_t i = 0; i < scan.points.size(); ++i) part.indices.push_back(int(i));
  seg.parts.push_back(part);
  seg.normals.assign(scan.points.size(), Eigen::Vector3f::UnitZ());
  seg.curvature.assign(scan.points.size(), 0.f);
  for (double angle : {90.0, 60.0}) {
    const auto every = Compute(scan, seg, {{"boundary_tests_per_cell", 0}, {"boundary_angle_deg", angle}});
    const auto sample = Compute(scan, seg, {{"boundary_angle_deg", angle}});
    const double e = every.values(0, Col(every, "boundary_ratio")), s = sample.values(0, Col(sample, "boundary_ratio"));
    EXPECT_GT(e, 0.001) << angle;
    EXPECT_NEAR(s, e, 0.2 * e) << angle;
  }
}

TEST(Paper24, DegeneratePartsGiveFiniteValues) {
  Scan scan;
  scan.points = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}, {2, 0, 0}};
  Segmentation seg;  // no normals / curvature at all
  furnihost::Part same, single, empty;
  same.indices = {0, 1, 2};
  single.indices = {3};
  seg.parts = {same, single, empty};
  const auto f = Compute(scan, seg, nlohmann::json::object());
  ASSERT_EQ(f.values.rows(), 3);
  EXPECT_TRUE(f.values.allFinite());
  EXPECT_FLOAT_EQ(f.values(0, Col(f, "boundary_ratio")), 1.f);  // no neighbour in any direction

  furnihost::Part bad;
  bad.indices = {7};
  seg.parts = {bad};
  EXPECT_THROW(Compute(scan, seg, nlohmann::json::object()), furnihost::StageError);
}

}  // namespace
