// furnihost::parallel: TbbFor hands out disjoint sub-ranges that cover [begin, end) exactly
// once, and VoxelIndex::Build over it equals the serial build.
#include "parallel/tbb_for.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <random>
#include <vector>

#include "furnihost/voxel_index.hpp"

namespace furnihost {
namespace {

TEST(TbbFor, CoversTheRangeOnce) {
  std::vector<std::atomic<int>> hits(10007);
  TbbFor()(3, hits.size(), 64, [&](size_t b, size_t e) {
    for (size_t i = b; i < e; ++i) ++hits[i];
  });
  for (size_t i = 0; i < hits.size(); ++i) EXPECT_EQ(hits[i].load(), i < 3 ? 0 : 1) << i;
}

TEST(TbbFor, VoxelIndexEqualsTheSerialBuild) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-2.f, 2.f);
  std::vector<Eigen::Vector3f> pts(50000);
  for (auto& p : pts) p = Eigen::Vector3f(u(rng), u(rng), u(rng));
  VoxelIndex serial, parallel;
  serial.Build(pts, 0.1f);
  parallel.Build(pts, 0.1f, VoxelIndex::Anchor::kBoundingBox, TbbFor());
  EXPECT_EQ(parallel.order, serial.order);
  EXPECT_EQ(parallel.cell_of, serial.cell_of);
  EXPECT_EQ(parallel.cell_start, serial.cell_start);
  EXPECT_EQ(parallel.nb, serial.nb);
}

TEST(TbbFor, EmptyRangeCallsNothing) {
  int calls = 0;
  TbbFor()(5, 5, 1, [&](size_t, size_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

}  // namespace
}  // namespace furnihost
