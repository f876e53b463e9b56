// furnihost::parallel: TbbFor hands out disjoint sub-ranges that cover [begin, end) exactly
// once, and VoxelIndex::Build and SortedByKey over it equal the serial ones.
#include "parallel/tbb_for.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <numeric>
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

// Several chunks (n > 2 x 65536), many ties, and each width: one pass, several passes, the full
// 32 bits, and a wider key (the unpacked sort).
TEST(TbbFor, SortedByKeyIsTheStableSortByKey) {
  std::mt19937_64 rng(4);
  for (int bits : {5, 11, 22, 32, 40}) {
    SCOPED_TRACE(bits);
    std::vector<uint64_t> key(200003);
    for (auto& k : key) k = rng() & ((uint64_t(1) << bits) - 1);
    std::vector<uint32_t> want(key.size());
    std::iota(want.begin(), want.end(), 0u);
    std::stable_sort(want.begin(), want.end(), [&](uint32_t a, uint32_t b) { return key[a] < key[b]; });
    EXPECT_EQ(SortedByKey(key, bits, TbbFor()), want);
    EXPECT_EQ(SortedByKey(key, bits), want);
  }
  EXPECT_TRUE(SortedByKey(std::vector<uint64_t>(), 8, TbbFor()).empty());
}

TEST(TbbFor, VoxelIndexOriginIsThePointsMinimumCorner) {
  const std::vector<Eigen::Vector3f> pts = {{1.f, -2.f, 0.5f}, {-0.25f, 3.f, 0.75f}, {0.5f, 0.f, -1.f}};
  VoxelIndex index;
  index.Build(pts, 0.5f, VoxelIndex::Anchor::kBoundingBox, TbbFor());
  EXPECT_EQ(index.Origin(), Eigen::Vector3f(-0.25f, -2.f, -1.f));
}

TEST(TbbFor, EmptyRangeCallsNothing) {
  int calls = 0;
  TbbFor()(5, 5, 1, [&](size_t, size_t) { ++calls; });
  EXPECT_EQ(calls, 0);
}

}  // namespace
}  // namespace furnihost
