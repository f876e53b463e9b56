// features.reduced is exactly features.paper24 without features 4, 7 and 8.
#include <gtest/gtest.h>

#include <random>

#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace {

furnihost::FeatureMatrix Compute(const std::string& type, const furnihost::Scan& scan,
                                 const furnihost::Segmentation& seg) {
  static auto reg = furnihost::testing::MakeRegistry();
  const auto* entry = reg->Find(type);
  EXPECT_NE(entry, nullptr) << type << " not found in " << furnihost::testing::PluginDir();
  const nlohmann::json params = {{"voxel_m", 0.03}, {"boundary_radius_m", 0.04}};
  furnihost::RunContext ctx;
  ctx.threads = 2;
  return reg->CreateAs<furnihost::Features>(type, entry->params.Resolve(params, "test"))->Compute(scan, seg, ctx);
}

TEST(Reduced, IsPaper24WithoutFeatures4_7_8) {
  // Three parts of different shapes: a plane, a rod, a noisy blob.
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  furnihost::Scan scan;
  furnihost::Segmentation seg;
  auto add_part = [&](int n, auto&& gen) {
    furnihost::Part part;
    for (int i = 0; i < n; ++i) {
      part.indices.push_back(int(scan.points.size()));
      scan.points.push_back(gen());
      seg.normals.push_back(Eigen::Vector3f(u(rng), u(rng), u(rng)).normalized());
      seg.curvature.push_back(0.1f * u(rng));
    }
    seg.parts.push_back(part);
  };
  add_part(800, [&] { return Eigen::Vector3f(u(rng), 0.5f * u(rng), 0.f); });
  add_part(200, [&] { return Eigen::Vector3f(2.f, 0.02f * u(rng), u(rng)); });
  add_part(300, [&] { return Eigen::Vector3f(-1.f + 0.1f * u(rng), 0.1f * u(rng), 0.1f * u(rng)); });

  const auto full = Compute("features.paper24", scan, seg);
  const auto red = Compute("features.reduced", scan, seg);
  ASSERT_EQ(full.values.cols(), 24);
  ASSERT_EQ(red.values.rows(), full.values.rows());
  // Dropped: feature 4 = columns 3-8, feature 7 = 14-19, feature 8 = 20-22.
  const std::vector<int> kept = {0, 1, 2, 9, 10, 11, 12, 13, 23};
  ASSERT_EQ(red.values.cols(), Eigen::Index(kept.size()));
  ASSERT_EQ(red.names.size(), kept.size());
  for (size_t j = 0; j < kept.size(); ++j) {
    EXPECT_EQ(red.names[j], full.names[kept[j]]);
    for (Eigen::Index r = 0; r < full.values.rows(); ++r)
      EXPECT_EQ(red.values(r, Eigen::Index(j)), full.values(r, kept[j])) << red.names[j] << " part " << r;
  }
  for (const auto& name : red.names) {
    EXPECT_EQ(name.find("ratio_e"), std::string::npos) << name;
    EXPECT_EQ(name.find("extent"), std::string::npos) << name;
  }
}

}  // namespace
