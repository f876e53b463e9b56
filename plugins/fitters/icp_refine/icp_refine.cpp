// fitters.icp_refine — upright ICP refinement of fitted detections (chain it after
// fitters.ransac_upright).
//
// For every detection with a model: the catalog model's surface is sampled (area-weighted,
// `sample_density_per_m2`; once per stage object and seed, reused for later scans) and placed
// at Detection::model_pose; the scene points are the
// points of the detection's supporting parts (Detection::support -> scene, part), taken to
// the world frame by Scan::pose, plus optionally the scan points near the placed model.
// ICP aligns the scene points (source: partial views, every point has a model counterpart)
// to the placed model (target: complete surface); the model then moves by the inverse.
//
// Upright by construction: "icp" uses PCL's TransformationEstimation2D, whose every step is
// a rotation about the vertical axis plus an (x, y) translation — z and roll/pitch of the
// input pose are kept exactly. "gicp" (Generalized-ICP) optimises all 6 DoF in each step;
// here each step is projected back to (x, y, yaw) before the next correspondence search.
//
// Frames: world = z up. Everything is computed in a world-aligned frame centred on the
// input model position (float precision for map coordinates).
#include <pcl/common/transforms.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/transformation_estimation_2D.h>
#include <pcl/search/kdtree.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <set>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"

namespace {

using furnihost::ParamSchema;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

struct IcpRefineOptions {
  std::string method = "icp";         // "icp" (point-to-point, 2D estimation) | "gicp"
  double max_correspondence_m = 0.1;  // farther pairs are ignored [m]
  int max_iterations = 50;
  double sample_density_per_m2 = 10000;  // model surface samples per m^2 (1 cm spacing)
  long long seed = 0;                 // model sampling seed; 0 = the run's seed
  double nearby_radius_m = 0.0;       // also use scan points this close to the model; 0 = off
  double floor_margin_m = 0.02;       // nearby points this close above the model's bottom are ignored
  int min_points = 20;                // fewer scene points: detection left unchanged
  double max_move_m = 0.3;            // larger corrections are refused (ICP diverged)
  double max_turn_deg = 30.0;
};

// Each parameter declared once; its default is IcpRefineOptions{}'s.
const furnihost::ParamBinding<IcpRefineOptions>& Binding() {
  using O = IcpRefineOptions;
  static const auto b =
      furnihost::ParamBinding<O>()
          .Enum("method", &O::method, {"icp", "gicp"},
                "PCL point-to-point ICP with an (x, y, yaw) estimator, or Generalized-ICP projected upright each step")
          .Number("max_correspondence_m", &O::max_correspondence_m, 1e-4, 10.0, "m", "point pairs farther apart are ignored")
          .Int("max_iterations", &O::max_iterations, 1, 10000, "count", "ICP iterations at most")
          .Number("sample_density_per_m2", &O::sample_density_per_m2, 1.0, 1e7, "1/m2", "model surface samples per square metre")
          .Int("seed", &O::seed, 0, 9.2e18, "1", "model sampling seed; 0 = the run's seed")
          .Number("nearby_radius_m", &O::nearby_radius_m, 0.0, 1.0, "m",
                  "also align scan points within this distance of the placed model, not only the supporting parts; 0 = off")
          .Number("floor_margin_m", &O::floor_margin_m, 0.0, 1.0, "m",
                  "nearby points less than this above the model's bottom are ignored (keeps the floor out)")
          .Int("min_points", &O::min_points, 3, 1e9, "count", "detections with fewer scene points are left unchanged")
          .Number("max_move_m", &O::max_move_m, 0.0, 10.0, "m", "a correction moving the model farther is refused")
          .Number("max_turn_deg", &O::max_turn_deg, 0.0, 180.0, "deg", "a correction turning the model more is refused");
  return b;
}

// Rotation about +z by the yaw of `m` and translation (x, y, 0) of `m`.
Eigen::Matrix4f ProjectUpright(const Eigen::Matrix4f& m) {
  const float yaw = std::atan2(m(1, 0), m(0, 0));
  Eigen::Matrix4f r = Eigen::Matrix4f::Identity();
  r.topLeftCorner<2, 2>() = Eigen::Rotation2Df(yaw).toRotationMatrix();
  r(0, 3) = m(0, 3);
  r(1, 3) = m(1, 3);
  return r;
}

// Point-to-point ICP restricted to (x, y, yaw) by PCL's 2D estimator.
class UprightIcp : public pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> {
 public:
  UprightIcp() {
    setTransformationEstimation(
        std::make_shared<pcl::registration::TransformationEstimation2D<pcl::PointXYZ, pcl::PointXYZ>>());
  }
  int Iterations() const { return nr_iterations_; }
};

// Generalized-ICP whose every step is projected to (x, y, yaw) (see the file comment).
class UprightGicp : public pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> {
 public:
  int Iterations() const { return nr_iterations_; }
  UprightGicp() {
    rigid_transformation_estimation_ = [this](const Cloud& src, const pcl::Indices& is,
                                              const Cloud& tgt, const pcl::Indices& it,
                                              Eigen::Matrix4f& t) {
      estimateRigidTransformationBFGS(src, is, tgt, it, t);
      t = ProjectUpright(t);
    };
  }
};

class IcpRefine : public furnihost::Fitter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit IcpRefine(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  std::vector<furnihost::Detection> Fit(const std::vector<furnihost::Detection>& input,
                                        const furnihost::FitContext& ctx) override {
    std::vector<furnihost::Detection> out = input;
    // Each model used is sampled once per stage object (model frame), deterministic per
    // (seed, model id), and reused by later Fit calls (the scans of a run).
    const uint64_t seed = o_.seed != 0 ? uint64_t(o_.seed) : ctx.run.seed;
    std::map<std::string, std::shared_ptr<const furnihost::Points>> samples;
    for (const auto& d : input) {
      if (d.model.empty() || samples.count(d.model)) continue;
      const furnihost::CatalogModel* m = nullptr;
      for (const auto* c : ctx.catalog)
        if (c && c->id == d.model) m = c;
      if (!m) throw furnihost::StageError("detection of model \"" + d.model + "\": model not in the catalog");
      samples[d.model] = Samples(*m, seed);
    }
    // World-frame copies of the scans, only when a detection needs the nearby points.
    std::vector<furnihost::Points> world;
    if (o_.nearby_radius_m > 0) {
      world.resize(ctx.scenes.size());
      for (size_t s = 0; s < ctx.scenes.size(); ++s)
        if (ctx.scenes[s].scan) {
          const auto& sc = *ctx.scenes[s].scan;
          world[s].resize(sc.points.size());
          for (size_t i = 0; i < sc.points.size(); ++i) world[s][i] = sc.pose * sc.points[i];
        }
    }
    tbb::task_arena arena(ctx.run.threads > 0 ? ctx.run.threads : tbb::task_arena::automatic);
    arena.execute([&] {
      tbb::parallel_for(size_t(0), out.size(), [&](size_t k) {
        if (!out[k].model.empty()) Refine(out[k], *samples.at(out[k].model), ctx, world);
      });
    });
    return out;
  }

 private:
  // The sampled surface of `m` for `seed`, from the cache or sampled now.
  std::shared_ptr<const furnihost::Points> Samples(const furnihost::CatalogModel& m, uint64_t seed) {
    // The id alone could name another mesh in another catalog: key by the mesh size too.
    const std::string key = m.id + "|" + std::to_string(m.mesh.vertices.size()) + "|" +
                            std::to_string(m.mesh.triangles.size()) + "|" + std::to_string(seed);
    std::lock_guard<std::mutex> lock(mu_);
    auto it = cache_.find(key);
    if (it != cache_.end()) return it->second;
    auto pts = std::make_shared<const furnihost::Points>(
        furnihost::SampleSurface(m.mesh, float(o_.sample_density_per_m2), seed ^ furnihost::Fnv1a(m.id, furnihost::kFnvOffsetTruncated)));
    if (pts->size() < 3) throw furnihost::StageError("model \"" + m.id + "\" has no surface to sample");
    cache_.emplace(key, pts);
    return pts;
  }

  void Refine(furnihost::Detection& d, const furnihost::Points& model_pts,
              const furnihost::FitContext& ctx, const std::vector<furnihost::Points>& world) const {
    const Eigen::Vector3d c0 = d.model_pose.translation().cast<double>();
    auto local = [&](const Eigen::Vector3f& w) { return (w.cast<double>() - c0).cast<float>(); };

    // Target: the model placed at its current pose; c0 is its translation, so in the local
    // frame only the rotation remains (no float round trip through map coordinates).
    Cloud::Ptr target(new Cloud);
    target->resize(model_pts.size());
    float bottom = std::numeric_limits<float>::infinity();
    const Eigen::Matrix3f rot = d.model_pose.linear();
    for (size_t i = 0; i < model_pts.size(); ++i) {
      (*target)[i].getVector3fMap() = rot * model_pts[i];
      bottom = std::min(bottom, (*target)[i].z);
    }
    auto tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
    tree->setInputCloud(target);

    // Source: the supporting parts' points, then (optionally) nearby scan points.
    Cloud::Ptr source(new Cloud);
    std::set<std::pair<int, int>> used_parts;
    std::vector<std::vector<char>> taken(ctx.scenes.size());
    for (const auto& sup : d.support) {
      if (sup.scene < 0 || size_t(sup.scene) >= ctx.scenes.size())
        throw furnihost::StageError("support names scene " + std::to_string(sup.scene) + " of " +
                                    std::to_string(ctx.scenes.size()), false);
      const auto& sp = ctx.scenes[sup.scene];
      if (!sp.scan || !sp.segmentation)
        throw furnihost::StageError("scene " + std::to_string(sup.scene) + " has no scan or segmentation", false);
      if (sup.part < 0 || size_t(sup.part) >= sp.segmentation->parts.size())
        throw furnihost::StageError("support names part " + std::to_string(sup.part) + " of " +
                                    std::to_string(sp.segmentation->parts.size()), false);
      if (!used_parts.insert({sup.scene, sup.part}).second) continue;
      auto& tk = taken[sup.scene];
      tk.resize(sp.scan->points.size(), 0);
      for (int i : sp.segmentation->parts[sup.part].indices) {
        if (i < 0 || size_t(i) >= sp.scan->points.size() || tk[i]) continue;
        tk[i] = 1;
        const Eigen::Vector3f w = sp.scan->pose * sp.scan->points[i];
        if (!w.allFinite()) continue;
        pcl::PointXYZ q;
        q.getVector3fMap() = local(w);
        source->push_back(q);
      }
    }
    const size_t from_parts = source->size();
    if (o_.nearby_radius_m > 0) {
      Eigen::AlignedBox3f box;
      for (const auto& q : *target) box.extend(q.getVector3fMap());
      box.min().array() -= float(o_.nearby_radius_m);
      box.max().array() += float(o_.nearby_radius_m);
      const float r2 = float(o_.nearby_radius_m * o_.nearby_radius_m);
      pcl::Indices nn(1);
      std::vector<float> d2(1);
      for (size_t s = 0; s < world.size(); ++s) {
        auto& tk = taken[s];
        tk.resize(world[s].size(), 0);
        for (size_t i = 0; i < world[s].size(); ++i) {
          if (tk[i]) continue;
          pcl::PointXYZ q;
          q.getVector3fMap() = local(world[s][i]);
          if (!q.getVector3fMap().allFinite() || !box.contains(q.getVector3fMap()) ||
              q.z < bottom + float(o_.floor_margin_m))
            continue;
          if (tree->nearestKSearch(q, 1, nn, d2) == 1 && d2[0] <= r2) source->push_back(q);
        }
      }
    }
    if (source->size() < size_t(o_.min_points)) {
      d.notes.push_back("icp: skipped, " + std::to_string(source->size()) + " scene points");
      return;
    }

    Eigen::Matrix4f t = Eigen::Matrix4f::Identity();  // scene -> placed model, (x, y, yaw)
    int iterations = 0;
    bool converged = false;
    Cloud aligned;
    auto run = [&](auto& reg) {
      reg.setInputSource(source);
      reg.setInputTarget(target);
      reg.setSearchMethodTarget(tree, true);  // built above; no second kd-tree
      reg.setMaxCorrespondenceDistance(o_.max_correspondence_m);
      reg.setMaximumIterations(o_.max_iterations);
      reg.setTransformationEpsilon(1e-10);  // stop when a step moves < 10 um (squared, m^2)
      reg.align(aligned);
      // Products of upright steps are upright; re-projecting only removes float drift.
      t = ProjectUpright(reg.getFinalTransformation());
      converged = reg.hasConverged();
      iterations = reg.Iterations();
    };
    if (o_.method == "icp") {
      UprightIcp icp;
      run(icp);
    } else {
      UprightGicp gicp;
      run(gicp);
    }
    // `aligned` holds the source moved by the unprojected transform; recompute it.
    pcl::transformPointCloud(*source, aligned, t);

    // The model moves by the inverse, about the local origin c0 (world-aligned axes).
    const Eigen::Matrix4f inv = t.inverse();
    const float dyaw = std::atan2(inv(1, 0), inv(0, 0));
    // delta(p_w) = c0 + R (p_w - c0) + t, with (R, t) = inv in the local frame.
    const Eigen::Isometry3d delta =
        Eigen::Translation3d(c0) * Eigen::Translation3d(double(inv(0, 3)), double(inv(1, 3)), 0.0) *
        Eigen::AngleAxisd(double(dyaw), Eigen::Vector3d::UnitZ()) * Eigen::Translation3d(-c0);
    const Eigen::Vector3f new_center = (delta * d.center.cast<double>()).cast<float>();
    const float moved = (new_center - d.center).norm();
    const double turn_deg = std::abs(double(dyaw)) * 180.0 / M_PI;
    char buf[160];
    if (!converged || moved > o_.max_move_m || turn_deg > o_.max_turn_deg) {
      std::snprintf(buf, sizeof buf, "icp: refused (%s, would move %.3f m, %.2f deg)",
                    converged ? "too far" : "not converged", double(moved), turn_deg);
      d.notes.push_back(buf);
      return;
    }
    d.model_pose = (delta * d.model_pose.cast<double>()).cast<float>();
    d.center = new_center;
    d.yaw = float(std::remainder(double(d.yaw) + double(dyaw), 2 * M_PI));

    // RMS over the scene points that have a model point within max_correspondence_m.
    pcl::Indices nn(1);
    std::vector<float> d2(1);
    double sum = 0;
    size_t covered = 0;
    const double max2 = o_.max_correspondence_m * o_.max_correspondence_m;
    for (const auto& q : aligned)
      if (tree->nearestKSearch(q, 1, nn, d2) == 1 && d2[0] <= max2) {
        sum += d2[0];
        ++covered;
      }
    if (covered) d.rms = float(std::sqrt(sum / double(covered)));
    else d.rms.reset();
    std::snprintf(buf, sizeof buf, "icp: moved %.3f m, %.2f deg (%d iterations, %zu + %zu points)",
                  double(moved), double(dyaw) * 180.0 / M_PI, iterations, from_parts,
                  source->size() - from_parts);
    d.notes.push_back(buf);
  }

  IcpRefineOptions o_;
  std::mutex mu_;  // guards cache_
  std::map<std::string, std::shared_ptr<const furnihost::Points>> cache_;
};

}  // namespace

FURNIHOST_PLUGIN(IcpRefine, "fitters.icp_refine", "1.0.0",
                 "upright (x, y, yaw) PCL ICP / GICP refinement of fitted catalog models")
