// The pipeline: a graph's stages, created once, run on scans (detection) or on the catalog
// (training). The shared entry of the CLI, `furnihost eval` and the tests. Its parts, each in a
// header of its own and all included here: the scan input (scan_input.hpp), the model file and
// cache (model_file.hpp, model_cache.hpp), the ensemble (ensemble.hpp) and the detections'
// JSON (detections.hpp); the executor and the stage kinds' runners are the host's own
// (framework/src/host/graph/).
#pragma once
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "furnihost/host/catalog.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/detections.hpp"
#include "furnihost/host/ensemble.hpp"
#include "furnihost/host/frame.hpp"
#include "furnihost/host/model_cache.hpp"
#include "furnihost/host/model_file.hpp"
#include "furnihost/host/registry.hpp"
#include "furnihost/host/scan_input.hpp"
#include "furnihost/stage.hpp"

namespace furnihost {

namespace graph {
struct StageInstances;
}

// What training learns from one catalog model: its training sensor's views run through the
// stages training views pass through, for each trained stage in the graph's order
// (branches[t]), and the time each stage took on them [ms] by stage tag.
struct ModelViews {
  std::vector<std::vector<TrainingView>> branches;
  std::map<std::string, double> time_ms;
};

// What a trained stage learned from a class: views seen, parts in them, and models learned from
// their mesh alone (StageNeeds::training_scans false: one view of no points each).
struct TrainingCount {
  int views = 0, parts = 0, meshes = 0;
};

// What training learned from a run of the catalog's models, [begin, end), when every trained stage
// merges (StageNeeds::training_merges): each trained stage's model of the run (Voter::Train on its
// views), in the graph's order, and the counts and times the model's summary and log give.
struct TrainedRun {
  size_t begin = 0, end = 0;
  std::vector<nlohmann::json> voter_models;
  std::vector<std::map<std::string, TrainingCount>> counts;  // per trained stage, by class
  std::map<std::string, double> time_ms;                      // by stage tag
  size_t from_meshes = 0;
};

// Not thread-safe: a Pipeline runs one Detect or Train at a time (copies share its stages).
class FURNIHOST_API Pipeline {
 public:
  Pipeline(const GraphConfig& graph, const Registry& registry);
  const GraphConfig& Graph() const { return graph_; }

  // Whether the graph has a stage that gives detections.
  bool HasDetectionChain() const;
  std::vector<std::string> MissingStages() const;  // kinds absent from the detection chain

  // Trains every trained stage (voter) of the graph on the catalog (the stages' runners on the
  // training sensor's views of each model).
  TrainedModel Train(const Catalog& catalog, const RunContext& ctx);
  // Training in two steps, so that processes can share the models (furnihost train / eval
  // under MPI): ScanModel, the per-model part, for each catalog model (any order, anywhere: it
  // depends on the model, the graph and the seed only), then TrainFromViews with every model's
  // views in catalog order. Train does both here.
  ModelViews ScanModel(const Catalog& catalog, size_t index, const RunContext& ctx);
  TrainedModel TrainFromViews(const Catalog& catalog, std::vector<ModelViews> scanned, const RunContext& ctx);
  // Training in runs of models, when TrainingMerges(): TrainRun trains every trained stage on the
  // models [begin, end) (anywhere: a run depends on its models, the graph and the seed only), then
  // MergeRuns joins runs that cover the catalog in order (Voter::Merge) into the model Train gives,
  // byte for byte. Processes that share a training then share the voters' work too, not only the
  // scanning.
  bool TrainingMerges() const;
  TrainedRun TrainRun(const Catalog& catalog, size_t begin, size_t end, const RunContext& ctx);
  TrainedModel MergeRuns(const Catalog& catalog, std::vector<TrainedRun> runs, const RunContext& ctx);

  using SceneInput = furnihost::SceneInput;
  // The detections, and the outputs behind them: the fields below `scans` hold those of the
  // stages the first sink takes, directly or not (of every stage when the graph has no sink),
  // the first of each in execution order.
  struct Result {
    std::vector<Scan> scans;
    std::vector<Segmentation> segmentations;
    std::vector<Proposals> proposals;     // one per scan when the chain has a proposer
    std::vector<FeatureMatrix> features;  // what its voter voted with (normalised), else raw
    size_t clamped_features = 0;          // of every voter
    VoteResult votes;
    // Every sink's detections in execution order of the sinks; with several sinks each names
    // its sink in Detection::chain.
    std::vector<Detection> detections;
    std::vector<std::string> sinks;  // the tags of the sinks that ran
    bool voted = false, fitted = false;
    // The world frame (detections, votes) is the first scan's working frame; this maps it to
    // the frame the user gave the scans in: the first scan's z-up frame, moved by its --pose.
    Eigen::Isometry3f world_to_user = Eigen::Isometry3f::Identity();
    StageTimes timings_ms;  // stage tag -> ms, in order
  };
  // Runs the chain on the scenes (fused into one vote space when there are several).
  // `model` may be null when the graph has no voter. `before_stages`, when given, is called
  // once the scans are read, framed and grounded, before the first stage reads `model` or
  // `catalog`: a caller may fill those meanwhile on another thread and wait for it there.
  // With the graph's ensemble (EnsembleOptions) the chain runs ensemble.runs times: first on
  // the scans as read, then on jittered copies; the detections are the runs' fused
  // (FuseDetections), every other field is the first run's (the timings summed). ensemble.cpp.
  // With the graph's calibration, the detections get their confidence and are decided at its
  // min_confidence (Calibration::Apply), last.
  Result Detect(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                const Catalog* catalog, const RunContext& ctx, const std::function<void()>& before_stages = {});

 private:
  // One run of the chain: the scans read (scan_input.hpp), then the stages (the executor).
  Result DetectOnce(const std::vector<SceneInput>& scenes, const TrainedModel* model, const Catalog* catalog,
                    const RunContext& ctx, const std::function<void()>& before_stages, const RunJitter& jitter);
  void Calibrate(std::vector<Detection>& detections) const;
  GraphConfig graph_;
  std::shared_ptr<graph::StageInstances> stages_;
  const StageConfig* input_ = nullptr;  // the detection sensor
  int neighbours_ = 0;                  // what the stages ask of each scan (StageNeeds::neighbours)
};

}  // namespace furnihost
