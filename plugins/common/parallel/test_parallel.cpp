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

// Each cell's neighbours are exactly the occupied cells within one step on every axis, in
// ascending order, on a sparse cloud (clumps and wide gaps: the cursors skip far at times), and
// NeighbourRuns groups them into maximal runs of consecutive cells (NeighbourSlotRuns: their
// slots).
TEST(TbbFor, VoxelIndexNeighboursAreTheAdjacentCells) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.f, 3.f), v(-0.05f, 0.05f);
  std::vector<Eigen::Vector3f> pts;
  for (int k = 0; k < 300; ++k) {
    const Eigen::Vector3f c(u(rng), u(rng), u(rng));
    for (int j = 0; j < 10; ++j) pts.push_back(c + Eigen::Vector3f(v(rng), v(rng), v(rng)));
  }
  VoxelIndex index;
  index.Build(pts, 0.04f, VoxelIndex::Anchor::kBoundingBox, TbbFor());
  const int cells = index.NumCells();
  ASSERT_GT(cells, 1000);
  std::vector<int> first, last;
  for (int c = 0; c < cells; ++c) {
    const Eigen::Vector3i a = index.CellCoords(c);
    std::vector<int> want;
    for (int d = 0; d < cells; ++d)
      if ((index.CellCoords(d) - a).cwiseAbs().maxCoeff() <= 1) want.push_back(d);
    const std::vector<int> got(index.nb.begin() + index.nb_start[c], index.nb.begin() + index.nb_start[c + 1]);
    ASSERT_EQ(got, want) << "cell " << c;
    index.NeighbourRuns(c, first, last);
    std::vector<int> joined;
    for (size_t r = 0; r < first.size(); ++r) {
      if (r > 0) {
        EXPECT_NE(last[r - 1] + 1, first[r]) << "cell " << c << ": runs " << r - 1 << " and " << r << " touch";
      }
      for (int d = first[r]; d <= last[r]; ++d) joined.push_back(d);
    }
    EXPECT_EQ(joined, want) << "cell " << c;
    EXPECT_LE(first.size(), 9u);
    // As slot ranges: each run's cells' slots, and their count.
    std::vector<int> b, e;
    int slots = 0;
    for (int d : want) slots += index.cell_start[d + 1] - index.cell_start[d];
    EXPECT_EQ(index.NeighbourSlotRuns(c, b, e), slots) << "cell " << c;
    ASSERT_EQ(b.size(), first.size());
    for (size_t r = 0; r < b.size(); ++r) {
      EXPECT_EQ(b[r], index.cell_start[first[r]]);
      EXPECT_EQ(e[r], index.cell_start[last[r] + 1]);
    }
  }
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
