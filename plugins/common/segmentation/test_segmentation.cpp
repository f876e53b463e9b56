// furnihost::segmentation below the plugins: copies.hpp (equal points grouped, -0 folded onto
// +0, a scan without copies left alone, a segmentation of the distinct positions spread back
// over the copies). cgal_normals.hpp is covered by the two CGAL segmenters' tests.
#include "segmentation/copies.hpp"

#include <gtest/gtest.h>

namespace furnihost {
namespace {

TEST(Copies, ScanWithoutCopiesIsLeftAlone) {
  Scan scan;
  scan.points = {{0.f, 0.f, 0.f}, {1.f, 0.f, 0.f}, {0.f, 1.f, 0.f}};
  const ScanCopies c = FindCopies(scan);
  EXPECT_FALSE(c.any);
  EXPECT_TRUE(c.of.empty());
}

TEST(Copies, GroupsEqualPointsAndFoldsNegativeZero) {
  Scan scan;
  scan.source = "s";
  scan.points = {{0.f, 0.f, 0.f}, {1.f, 2.f, 3.f}, {-0.f, 0.f, -0.f}, {1.f, 2.f, 3.f}, {0.f, 0.f, 0.f}};
  const ScanCopies c = FindCopies(scan);
  ASSERT_TRUE(c.any);
  ASSERT_EQ(c.distinct.points.size(), 2u);
  EXPECT_EQ(c.of, (std::vector<uint32_t>{0, 1, 0, 1, 0}));
  EXPECT_EQ(c.distinct.source, "s");
}

TEST(Copies, SegmentationSpreadsOverTheCopies) {
  Scan scan;
  scan.points = {{0.f, 0.f, 0.f}, {1.f, 0.f, 0.f}, {0.f, 0.f, 0.f}, {5.f, 5.f, 5.f}, {5.f, 5.f, 5.f}};
  const ScanCopies c = FindCopies(scan);
  ASSERT_EQ(c.distinct.points.size(), 3u);
  // The segmenter's view: positions 0 and 1 form a part, position 2 (5, 5, 5) is discarded.
  Segmentation d;
  d.normals = {{0.f, 0.f, 1.f}, {0.f, 0.f, 1.f}, {1.f, 0.f, 0.f}};
  d.curvature = {0.1f, 0.2f, 0.3f};
  Part part;
  part.indices = {0, 1};
  d.parts.push_back(part);
  d.discarded_points = 1;
  const Segmentation s = SpreadOverCopies(d, c, scan);
  ASSERT_EQ(s.normals.size(), 5u);
  EXPECT_EQ(s.curvature, (std::vector<float>{0.1f, 0.2f, 0.1f, 0.3f, 0.3f}));
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].indices, (std::vector<int>{0, 1, 2}));
  EXPECT_TRUE(s.parts[0].centroid.isApprox(Eigen::Vector3f(1.f / 3.f, 0.f, 0.f)));
  EXPECT_EQ(s.discarded_points, 2);  // the second copy of (5, 5, 5) too
}

}  // namespace
}  // namespace furnihost
