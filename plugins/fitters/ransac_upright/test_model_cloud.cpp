// ModelCloud's coverage grid against its kd-tree: Covered(q) must give the exact answer
// (CoveredExact) for every query, the grid only decides the cells where it is sure. Queries:
// uniform in the grid's box (mostly far cells), and the model's own points jittered by up to
// 1.5x the inlier distance (the cells near the surface, where covered / ambiguous / outside
// meet).
#include <gtest/gtest.h>

#include <random>

#include "model_cloud.hpp"
#include "synthetic_scene.hpp"

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

}  // namespace
