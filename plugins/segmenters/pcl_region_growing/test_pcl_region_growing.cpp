// segmenters.pcl_region_growing through the registry, on the box scene of box_scene.hpp.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include "box_scene.hpp"
#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace furnihost::testing {
namespace {

const char* kType = "segmenters.pcl_region_growing";

std::shared_ptr<Segmenter> Make(const Registry& reg, nlohmann::json params = nlohmann::json::object()) {
  const PluginEntry* e = reg.Find(kType);
  if (!e) throw std::runtime_error(std::string(kType) + " not found in " + PluginDir());
  return reg.CreateAs<Segmenter>(kType, e->params.Resolve(params, "test"));
}

// Every face of the box and the floor must be one part: >= 80 % of the face's points in
// one part (the rest are edge points whose normals lean > 40 deg), >= 95 % of that part
// from that face, and exactly 7 parts of >= 500 points (a quarter of the smallest face).
void ExpectSevenPlanes(const BoxScene& s, const Segmentation& seg) {
  ExpectWellFormed(s.scan, seg);
  const FaceScore sc = ScoreFaces(s, seg, 500);
  EXPECT_EQ(sc.large_parts, 7);
  for (int f = 0; f < s.faces; ++f) {
    EXPECT_GE(sc.recall[f], 0.80) << "face " << f;
    EXPECT_GE(sc.purity[f], 0.95) << "face " << f;
  }
}

// Floor points away from the box and its border: angle of the normal to +z. With 1 mm noise
// and ~28 neighbours in 3 cm, a PCA normal's error is ~0.5 deg rms, so the mean must stay
// below `mean_deg` and 95 % of the points below `p95_deg`; none may be unknown.
void ExpectFloorNormals(const BoxScene& s, const Segmentation& seg, const Eigen::Vector3f& offset,
                        double mean_deg, double p95_deg) {
  std::vector<double> err;
  for (size_t i = 0; i < s.scan.points.size(); ++i) {
    const Eigen::Vector3f p = s.scan.points[i] - offset;
    if (s.face[i] != 0 || (std::abs(p.x()) < 0.4f && std::abs(p.y()) < 0.3f)) continue;
    if (std::abs(p.x()) > 0.75f || std::abs(p.y()) > 0.75f) continue;  // floor border
    ASSERT_TRUE(seg.normals[i].allFinite()) << i;
    err.push_back(std::acos(std::clamp(double(seg.normals[i].z()), -1.0, 1.0)) * 180.0 / M_PI);
  }
  ASSERT_GT(err.size(), 10000u);
  std::sort(err.begin(), err.end());
  const double mean = std::accumulate(err.begin(), err.end(), 0.0) / double(err.size());
  const double p95 = err[err.size() * 95 / 100];
  std::printf("floor normal error: mean %.2f deg, p95 %.2f deg, max %.2f deg\n", mean, p95, err.back());
  EXPECT_LT(mean, mean_deg);
  EXPECT_LT(p95, p95_deg);
}

TEST(PclRegionGrowing, OmpNormalsSegmentBoxIntoSevenPlanes) {
  auto reg = MakeRegistry();
  const BoxScene s = MakeBoxScene();
  const Segmentation seg = Make(*reg)->Segment(s.scan, RunContext{});
  ExpectSevenPlanes(s, seg);
  ExpectFloorNormals(s, seg, Eigen::Vector3f::Zero(), 1.0, 2.0);
  // Every finite normal faces the sensor.
  for (size_t i = 0; i < s.scan.points.size(); ++i)
    if (seg.normals[i].allFinite()) {
      EXPECT_GT(seg.normals[i].dot(*s.scan.origin - s.scan.points[i]), 0.f) << i;
    }
}

TEST(PclRegionGrowing, MlsNormalsSegmentBoxIntoSevenPlanes) {
  auto reg = MakeRegistry();
  const BoxScene s = MakeBoxScene();
  const Segmentation seg = Make(*reg, {{"normals", "mls"}})->Segment(s.scan, RunContext{});
  ExpectSevenPlanes(s, seg);
  ExpectFloorNormals(s, seg, Eigen::Vector3f::Zero(), 1.0, 2.0);
}

TEST(PclRegionGrowing, MapCoordinatesFarFromOrigin) {
  auto reg = MakeRegistry();
  const Eigen::Vector3f offset(500.f, -800.f, 0.f);
  const BoxScene s = MakeBoxScene(0.01f, 0.001f, 7, offset);
  const Segmentation seg = Make(*reg)->Segment(s.scan, RunContext{});
  ExpectSevenPlanes(s, seg);
  ExpectFloorNormals(s, seg, offset, 1.0, 2.0);
}

TEST(PclRegionGrowing, SmallIsolatedClusterIsDiscardedAndCounted) {
  auto reg = MakeRegistry();
  BoxScene s = MakeBoxScene();
  const size_t first = s.scan.points.size();
  for (int i = 0; i < 6; ++i) {  // 6 < min_points = 10, 2 m away from everything
    s.scan.points.emplace_back(3.f + 0.01f * float(i), 3.f, 0.5f + 0.002f * float(i % 2));
    s.face.push_back(0);
  }
  const Segmentation seg = Make(*reg)->Segment(s.scan, RunContext{});
  ExpectWellFormed(s.scan, seg);
  for (const auto& part : seg.parts)
    for (int i : part.indices) EXPECT_LT(size_t(i), first);
  EXPECT_GE(seg.discarded_points, 6);
}

TEST(PclRegionGrowing, DeterministicAndEmptyInput) {
  auto reg = MakeRegistry();
  auto seg = Make(*reg);
  const BoxScene s = MakeBoxScene(0.02f);
  const Segmentation a = seg->Segment(s.scan, RunContext{}), b = seg->Segment(s.scan, RunContext{});
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t p = 0; p < a.parts.size(); ++p) EXPECT_EQ(a.parts[p].indices, b.parts[p].indices);
  const Segmentation e = seg->Segment(Scan{}, RunContext{});
  EXPECT_TRUE(e.parts.empty());
  EXPECT_TRUE(e.normals.empty());
  EXPECT_EQ(e.discarded_points, 0);
}

// Copies of points are segmented as their distinct positions and spread back (PCL's k-d tree
// would take N^2 on them): the box scene with every point stored 3 times gives each copy its
// point's part and normal, and a million copies of one point finish (one position: too small
// for a part, all discarded).
TEST(PclRegionGrowing, CopiesTakeTheirPointsPartAndNormal) {
  auto reg = MakeRegistry();
  auto seg = Make(*reg);
  const BoxScene s = MakeBoxScene(0.02f);
  Scan copies = s.scan;
  for (int c = 0; c < 2; ++c) copies.points.insert(copies.points.end(), s.scan.points.begin(), s.scan.points.end());
  const Segmentation a = seg->Segment(s.scan, RunContext{}), b = seg->Segment(copies, RunContext{});
  const size_t n = s.scan.points.size();
  ExpectWellFormed(copies, b);
  ASSERT_EQ(b.parts.size(), a.parts.size());
  for (size_t p = 0; p < a.parts.size(); ++p) {
    std::vector<int> expect;
    for (int c = 0; c < 3; ++c)
      for (int i : a.parts[p].indices) expect.push_back(i + int(c * n));
    EXPECT_EQ(b.parts[p].indices, expect) << "part " << p;
    EXPECT_LT((b.parts[p].centroid - a.parts[p].centroid).norm(), 1e-4f) << "part " << p;
  }
  for (size_t i = 0; i < copies.points.size(); ++i) {
    const Eigen::Vector3f& x = a.normals[i % n];
    if (x.allFinite()) {
      EXPECT_EQ(b.normals[i], x) << i;
    }
  }
  EXPECT_EQ(b.discarded_points, 3 * a.discarded_points);
  Scan same;
  same.points.assign(1000000, Eigen::Vector3f(0.f, 0.f, 0.f));
  const Segmentation f = seg->Segment(same, RunContext{});
  EXPECT_TRUE(f.parts.empty());
  EXPECT_EQ(f.discarded_points, 1000000);
}

TEST(PclRegionGrowing, RejectsMaxBelowMin) {
  auto reg = MakeRegistry();
  EXPECT_ANY_THROW(Make(*reg, {{"min_points", 50}, {"max_points", 20}}));
  EXPECT_ANY_THROW(Make(*reg, {{"normals", "pca"}}));  // not a declared choice
}

}  // namespace
}  // namespace furnihost::testing
