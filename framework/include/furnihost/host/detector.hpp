// A graph ready to run: what `furnihost detect`, `train` and `eval` and the Python module share,
// so a scan gives the same detections through each. It holds the validated graph, its stages
// (Pipeline), and the catalog and trained model, loaded once (the model from its cache, or
// trained) on a worker while the first scan is read; then detection on scan files or on points
// a program holds (Pipeline::SceneInput::scan), and evaluation on a dataset manifest.
#pragma once
#include <exception>
#include <functional>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>
#include <string>
#include <tbb/task_group.h>
#include <vector>

#include "furnihost/host/catalog.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/host/pipeline.hpp"
#include "furnihost/host/registry.hpp"

namespace furnihost {

struct DetectorOptions {
  bool strict_catalog = false;  // invalid catalog entries are fatal instead of skipped
  bool retrain = false;         // train the model even when its cache is valid
  // How the model is had (from its cache, or trained and cached; `force`: trained whatever the
  // cache holds). Empty: EnsureModel. The command line sets it to share training among MPI ranks.
  std::function<TrainedModel(Pipeline&, const Catalog&, const RunContext&, bool force)> ensure_model;
};

// What an evaluation keeps of one scene's detection: the detections (in the scan's z-up frame),
// whether a fitter ran and a voter voted, its record, the voter's centres before a fitter moved
// them, the ground truth in the z-up frame when the file's frame differs, and with
// detections_dir its frame, pose and ground (no points), so that its detections are written in
// the file's frame like detect's detections.json.
struct SceneOutcome {
  Pipeline::Result result;
  SceneRecord record;
  std::vector<Eigen::Vector3f> voter_centres;
  std::optional<std::vector<GroundTruthObject>> truth_working;
  std::optional<Scan> frame;
};

// What an evaluation run needs besides the graph (`furnihost eval`'s options).
struct EvalRunInput {
  const Dataset* dataset = nullptr;
  const std::vector<std::vector<GroundTruthObject>>* truth = nullptr;  // per scene, ReadGroundTruth
  WidthConvention width = WidthConvention::Max;
  int jobs = 0;                // scenes processed in parallel (0 = as cores and memory allow)
  // When set: each scene's detections as <dir>/<file>/<seed>/<scene>.json, <scene> the scan's
  // stem made safe and distinct (UniqueSafeNames).
  std::string detections_dir;
  std::string name;  // the config's label (progress and messages)
  std::string file;  // the config's folder in detections_dir, a safe name (UniqueSafeNames); "" = SafeName(name)
  double jitter_m = 0;         // noise added to each scene's points, drawn from the seed and the scan's path
};

class FURNIHOST_API Detector {
 public:
  // `registry` stays alive with the detector (its stages' libraries are loaded through it).
  Detector(GraphConfig graph, std::shared_ptr<const Registry> registry, const RunContext& ctx,
           const DetectorOptions& options = {});
  // Waits for a loading under way, dropping its error (a caller leaving by an exception
  // reports its own).
  ~Detector();
  Detector(const Detector&) = delete;
  Detector& operator=(const Detector&) = delete;

  const GraphConfig& Graph() const { return graph_; }
  const RunContext& Context() const { return ctx_; }
  const Registry& Plugins() const { return *registry_; }
  // Whether the graph has a voter (then detection needs the catalog and the model).
  bool HasDetectionChain() const { return pipeline_.HasDetectionChain(); }
  std::vector<std::string> MissingStages() const { return pipeline_.MissingStages(); }

  // Starts loading the catalog and the model on a worker (nothing when they are loaded, being
  // loaded, or the graph has no voter). Detect waits for it before its first stage, so reading
  // and framing a scan overlap it.
  void StartLoading();
  // Waits for the catalog and the model (starting their loading when it has not started);
  // rethrows the loading's error, after which the next call loads again.
  void WaitLoaded();
  // "cache" or "trained" once loaded (how the model was had), "none" without a voter.
  const std::string& ModelSource() const { return model_source_; }
  const Catalog& GetCatalog();    // WaitLoaded first
  const TrainedModel& GetModel();  // WaitLoaded first

  // Trains the model from the catalog now, whatever the cache holds, and writes the cache (a
  // model the loading trained a moment ago is returned as it is).
  const TrainedModel& Train();

  // Runs the graph on one group of scenes (several: fused in one vote space). InputError /
  // StageError on bad input, the loading's error included. Not reentrant: one call at a time.
  Pipeline::Result Detect(const std::vector<Pipeline::SceneInput>& scenes);

  // Runs the graph over a dataset with detection seed `seed` (the model stays the graph's) and
  // matches the detections with the ground truth: one run's figures, as `furnihost eval`
  // records them for each seed.
  RunFigures Evaluate(const EvalRunInput& input, uint64_t seed);
  // One scene of Evaluate (scene `i` of the dataset, detection seed `seed`), for callers that
  // share the scenes among processes; Figures then makes the run's figures from the outcomes
  // of all scenes, in the dataset's order (`wall_ms` and `jobs` as the caller ran them).
  SceneOutcome EvaluateScene(const EvalRunInput& input, uint64_t seed, size_t i);
  RunFigures Figures(const EvalRunInput& input, uint64_t seed, std::vector<SceneOutcome>& outcomes, double wall_ms,
                     int jobs) const;

 private:
  void Load();  // the loading task's body
  TrainedModel Ensure(const RunContext& train, bool force);
  SceneOutcome RunScene(Pipeline& p, const EvalRunInput& in, const RunContext& ctx, size_t i) const;

  GraphConfig graph_;
  std::shared_ptr<const Registry> registry_;
  RunContext ctx_;
  DetectorOptions options_;
  Pipeline pipeline_;
  Catalog catalog_;
  TrainedModel model_;
  std::string model_source_ = "none";
  bool peak_reset_ = false;  // the process's peak memory was reset when the last run began
  bool loaded_ = false, loading_ = false;
  std::exception_ptr load_error_;
  tbb::task_group loading_group_;
};

// The detections.json document of one run (`r`, made from `scenes`): the scan path(s), graph,
// seed, points, parts, stages run (and `missing` ones), the scans' frames and grounds, the sinks
// of a graph with several, every detection (DetectionToJson in the first scan's file frame) and
// the time per stage, `total_ms` that of the whole run.
FURNIHOST_API nlohmann::json DetectionsDocument(const Pipeline::Result& r,
                                                const std::vector<Pipeline::SceneInput>& scenes,
                                                const std::string& graph, uint64_t seed,
                                                const std::vector<std::string>& missing, double total_ms);

// The summary of an evaluation (summary.json of `furnihost eval` without the git and machine
// records the command adds): the dataset, the matching rules, and each config's figures.
FURNIHOST_API nlohmann::json EvalSummaryJson(const Dataset& dataset, const std::string& dataset_hash,
                                             WidthConvention width, const std::vector<ConfigSummary>& configs);
// The dataset as a run record names it: path, hash, scenes, classes and class map.
FURNIHOST_API nlohmann::json DatasetJson(const Dataset& dataset, const std::string& dataset_hash);

// An error's text on one line, whatever it quotes (file names, parser excerpts of binary
// files): control characters become spaces and bytes that are not UTF-8 become '?'. What the
// command line prints after "furnihost: error: " and the Python module raises.
FURNIHOST_API std::string OneLine(const std::string& text);

// The folder of the shipped graph configs (configs/) and the bundled data (data/catalog,
// data/demo): <prefix>/share/furnihost beside an installed host library (HostLibraryDir), else
// the source tree the host was built from; "" when neither holds configs/.
FURNIHOST_API std::string ShareDir();

// The graph a scan is detected with when none is given, by what the scan says: with a sensor
// origin (--origin, or a PCD's VIEWPOINT) a one-spot scan, the laser route
// (configs/laser_room.json); without, a room reconstruction (configs/room.json). Both train on
// the bundled catalog. Returns the config's path under ShareDir(); InputError when it is missing.
FURNIHOST_API std::string DefaultGraph(bool has_origin);

}  // namespace furnihost
