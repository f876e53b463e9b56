// Training and detection through a validated graph: the orchestration shared by the CLI,
// `furnihost eval` and the integration tests.
#pragma once
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "furnihost/catalog.hpp"
#include "furnihost/config.hpp"
#include "furnihost/frame.hpp"
#include "furnihost/normaliser.hpp"
#include "furnihost/registry.hpp"
#include "furnihost/stage.hpp"

namespace furnihost {

constexpr int kModelFormatVersion = 1;

// One voter's learned model: its features' normaliser and what its Train returned.
struct TrainedVoter {
  std::string voter_type;
  Normaliser normaliser;
  nlohmann::json voter_model;
};

// The learned model: everything detection needs besides the plugins themselves.
struct TrainedModel {
  int format_version = kModelFormatVersion;
  nlohmann::json training_config;  // the graph parts that shape the model (see TrainingKey)
  std::string catalog_hash;
  // A graph with one voter: its model (the file layout of every model before graphs could
  // hold several voters).
  std::string voter_type;
  Normaliser normaliser;
  nlohmann::json voter_model;
  // A graph with several voters: each one's model by voter tag (the fields above stay empty).
  std::map<std::string, TrainedVoter> voters;
  nlohmann::json summary;  // models, views, parts per class, time per stage

  // The model of the voter `tag`, or null when the file has none for it.
  const TrainedVoter* FindVoter(const std::string& tag) const;
};

// The subset of a resolved graph that determines the trained model: the seed, the training
// sensor and, for each voter, the segmenter, features and voter (type + params) it learns
// through. One voter: {seed, training_sensor, segmenter, features, voter} as before; several:
// {seed, training_sensor, voters: {tag: {segmenter, features, voter}}}, so a model cache of
// the other shape is stale and retrained.
FURNIHOST_API nlohmann::json TrainingKey(const GraphConfig& graph);

// Writes atomically: magic line "furnihost-model\n" followed by CBOR.
FURNIHOST_API void SaveModel(const std::string& path, const TrainedModel& model);
// InputError on a missing/corrupt file or another format version (says what to do).
FURNIHOST_API TrainedModel LoadModel(const std::string& path);
// "" when compatible, else one line saying what differs.
FURNIHOST_API std::string Incompatibility(const TrainedModel& model, const GraphConfig& graph,
                                          const std::string& catalog_hash);

// The stages of a graph, created once and reused for every scan.
class FURNIHOST_API Pipeline {
 public:
  Pipeline(const GraphConfig& graph, const Registry& registry);
  const GraphConfig& Graph() const { return graph_; }

  bool HasDetectionChain() const { return !voters_.empty(); }
  std::vector<std::string> MissingStages() const;  // kinds absent from the detection chain

  TrainedModel Train(const Catalog& catalog, const RunContext& ctx);

  struct SceneInput {
    std::string path;
    // A scan already in memory (ScanFromPoints with frame.shift): the input sensor takes it
    // instead of reading `path`, which then only names it.
    std::shared_ptr<const Scan> scan;
    std::optional<Eigen::Vector3f> origin;  // in the file's frame
    Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
    FrameOptions frame;                      // up axis / transform / global shift
    // Gaussian noise [m] added to the points as read, before the frame and every stage
    // (JitterPoints with jitter_seed; 0 = none): `furnihost eval --jitter`.
    float jitter_m = 0.f;
    uint64_t jitter_seed = 0;
  };
  // With several stages of a kind, the fields below hold the first one's output (execution
  // order); `detections` holds every sink's (GraphConfig::Sinks).
  struct Result {
    std::vector<Scan> scans;
    std::vector<Segmentation> segmentations;
    std::vector<Proposals> proposals;     // one per scan when the graph has a proposer
    std::vector<FeatureMatrix> features;  // normalised (for the first voter) when a model was given
    size_t clamped_features = 0;
    VoteResult votes;
    // Every sink's detections in execution order of the sinks; with several sinks each names
    // its sink in Detection::chain.
    std::vector<Detection> detections;
    std::vector<std::string> sinks;  // the tags of the sinks that ran
    bool voted = false, fitted = false;
    // The world frame (detections, votes) is the first scan's working frame; this maps it to
    // the frame the user gave the scans in: the first scan's z-up frame, moved by its --pose.
    Eigen::Isometry3f world_to_user = Eigen::Isometry3f::Identity();
    std::vector<std::pair<std::string, double>> timings_ms;  // stage tag -> ms, in order
  };
  // Runs the chain on the scenes (fused into one vote space when there are several).
  // `model` may be null when the graph has no voter. `before_stages`, when given, is called
  // once the scans are read, framed and grounded, before the first stage reads `model` or
  // `catalog`: a caller may fill those meanwhile on another thread and wait for it there.
  // With the graph's ensemble (EnsembleOptions) the chain runs ensemble.runs times: first on
  // the scans as read, then on jittered copies; the detections are the runs' fused
  // (FuseDetections), every other field is the first run's (the timings summed).
  Result Detect(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                const Catalog* catalog, const RunContext& ctx, const std::function<void()>& before_stages = {});

  // Calls `f` and rethrows any exception with the stage tag and type in front.
  template <class F>
  auto Call(const StageConfig& s, F&& f) -> decltype(f());

 private:
  // An ensemble's run after the first: each scan jittered as read, the noise drawn along the
  // axes of the first run's working frame of that scan (`reference`: the first run's scans).
  struct RunJitter {
    float sigma_m = 0.f;
    uint64_t seed = 0;
    const std::vector<Scan>* reference = nullptr;
  };
  // One run of the chain.
  Result DetectOnce(const std::vector<SceneInput>& scenes, const TrainedModel* model, const Catalog* catalog,
                    const RunContext& ctx, const std::function<void()>& before_stages, const RunJitter& run_jitter);
  // One trained voter's plugin and the model id it has loaded.
  struct VoterSlot {
    std::shared_ptr<Voter> voter;
    std::string loaded_model_id;
  };
  GraphConfig graph_;
  const StageConfig *input_cfg_ = nullptr, *train_cfg_ = nullptr;
  std::shared_ptr<Sensor> input_, training_;
  // Every other stage's plugin by tag (segmenters, proposers, features, fitters).
  std::map<std::string, std::shared_ptr<Stage>> stages_;
  std::map<std::string, VoterSlot> voters_;  // by voter tag
  // The plugin of stage `s` as its kind's interface.
  template <class T>
  T& StageAs(const StageConfig& s) const;
  // Typical box size [w, d, h] of each class (the median of its catalog models), for the boxes
  // of detections no fitter gave a model.
  std::map<std::string, Eigen::Vector3f> class_size_;
  const Catalog* sized_catalog_ = nullptr;
};

// Fuses the detections of several runs of one chain on (jittered copies of) one scan: per
// class and chain, greedily from the highest score, a detection takes from each other run the
// best-scored one not yet taken whose box (AABB) overlaps its own at IoU >= join_iou. The
// fused detection is the first run's member's (model, pose, checks, proposal, support), or the
// top one's with proposal -1 and no support when the first run has none, with
//   score = the sum of the members' scores / runs.size() (a run without one adds 0),
//   box = the members' mean centre and size (sizes swapped into the fused box's yaw), its
//         centre and model pose moved with the box;
// a "score" check is decided again on the fused score (an accepted detection whose fused score
// falls below its threshold is rejected; a rejected one whose fused score reaches it is accepted
// when no other check failed), evidence "ensemble_runs" counts the members. A
// detection without a box joins none. Sorted by fused score (descending); deterministic.
FURNIHOST_API std::vector<Detection> FuseDetections(const std::vector<std::vector<Detection>>& runs, double join_iou);

// The median extents of each class's models in the catalog.
FURNIHOST_API std::map<std::string, Eigen::Vector3f> TypicalClassSizes(const Catalog& catalog);

// Resolves the model for a graph: loads the cache when compatible, otherwise trains and
// writes it (atomically). `force` retrains.
FURNIHOST_API TrainedModel EnsureModel(Pipeline& pipeline, const Catalog& catalog,
                                       const RunContext& ctx, bool force = false);

// A detection moved by an upright transform t (a turn about z and a translation): centre, yaw,
// model pose and box.
FURNIHOST_API Detection TransformDetection(Detection d, const Eigen::Isometry3f& t);

// Detection JSON as written to detections.json. With a scan, geometry (centre, box, model
// pose) is written in the scan's file frame (ScanFrame) and the height above its ground is
// added; without, in the working frame.
FURNIHOST_API nlohmann::json DetectionToJson(const Detection& d, const Scan* scan = nullptr);

}  // namespace furnihost
