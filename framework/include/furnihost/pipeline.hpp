// Training and detection through a validated graph: the orchestration shared by the CLI,
// `furnihost eval` and the integration tests.
#pragma once
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

// The learned model: everything detection needs besides the plugins themselves.
struct TrainedModel {
  int format_version = kModelFormatVersion;
  nlohmann::json training_config;  // the graph parts that shape the model (see TrainingKey)
  std::string catalog_hash;
  std::string voter_type;
  Normaliser normaliser;
  nlohmann::json voter_model;
  nlohmann::json summary;  // models, views, parts per class, time per stage
};

// The subset of a resolved graph that determines the trained model: training sensor,
// segmenter, features and voter (type + params) and the seed.
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

  bool HasDetectionChain() const { return voter_ != nullptr; }
  std::vector<std::string> MissingStages() const;  // kinds absent from the detection chain

  TrainedModel Train(const Catalog& catalog, const RunContext& ctx);

  struct SceneInput {
    std::string path;
    std::optional<Eigen::Vector3f> origin;  // in the file's frame
    Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
    FrameOptions frame;                      // up axis / transform / global shift
  };
  struct Result {
    std::vector<Scan> scans;
    std::vector<Segmentation> segmentations;
    std::vector<Proposals> proposals;     // one per scan when the graph has a proposer
    std::vector<FeatureMatrix> features;  // normalised when a model was given
    size_t clamped_features = 0;
    VoteResult votes;
    std::vector<Detection> detections;
    bool voted = false, fitted = false;
    // The world frame (detections, votes) is the first scan's working frame; this maps it to
    // the frame the user gave the scans in: the first scan's z-up frame, moved by its --pose.
    Eigen::Isometry3f world_to_user = Eigen::Isometry3f::Identity();
    std::vector<std::pair<std::string, double>> timings_ms;  // stage tag -> ms, in order
  };
  // Runs the chain on the scenes (fused into one vote space when there are several).
  // `model` may be null when the graph has no voter.
  Result Detect(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                const Catalog* catalog, const RunContext& ctx);

  // Calls `f` and rethrows any exception with the stage tag and type in front.
  template <class F>
  auto Call(const StageConfig& s, F&& f) -> decltype(f());

 private:
  GraphConfig graph_;
  const StageConfig *input_cfg_ = nullptr, *train_cfg_ = nullptr, *seg_cfg_ = nullptr,
                    *prop_cfg_ = nullptr, *feat_cfg_ = nullptr, *voter_cfg_ = nullptr;
  std::vector<const StageConfig*> fitter_cfgs_;
  std::shared_ptr<Sensor> input_, training_;
  std::shared_ptr<Segmenter> segmenter_;
  std::shared_ptr<Proposer> proposer_;
  std::shared_ptr<Features> features_;
  std::shared_ptr<Voter> voter_;
  std::vector<std::shared_ptr<Fitter>> fitters_;
  std::string loaded_model_id_;
  // Typical box size [w, d, h] of each class (the median of its catalog models), for the boxes
  // of detections no fitter gave a model.
  std::map<std::string, Eigen::Vector3f> class_size_;
  const Catalog* sized_catalog_ = nullptr;
};

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
