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
// With synthesis (scans with a sensor origin: single views, one-spot laser scans), the stage
// recognises by analysis by synthesis instead (view_synthesis.hpp, pose_search.hpp): each
// candidate's class models are posed (x, y, yaw and a stretch per axis within the class's
// catalog sizes), rendered as the sensor would see them and compared with what it measured;
// the score weighs the surface explained, the surface the sensor saw through (free space) and
// what the model leaves unseen, and the candidates are taken jointly (ExplainAway), so
// alternatives of one cluster (a table with a chair under it, or one "sofa") are decided here.
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
#include "decision/decision_params.hpp"
#include "model_cloud.hpp"
#include "occupancy.hpp"
#include "shape/shape.hpp"
#include "pose_search.hpp"
#include "upright_ransac.hpp"
#include "view_synthesis.hpp"

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
  // Recognition by analysis by synthesis (scans with a sensor origin; view_synthesis.hpp).
  bool synthesis = false;
  RangeImageOptions view;
  CompareOptions compare;
  SearchOptions search;
  std::map<std::string, std::string> class_map;  // catalog class -> detected class
  int models_per_detection = 2;
  int render_samples = 1500;
  float stretch_margin = 0.1f;
  float select_pixel_deg = 1.0f;
  float min_new_share = 0.5f;
  float max_box_iou = 0.3f;
  int max_candidates = 12;
  float shape_exponent = 1.f;
  float prior_floor = 0.003f;
  float completeness_exponent = 0.5f;
  float evidence_m2 = 0.1f;
  float explained_exponent = 1.f;
  float agreement_exponent = 0.5f;
  std::map<std::string, float> thresholds;
  float default_threshold = 0.1f;

  void Check() const {
    sampling.Check();
    ransac.Check();
    grid.Check();
    view.Check();
    compare.Check();
    search.Check();
  }
};

// Each parameter declared once; its default is RansacUprightOptions{}'s (the nested option
// structs' defaults: model_cloud.hpp, upright_ransac.hpp, occupancy.hpp).
const ParamBinding<RansacUprightOptions>& Binding() {
  using O = RansacUprightOptions;
  static const auto b = BindDecision(
      ParamBinding<O>()
          .Number("model_density_per_m2", [](O& o) -> double& { return o.sampling.density_per_m2; }, 100, 1e6, "1/m2",
                  "model cloud density [points/m² of outer face area] (1 cm spacing; paper's models: 5k-15k points)")
          .Int("min_model_points", [](O& o) -> int& { return o.sampling.min_points; }, 100, 1e6, "count",
               "small models are sampled denser up to this count")
          .Int("max_model_points", [](O& o) -> int& { return o.sampling.max_points; }, 100, 1e6, "count",
               "large models are sampled sparser down to this count (40k keeps big cabinets near 2 cm spacing)")
          .Number("height_tolerance_m", [](O& o) -> float& { return o.ransac.height_tolerance; }, 0.001, 0.2, "m",
                  "candidate correspondences: model points within this height [m] of the sampled scan point")
          .Number("correspondence_fraction", [](O& o) -> float& { return o.ransac.correspondence_fraction; }, 0.01, 1,
                  "1", "share of the candidate correspondences tried per sample (paper: ~50 %)")
          .Int("max_correspondences", [](O& o) -> int& { return o.ransac.max_correspondences; }, 0, 1e6, "count",
               "cap on the candidates tried per sample; 0 = no cap")
          // Also RansacOptions::min_horizontal_normal: copied in ParseOptions.
          .Number("min_horizontal_normal", [](O& o) -> float& { return o.sampling.min_horizontal_normal; }, 0, 1, "1",
                  "|n_xy| above this: the yaw comes from the normals, else a random yaw (paper: tables)")
          .Number("normal_z_tolerance", [](O& o) -> float& { return o.ransac.normal_z_tolerance; }, 0, 1, "1",
                  "candidates need a normal tilt |n_z| within this of the scan point's")
          .Bool("normal_sign_ambiguous", [](O& o) -> bool& { return o.ransac.normal_sign_ambiguous; },
                "normals' signs are arbitrary: try yaw and yaw + 180°")
          .Number("inlier_distance_m", [](O& o) -> float& { return o.sampling.inlier_distance; }, 0.001, 0.5, "m",
                  "a scan point is covered when a model point is this close")
          .Number("score_fraction", [](O& o) -> float& { return o.ransac.score_fraction; }, 0.01, 1, "1",
                  "share of the part points each candidate is scored on (paper: ~50 %)")
          .Int("max_score_points", [](O& o) -> int& { return o.ransac.max_score_points; }, 0, 10000000, "count",
               "at most this many part points per candidate (dense scans: the share is estimated as well from "
               "a few thousand); ICP and the final coverage use at most 4x as many; 0 = all (paper)")
          .Number("p_success", [](O& o) -> double& { return o.ransac.p_success; }, 0.5, 0.999999, "1",
                  "RANSAC success probability of eq. 7")
          .Int("max_iterations", [](O& o) -> int& { return o.ransac.max_iterations; }, 1, 100000, "count",
               "cap on the samples per model (eq. 7 starts at infinity)")
          .Int("min_iterations", [](O& o) -> int& { return o.ransac.min_iterations; }, 0, 100000, "count",
               "samples per model at least: eq. 7 assumes every covered scan point yields the pose, which noisy "
               "normals do not")
          .Number("model_tie_tolerance", [](O& o) -> float& { return o.ransac.model_tie_tolerance; }, 0, 1, "1",
                  "models covering within this share of the best are ranked by explained model surface")
          .Int("refine_iterations", [](O& o) -> int& { return o.ransac.refine_iterations; }, 0, 100, "count",
               "upright ICP steps after RANSAC (not in the paper; 0 = off)")
          // refine_plane = index of the choice: point 0 (false), plane 1 (true).
          .Enum("refine_metric", [](O& o) -> bool& { return o.ransac.refine_plane; }, {"point", "plane"},
                "ICP distance: 'point' to the nearest model sample, 'plane' along the model's horizontal normal there")
          .Number("max_shift_m", [](O& o) -> float& { return o.ransac.max_shift; }, 0, 10, "m",
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
          .Number("part_inside_fraction", &O::part_inside_fraction, 0, 1, "1",
                  "a supporting part is fitted only if this share of its points is within reach (drops floor, wall "
                  "and neighbours' parts); 0 = every part")
          .Bool("crop_parts", &O::crop_parts,
                "a part mostly out of reach contributes its points within reach (true) or nothing (false)")
          // Also RansacOptions::min_coverage: copied in ParseOptions.
          .Number("min_coverage", &O::min_coverage, 0, 1, "1",
                  "reject when the model covers less than this share of the part points (paper: 0.5)")
          .Number("max_free_space_ratio", &O::max_free_space_ratio, 0, 1, "1",
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
          .Number("keep_min_coverage", &O::keep_min_coverage, 0, 1, "1",
                  "with keep_accepted: ... unless the class's best model covers less than this share of its points "
                  "(the fit contradicts the recogniser: a dresser taken for a table by its size)")
          .Bool("one_class_per_object", &O::one_class_per_object,
                "one object, one class: of accepted detections made from proposals (voters.catalog_shape) whose "
                "proposal boxes overlap by more than object_iou, those of another class than the highest-scored one "
                "are refused (a chest also fitted as a table, an armchair also as a sofa)")
          .Number("object_iou", &O::object_iou, 0.01, 1, "1",
                  "with one_class_per_object: the 3D IoU of two proposals' boxes above which they are one object")
          .Number("grid_resolution_m", [](O& o) -> double& { return o.grid.resolution; }, 0.005, 1, "m",
                  "OctoMap voxel edge [m] of the per-scan occupancy grids")
          .Number("grid_max_range_m", [](O& o) -> double& { return o.grid.max_range; }, 0, 1000, "m",
                  "rays longer than this only clear space [m]; 0 = unlimited")
          .Int("grid_cache_size", &O::grid_cache_size, 1, 1000, "count",
               "occupancy grids kept between calls (least recently used dropped)")
          .Number("free_space_margin_m", [](O& o) -> float& { return o.free_space.free_margin; }, 0, 1, "m",
                  "model points are pushed this far from the sensor before the free-space look-up")
          .Number("visibility_margin_m", [](O& o) -> float& { return o.free_space.visibility_margin; }, 0, 1, "m",
                  "model points this far behind the model's own front surface count as self-occluded")
          .Int("free_space_erosion", [](O& o) -> int& { return o.free_space.erosion; }, 0, 1, "1",
               "1: a model point is in free space only if its voxel and the 6 neighbours are free; 0: its voxel")
          .Bool("synthesis", &O::synthesis,
                "recognition by analysis by synthesis on scans with a sensor origin: the class's catalog models are "
                "posed on each detection (x, y, yaw, a stretch per axis within the class's catalog sizes), rendered as "
                "the sensor would see them and compared with what it measured (surface explained, surface where it "
                "saw through: free space); the set of objects that explains the view is chosen jointly (false: the "
                "paper's RANSAC coverage and OctoMap free-space verification)")
          .Object("class_map", nlohmann::json::object(),
                  "synthesis: catalog class -> detected class (as the recogniser's), e.g. {\"armchair\": \"chair\"}: a "
                  "detection of a class is fitted with the models of every catalog class mapped onto it",
                  [](O& o, const nlohmann::json& j) {
                    for (auto it = j.begin(); it != j.end(); ++it) {
                      if (!it->is_string() || it->get<std::string>().empty())
                        throw InputError("class_map/" + it.key() + ": expected a class name");
                      o.class_map[it.key()] = it->get<std::string>();
                    }
                  })
          .Int("models_per_detection", &O::models_per_detection, 1, 100, "count",
               "synthesis: catalog models posed per detection (the recogniser's, then the class's closest in size)")
          .Int("render_samples", &O::render_samples, 100, 100000, "count",
               "synthesis: surface samples a model is rendered with (about; 1.5-6 cm apart)")
          .Number("stretch_margin", &O::stretch_margin, 0, 1, "1",
                  "synthesis: a model may be stretched to the class's catalog sizes widened by this share")
          .Number("view_pixel_scale", [](O& o) -> float& { return o.view.pixel_scale; }, 0.1, 10, "1",
                  "synthesis: range image pixel edge as a multiple of the scan's mean angular point spacing")
          .Number("seen_tolerance_m", [](O& o) -> float& { return o.compare.seen_tolerance; }, 0.001, 1, "m",
                  "synthesis: a model surface whose measured depth is within this (plus seen_per_m2 x depth^2) is seen")
          .Number("seen_per_m2", [](O& o) -> float& { return o.compare.seen_per_m2; }, 0, 1, "1/m",
                  "synthesis: the range-dependent part of the depth tolerances [1/m]")
          .Number("free_margin_m", [](O& o) -> float& { return o.compare.free_margin; }, 0.001, 2, "m",
                  "synthesis: a model surface with a measurement this far behind it is in free space")
          .Number("free_weight", [](O& o) -> float& { return o.search.free_weight; }, 0, 100, "1",
                  "synthesis: pose objective = furniture surface explained - free_weight x surface in free space")
          .Number("search_shift_m", [](O& o) -> float& { return o.search.max_shift; }, 0, 10, "m",
                  "synthesis: farthest a pose search moves a model from its start")
          .Int("search_starts", [](O& o) -> int& { return o.search.keep_starts; }, 1, 100, "count",
               "synthesis: best starting poses searched from (of 8 per model: 4 yaws x 2 positions)")
          .Int("search_evaluations", [](O& o) -> int& { return o.search.max_evaluations; }, 1, 10000, "count",
               "synthesis: renderings per searched start")
          .Number("select_pixel_deg", &O::select_pixel_deg, 0.05, 10, "deg",
                  "synthesis: pixel size at which the objects' explained surfaces are compared for the joint choice")
          .Number("min_new_share", &O::min_new_share, 0, 1, "1",
                  "synthesis: a detection whose explained surface is explained by better-scored kept ones but for "
                  "less than this share is explained away (a duplicate, or several objects read as one)")
          .Number("max_box_iou", &O::max_box_iou, 0, 1, "1",
                  "synthesis: a detection whose box overlaps a better-scored kept one's by more 3D IoU is explained "
                  "away (two objects do not stand in one place; a chair pushed under a table overlaps it by about 0.2)")
          .Int("max_candidates", &O::max_candidates, 1, 100000, "count",
               "synthesis: detections searched per scene and class, those whose first poses explain the most first "
               "(the others are dropped)")
          .Number("shape_exponent", &O::shape_exponent, 0, 10, "1",
                  "synthesis: score = max(recogniser score, prior_floor)^this x explained share^explained_exponent x "
                  "(seen / (seen + free))^agreement_exponent x completeness^completeness_exponent x (1 - "
                  "exp(-seen / evidence_m2)) x share left by the joint choice")
          .Number("prior_floor", &O::prior_floor, 0, 1, "1",
                  "synthesis: the recogniser's score counts at least this much (a fragment of an object, a chair "
                  "seen under a table, has a shape unlike its class's)")
          .Number("explained_exponent", &O::explained_exponent, 0, 10, "1",
                  "synthesis: exponent of the share of the detection's own points the model explains")
          .Number("agreement_exponent", &O::agreement_exponent, 0, 10, "1",
                  "synthesis: exponent of the model's seen surface over its seen and free surface")
          .Number("completeness_exponent", &O::completeness_exponent, 0, 10, "1",
                  "synthesis: exponent of the share of the model's surface facing the sensor (not hidden behind "
                  "anything measured) that it saw: the seen surface over the seen, free and unmeasured")
          .Number("evidence_m2", &O::evidence_m2, 0, 100, "m2",
                  "synthesis: the score is also multiplied by 1 - exp(-seen / evidence_m2): a few square centimetres "
                  "that a model explains fully are weak evidence of it (0 = off)")
      , DecisionFields{&O::thresholds, &O::default_threshold}, {"", "synthesis: ", false});
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
    if (o_.synthesis) {
      bool any_origin = false;
      for (const SceneParts& sp : ctx.scenes) any_origin = any_origin || (sp.scan && sp.scan->origin);
      if (any_origin) {
        arena.execute([&] { out = FitSynthesis(input, ctx); });
        return out;
      }
      spdlog::info("fitters.ransac_upright: no scan has a sensor origin; synthesis needs one: coverage fit instead");
    }
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
  std::string Mapped(const std::string& cls) const {
    auto it = o_.class_map.find(cls);
    return it == o_.class_map.end() ? cls : it->second;
  }

  // The render clouds of `models` (same order): kept per stage object, and between runs in
  // cloud_cache beside the sampled clouds (a few kilobytes each: loading them spares sampling
  // or loading the dense clouds); the missing ones thinned from the sampled clouds.
  std::vector<std::shared_ptr<const RenderCloud>> Renders(const std::vector<const CatalogModel*>& models) {
    std::vector<std::shared_ptr<const RenderCloud>> out(models.size());
    std::vector<uint64_t> keys(models.size());
    std::vector<size_t> missing;
    for (size_t i = 0; i < models.size(); ++i) {
      const uint64_t base = ModelCloud::CacheKey(*models[i], o_.sampling, Fnv1a(models[i]->id, kFnvOffsetTruncated));
      keys[i] = RenderCloud::CacheKey(base, o_.render_samples);
      std::lock_guard<std::mutex> lock(mu_);
      auto it = renders_.find(keys[i]);
      if (it != renders_.end()) out[i] = it->second;
      else missing.push_back(i);
    }
    auto path_of = [&](uint64_t key) {
      char name[32];
      std::snprintf(name, sizeof(name), "%016llx.fhrc", static_cast<unsigned long long>(key));
      return o_.cloud_cache + "/" + name;
    };
    std::vector<size_t> sample;
    for (size_t i : missing) {
      if (!o_.cloud_cache.empty())
        if (auto r = RenderCloud::Load(path_of(keys[i]), keys[i])) {
          out[i] = std::move(r);
          continue;
        }
      sample.push_back(i);
    }
    if (!sample.empty()) {
      std::vector<const CatalogModel*> ms;
      for (size_t i : sample) ms.push_back(models[i]);
      const std::vector<std::shared_ptr<const ModelCloud>> clouds = Clouds(ms);
      for (size_t k = 0; k < sample.size(); ++k) {
        const size_t i = sample[k];
        auto r = std::make_shared<const RenderCloud>(
            MakeRenderCloud(clouds[k]->Cloud(), clouds[k]->Bounds(), o_.render_samples));
        if (!o_.cloud_cache.empty()) {
          try {
            r->Save(path_of(keys[i]), keys[i]);
          } catch (const std::exception& e) {
            if (!cache_warned_.exchange(true))
              spdlog::warn("fitters.ransac_upright: render clouds not cached ({})", e.what());
          }
        }
        out[i] = std::move(r);
      }
    }
    std::lock_guard<std::mutex> lock(mu_);
    for (size_t i : missing) renders_.emplace(keys[i], out[i]);
    return out;
  }

  // Per scan point: 1 when it may belong to furniture (neither the proposer's wall or floor,
  // nor within 5 cm of the ground).
  static std::vector<uint8_t> ObjectPoints(const SceneParts& sp) {
    const Scan& scan = *sp.scan;
    std::vector<uint8_t> obj(scan.points.size(), 1);
    const bool removed = sp.proposals && sp.proposals->removed.size() == scan.points.size();
    for (size_t i = 0; i < scan.points.size(); ++i) {
      if (removed && sp.proposals->removed[i]) obj[i] = 0;
      else if (scan.ground && scan.ground->Above(scan.points[i]) < 0.05f) obj[i] = 0;
    }
    return obj;
  }

  // Recognition by analysis by synthesis. Every detection (a recogniser's hypothesis of a class
  // on a proposal, or a voter's on its supporting parts) is first tried with its class's
  // closest catalog model at a few starting poses; the max_candidates per scene that explain
  // the most (weighed by the recogniser's score, floored at prior_floor: a fragment's shape
  // says little) get the full pose search (SearchPose) over models_per_detection models. A
  // detection's score combines that prior with the share of its own points the model explains
  // and the model's seen surface against its surface in free space; then the detections are
  // taken by score, each keeping the furniture surface no better one explains (ExplainAway): a
  // table and the chair under it both stay, a sofa that would explain both after them is
  // explained away.
  struct SynthesisInput {
    Points points;               // the detection's points (world frame, above the floor)
    shape::Footprint footprint;  // of those points
    float top = 0.f, floor_z = 0.f;
    std::vector<size_t> models;  // indices into the class's models, closest first
  };

  // The starting poses of `models` (the first `count`) for a detection: its footprint's centre
  // and, when it differs, the position that puts the model's near face on the points' near face
  // (a view sees an object's front); four yaws along the footprint's axes; the model stretched
  // uniformly to the points' top, within its class's range.
  static std::vector<Start> Starts(const SynthesisInput& in, const std::vector<const CatalogModel*>& class_models,
                                   const std::vector<StretchRange>& ranges, size_t count, const Eigen::Vector3f& eye) {
    std::vector<Start> starts;
    const shape::Footprint& f = in.footprint;
    Eigen::Vector2f dir = f.center - eye.head<2>();
    dir = dir.norm() > 1e-3f ? Eigen::Vector2f(dir.normalized()) : Eigen::Vector2f(1.f, 0.f);
    float near = INFINITY;
    for (const auto& q : in.points) near = std::min(near, (q.head<2>() - f.center).dot(dir));
    for (size_t r = 0; r < count && r < in.models.size(); ++r) {
      const Eigen::Vector3f z = class_models[in.models[r]]->size;
      const bool wide = z.x() >= z.y();
      const StretchRange& sr = ranges[r];
      const float s0 = std::clamp(in.top / z.z(), sr.lo.z(), sr.hi.z());
      for (int q = 0; q < 4; ++q) {
        ModelPlacement p;
        p.yaw = f.yaw + (wide ? 0.f : float(M_PI / 2)) + float(q) * float(M_PI / 2);
        p.sx = p.sy = p.sz = s0;
        p.x = f.center.x(), p.y = f.center.y(), p.z = in.floor_z;
        starts.push_back({int(r), p});
        const float c = std::cos(p.yaw), s = std::sin(p.yaw);
        const float half = 0.5f * s0 * (std::abs(c * dir.x() + s * dir.y()) * z.x() + std::abs(-s * dir.x() + c * dir.y()) * z.y());
        const float shift = near + half;
        if (std::abs(shift) > 0.02f) {
          p.x = f.center.x() + dir.x() * shift, p.y = f.center.y() + dir.y() * shift;
          starts.push_back({int(r), p});
        }
      }
    }
    return starts;
  }

  std::vector<Detection> FitSynthesis(const std::vector<Detection>& input, const FitContext& ctx) {
    Stopwatch sw;
    // The views: every scan with a sensor origin.
    std::vector<std::unique_ptr<RangeImage>> images;
    std::vector<View> views;
    Eigen::Vector3f eye = Eigen::Vector3f::Zero();  // the first view's sensor, world frame
    for (const SceneParts& sp : ctx.scenes) {
      if (!sp.scan || !sp.scan->origin) continue;
      images.push_back(std::make_unique<RangeImage>(sp.scan->points, ObjectPoints(sp), *sp.scan->origin, o_.view));
      if (views.empty()) eye = sp.scan->pose * *sp.scan->origin;
      views.push_back({images.back().get(), sp.scan->pose.inverse()});
    }
    const double ms_images = sw.Ms();
    const Scan* ground_scan = nullptr;
    for (const SceneParts& sp : ctx.scenes)
      if (sp.scan && !ground_scan) ground_scan = sp.scan;
    // The level of the joint choice: pixels about select_pixel_deg wide.
    int sel = 0;
    {
      const float want = o_.select_pixel_deg * float(M_PI / 180.0);
      float best = INFINITY;
      for (int l = 0; l < images.front()->Levels(); ++l) {
        const float d = std::abs(std::log(images.front()->PixelRad(l) / want));
        if (d < best) best = d, sel = l;
      }
    }
    // Models per detected class, their stretch ranges (the class's catalog sizes, widened).
    std::map<std::string, std::vector<const CatalogModel*>> by_class;
    for (const CatalogModel* m : ctx.catalog)
      if (m) by_class[Mapped(m->cls)].push_back(m);
    std::set<std::string> wanted;
    for (const auto& d : input) wanted.insert(d.cls);
    std::vector<const CatalogModel*> needed;
    for (const auto& [cls, ms] : by_class)
      if (wanted.count(cls)) needed.insert(needed.end(), ms.begin(), ms.end());
    const std::vector<std::shared_ptr<const RenderCloud>> renders = Renders(needed);
    std::map<const CatalogModel*, std::shared_ptr<const RenderCloud>> render_of;
    for (size_t i = 0; i < needed.size(); ++i) render_of[needed[i]] = renders[i];
    std::map<const CatalogModel*, StretchRange> range_of;
    for (const auto& [cls, ms] : by_class) {
      Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = Eigen::Vector3f::Zero();  // length, width, height
      for (const CatalogModel* m : ms) {
        const Eigen::Vector3f lwh(std::max(m->size.x(), m->size.y()), std::min(m->size.x(), m->size.y()), m->size.z());
        lo = lo.cwiseMin(lwh), hi = hi.cwiseMax(lwh);
      }
      const float a = 1.f - o_.stretch_margin, b = 1.f + o_.stretch_margin;
      for (const CatalogModel* m : ms) {
        const Eigen::Vector3f z = m->size;
        const bool wide = z.x() >= z.y();
        StretchRange sr;
        sr.lo = a * Eigen::Vector3f((wide ? lo.x() : lo.y()) / z.x(), (wide ? lo.y() : lo.x()) / z.y(), lo.z() / z.z());
        sr.hi = b * Eigen::Vector3f((wide ? hi.x() : hi.y()) / z.x(), (wide ? hi.y() : hi.x()) / z.y(), hi.z() / z.z());
        range_of[m] = sr;
      }
    }
    // The detections of classes with models, and their points.
    std::vector<size_t> cand;
    for (size_t d = 0; d < input.size(); ++d)
      if (by_class.count(input[d].cls)) cand.push_back(d);
    std::vector<SynthesisInput> in(cand.size());
    for (size_t k = 0; k < cand.size(); ++k) {
      const Detection& det = input[cand[k]];
      std::vector<Eigen::AlignedBox3f> boxes;
      for (const CatalogModel* m : by_class.at(det.cls)) boxes.push_back(render_of.at(m)->bounds);
      in[k].floor_z = ground_scan ? ground_scan->GroundZ(det.center.x(), det.center.y()) : 0.f;
      int dropped = 0;
      in[k].points = Gather(det, ctx, &boxes, in[k].floor_z, &dropped, nullptr).points;
    }
    auto ranges_of = [&](const Detection& det, const SynthesisInput& x) {
      std::vector<StretchRange> r;
      for (size_t m : x.models) r.push_back(range_of.at(by_class.at(det.cls)[m]));
      return r;
    };
    auto renders_of = [&](const Detection& det, const SynthesisInput& x) {
      std::vector<const RenderCloud*> r;
      for (size_t m : x.models) r.push_back(render_of.at(by_class.at(det.cls)[m]).get());
      return r;
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    // Screening: each detection's closest model at its starts.
    std::vector<double> screen(cand.size(), -1e300);
    tbb::parallel_for(size_t(0), cand.size(), [&](size_t k) {
      const Detection& det = input[cand[k]];
      SynthesisInput& x = in[k];
      if (x.points.size() < 5) return;
      std::vector<Eigen::Vector2f> xy(x.points.size());
      std::vector<float> hz(x.points.size());
      for (size_t i = 0; i < x.points.size(); ++i) xy[i] = x.points[i].head<2>(), hz[i] = x.points[i].z() - x.floor_z;
      x.footprint = shape::OrientedFootprint(xy);
      const size_t q = hz.size() * 98 / 100;
      std::nth_element(hz.begin(), hz.begin() + long(q), hz.end());
      x.top = std::max(hz[q], 0.05f);
      // The class's models: the recogniser's first, then the closest in size.
      const std::vector<const CatalogModel*>& ms = by_class.at(det.cls);
      std::vector<std::pair<float, size_t>> rank;
      for (size_t m = 0; m < ms.size(); ++m) {
        const Eigen::Vector3f& z = ms[m]->size;
        const float e = ms[m]->id == det.model ? -1.f
                                               : std::abs(std::log(std::max(x.footprint.length, 0.05f) / std::max(z.x(), z.y()))) +
                                                     std::abs(std::log(std::max(x.footprint.width, 0.05f) / std::min(z.x(), z.y()))) +
                                                     std::abs(std::log(x.top / z.z()));
        rank.emplace_back(e, m);
      }
      std::stable_sort(rank.begin(), rank.end());
      for (size_t r = 0; r < rank.size() && r < size_t(o_.models_per_detection); ++r) x.models.push_back(rank[r].second);
      SearchOptions once = o_.search;
      once.keep_starts = 1;
      once.max_evaluations = 0;
      const SearchResult r = SearchPose(renders_of(det, x), ranges_of(det, x),
                                        Starts(x, ms, ranges_of(det, x), 1, eye), views, o_.compare, once,
                                        &scratch.local());
      if (r.model < 0) return;
      // How much of its own surface the start explains, and how little of the model's the
      // sensor saw through, weighed by the prior.
      std::vector<uint64_t> own;
      std::vector<float> own_area;
      PointPixels(x.points, views, sel, o_.compare, &own, &own_area);
      double total = 0.0;
      for (float a : own_area) total += a;
      const Comparison& c = r.comparison;
      if (!(total > 0.0) || !(c.seen_object > 0.0)) return;
      screen[k] = std::pow(std::max(double(det.score), double(o_.prior_floor)), double(o_.shape_exponent)) *
                  std::min(1.0, c.seen_object / total) * c.seen_object / (c.seen_object + c.free);
    });
    // Per scene and class, the max_candidates that screened best.
    std::vector<size_t> order;  // into cand
    for (size_t k = 0; k < cand.size(); ++k)
      if (screen[k] > 0.0) order.push_back(k);
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return screen[a] > screen[b]; });
    {
      std::map<std::pair<int, std::string>, int> per_scene;
      std::vector<size_t> kept;
      for (size_t k : order) {
        const Detection& det = input[cand[k]];
        const int scene = det.proposal >= 0 ? det.proposal_scene : (det.support.empty() ? 0 : det.support.front().scene);
        if (per_scene[{scene, det.cls}]++ < o_.max_candidates) kept.push_back(k);
      }
      order.swap(kept);
    }
    const double ms_screen = sw.Ms();
    struct Fitted {
      SearchResult r;
      const CatalogModel* model = nullptr;
      ExplainedPixels pixels;
      double explained_share = 0.0, own_area = 0.0, explained_area = 0.0;
      float prior = 0.f;
    };
    std::vector<Fitted> fit(order.size());
    tbb::parallel_for(size_t(0), order.size(), [&](size_t j) {
      const size_t k = order[j];
      const Detection& det = input[cand[k]];
      const SynthesisInput& x = in[k];
      Scratch& sc = scratch.local();
      const std::vector<const CatalogModel*>& ms = by_class.at(det.cls);
      const std::vector<const RenderCloud*> renders = renders_of(det, x);
      Fitted& ft = fit[j];
      ft.r = SearchPose(renders, ranges_of(det, x), Starts(x, ms, ranges_of(det, x), x.models.size(), eye), views,
                        o_.compare, o_.search, &sc);
      if (ft.r.model < 0) return;
      ft.model = ms[x.models[size_t(ft.r.model)]];
      std::vector<uint64_t> keys;
      std::vector<float> areas;
      ComparePose(*renders[size_t(ft.r.model)], ft.r.pose, views, o_.compare, &sc, &keys, &areas, sel);
      std::vector<size_t> idx(keys.size());
      for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
      std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return keys[a] < keys[b]; });
      for (size_t i : idx) {
        if (!ft.pixels.keys.empty() && ft.pixels.keys.back() == keys[i]) {
          ft.pixels.areas.back() += areas[i];
        } else {
          ft.pixels.keys.push_back(keys[i]);
          ft.pixels.areas.push_back(areas[i]);
        }
      }
      std::vector<uint64_t> own;
      std::vector<float> own_area;
      PointPixels(x.points, views, sel, o_.compare, &own, &own_area);
      // The share of the detection's surface the model explains, the detection's surface being
      // its own points' pixels and those the model explains: a model that moved from a fragment
      // onto its whole object is judged on that object, one that leaves most of its own points
      // unexplained (a chair model on a table with a chair under it) loses.
      double own_total = 0.0, unexplained = 0.0, explained = 0.0;
      for (size_t i = 0; i < own.size(); ++i) {
        own_total += own_area[i];
        if (!std::binary_search(ft.pixels.keys.begin(), ft.pixels.keys.end(), own[i])) unexplained += own_area[i];
      }
      for (float a : ft.pixels.areas) explained += a;
      ft.own_area = own_total;
      ft.explained_area = explained;
      ft.explained_share = explained + unexplained > 0.0 ? explained / (explained + unexplained) : 0.0;
      const Comparison& c = ft.r.comparison;
      const double agree = c.seen_object + c.free > 0.0 ? c.seen_object / (c.seen_object + c.free) : 0.0;
      ft.prior = float(std::pow(std::max(double(det.score), double(o_.prior_floor)), double(o_.shape_exponent)));
      const double visible = c.seen_object + c.seen_other + c.free + c.unknown;
      const double complete = visible > 0.0 ? c.seen_object / visible : 0.0;
      ft.pixels.score = ft.prior * std::pow(ft.explained_share, double(o_.explained_exponent)) *
                        std::pow(agree, double(o_.agreement_exponent)) *
                        std::pow(complete, double(o_.completeness_exponent)) *
                        (o_.evidence_m2 > 0.f ? 1.0 - std::exp(-c.seen_object / double(o_.evidence_m2)) : 1.0);
    });
    // The joint choice.
    std::vector<ExplainedPixels> chosen(order.size());
    for (size_t j = 0; j < order.size(); ++j) {
      chosen[j] = fit[j].pixels;
      if (fit[j].model) {
        const Eigen::AlignedBox3f& b = render_of.at(fit[j].model)->bounds;
        const ModelPlacement& p = fit[j].r.pose;
        chosen[j].box = OrientedBox{p.Apply(b.center()), b.sizes().cwiseProduct(Eigen::Vector3f(p.sx, p.sy, p.sz)), p.yaw}.Aabb();
      }
    }
    const std::vector<Choice> choice = ExplainAway(chosen, o_.min_new_share, o_.max_box_iou);
    std::vector<Detection> out;
    for (size_t j = 0; j < order.size(); ++j) {
      const Fitted& ft = fit[j];
      Detection det = input[cand[order[j]]];
      det.checks.clear();
      det.free_space_ratio.reset();
      det.coverage.reset();
      det.rms.reset();
      det.iterations = ft.r.evaluations;
      const float voter_score = det.score;
      if (!ft.model) continue;
      const Eigen::AlignedBox3f& bounds = render_of.at(ft.model)->bounds;
      ModelPlacement p = ft.r.pose;
      p.yaw = std::remainder(p.yaw, float(2 * M_PI));
      const Comparison& c = ft.r.comparison;
      det.model = ft.model->id;
      det.model_pose = p.Rigid();
      det.yaw = p.yaw;
      const Eigen::Vector3f size = bounds.sizes().cwiseProduct(Eigen::Vector3f(p.sx, p.sy, p.sz));
      det.center = p.Apply(bounds.center());
      det.box = OrientedBox{det.center, size, p.yaw};
      det.box_source = "model";
      det.coverage = float(ft.explained_share);
      const double seen = c.seen_object + c.seen_other;
      det.free_space_ratio = seen + c.free > 0.0 ? float(c.free / (seen + c.free)) : 0.f;
      det.score = float(ft.pixels.score) * choice[j].share;
      det.evidence["recogniser_score"] = voter_score;
      det.evidence["syn_seen_m2"] = float(c.seen_object);
      det.evidence["syn_seen_other_m2"] = float(c.seen_other);
      det.evidence["syn_free_m2"] = float(c.free);
      det.evidence["syn_occluded_m2"] = float(c.occluded);
      det.evidence["syn_unknown_m2"] = float(c.unknown);
      det.evidence["syn_own_m2"] = float(ft.own_area);
      det.evidence["syn_explained_m2"] = float(ft.explained_area);
      det.evidence["syn_explained_share"] = float(ft.explained_share);
      det.evidence["syn_new_share"] = choice[j].share;
      det.evidence["syn_stretch_x"] = p.sx;
      det.evidence["syn_stretch_y"] = p.sy;
      det.evidence["syn_stretch_z"] = p.sz;
      const auto thr = o_.thresholds.find(det.cls);
      det.checks.push_back(Check::AtMost("free_space_ratio", *det.free_space_ratio, o_.max_free_space_ratio));
      det.checks.push_back(Check::AtLeast("score", det.score, thr == o_.thresholds.end() ? o_.default_threshold : thr->second));
      det.checks.push_back(Check::AtLeast("new_share", choice[j].share, o_.min_new_share));
      det.checks.push_back(Check::AtMost("box_iou_with_kept", choice[j].overlap, o_.max_box_iou));
      det.verified = std::all_of(det.checks.begin(), det.checks.end(), [](const Check& x) { return x.passed; });
      if (!choice[j].kept) det.notes.push_back("explained away by better-scored detections");
      out.push_back(std::move(det));
    }
    spdlog::debug("fitters.ransac_upright: synthesis: images {:.0f} ms, {} detections screened ({:.0f} ms), {} searched "
                  "({:.0f} ms)", ms_images, cand.size(), ms_screen - ms_images, order.size(), sw.Ms() - ms_screen);
    return out;
  }

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
  // `models`: the class's model boxes (model frame).
  Reach ReachOf(const Detection& det, const std::vector<Eigen::AlignedBox3f>& models, float floor_z) const {
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
  static std::vector<Eigen::AlignedBox3f> Boxes(const std::vector<const ModelCloud*>& models) {
    std::vector<Eigen::AlignedBox3f> b;
    for (const ModelCloud* m : models) b.push_back(m->Bounds());
    return b;
  }

  // Normals estimated for a proposal's points, by (scene, proposal, lowest height kept): the
  // candidates of several classes on one proposal share them.
  using NormalsCache = std::map<std::tuple<int, int, float>, Points>;

  ScenePoints Gather(const Detection& det, const FitContext& ctx, const std::vector<Eigen::AlignedBox3f>* models,
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
  std::map<uint64_t, std::shared_ptr<const RenderCloud>> renders_;
  std::vector<GridEntry> grids_;
  uint64_t clock_ = 0;
};

}  // namespace
}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::RansacUprightFitter, "fitters.ransac_upright", "1.6.0",
                 "upright RANSAC fit of catalog models (x, y, yaw) with coverage and OctoMap free-space verification")
