// segmenters.cgal_region_growing through the registry. The box scene shared with the other
// alternatives is in plugins/segmenters/pcl_region_growing/test_segmenter_comparison.cpp.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "labelled_scene.hpp"

namespace furnihost::testing {
namespace {

const char* kType = "segmenters.cgal_region_growing";

std::shared_ptr<Segmenter> Make(const Registry& reg, const nlohmann::json& params = nlohmann::json::object()) {
  return MakeSegmenter(reg, kType, params);
}

// Labels: 0 floor, 1 wall, 2 vertical cylinder (MakeFloorWallCylinder).
using Scene = LabelledScene;

Scene MakeScene(const Eigen::Vector3f& offset = Eigen::Vector3f::Zero()) { return MakeFloorWallCylinder(11, offset); }

double AngleDeg(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::acos(std::clamp(double(a.dot(b)), -1.0, 1.0)) * 180.0 / M_PI;
}

// Floor and wall each one part (>= 85 % of their points, >= 95 % pure); the cylinder is split
// into several parts (planar regions only), each part's normals within 2 * angle_deg + 5 deg
// of each other (every member is within angle_deg of the part's plane normal).
void ExpectPlanesAndFacets(const Scene& s, const Segmentation& seg, double angle_deg) {
  const size_t n = s.scan.points.size();
  ASSERT_EQ(seg.normals.size(), n);
  ASSERT_EQ(seg.curvature.size(), n);
  std::vector<int> size(3, 0), best(3, 0), best_total(3, 1);
  size_t assigned = 0;
  int cylinder_parts = 0;
  for (const auto& part : seg.parts) {
    std::vector<int> c(3, 0);
    for (int i : part.indices) ++c[s.label[i]];
    assigned += part.indices.size();
    for (int l = 0; l < 3; ++l)
      if (c[l] > best[l]) best[l] = c[l], best_total[l] = int(part.indices.size());
    if (c[2] * 2 > int(part.indices.size())) {
      ++cylinder_parts;
      double spread = 0;
      for (size_t a = 0; a < part.indices.size(); a += 7)
        for (size_t b = a + 1; b < part.indices.size(); b += 7) {
          const auto& na = seg.normals[part.indices[a]];
          const auto& nb = seg.normals[part.indices[b]];
          // |cos|: CGAL compares unoriented normals.
          if (na.allFinite() && nb.allFinite()) spread = std::max(spread, AngleDeg(na, nb.dot(na) < 0 ? -nb : nb));
        }
      EXPECT_LE(spread, 2 * angle_deg + 5.0);
    }
  }
  for (int l : s.label) ++size[l];
  for (int l = 0; l < 2; ++l) {
    EXPECT_GE(double(best[l]) / size[l], 0.85) << "plane " << l;
    EXPECT_GE(double(best[l]) / best_total[l], 0.95) << "plane " << l;
  }
  EXPECT_GE(cylinder_parts, 2);
  EXPECT_EQ(size_t(seg.discarded_points), n - assigned);
}

// Normals: unit, towards the sensor. Floor interior (away from the cylinder and borders):
// the mean angle to +z below `mean_deg`, 95 % of the points below `p95_deg`.
void ExpectFloorNormals(const Scene& s, const Segmentation& seg, double mean_deg, double p95_deg,
                        const char* what, const Eigen::Vector3f& offset = Eigen::Vector3f::Zero()) {
  std::vector<double> err;
  for (size_t i = 0; i < s.scan.points.size(); ++i) {
    const auto& nm = seg.normals[i];
    if (!nm.allFinite()) continue;
    EXPECT_NEAR(nm.norm(), 1.f, 1e-3f);
    EXPECT_GT(nm.dot(*s.scan.origin - s.scan.points[i]), 0.f) << i;
    const Eigen::Vector3f p = s.scan.points[i] - offset;
    if (s.label[i] == 0 && std::abs(p.x()) < 0.5f && std::abs(p.y()) < 0.5f &&
        (p.head<2>() - Eigen::Vector2f(-0.3f, 0.f)).norm() > 0.2f)
      err.push_back(AngleDeg(nm, Eigen::Vector3f::UnitZ()));
  }
  ASSERT_GT(err.size(), 5000u);
  std::sort(err.begin(), err.end());
  const double mean = std::accumulate(err.begin(), err.end(), 0.0) / double(err.size());
  const double p95 = err[err.size() * 95 / 100];
  std::printf("floor normal error (%s): mean %.2f deg, p95 %.2f deg, max %.2f deg\n", what, mean, p95, err.back());
  EXPECT_LT(mean, mean_deg);
  EXPECT_LT(p95, p95_deg);
}

TEST(CgalRegionGrowing, PlanesAreOnePartEachCylinderSplits) {
  auto reg = MakeRegistry();
  const Scene s = MakeScene();
  const Segmentation seg = Make(*reg)->Segment(s.scan, RunContext{});
  ExpectPlanesAndFacets(s, seg, 40.0);
  // Jet fitting (order 2 in 3 cm, 1 mm noise) spends degrees of freedom on the noise: its
  // normals are ~3x noisier than PCA's on a plane (see the variants test for PCA's bound).
  ExpectFloorNormals(s, seg, 4.0, 8.0, "jet");
}

TEST(CgalRegionGrowing, VariantsPcaKnnPlaneFitSeedsAndMapCoordinates) {
  auto reg = MakeRegistry();
  {
    const Scene s = MakeScene();
    const nlohmann::json p = {{"normals", "pca"}, {"neighbourhood", "knn"}, {"seed_order", "plane_fit"}, {"angle_deg", 25}};
    const Segmentation seg = Make(*reg, p)->Segment(s.scan, RunContext{});
    ExpectPlanesAndFacets(s, seg, 25.0);
    ExpectFloorNormals(s, seg, 1.0, 2.0, "pca");  // ~0.5 deg rms expected from the noise
  }
  {
    const Eigen::Vector3f offset(700.f, -400.f, 2.f);
    const Scene s = MakeScene(offset);
    const Segmentation seg = Make(*reg)->Segment(s.scan, RunContext{});
    ExpectPlanesAndFacets(s, seg, 40.0);
    ExpectFloorNormals(s, seg, 4.0, 8.0, "jet, map coordinates", offset);
  }
}

TEST(CgalRegionGrowing, DeterministicTinyAndNonFiniteInput) {
  auto reg = MakeRegistry();
  auto seg = Make(*reg);
  Scene s = MakeScene();
  s.scan.points[5] = Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  RunContext one;
  one.threads = 1;
  const Segmentation a = seg->Segment(s.scan, one), b = seg->Segment(s.scan, RunContext{});
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t p = 0; p < a.parts.size(); ++p) EXPECT_EQ(a.parts[p].indices, b.parts[p].indices);
  EXPECT_FALSE(a.normals[5].allFinite());
  for (const auto& part : a.parts)
    for (int i : part.indices) EXPECT_NE(i, 5);

  Scan tiny;
  tiny.points = {{0, 0, 0}, {0.01f, 0, 0}, {0, 0.01f, 0}};
  const Segmentation t = seg->Segment(tiny, RunContext{});
  EXPECT_TRUE(t.parts.empty());
  EXPECT_EQ(t.discarded_points, 3);
  EXPECT_EQ(t.normals.size(), 3u);
}

TEST(CgalRegionGrowing, RejectsAngleAboveNinety) {
  auto reg = MakeRegistry();
  EXPECT_ANY_THROW(Make(*reg, {{"angle_deg", 120}}));
}

}  // namespace
}  // namespace furnihost::testing
