// segmenters.cgal_efficient_ransac through the registry. The box scene shared with the other
// alternatives is in plugins/segmenters/pcl_region_growing/test_segmenter_comparison.cpp.
#include <random>

#include "labelled_scene.hpp"

namespace furnihost::testing {
namespace {

const char* kType = "segmenters.cgal_efficient_ransac";

std::shared_ptr<Segmenter> Make(const Registry& reg, const nlohmann::json& params = nlohmann::json::object()) {
  return MakeSegmenter(reg, kType, params);
}

// Labels: 0 floor, 1 wall, 2 vertical cylinder (MakeFloorWallCylinder), 3 a 30-point blob
// (too small for a shape, big enough for a part), 4 a 5-point blob (discarded).
using Scene = LabelledScene;

Scene MakeScene() {
  Scene s = MakeFloorWallCylinder(3);
  std::uniform_real_distribution<float> u(-0.02f, 0.02f);
  for (int i = 0; i < 30; ++i) s.Add({0.2f + u(s.rng), 0.3f + u(s.rng), 1.5f + u(s.rng)}, 3);
  for (int i = 0; i < 5; ++i) s.Add({-0.5f + 0.005f * i, 0.5f, 2.5f}, 4);
  return s;
}

struct Score {
  std::vector<double> recall, purity;
};

Score ScoreLabels(const Scene& s, const Segmentation& seg) {
  Score r{std::vector<double>(5, 0.0), std::vector<double>(5, 0.0)};
  std::vector<int> size(5, 0);
  for (int l : s.label) ++size[l];
  for (const auto& part : seg.parts) {
    std::vector<int> c(5, 0);
    for (int i : part.indices) ++c[s.label[i]];
    for (int l = 0; l < 5; ++l)
      if (double(c[l]) / size[l] > r.recall[l]) {
        r.recall[l] = double(c[l]) / size[l];
        r.purity[l] = double(c[l]) / double(part.indices.size());
      }
  }
  return r;
}

void ExpectWellFormed(const Scene& s, const Segmentation& seg) {
  const size_t n = s.scan.points.size();
  ASSERT_EQ(seg.normals.size(), n);
  ASSERT_EQ(seg.curvature.size(), n);
  std::vector<char> seen(n, 0);
  size_t assigned = 0;
  for (const auto& part : seg.parts)
    for (int i : part.indices) {
      ASSERT_TRUE(i >= 0 && size_t(i) < n);
      ASSERT_FALSE(seen[i]);
      seen[i] = 1;
      ++assigned;
    }
  EXPECT_EQ(size_t(seg.discarded_points), n - assigned);
}

// Floor and wall: one part each holding >= 85 % of them, >= 95 % pure. Blob of 30: a part
// (>= 90 % of it). Blob of 5: in no part.
void ExpectPlanesAndBlobs(const Scene& s, const Segmentation& seg) {
  ExpectWellFormed(s, seg);
  const Score sc = ScoreLabels(s, seg);
  for (int l = 0; l < 2; ++l) {
    EXPECT_GE(sc.recall[l], 0.85) << "plane " << l;
    EXPECT_GE(sc.purity[l], 0.95) << "plane " << l;
  }
  EXPECT_GE(sc.recall[3], 0.9);
  EXPECT_EQ(sc.recall[4], 0.0);
  EXPECT_GE(seg.discarded_points, 5);
}

TEST(CgalEfficientRansac, PlanesCylinderAndLeftoverGroups) {
  auto reg = MakeRegistry();
  const Scene s = MakeScene();
  const Segmentation seg = Make(*reg)->Segment(s.scan, RunContext{});
  ExpectPlanesAndBlobs(s, seg);
  // With cylinders on, most of the cylinder is one part (>= 70 %: the shape's epsilon band
  // and normal test drop some of its points), >= 95 % pure.
  const Score sc = ScoreLabels(s, seg);
  EXPECT_GE(sc.recall[2], 0.70);
  EXPECT_GE(sc.purity[2], 0.95);
  for (size_t i = 0; i < s.scan.points.size(); ++i)
    if (seg.normals[i].allFinite()) {
      EXPECT_NEAR(seg.normals[i].norm(), 1.f, 1e-3f);
      EXPECT_GT(seg.normals[i].dot(*s.scan.origin - s.scan.points[i]), 0.f) << i;
    }
}

TEST(CgalEfficientRansac, PlanesOnlySplitsTheCylinder) {
  auto reg = MakeRegistry();
  const Scene s = MakeScene();
  const Segmentation seg = Make(*reg, {{"shapes", "planes"}, {"normals", "pca"}})->Segment(s.scan, RunContext{});
  ExpectPlanesAndBlobs(s, seg);
  // No single part can hold most of the cylinder when only planes are fitted (a plane's
  // +-1 cm band and 25 deg normal cone cover well under half of it).
  EXPECT_LT(ScoreLabels(s, seg).recall[2], 0.5);
}

TEST(CgalEfficientRansac, DeterministicForASeed) {
  auto reg = MakeRegistry();
  auto seg = Make(*reg);
  const Scene s = MakeScene();
  RunContext a, b;
  a.seed = b.seed = 1234;
  const Segmentation x = seg->Segment(s.scan, a), y = seg->Segment(s.scan, b);
  ASSERT_EQ(x.parts.size(), y.parts.size());
  for (size_t p = 0; p < x.parts.size(); ++p) EXPECT_EQ(x.parts[p].indices, y.parts[p].indices);
  RunContext c;
  c.seed = 99;
  ExpectPlanesAndBlobs(s, seg->Segment(s.scan, c));  // another seed, same quality
}

}  // namespace
}  // namespace furnihost::testing
