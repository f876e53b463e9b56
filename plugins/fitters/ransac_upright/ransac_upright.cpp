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
#include "ransac_upright.hpp"

namespace furnihost::ransac_upright {

std::string CloudCacheDir(const std::string& v) {
  if (v == "off" || v.empty()) return {};
  return v == "auto" ? CacheFolder("model_clouds") : v;
}

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
          .Number("view_prior_exponent", &O::view_prior_exponent, 0, 10, "1",
                  "synthesis: the score is also multiplied by the view prior^this: how the detection's points within "
                  "the fitted model's box compare, in extents along the model's axes, top, bottom and top-view "
                  "profile, with the part of the posed model the sensor should see (its surface seen or in free "
                  "space; a chair the view's edge cuts or whose legs are hidden is compared with that part of a "
                  "chair) (0 = off)")
          .Number("class_compete_exponent", &O::class_compete_exponent, 0, 10, "1",
                  "synthesis: a detection whose box overlaps one of another class by more than max_box_iou (another "
                  "reading of the object) is weighed by (its pose objective / the best of those readings')^this: the "
                  "class whose posed model explains more of the object wins (0 = off)")
          .Number("view_prior_size", &O::view_prior_size, 0.01, 10, "1",
                  "synthesis: view prior's spread of the log ratio of the extents and tops")
          .Number("view_prior_bottom_m", &O::view_prior_bottom_m, 0.01, 10, "m",
                  "synthesis: view prior's spread of the difference of the bottoms")
          .Number("view_prior_profile", &O::view_prior_profile, 0.001, 10, "1",
                  "synthesis: view prior's spread of the top-view profiles' earth mover's distance")
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

uint64_t HypothesisSeed(uint64_t run_seed, const Detection& d) {
  const uint64_t cls = Fnv1a(d.cls, kFnvOffsetTruncated);
  return SplitMix64(run_seed ^ SplitMix64(Fnv1a(d.center.data(), sizeof(float) * 3, cls)));
}

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

std::vector<Detection> RansacUprightFitter::Fit(const std::vector<Detection>& input, const FitContext& ctx) {
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

// Sampled clouds of `models` (same order), building the missing ones in parallel.
std::vector<std::shared_ptr<const ModelCloud>> RansacUprightFitter::Clouds(const std::vector<const CatalogModel*>& models) {
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
std::shared_ptr<const octomap::OcTree> RansacUprightFitter::Grid(const Scan& scan) {
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

}  // namespace furnihost::ransac_upright

FURNIHOST_PLUGIN(furnihost::ransac_upright::RansacUprightFitter, "fitters.ransac_upright", "1.7.0",
                 "upright RANSAC fit of catalog models (x, y, yaw) with coverage and OctoMap free-space verification")
