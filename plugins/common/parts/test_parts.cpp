// furnihost::parts below the plugins: the column names, the reduced set as a column subset of
// the 24 on random parts, determinism, the declared parameters resolving to the option
// defaults, and the option checks. The paper-level cases (tilted patches, rotation invariance,
// boundaries) are in features.paper24's tests.
#include "parts/part_features.hpp"

#include <gtest/gtest.h>

#include <random>

#include "furnihost/error.hpp"
#include "parts/part_features_schema.hpp"

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
