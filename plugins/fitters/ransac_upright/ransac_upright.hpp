// fitters.ransac_upright, private to the plugin: its options and the fitter, whose steps live one
// concern per file:
//   ransac_upright.cpp  the parameters, Fit (the detections to fit, by way of the two methods) and
//                       the caches of model clouds and occupancy grids
//   fit.cpp             upright RANSAC with coverage and free-space verification (FitAll)
//   synthesis.cpp       recognition by analysis by synthesis (FitSynthesis)
#pragma once

#include <octomap/OcTree.h>

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

#include "furnihost/plugin.hpp"
#include "model_cloud.hpp"
#include "occupancy.hpp"
#include "pose_search.hpp"
#include "shape/shape.hpp"
#include "upright_ransac.hpp"
#include "view_synthesis.hpp"

namespace furnihost::ransac_upright {

// "off" -> none; "auto" -> CacheFolder("model_clouds") ($FURNIHOST_CACHE_DIR, else
// $XDG_CACHE_HOME/furnihost, else ~/.cache/furnihost, + /model_clouds); else the folder given.
std::string CloudCacheDir(const std::string& v);

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
  float view_prior_exponent = 0.f;
  float class_compete_exponent = 0.f;
  float view_prior_size = 0.25f;
  float view_prior_bottom_m = 0.15f;
  float view_prior_profile = 0.08f;
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
const ParamBinding<RansacUprightOptions>& Binding();

// The options of `p`, with the settings several steps share copied into each (ransac_upright.cpp).
RansacUprightOptions ParseOptions(const nlohmann::json& p);

// v with 2 decimals.
std::string Fixed2(double v);

// RANSAC seed of one hypothesis: the run's seed mixed with the hypothesis itself (class and
// voter centre, FNV-1a over their bytes), not with its place in the list, so a hypothesis fits
// the same whatever else the voter found (an A/B change of one class's threshold leaves the
// other classes' fits alone; with list-index seeds it re-drew all of them).
uint64_t HypothesisSeed(uint64_t run_seed, const Detection& d);

// Identifies a scan's grid in the cache: the pointer alone could be reused by a later scan.
struct GridKey {
  const Scan* scan = nullptr;
  size_t n = 0;
  uint64_t fingerprint = 0;
  bool operator==(const GridKey& o) const { return scan == o.scan && n == o.n && fingerprint == o.fingerprint; }
};

GridKey KeyOf(const Scan& s, double resolution);

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

  std::vector<Detection> Fit(const std::vector<Detection>& input, const FitContext& ctx) override;

 private:
  std::string Mapped(const std::string& cls) const {
    auto it = o_.class_map.find(cls);
    return it == o_.class_map.end() ? cls : it->second;
  }

  std::vector<std::shared_ptr<const RenderCloud>> Renders(const std::vector<const CatalogModel*>& models);

  static std::vector<uint8_t> ObjectPoints(const SceneParts& sp);

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

  static std::vector<Start> Starts(const SynthesisInput& in, const std::vector<const CatalogModel*>& class_models,
                                   const std::vector<StretchRange>& ranges, size_t count, const Eigen::Vector3f& eye);

  std::vector<Detection> FitSynthesis(const std::vector<Detection>& input, const FitContext& ctx);

  void FitAll(std::vector<Detection>* dets, const FitContext& ctx);

  void OneClassPerObject(std::vector<Detection>* dets, const FitContext& ctx) const;

  static void Reject(Detection* det, Check failed) {
    det->verified = false;
    det->checks.push_back(std::move(failed));
  }

  static std::string TrialNote(const FitResult& f, const std::vector<const ModelCloud*>& models);

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
  Reach ReachOf(const Detection& det, const std::vector<Eigen::AlignedBox3f>& models, float floor_z) const;
  static std::vector<Eigen::AlignedBox3f> Boxes(const std::vector<const ModelCloud*>& models) {
    std::vector<Eigen::AlignedBox3f> b;
    for (const ModelCloud* m : models) b.push_back(m->Bounds());
    return b;
  }

  // Normals estimated for a proposal's points, by (scene, proposal, lowest height kept): the
  // candidates of several classes on one proposal share them.
  using NormalsCache = std::map<std::tuple<int, int, float>, Points>;

  ScenePoints Gather(const Detection& det, const FitContext& ctx, const std::vector<Eigen::AlignedBox3f>* models,
                     float floor_z, int* dropped, NormalsCache* normals_cache) const;

  static void ProposalPoints(const Detection& det, const FitContext& ctx, float low, ScenePoints* sp,
                             NormalsCache* cache);

  std::vector<std::shared_ptr<const ModelCloud>> Clouds(const std::vector<const CatalogModel*>& models);

  std::shared_ptr<const octomap::OcTree> Grid(const Scan& scan);

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

}  // namespace furnihost::ransac_upright
