// VoxelIndex, the index behind every neighbourhood (segmenters and features), against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <random>
#include <set>

#include "furnihost/voxel_index.hpp"
#include "parallel/tbb_for.hpp"
#include "test_region_growing_scenes.hpp"

namespace {

using namespace rg_test;

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

}  // namespace
