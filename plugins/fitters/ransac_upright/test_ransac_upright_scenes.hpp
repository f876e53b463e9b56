// Scenes and helpers of the fitters.ransac_upright tests: the fitter through the registry, a catalog
// of box furniture, ray-cast scans of it (synthetic_scene.hpp), voter-like hypotheses and pose errors.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "furnihost/geometry.hpp"
#include "furnihost/stage.hpp"
#include "synthetic_scene.hpp"
#include "test_support.hpp"

namespace ransac_test {

using namespace furnihost;
using namespace furnihost::synthetic;

constexpr float kPi = 3.14159265358979f;
constexpr float kCentreTol = 0.03f;           // [m]
constexpr float kYawTol = 5.f * kPi / 180.f;  // [rad]

inline std::shared_ptr<Fitter> MakeFitter(const nlohmann::json& params = nlohmann::json::object()) {
  static const auto reg = furnihost::testing::MakeRegistry();
  const PluginEntry* e = reg->Find("fitters.ransac_upright");
  if (!e) throw std::runtime_error("fitters.ransac_upright not found in " + furnihost::testing::PluginDir());
  return reg->CreateAs<Fitter>("fitters.ransac_upright", e->params.Resolve(params, "test"));
}

inline float AngleDiff(float a, float b, float period = 2 * kPi) {
  float d = std::fmod(std::fabs(a - b), period);
  return std::min(d, period - d);
}

inline Eigen::Isometry3f Upright(float x, float y, float yaw) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3f(x, y, 0.f);
  return t;
}

// Catalog of box furniture; meshes follow the catalog convention (bbox bottom centre at 0).
struct Catalog {
  std::vector<CatalogModel> models;
  std::vector<const CatalogModel*> Ptrs() const {
    std::vector<const CatalogModel*> p;
    for (const auto& m : models) p.push_back(&m);
    return p;
  }
  const CatalogModel& Get(const std::string& id) const {
    for (const auto& m : models)
      if (m.id == id) return m;
    throw std::runtime_error("no model " + id);
  }
};

inline Catalog FurnitureCatalog() {
  Catalog c;
  c.models.push_back(Model("chair_a", "chair", Chair(0.45f, 0.45f, 0.45f, 0.45f).mesh));
  c.models.push_back(Model("chair_b", "chair", Chair(0.56f, 0.50f, 0.40f, 0.62f, 0.05f).mesh));
  c.models.push_back(Model("table_a", "table", Table(1.2f, 0.8f, 0.75f).mesh));
  return c;
}

// Scans and segmentations that FitContext points into (kept at stable addresses).
struct Scenes {
  std::vector<std::unique_ptr<SimScan>> scans;
  std::vector<std::unique_ptr<Segmentation>> segs;
  int Add(SimScan s, int object, std::vector<int>* parts) {
    scans.push_back(std::make_unique<SimScan>(std::move(s)));
    std::vector<int> dummy;
    segs.push_back(std::make_unique<Segmentation>(PartsOf(*scans.back(), object, parts ? parts : &dummy)));
    return static_cast<int>(scans.size()) - 1;
  }
  FitContext Ctx(const Catalog& cat, int threads = 0, uint64_t seed = 7) const {
    FitContext ctx;
    for (size_t i = 0; i < scans.size(); ++i) ctx.scenes.push_back({&scans[i]->scan, segs[i].get(), nullptr});
    ctx.catalog = cat.Ptrs();
    ctx.run.seed = seed;
    ctx.run.threads = threads;
    return ctx;
  }
};

// A voter-like hypothesis: its centre is the mean of its parts' points (world frame); invalid
// scene or part numbers are kept in the support (the fitter must refuse them).
inline Detection Hypothesis(const Scenes& sc, const std::string& cls, int scene, const std::vector<int>& parts) {
  Detection d;
  d.cls = cls;
  d.score = 1.f;
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  int n = 0;
  for (int p : parts) {
    d.support.push_back({scene, p, 1.f});
    if (scene < 0 || scene >= int(sc.scans.size()) || p < 0 || p >= int(sc.segs[scene]->parts.size())) continue;
    const Scan& scan = sc.scans[scene]->scan;
    for (int i : sc.segs[scene]->parts[p].indices) {
      sum += scan.pose * scan.points[i];
      ++n;
    }
  }
  if (n > 0) d.center = sum / float(n);
  return d;
}

const Eigen::Vector3f kSensor(0.f, 0.f, 1.3f);
// The scan frame differs from the world frame, so that Scan::pose is exercised.
const Eigen::Isometry3f kScanPose = Upright(0.4f, -0.3f, 0.5f);

// One object of the catalog placed in a room and scanned from kSensor.
inline SimScan ScanOf(const CatalogModel& m, const Eigen::Isometry3f& pose, uint64_t seed, bool with_origin = true,
               bool object_present = true, int rays = 90) {
  World w;
  w.AddRoom(5.f, 2.5f);
  Furniture f;
  f.mesh = m.mesh;
  f.component.assign(m.mesh.triangles.size(), 0);
  // Components = the 12 triangles of each box, which is how the furniture was built.
  for (size_t t = 0; t < f.component.size(); ++t) f.component[t] = static_cast<int>(t / 12);
  if (object_present) w.Add(f.mesh, pose, 0, &f.component);
  const Eigen::Vector3f centre = pose * BoundsOf(m.mesh).center();
  const float radius = 0.5f * m.size.norm() + 0.1f;
  // ~90 x 90 rays over the object's angular box: about 2-3k points on a chair at 2 m.
  return SimulateObject(w, kSensor, centre, radius, rays, 0.003f, 0.05f, seed, kScanPose, with_origin);
}

struct PoseError {
  float centre, yaw;
};
inline PoseError ErrorOf(const Detection& d, const CatalogModel& m, const Eigen::Isometry3f& truth, float period = 2 * kPi) {
  const Eigen::Vector3f c = truth * BoundsOf(m.mesh).center();
  const float yaw = std::atan2(truth.linear()(1, 0), truth.linear()(0, 0));
  return {(d.center - c).norm(), AngleDiff(d.yaw, yaw, period)};
}

// The chair most tests fit: chair_a at kChairPose, scanned from kSensor (scan seed 1); returns
// its scene index and fills its parts.
const Eigen::Isometry3f kChairPose = Upright(1.8f, 0.9f, 2.2f);
inline int AddChair(const Catalog& cat, Scenes* sc, std::vector<int>* parts) {
  return sc->Add(ScanOf(cat.Get("chair_a"), kChairPose, 1), 0, parts);
}

// The same fit, bit for bit (seeds, threads and caches must not change it).
inline void ExpectSameFit(const Detection& a, const Detection& b) {
  EXPECT_EQ(a.model, b.model);
  EXPECT_EQ(a.yaw, b.yaw);
  EXPECT_EQ(a.center, b.center);
  EXPECT_EQ(a.coverage, b.coverage);
  EXPECT_EQ(a.rms, b.rms);
  EXPECT_EQ(a.free_space_ratio, b.free_space_ratio);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.verified, b.verified);
  EXPECT_EQ(a.Rejection(), b.Rejection());
  EXPECT_EQ(a.checks.size(), b.checks.size());
  EXPECT_TRUE(a.model_pose.matrix() == b.model_pose.matrix());
}

}  // namespace ransac_test
