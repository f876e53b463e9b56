// The swappable segmenters side by side: each is created by type name through the registry
// with its declared defaults and run on the same box scene (7 planes: floor + 6 box faces,
// 1 cm grid, 1 mm noise). All must find the 7 planes (same tolerances for all of them);
// the part counts are printed so the alternatives can be compared in the log.
#include <algorithm>
#include <cstdio>

#include "box_scene.hpp"
#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace furnihost::testing {
namespace {

class SegmenterComparison : public ::testing::TestWithParam<const char*> {};

TEST_P(SegmenterComparison, BoxSceneGivesSevenPlanarParts) {
  const std::string type = GetParam();
  auto reg = MakeRegistry();
  const PluginEntry* e = reg->Find(type);
  ASSERT_NE(e, nullptr) << type << " not found in " << PluginDir();
  auto seg = reg->CreateAs<Segmenter>(type, e->params.Resolve(nlohmann::json::object(), "test"));
  const BoxScene s = MakeBoxScene();
  const Segmentation out = seg->Segment(s.scan, RunContext{});
  ExpectWellFormed(s.scan, out);

  // Tolerances shared by all alternatives: one part per plane holding >= 75 % of it, >= 90 %
  // pure, 7 parts of >= 500 points (a quarter of the smallest face), <= 15 % unassigned.
  const FaceScore sc = ScoreFaces(s, out, 500);
  std::printf("%-36s parts %3zu  large %d  unassigned %5d / %zu\n", type.c_str(), out.parts.size(),
              sc.large_parts, out.discarded_points, s.scan.points.size());
  for (const auto& part : out.parts) {
    if (part.indices.size() < 500) continue;
    std::vector<int> count(s.faces, 0);
    for (int i : part.indices) ++count[s.face[i]];
    const int f = int(std::max_element(count.begin(), count.end()) - count.begin());
    std::printf("  part of %5zu points: %5.1f %% from face %d\n", part.indices.size(),
                100.0 * count[f] / double(part.indices.size()), f);
  }
  EXPECT_EQ(sc.large_parts, 7);
  for (int f = 0; f < s.faces; ++f) {
    EXPECT_GE(sc.recall[f], 0.75) << "face " << f;
    EXPECT_GE(sc.purity[f], 0.90) << "face " << f;
  }
  EXPECT_LE(out.discarded_points, int(0.15 * double(s.scan.points.size())));
  // Distinct faces, distinct parts.
  for (int f = 0; f < s.faces; ++f)
    for (int g = f + 1; g < s.faces; ++g) EXPECT_NE(sc.best_part[f], sc.best_part[g]);
}

// Without a sensor origin every alternative orients its normals towards the scan frame's
// origin (PCL's convention), so their outputs stay interchangeable.
TEST_P(SegmenterComparison, NormalsFaceTheScanOriginWithoutASensor) {
  const std::string type = GetParam();
  auto reg = MakeRegistry();
  const PluginEntry* e = reg->Find(type);
  ASSERT_NE(e, nullptr) << type << " not found in " << PluginDir();
  auto seg = reg->CreateAs<Segmenter>(type, e->params.Resolve(nlohmann::json::object(), "test"));
  BoxScene s = MakeBoxScene(0.02f, 0.001f, 7, Eigen::Vector3f(2.f, 1.f, -1.f));
  s.scan.origin.reset();
  const Segmentation out = seg->Segment(s.scan, RunContext{});
  ASSERT_EQ(out.normals.size(), s.scan.points.size());
  int finite = 0;
  for (size_t i = 0; i < s.scan.points.size(); ++i)
    if (out.normals[i].allFinite()) {
      ++finite;
      EXPECT_GE(out.normals[i].dot(-s.scan.points[i]), 0.f) << i;
    }
  EXPECT_GT(finite, int(0.9 * double(s.scan.points.size())));
}

INSTANTIATE_TEST_SUITE_P(Alternatives, SegmenterComparison,
                         ::testing::Values("segmenters.pcl_region_growing",
                                           "segmenters.cgal_region_growing",
                                           "segmenters.cgal_efficient_ransac"),
                         [](const auto& info) {
                           std::string n = info.param;
                           return n.substr(n.find('.') + 1);
                         });

}  // namespace
}  // namespace furnihost::testing
