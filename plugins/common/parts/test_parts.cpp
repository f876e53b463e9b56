// furnihost::parts below the plugins: the column names, the reduced set as a column subset of
// the 24 on random parts, determinism, the declared parameters resolving to the option
// defaults, and the option checks. The paper-level cases (tilted patches, rotation invariance,
// boundaries) are in features.paper24's tests.
#include "parts/part_features.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "furnihost/error.hpp"
#include "parts/part_features_schema.hpp"
#include "simd/left_pack.hpp"

namespace furnihost::parts {
namespace {

TEST(PartFeatures, ColumnNames) {
  ASSERT_EQ(Paper24Names().size(), size_t(kPaper24Columns));
  EXPECT_EQ(Paper24Names().front(), "boundary_ratio");
  EXPECT_EQ(Paper24Names().back(), "occupancy");
  EXPECT_EQ(ReducedColumns(), (std::vector<int>{0, 1, 2, 9, 10, 11, 12, 13, 23}));
}

// Random points in `parts` boxes, one part each; normals +z, curvature 0.01.
void RandomParts(int parts, Scan& scan, Segmentation& seg) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int k = 0; k < parts; ++k) {
    Part part;
    const Eigen::Vector3f size(0.1f + 0.5f * u(rng), 0.1f + 0.5f * u(rng), 0.02f + 0.3f * u(rng));
    const Eigen::Vector3f at(3.f * u(rng), 3.f * u(rng), u(rng));
    for (int i = 0; i < 200; ++i) {
      part.indices.push_back(static_cast<int>(scan.points.size()));
      scan.points.push_back(at + size.cwiseProduct(Eigen::Vector3f(u(rng), u(rng), u(rng))));
      seg.normals.push_back(Eigen::Vector3f::UnitZ());
      seg.curvature.push_back(0.01f);
      part.centroid += scan.points.back() / 200.f;
    }
    seg.parts.push_back(part);
  }
}

TEST(PartFeatures, ReducedIsASubsetOfTheTwentyFour) {
  Scan scan;
  Segmentation seg;
  RandomParts(6, scan, seg);
  const PartFeatureOptions o;
  const FeatureMatrix full = ComputePaper24(scan, seg, o);
  const FeatureMatrix reduced = ComputeReduced(scan, seg, o);
  ASSERT_EQ(full.values.rows(), 6);
  ASSERT_EQ(full.values.cols(), kPaper24Columns);
  EXPECT_EQ(full.names, Paper24Names());
  ASSERT_EQ(reduced.values.rows(), 6);
  ASSERT_EQ(reduced.values.cols(), static_cast<Eigen::Index>(ReducedColumns().size()));
  for (size_t c = 0; c < ReducedColumns().size(); ++c) {
    EXPECT_EQ(reduced.names[c], Paper24Names()[ReducedColumns()[c]]);
    for (int r = 0; r < 6; ++r)
      EXPECT_EQ(reduced.values(r, c), full.values(r, ReducedColumns()[c])) << "row " << r << " column " << c;
  }
  EXPECT_TRUE(full.values.allFinite());
}

TEST(PartFeatures, DeterministicAcrossRuns) {
  Scan scan;
  Segmentation seg;
  RandomParts(4, scan, seg);
  const PartFeatureOptions o;
  EXPECT_TRUE(ComputePaper24(scan, seg, o).values == ComputePaper24(scan, seg, o).values);
}

// The boundary test gathers its neighbours 8 at a time where the CPU has AVX2: the features
// must be the scalar loop's bit for bit, for wide (>= 90 deg) and narrow gap thresholds. Flat
// noisy discs of several densities and tilts, so the boundary ratio takes many values.
TEST(PartFeatures, AvxBoundaryTestGivesTheScalarFeatures) {
  // Without AVX2 both runs take the scalar loop (the dispatch is tested in test_simd): the
  // features must still agree and vary.
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::normal_distribution<float> g(0.f, 1.f);
  Scan scan;
  Segmentation seg;
  for (int k = 0; k < 12; ++k) {
    const Eigen::Vector3f n = Eigen::Vector3f(g(rng), g(rng), g(rng)).normalized();
    const Eigen::Vector3f a = n.unitOrthogonal(), b = n.cross(a);
    const float radius = 0.1f + 0.3f * u(rng), density = 500.f + 8000.f * u(rng);
    const int m = int(3.14159f * radius * radius * density);
    Part part;
    for (int i = 0; i < m; ++i) {
      const float r = radius * std::sqrt(u(rng)), t = 6.2831853f * u(rng);
      part.indices.push_back(int(scan.points.size()));
      scan.points.push_back(Eigen::Vector3f(3.f * k, 0, 0) + r * std::cos(t) * a + r * std::sin(t) * b + 0.002f * g(rng) * n);
      seg.normals.push_back((n + 0.05f * Eigen::Vector3f(g(rng), g(rng), g(rng))).normalized());
      seg.curvature.push_back(0.01f);
    }
    seg.parts.push_back(part);
  }
  for (double angle : {90.0, 60.0}) {
    PartFeatureOptions o;
    o.boundary_angle_deg = angle;
    simd::SetAvx2(false);
    const FeatureMatrix a = ComputePaper24(scan, seg, o);
    simd::SetAvx2(true);
    const FeatureMatrix b = ComputePaper24(scan, seg, o);
    ASSERT_EQ(a.values.size(), b.values.size());
    EXPECT_EQ(std::memcmp(a.values.data(), b.values.data(), sizeof(float) * size_t(a.values.size())), 0) << angle;
    // The boundary ratios differ from part to part (the test is not of all-0 or all-1 ratios).
    EXPECT_GT(a.values.col(0).maxCoeff() - a.values.col(0).minCoeff(), 0.1f) << angle;
  }
}

TEST(PartFeatures, DeclaredParametersResolveToTheDefaults) {
  const auto& b = PartFeatureBinding();
  const PartFeatureOptions o = b.Parse(b.Schema().Resolve(nlohmann::json::object(), "test"));
  const PartFeatureOptions d;
  EXPECT_EQ(o.voxel_m, d.voxel_m);
  EXPECT_EQ(o.boundary_radius_m, d.boundary_radius_m);
  EXPECT_EQ(o.boundary_angle_deg, d.boundary_angle_deg);
  EXPECT_EQ(o.boundary_tests_per_cell, d.boundary_tests_per_cell);
  EXPECT_EQ(b.Schema().Find("voxel_m")->default_value, 0.02);
  EXPECT_EQ(b.Schema().Find("boundary_angle_deg")->unit, "deg");
  EXPECT_THROW(b.Parse({{"boundary_angle_deg", 180}}), InputError);
}

TEST(PartFeatures, OptionChecks) {
  PartFeatureOptions o;
  o.voxel_m = 0;
  EXPECT_THROW(o.Check(), StageError);
  o = PartFeatureOptions();
  o.boundary_angle_deg = 180;
  EXPECT_THROW(o.Check(), StageError);
  EXPECT_NO_THROW(PartFeatureOptions().Check());
}

}  // namespace
}  // namespace furnihost::parts
