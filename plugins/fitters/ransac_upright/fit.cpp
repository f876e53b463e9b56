// fitters.ransac_upright: upright RANSAC of the class's catalog models on each detection's points,
// verified by coverage and free space (FitAll), one class per object, and the points to fit.
#include <octomap/OcTree.h>
#include <tbb/parallel_for.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <tuple>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"
#include "model_cloud.hpp"
#include "occupancy.hpp"
#include "shape/shape.hpp"
#include "pose_search.hpp"
#include "upright_ransac.hpp"
#include "view_synthesis.hpp"
#include "ransac_upright.hpp"

namespace furnihost::ransac_upright {

void RansacUprightFitter::FitAll(std::vector<Detection>* dets, const FitContext& ctx) {
  // Each model stands on the ground under its hypothesis (the first scan's, in the world frame).
  const Scan* ground_scan = nullptr;
  for (const SceneParts& sp : ctx.scenes)
    if (sp.scan && !ground_scan) ground_scan = sp.scan;
  std::vector<RansacOptions> ro(dets->size(), o_.ransac);
  for (size_t d = 0; d < dets->size(); ++d) {
    const Eigen::Vector3f& c = (*dets)[d].center;
    ro[d].floor_z = ground_scan ? ground_scan->GroundZ(c.x(), c.y()) : 0.f;
    ro[d].prior_xy = (*dets)[d].center.head<2>();
  }
  // Models per class, in catalog order; sampled once per stage object.
  std::set<std::string> classes;
  for (const auto& d : *dets) classes.insert(d.cls);
  std::vector<const CatalogModel*> needed;
  for (const CatalogModel* m : ctx.catalog)
    if (m && classes.count(m->cls)) needed.push_back(m);
  const std::vector<std::shared_ptr<const ModelCloud>> clouds = Clouds(needed);
  std::map<std::string, std::vector<const ModelCloud*>> by_class;
  for (size_t i = 0; i < needed.size(); ++i) by_class[needed[i]->cls].push_back(clouds[i].get());

  // Scene points of every detection (world frame), from the supporting parts within reach.
  std::vector<ScenePoints> scenes(dets->size());
  std::vector<int> dropped_parts(dets->size(), 0);
  std::vector<Points> world(ctx.scenes.size());  // every scan in the world frame, for the context
  for (size_t s = 0; s < ctx.scenes.size(); ++s)
    if (ctx.scenes[s].scan) {
      const Scan& scan = *ctx.scenes[s].scan;
      world[s].reserve(scan.points.size());
      for (const auto& p : scan.points)
        if (p.allFinite()) world[s].push_back(scan.pose * p);
    }
  tbb::parallel_for(size_t(0), dets->size(), [&](size_t d) {
    auto it = by_class.find((*dets)[d].cls);
    if (it == by_class.end()) return;
    const Reach r = ReachOf((*dets)[d], Boxes(it->second), ro[d].floor_z);
    for (const Points& w : world)
      for (const auto& p : w)
        if (r.Contains(p)) scenes[d].context.push_back(p);
  });
  NormalsCache normals_cache;
  for (size_t d = 0; d < dets->size(); ++d) {
    auto it = by_class.find((*dets)[d].cls);
    Points context = std::move(scenes[d].context);
    const std::vector<Eigen::AlignedBox3f> boxes = it == by_class.end() ? std::vector<Eigen::AlignedBox3f>()
                                                                        : Boxes(it->second);
    scenes[d] = Gather((*dets)[d], ctx, it == by_class.end() ? nullptr : &boxes, ro[d].floor_z, &dropped_parts[d],
                       &normals_cache);
    scenes[d].context = std::move(context);
  }

  // RANSAC per detection, in parallel; each has its own seed (HypothesisSeed), so neither
  // the order nor the other hypotheses matter.
  std::vector<FitResult> fits(dets->size());
  tbb::parallel_for(size_t(0), dets->size(), [&](size_t d) {
    auto it = by_class.find((*dets)[d].cls);
    if (it == by_class.end() || scenes[d].points.empty()) return;
    fits[d] = FitUpright(scenes[d], it->second, ro[d], HypothesisSeed(ctx.run.seed, (*dets)[d]));
  });

  std::vector<char> passed(dets->size(), 0);
  for (size_t d = 0; d < dets->size(); ++d) {
    Detection& det = (*dets)[d];
    det.free_space_ratio.reset();  // recomputed below
    det.checks.clear();
    det.coverage.reset();
    det.rms.reset();
    det.iterations = 0;
    auto it = by_class.find(det.cls);
    if (it == by_class.end()) {
      det.notes.push_back("no catalog model of class '" + det.cls + "'");
      Reject(&det, Check::AtLeast("catalog_models", 0, 1));
      continue;
    }
    if (dropped_parts[d] > 0)
      det.notes.push_back("support: " + std::to_string(dropped_parts[d]) + " of " + std::to_string(det.support.size()) +
                          " parts out of the class' reach (floor, walls, other objects)" +
                          (o_.crop_parts ? ", cropped to it" : ", left out"));
    if (scenes[d].points.empty()) {
      Reject(&det, Check::AtLeast("part_points", 0, 1));
      continue;
    }
    const FitResult& f = fits[d];
    det.iterations = f.iterations;
    det.notes.push_back(TrialNote(f, it->second));
    if (f.model < 0) {
      det.coverage = 0.f;
      Reject(&det, Check::AtLeast("poses_found", 0, 1));
      continue;
    }
    const ModelCloud& m = *it->second[f.model];
    det.model = m.Id();
    det.model_pose = f.pose;
    det.center = f.pose * m.Bounds().center();
    det.yaw = f.yaw;
    det.coverage = f.coverage;
    if (f.rms >= 0.f) det.rms = f.rms;
    det.box = OrientedBox{det.center, m.Bounds().sizes(), f.yaw};
    det.box_source = "model";
    det.checks.push_back(Check::AtLeast("coverage", f.coverage, o_.min_coverage));
    if (!det.checks.back().passed) {
      det.verified = false;
      continue;
    }
    passed[d] = 1;
  }

  // Free-space test against every scan that has a sensor origin.
  std::vector<const Scan*> scans;
  for (const SceneParts& sp : ctx.scenes)
    if (sp.scan && sp.scan->origin && std::find(scans.begin(), scans.end(), sp.scan) == scans.end())
      scans.push_back(sp.scan);
  const bool any_passed = std::find(passed.begin(), passed.end(), 1) != passed.end();
  std::vector<std::shared_ptr<const octomap::OcTree>> grids;
  if (any_passed)
    for (const Scan* s : scans) grids.push_back(Grid(*s));
  tbb::parallel_for(size_t(0), dets->size(), [&](size_t d) {
    if (!passed[d]) return;
    Detection& det = (*dets)[d];
    if (scans.empty()) {
      det.notes.push_back("free-space test skipped: scan has no sensor origin");
      det.verified = true;
      return;
    }
    const ModelCloud& m = *by_class.at(det.cls)[fits[d].model];
    FreeSpaceOptions fo = o_.free_space;
    fo.point_spacing = m.Spacing();
    auto free_ratio = [&](const Eigen::Isometry3f& model_pose) {
      long visible = 0, free = 0;
      for (size_t s = 0; s < scans.size(); ++s) {
        const Eigen::Isometry3f to_scan = scans[s]->pose.inverse() * model_pose;
        Points pts(m.Cloud().size());
        for (size_t i = 0; i < pts.size(); ++i) pts[i] = to_scan * m.Cloud()[i];
        const FreeSpaceCount c = CountFreeSpace(*grids[s], pts, *scans[s]->origin, fo);
        visible += c.visible;
        free += c.free;
      }
      return visible > 0 ? float(double(free) / double(visible)) : 0.f;
    };
    det.free_space_ratio = free_ratio(det.model_pose);
    if (*det.free_space_ratio > o_.max_free_space_ratio && o_.free_space_alternatives) {
      // Coverage cannot tell near-tied poses apart (a model unlike the object, or a view of
      // one side); what the sensor saw through can: the first that covers enough and is
      // not in free space replaces the refused one.
      const RansacOptions& ro_d = ro[d];
      for (const Eigen::Vector3f& alt : fits[d].alternatives) {
        const FitResult f = FinishAt(scenes[d], m, fits[d].model, ro_d, alt.x(), alt.y(), alt.z());
        if (f.coverage < o_.min_coverage) continue;
        const float ratio = free_ratio(f.pose);
        if (ratio > o_.max_free_space_ratio) continue;
        det.notes.push_back("free space refused the best pose (" + Fixed2(*det.free_space_ratio) +
                            "); a near-tied pose passes");
        det.model_pose = f.pose;
        det.center = f.pose * m.Bounds().center();
        det.yaw = f.yaw;
        det.coverage = f.coverage;
        det.rms.reset();
        if (f.rms >= 0.f) det.rms = f.rms;
        det.box = OrientedBox{det.center, m.Bounds().sizes(), f.yaw};
        for (Check& c : det.checks)
          if (c.name == "coverage") c = Check::AtLeast("coverage", f.coverage, o_.min_coverage);
        det.free_space_ratio = ratio;
        break;
      }
    }
    det.checks.push_back(Check::AtMost("free_space_ratio", *det.free_space_ratio, o_.max_free_space_ratio));
    det.verified = det.checks.back().passed;
  });
}

// Accepted detections from proposals, strongest (recogniser score) first: one whose proposal
// overlaps a stronger accepted one's of another class by more than object_iou is the same
// object read as another class, and is refused.
void RansacUprightFitter::OneClassPerObject(std::vector<Detection>* dets, const FitContext& ctx) const {
  auto box_of = [&](const Detection& d) -> const Eigen::AlignedBox3f* {
    if (d.proposal < 0 || d.proposal_scene < 0 || d.proposal_scene >= int(ctx.scenes.size())) return nullptr;
    const Proposals* p = ctx.scenes[size_t(d.proposal_scene)].proposals;
    return p && d.proposal < int(p->items.size()) ? &p->items[size_t(d.proposal)].box : nullptr;
  };
  std::vector<size_t> order;
  for (size_t i = 0; i < dets->size(); ++i)
    if ((*dets)[i].verified.value_or(false) && box_of((*dets)[i])) order.push_back(i);
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return (*dets)[a].score > (*dets)[b].score; });
  std::vector<size_t> kept;
  for (size_t i : order) {
    Detection& d = (*dets)[i];
    float worst = 0.f;
    const Detection* by = nullptr;
    for (size_t k : kept) {
      const Detection& s = (*dets)[k];
      if (s.cls == d.cls || s.proposal_scene != d.proposal_scene) continue;
      const float iou = shape::BoxIou(*box_of(s), *box_of(d));
      if (iou > worst) {
        worst = iou;
        by = &s;
      }
    }
    if (by && worst > o_.object_iou) {
      d.notes.push_back("the same object as an accepted " + by->cls + " (score " + Fixed2(by->score) + ")");
      Reject(&d, Check::AtMost("iou_with_stronger_class", worst, o_.object_iou));
      continue;
    }
    kept.push_back(i);
  }
}

std::string RansacUprightFitter::TrialNote(const FitResult& f, const std::vector<const ModelCloud*>& models) {
  std::string s = "ransac:";
  for (size_t i = 0; i < models.size(); ++i) {
    const ModelTrial& t = f.trials[i];
    s += " " + models[i]->Id() + " " +
         (t.subset_coverage >= 0 ? Fixed2(t.subset_coverage) : std::string("abandoned")) + " (" +
         std::to_string(t.samples) + " it)" + (int(i) == f.model ? " *" : "") + ";";
  }
  if (!s.empty() && s.back() == ';') s.pop_back();
  return s;
}

// `models`: the class's model boxes (model frame).
RansacUprightFitter::Reach RansacUprightFitter::ReachOf(const Detection& det, const std::vector<Eigen::AlignedBox3f>& models,
                                                       float floor_z) const {
  Reach r;
  r.centre = det.center.head<2>();
  r.low = floor_z + o_.min_point_height;
  r.top = -std::numeric_limits<float>::infinity();
  for (const Eigen::AlignedBox3f& b : models) {
    r.radius = std::max(r.radius, std::hypot(std::max(std::fabs(b.min().x()), std::fabs(b.max().x())),
                                             std::max(std::fabs(b.min().y()), std::fabs(b.max().y()))));
    r.top = std::max(r.top, floor_z + b.max().z() + o_.sampling.inlier_distance);
  }
  r.radius += o_.reach_margin;
  return r;
}

ScenePoints RansacUprightFitter::Gather(const Detection& det, const FitContext& ctx, const std::vector<Eigen::AlignedBox3f>* models,
                   float floor_z, int* dropped, NormalsCache* normals_cache) const {
  ScenePoints sp;
  const bool filter = models && !models->empty() && o_.part_inside_fraction > 0.f;
  const Reach reach = filter ? ReachOf(det, *models, floor_z) : Reach{};
  const float low = reach.low;
  ScenePoints part;
  std::set<std::pair<int, int>> seen;
  for (const Support& s : det.support) {
    if (!seen.insert({s.scene, s.part}).second) continue;
    if (s.scene < 0 || s.scene >= int(ctx.scenes.size()))
      throw StageError("detection support names scene " + std::to_string(s.scene) + " but there are " +
                       std::to_string(ctx.scenes.size()));
    const SceneParts& scene = ctx.scenes[s.scene];
    if (!scene.scan || !scene.segmentation) throw StageError("scene " + std::to_string(s.scene) + " has no scan or segmentation");
    const Scan& scan = *scene.scan;
    const Segmentation& seg = *scene.segmentation;
    if (s.part < 0 || s.part >= int(seg.parts.size()))
      throw StageError("detection support names part " + std::to_string(s.part) + " of scene " +
                       std::to_string(s.scene) + " which has " + std::to_string(seg.parts.size()));
    const bool normals = seg.normals.size() == scan.points.size();
    const Eigen::Matrix3f R = scan.pose.linear();
    part.points.clear();
    part.normals.clear();
    int inside = 0;
    std::vector<char> in_reach;
    for (int i : seg.parts[s.part].indices) {
      if (i < 0 || i >= int(scan.points.size()))
        throw StageError("part " + std::to_string(s.part) + " of scene " + std::to_string(s.scene) +
                         " indexes point " + std::to_string(i) + " of " + std::to_string(scan.points.size()));
      if (!scan.points[i].allFinite()) continue;
      const Eigen::Vector3f p = scan.pose * scan.points[i];
      if (filter && p.z() < low) continue;
      const bool in = reach.Contains(p);
      inside += in;
      in_reach.push_back(in);
      part.points.push_back(p);
      part.normals.push_back(normals ? Eigen::Vector3f(R * seg.normals[i]) : Eigen::Vector3f::Constant(NAN));
    }
    if (filter && (part.points.empty() || inside < o_.part_inside_fraction * float(part.points.size()))) {
      ++*dropped;
      if (!o_.crop_parts) continue;
      // A part that reaches far beyond the object (a segmentation that merged floor, walls
      // and furniture) still holds the object's points: its points within reach are kept.
      size_t k = 0;
      for (size_t i = 0; i < part.points.size(); ++i)
        if (in_reach[i]) {
          part.points[k] = part.points[i];
          part.normals[k++] = part.normals[i];
        }
      part.points.resize(k);
      part.normals.resize(k);
    }
    sp.points.insert(sp.points.end(), part.points.begin(), part.points.end());
    sp.normals.insert(sp.normals.end(), part.normals.begin(), part.normals.end());
  }
  if (det.support.empty() && det.proposal >= 0)
    ProposalPoints(det, ctx, filter ? low : -INFINITY, &sp, normals_cache);
  return sp;
}

// A recogniser of object proposals (voters.catalog_shape) names no parts: the points to fit
// are the proposal's own (world frame), those below `low` (the floor) left out; normals from
// the segmentation when the graph has one.
void RansacUprightFitter::ProposalPoints(const Detection& det, const FitContext& ctx, float low, ScenePoints* sp,
                           NormalsCache* cache) {
  const int s = det.proposal_scene;
  if (s < 0 || s >= int(ctx.scenes.size()))
    throw StageError("detection names the proposal of scene " + std::to_string(s) + " but there are " +
                     std::to_string(ctx.scenes.size()));
  const SceneParts& scene = ctx.scenes[size_t(s)];
  if (!scene.scan || !scene.proposals || det.proposal >= int(scene.proposals->items.size()))
    throw StageError("detection names proposal " + std::to_string(det.proposal) + " of scene " + std::to_string(s) +
                     ", which has " + std::to_string(scene.proposals ? scene.proposals->items.size() : 0));
  const Scan& scan = *scene.scan;
  const Points* normals =
      scene.segmentation && scene.segmentation->normals.size() == scan.points.size() ? &scene.segmentation->normals
                                                                                     : nullptr;
  const Eigen::Matrix3f R = scan.pose.linear();
  const size_t first = sp->points.size();
  for (int i : scene.proposals->items[size_t(det.proposal)].indices) {
    if (i < 0 || i >= int(scan.points.size()))
      throw StageError("proposal " + std::to_string(det.proposal) + " indexes point " + std::to_string(i) + " of " +
                       std::to_string(scan.points.size()));
    if (!scan.points[size_t(i)].allFinite()) continue;
    const Eigen::Vector3f p = scan.pose * scan.points[size_t(i)];
    if (p.z() < low) continue;
    sp->points.push_back(p);
    sp->normals.push_back(normals ? Eigen::Vector3f(R * (*normals)[size_t(i)]) : Eigen::Vector3f::Constant(NAN));
  }
  // Without a segmentation's normals, every RANSAC sample would draw a random yaw (a few in
  // hundreds near the right one): the proposal's own k-NN plane normals give each sample the
  // yaw of its face, as parts' normals do.
  constexpr int kNeighbours = 16;
  if (cache && !normals && sp->points.size() - first > size_t(kNeighbours)) {
    Points& own_normals = (*cache)[{s, det.proposal, low}];
    if (own_normals.empty()) {
      const Points own(sp->points.begin() + std::ptrdiff_t(first), sp->points.end());
      const shape::KnnIndex index(own);
      own_normals = shape::EstimateLocalShape(index, kNeighbours).normals;
    }
    std::copy(own_normals.begin(), own_normals.end(), sp->normals.begin() + std::ptrdiff_t(first));
  }
}

}  // namespace furnihost::ransac_upright
