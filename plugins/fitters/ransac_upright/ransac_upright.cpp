// fitters.ransac_upright — the paper's model fitting and verification (Sect. VI-C, VII-B):
// catalog models of the hypothesis' class become dense point clouds, an upright RANSAC finds
// x, y and yaw of each on the floor plane, the model covering the most part points (tie-broken
// by explained model surface) is kept, then the fit is verified by its coverage and by an
// OctoMap free-space test per scan that has a sensor origin.
//
// Not in the paper: the part points fitted are those of the supporting parts within reach of
// the hypothesis (see Gather: the voter's support also holds floor, wall and merged parts), and
// near-tied poses / models are ranked by the share of the model explained by the scan around
// the hypothesis (a partial support cannot tell a chair from its turn by 180°); optionally
// (max_shift_m) only poses within a distance of the voter's centre are tried, and the kept pose
// is refined by upright ICP steps (refine_iterations, point-to-plane by default).
//
// After a recogniser of object proposals (voters.catalog_shape; configs/laser_room.json) the
// points fitted are the proposal's, with normals of their own k-NN planes when the graph has no
// segmentation. Options for that route: free_space_alternatives (a pose refused by free space
// gives way to a near-tied one that is not), keep_accepted (what the recogniser accepted by its
// own threshold stays when no model fits it, unless the fit contradicts it) and
// one_class_per_object (two accepted readings of one proposal: the higher-scored class stays).
//
// Model clouds are sampled once per stage object (Pipeline keeps its stages for every scan of
// a run) and kept between runs in a disk cache of their own (cloud_cache; ModelCloud::Save /
// Load), not in the model file: Pipeline does not call Fitter::Prepare, and the clouds depend
// on fitter parameters that are not part of the model file's key.
//
// Frames: detections and fitted poses in the world frame (Scan::pose maps scan -> world);
// occupancy grids in each scan's own frame. Assumption: objects stand on the scan's ground
// (Scan::ground, level under each object).
#include <octomap/OcTree.h>
#include <tbb/parallel_for.h>
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
#include "upright_ransac.hpp"

namespace furnihost {
namespace {

using namespace ransac_upright;

// "off" -> none; "auto" -> CacheFolder("model_clouds") ($FURNIHOST_CACHE_DIR, else
// $XDG_CACHE_HOME/furnihost, else ~/.cache/furnihost, + /model_clouds); else the folder given.
std::string CloudCacheDir(const std::string& v) {
  if (v == "off" || v.empty()) return {};
  return v == "auto" ? CacheFolder("model_clouds") : v;
}

struct RansacUprightOptions {
  SamplingOptions sampling;
  RansacOptions ransac;
  OccupancyOptions grid;
  FreeSpaceOptions free_space;
  float min_coverage = 0.5f;
  float max_free_space_ratio = 0.2f;
  int grid_cache_size = 4;
  float min_point_height = 0.02f;
  float reach_margin = 0.3f;
  float part_inside_fraction = 0.8f;
  bool crop_parts = true;
  bool keep_accepted = false;  // a detection its recogniser accepted stays accepted when the fit fails
  float keep_min_coverage = 0.25f;  // ... unless the best model covers less than this share
  bool free_space_alternatives = false;  // a pose refused by free space: try the near-tied ones
  bool one_class_per_object = false;  // accepted proposals of other classes overlapping a stronger one are refused
  float object_iou = 0.5f;            // ... when their proposals' boxes overlap by this 3D IoU
  std::string cloud_cache_setting = "auto";  // as given: "auto", "off" or a folder
  std::string cloud_cache;  // folder of sampled model clouds (from cloud_cache_setting); empty = none

  void Check() const {
    sampling.Check();
    ransac.Check();
    grid.Check();
  }
};

// Each parameter declared once; its default is RansacUprightOptions{}'s (the nested option
// structs' defaults: model_cloud.hpp, upright_ransac.hpp, occupancy.hpp).
const ParamBinding<RansacUprightOptions>& Binding() {
  using O = RansacUprightOptions;
  static const auto b =
      ParamBinding<O>()
          .Number("model_density_per_m2", [](O& o) -> double& { return o.sampling.density_per_m2; }, 100, 1e6, "",
                  "model cloud density [points/m² of outer face area] (1 cm spacing; paper's models: 5k-15k points)")
          .Int("min_model_points", [](O& o) -> int& { return o.sampling.min_points; }, 100, 1e6, "",
               "small models are sampled denser up to this count")
          .Int("max_model_points", [](O& o) -> int& { return o.sampling.max_points; }, 100, 1e6, "",
               "large models are sampled sparser down to this count (40k keeps big cabinets near 2 cm spacing)")
          .Number("height_tolerance_m", [](O& o) -> float& { return o.ransac.height_tolerance; }, 0.001, 0.2, "",
                  "candidate correspondences: model points within this height [m] of the sampled scan point")
          .Number("correspondence_fraction", [](O& o) -> float& { return o.ransac.correspondence_fraction; }, 0.01, 1,
                  "", "share of the candidate correspondences tried per sample (paper: ~50 %)")
          .Int("max_correspondences", [](O& o) -> int& { return o.ransac.max_correspondences; }, 0, 1e6, "",
               "cap on the candidates tried per sample; 0 = no cap")
          // Also RansacOptions::min_horizontal_normal: copied in ParseOptions.
          .Number("min_horizontal_normal", [](O& o) -> float& { return o.sampling.min_horizontal_normal; }, 0, 1, "",
                  "|n_xy| above this: the yaw comes from the normals, else a random yaw (paper: tables)")
          .Number("normal_z_tolerance", [](O& o) -> float& { return o.ransac.normal_z_tolerance; }, 0, 1, "",
                  "candidates need a normal tilt |n_z| within this of the scan point's")
          .Bool("normal_sign_ambiguous", [](O& o) -> bool& { return o.ransac.normal_sign_ambiguous; },
                "normals' signs are arbitrary: try yaw and yaw + 180°")
          .Number("inlier_distance_m", [](O& o) -> float& { return o.sampling.inlier_distance; }, 0.001, 0.5, "m",
                  "a scan point is covered when a model point is this close")
          .Number("score_fraction", [](O& o) -> float& { return o.ransac.score_fraction; }, 0.01, 1, "",
                  "share of the part points each candidate is scored on (paper: ~50 %)")
          .Int("max_score_points", [](O& o) -> int& { return o.ransac.max_score_points; }, 0, 10000000, "",
               "at most this many part points per candidate (dense scans: the share is estimated as well from "
               "a few thousand); ICP and the final coverage use at most 4x as many; 0 = all (paper)")
          .Number("p_success", [](O& o) -> double& { return o.ransac.p_success; }, 0.5, 0.999999, "",
                  "RANSAC success probability of eq. 7")
          .Int("max_iterations", [](O& o) -> int& { return o.ransac.max_iterations; }, 1, 100000, "",
               "cap on the samples per model (eq. 7 starts at infinity)")
          .Int("min_iterations", [](O& o) -> int& { return o.ransac.min_iterations; }, 0, 100000, "",
               "samples per model at least: eq. 7 assumes every covered scan point yields the pose, which noisy "
               "normals do not")
          .Number("model_tie_tolerance", [](O& o) -> float& { return o.ransac.model_tie_tolerance; }, 0, 1, "",
                  "models covering within this share of the best are ranked by explained model surface")
          .Int("refine_iterations", [](O& o) -> int& { return o.ransac.refine_iterations; }, 0, 100, "",
               "upright ICP steps after RANSAC (not in the paper; 0 = off)")
          // refine_plane = index of the choice: point 0 (false), plane 1 (true).
          .Enum("refine_metric", [](O& o) -> bool& { return o.ransac.refine_plane; }, {"point", "plane"},
                "ICP distance: 'point' to the nearest model sample, 'plane' along the model's horizontal normal there")
          .Number("max_shift_m", [](O& o) -> float& { return o.ransac.max_shift; }, 0, 10, "",
                  "poses that move the centre farther than this [m] from the voter's centre are not tried (the "
                  "voter's centre error; keeps a fit from sliding onto a neighbouring object); 0 = no limit (paper)")
          .String("cloud_cache", &O::cloud_cache_setting,
                  "folder where sampled model clouds are kept between runs (they cost ~75 % of a single-scan "
                  "detection); 'auto': $FURNIHOST_CACHE_DIR, else $XDG_CACHE_HOME/furnihost, else "
                  "~/.cache/furnihost (+ /model_clouds); 'off': sample every run. Keyed by mesh, sampling parameters "
                  "and format")
          .Number("min_point_height_m", &O::min_point_height, 0, 1, "m",
                  "part points less than this above floor_z are not fitted (floor points; no model explains them)")
          .Number("reach_margin_m", &O::reach_margin, 0, 10, "m",
                  "reach of a hypothesis: its class's largest footprint half-diagonal plus this (the voter's centre "
                  "error)")
          .Number("part_inside_fraction", &O::part_inside_fraction, 0, 1, "",
                  "a supporting part is fitted only if this share of its points is within reach (drops floor, wall "
                  "and neighbours' parts); 0 = every part")
          .Bool("crop_parts", &O::crop_parts,
                "a part mostly out of reach contributes its points within reach (true) or nothing (false)")
          // Also RansacOptions::min_coverage: copied in ParseOptions.
          .Number("min_coverage", &O::min_coverage, 0, 1, "",
                  "reject when the model covers less than this share of the part points (paper: 0.5)")
          .Number("max_free_space_ratio", &O::max_free_space_ratio, 0, 1, "",
                  "reject when more than this share of the visible model surface is in free space")
          .Bool("free_space_alternatives", &O::free_space_alternatives,
                "when free space refuses the best pose, try the model's near-tied poses (within "
                "model_tie_tolerance of its coverage, best first): the first that still covers min_coverage "
                "and passes the free-space test is taken (false: the best pose is verified alone, paper)")
          .Bool("keep_accepted", &O::keep_accepted,
                "a detection that its recogniser accepted on its own (a score over the class threshold, e.g. "
                "voters.catalog_shape) stays accepted, with the recogniser's box, when no model fits it (objects "
                "unlike every catalog model of their class are not lost); every other candidate, those below the "
                "recogniser's threshold too, is the fit's to accept; false = the fit decides alone (paper)")
          .Number("keep_min_coverage", &O::keep_min_coverage, 0, 1, "",
                  "with keep_accepted: ... unless the class's best model covers less than this share of its points "
                  "(the fit contradicts the recogniser: a dresser taken for a table by its size)")
          .Bool("one_class_per_object", &O::one_class_per_object,
                "one object, one class: of accepted detections made from proposals (voters.catalog_shape) whose "
                "proposal boxes overlap by more than object_iou, those of another class than the highest-scored one "
                "are refused (a chest also fitted as a table, an armchair also as a sofa)")
          .Number("object_iou", &O::object_iou, 0.01, 1, "",
                  "with one_class_per_object: the 3D IoU of two proposals' boxes above which they are one object")
          .Number("grid_resolution_m", [](O& o) -> double& { return o.grid.resolution; }, 0.005, 1, "",
                  "OctoMap voxel edge [m] of the per-scan occupancy grids")
          .Number("grid_max_range_m", [](O& o) -> double& { return o.grid.max_range; }, 0, 1000, "",
                  "rays longer than this only clear space [m]; 0 = unlimited")
          .Int("grid_cache_size", &O::grid_cache_size, 1, 1000, "",
               "occupancy grids kept between calls (least recently used dropped)")
          .Number("free_space_margin_m", [](O& o) -> float& { return o.free_space.free_margin; }, 0, 1, "m",
                  "model points are pushed this far from the sensor before the free-space look-up")
          .Number("visibility_margin_m", [](O& o) -> float& { return o.free_space.visibility_margin; }, 0, 1, "m",
                  "model points this far behind the model's own front surface count as self-occluded")
          .Int("free_space_erosion", [](O& o) -> int& { return o.free_space.erosion; }, 0, 1, "",
               "1: a model point is in free space only if its voxel and the 6 neighbours are free; 0: its voxel");
  return b;
}

RansacUprightOptions ParseOptions(const nlohmann::json& p) {
  RansacUprightOptions o = Binding().Parse(p);
  o.ransac.min_horizontal_normal = o.sampling.min_horizontal_normal;
  o.ransac.min_coverage = o.min_coverage;
  o.cloud_cache = CloudCacheDir(o.cloud_cache_setting);
  o.Check();  // the library structs' own checks (they are also used without this plugin)
  return o;
}

std::string Fixed2(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

// RANSAC seed of one hypothesis: the run's seed mixed with the hypothesis itself (class and
// voter centre, FNV-1a over their bytes), not with its place in the list, so a hypothesis fits
// the same whatever else the voter found (an A/B change of one class's threshold leaves the
// other classes' fits alone; with list-index seeds it re-drew all of them).
uint64_t HypothesisSeed(uint64_t run_seed, const Detection& d) {
  const uint64_t cls = Fnv1a(d.cls, kFnvOffsetTruncated);
  return SplitMix64(run_seed ^ SplitMix64(Fnv1a(d.center.data(), sizeof(float) * 3, cls)));
}

// Identifies a scan's grid in the cache: the pointer alone could be reused by a later scan.
struct GridKey {
  const Scan* scan = nullptr;
  size_t n = 0;
  uint64_t fingerprint = 0;
  bool operator==(const GridKey& o) const { return scan == o.scan && n == o.n && fingerprint == o.fingerprint; }
};

GridKey KeyOf(const Scan& s, double resolution) {
  GridKey k{&s, s.points.size(), kFnvOffsetTruncated};
  auto mix = [&](const void* p, size_t len) {
    std::string bytes(static_cast<const char*>(p), len);
    k.fingerprint = Fnv1a(bytes, k.fingerprint);
  };
  const size_t n = s.points.size();
  for (size_t i : {size_t(0), n / 3, n / 2, (2 * n) / 3, n ? n - 1 : 0})
    if (i < n) mix(s.points[i].data(), sizeof(float) * 3);
  if (s.origin) mix(s.origin->data(), sizeof(float) * 3);
  mix(&resolution, sizeof resolution);
  return k;
}

class RansacUprightFitter : public Fitter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }

  explicit RansacUprightFitter(const nlohmann::json& p) : o_(ParseOptions(p)) {}

  // Samples (or loads from cloud_cache) every catalog model once, in parallel. Nothing is
  // returned for the model file (see the file comment).
  // (Fit samples the models it needs on first use when no host calls Prepare.)
  nlohmann::json Prepare(const std::vector<const CatalogModel*>& catalog, const nlohmann::json&) override {
    tbb::this_task_arena::isolate([&] { Clouds(catalog); });
    return nullptr;
  }

  std::vector<Detection> Fit(const std::vector<Detection>& input, const FitContext& ctx) override {
    std::vector<Detection> out = input;
    if (out.empty()) return out;
    const int threads = ctx.run.threads > 0 ? ctx.run.threads : tbb::task_arena::automatic;
    tbb::task_arena arena(threads);
    arena.execute([&] { FitAll(&out, ctx); });
    if (o_.keep_accepted)
      for (size_t d = 0; d < out.size(); ++d)
        if (input[d].verified.value_or(false) && !out[d].verified.value_or(false) &&
            out[d].coverage.value_or(0.f) >= o_.keep_min_coverage) {
          // The recogniser's verdict, pose and box stand; the failed fit is kept as a note.
          std::vector<std::string> notes = std::move(out[d].notes);
          const std::string why = out[d].Rejection();
          const std::optional<float> coverage = out[d].coverage;
          out[d] = input[d];
          out[d].notes.insert(out[d].notes.end(), notes.begin(), notes.end());
          out[d].notes.push_back("no catalog model fits it (" + why + "): kept, its recogniser accepted it");
          if (coverage) out[d].evidence["fit_coverage"] = *coverage;
        }
    if (o_.one_class_per_object) OneClassPerObject(&out, ctx);
    return out;
  }

 private:
  void FitAll(std::vector<Detection>* dets, const FitContext& ctx) {
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
      const Reach r = ReachOf((*dets)[d], it->second, ro[d].floor_z);
      for (const Points& w : world)
        for (const auto& p : w)
          if (r.Contains(p)) scenes[d].context.push_back(p);
    });
    NormalsCache normals_cache;
    for (size_t d = 0; d < dets->size(); ++d) {
      auto it = by_class.find((*dets)[d].cls);
      Points context = std::move(scenes[d].context);
      scenes[d] = Gather((*dets)[d], ctx, it == by_class.end() ? nullptr : &it->second, ro[d].floor_z,
                          &dropped_parts[d], &normals_cache);
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
  void OneClassPerObject(std::vector<Detection>* dets, const FitContext& ctx) const {
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

  static void Reject(Detection* det, Check failed) {
    det->verified = false;
    det->checks.push_back(std::move(failed));
  }

  static std::string TrialNote(const FitResult& f, const std::vector<const ModelCloud*>& models) {
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

  // Points of the detection's supporting parts (world frame). With `models` (the class's
  // models): points less than min_point_height_m above the floor are left out, and a part is
  // used whole only when at least part_inside_fraction of its other points lie within reach of
  // the hypothesis, i.e. inside the upright cylinder around its centre of radius (largest model
  // footprint half-diagonal + reach_margin_m) and below the tallest model; of the other parts
  // only the points within reach are used (crop_parts) or none. The voter's support is every
  // part with a vote near the maximum: floor and wall parts, neighbouring objects and parts
  // that merged all of these (region growing over a connected room) included, which no
  // placement of one model can explain.
  // Where the points of an object of the hypothesis' class can be: the upright cylinder around
  // its centre of radius (largest model footprint half-diagonal + reach_margin_m), from
  // min_point_height_m above the floor to the top of the tallest model.
  struct Reach {
    Eigen::Vector2f centre;
    float radius = 0.f, low = 0.f, top = 0.f;
    bool Contains(const Eigen::Vector3f& p) const {
      return p.z() >= low && p.z() <= top && (p.head<2>() - centre).norm() <= radius;
    }
  };
  Reach ReachOf(const Detection& det, const std::vector<const ModelCloud*>& models, float floor_z) const {
    Reach r;
    r.centre = det.center.head<2>();
    r.low = floor_z + o_.min_point_height;
    r.top = -std::numeric_limits<float>::infinity();
    for (const ModelCloud* m : models) {
      const Eigen::AlignedBox3f& b = m->Bounds();
      r.radius = std::max(r.radius, std::hypot(std::max(std::fabs(b.min().x()), std::fabs(b.max().x())),
                                               std::max(std::fabs(b.min().y()), std::fabs(b.max().y()))));
      r.top = std::max(r.top, floor_z + b.max().z() + m->InlierDistance());
    }
    r.radius += o_.reach_margin;
    return r;
  }

  // Normals estimated for a proposal's points, by (scene, proposal, lowest height kept): the
  // candidates of several classes on one proposal share them.
  using NormalsCache = std::map<std::tuple<int, int, float>, Points>;

  ScenePoints Gather(const Detection& det, const FitContext& ctx, const std::vector<const ModelCloud*>* models,
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
  static void ProposalPoints(const Detection& det, const FitContext& ctx, float low, ScenePoints* sp,
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
    if (!normals && sp->points.size() - first > size_t(kNeighbours)) {
      Points& own_normals = (*cache)[{s, det.proposal, low}];
      if (own_normals.empty()) {
        const Points own(sp->points.begin() + std::ptrdiff_t(first), sp->points.end());
        const shape::KnnIndex index(own);
        own_normals = shape::EstimateLocalShape(index, kNeighbours).normals;
      }
      std::copy(own_normals.begin(), own_normals.end(), sp->normals.begin() + std::ptrdiff_t(first));
    }
  }

  // Sampled clouds of `models` (same order), building the missing ones in parallel.
  std::vector<std::shared_ptr<const ModelCloud>> Clouds(const std::vector<const CatalogModel*>& models) {
    std::vector<std::shared_ptr<const ModelCloud>> out(models.size());
    std::vector<size_t> missing;
    std::vector<std::string> keys(models.size());
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (size_t i = 0; i < models.size(); ++i) {
        const CatalogModel& m = *models[i];
        // The id alone could name another mesh in another catalog: key by the mesh size too.
        keys[i] = m.id + "|" + std::to_string(m.mesh.vertices.size()) + "|" + std::to_string(m.mesh.triangles.size());
        auto it = clouds_.find(keys[i]);
        if (it != clouds_.end()) out[i] = it->second;
        else missing.push_back(i);
      }
    }
    std::atomic<int> loaded{0};
    if (!missing.empty() && !o_.cloud_cache.empty()) {
      std::error_code ec;  // a failure shows as the first Save's error below
      std::filesystem::create_directories(o_.cloud_cache, ec);
    }
    tbb::parallel_for(size_t(0), missing.size(), [&](size_t k) {
      const CatalogModel& m = *models[missing[k]];
      const uint64_t seed = Fnv1a(m.id, kFnvOffsetTruncated);
      if (o_.cloud_cache.empty()) {
        out[missing[k]] = std::make_shared<const ModelCloud>(m, o_.sampling, seed);
        return;
      }
      const uint64_t key = ModelCloud::CacheKey(m, o_.sampling, seed);
      char name[32];
      std::snprintf(name, sizeof(name), "%016llx.fhmc", static_cast<unsigned long long>(key));
      const std::string path = o_.cloud_cache + "/" + name;
      if (auto c = ModelCloud::Load(path, key, m.id)) {
        out[missing[k]] = std::move(c);
        ++loaded;
        return;
      }
      auto c = std::make_shared<const ModelCloud>(m, o_.sampling, seed);
      try {
        c->Save(path, key);
      } catch (const std::exception& e) {
        if (!cache_warned_.exchange(true))
          spdlog::warn("fitters.ransac_upright: model clouds not cached ({}); set cloud_cache to a writable folder "
                       "or 'off'", e.what());
      }
      out[missing[k]] = std::move(c);
    });
    if (!missing.empty() && !o_.cloud_cache.empty())
      spdlog::debug("fitters.ransac_upright: {} model clouds from {}, {} sampled", loaded.load(), o_.cloud_cache,
                    missing.size() - loaded.load());
    std::lock_guard<std::mutex> lock(mu_);
    for (size_t i : missing) clouds_.emplace(keys[i], out[i]);
    return out;
  }

  // The occupancy grid of a scan, built once per run (bounded least-recently-used cache).
  std::shared_ptr<const octomap::OcTree> Grid(const Scan& scan) {
    const GridKey key = KeyOf(scan, o_.grid.resolution);
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (auto& e : grids_)
        if (e.key == key) {
          e.last_use = ++clock_;
          return e.tree;
        }
    }
    OccupancyStats st;
    Stopwatch sw;
    auto tree = BuildOccupancy(scan.points, *scan.origin, o_.grid, &st);
    spdlog::debug("fitters.ransac_upright: occupancy grid of {} ({} points, {} rays): {} free, {} occupied voxels, {:.0f} ms",
                  scan.source, scan.points.size(), st.rays, st.free, st.occupied, sw.Ms());
    std::lock_guard<std::mutex> lock(mu_);
    grids_.push_back({key, tree, ++clock_});
    while (int(grids_.size()) > o_.grid_cache_size) {
      auto oldest = std::min_element(grids_.begin(), grids_.end(),
                                     [](const GridEntry& a, const GridEntry& b) { return a.last_use < b.last_use; });
      grids_.erase(oldest);
    }
    return tree;
  }

  struct GridEntry {
    GridKey key;
    std::shared_ptr<const octomap::OcTree> tree;
    uint64_t last_use = 0;
  };

  const RansacUprightOptions o_;
  std::atomic<bool> cache_warned_{false};
  std::mutex mu_;  // guards the two caches below
  std::map<std::string, std::shared_ptr<const ModelCloud>> clouds_;
  std::vector<GridEntry> grids_;
  uint64_t clock_ = 0;
};

}  // namespace
}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::RansacUprightFitter, "fitters.ransac_upright", "1.5.0",
                 "upright RANSAC fit of catalog models (x, y, yaw) with coverage and OctoMap free-space verification")
