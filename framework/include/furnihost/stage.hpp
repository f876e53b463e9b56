// One abstract interface per stage kind. Plugins implement one of them; the host calls them.
// Every call is pure with respect to the stage object (no hidden state between scans other
// than what Load() installs) and deterministic for the seed in the context.
#pragma once
#include <cstdint>
#include <optional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost {

// The kinds of stage. What each takes and gives is the host's business (its kinds' table); a
// plugin implements the interface of its kind below.
enum class StageKind { Sensor, Segmenter, Features, Voter, Fitter, Proposer };

// Run-wide facts every stage may read.
struct RunContext {
  uint64_t seed = 42;
  int threads = 0;  // 0 = all cores
  bool verbose = false;
};

// What a stage asks the host to prepare with every scan it is given.
struct StageNeeds {
  // > 0: Scan::neighbours listing at least this many nearest positions per position (itself first),
  // which the host finds with the scan's working frame when it can (ScanNeighbours says
  // when); a stage still checks ScanNeighbours::Describes and searches its own otherwise.
  int neighbours = 0;
  // Voters: false when Train learns every catalog model that has a mesh from the mesh alone
  // (TrainingView::model), not from what the training sensor saw of it. When every voter a
  // training feeds says so, the host scans only the models without a mesh and gives Train one
  // view of each other model with no points (view -1, scan empty): training then costs what
  // the voters' own work on the meshes costs.
  bool training_scans = true;
  // Voters: true when Train learns each catalog model on its own, so that Train on the views of
  // consecutive runs of the catalog's models, then Merge of those models in catalog order, gives
  // the model Train on every view gives, byte for byte. The host then shares a voter's training
  // among processes (`mpirun furnihost train`: each rank trains a run of models). Voters whose
  // views carry features never merge: the host fits the features' normaliser on every view.
  bool training_merges = false;
};

class FURNIHOST_API Stage {
 public:
  virtual ~Stage();
  virtual StageKind Kind() const = 0;
  // Asked once, after construction (the parameters are set).
  virtual StageNeeds Needs() const { return {}; }
};

// ---- sensor ----------------------------------------------------------------------------
// A placed object of a synthetic scene (world frame: x, y on the floor, z up).
struct PlacedObject {
  const CatalogModel* model = nullptr;
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();  // model -> world
};

// What a sensor is asked to acquire: either a file (`path`), or a synthetic scene of
// `objects` plus optional `extra` geometry (floor, walls) scanned from `poses`.
struct SensorRequest {
  std::string path;
  std::vector<PlacedObject> objects;
  Mesh extra;
  std::vector<Eigen::Isometry3f> poses;  // sensor -> world; x forward, z up. Empty = the
                                         // sensor's default pattern (e.g. 16 training views)
  std::optional<Eigen::Vector3f> origin;  // for file sensors: origin given on the CLI (file frame)
  ShiftOption shift;                      // for file sensors: global shift (ReadScan)
  // For file sensors: a scan already in memory (points a program holds, made by ScanFromPoints
  // with `shift`), taken as if read from a file instead of reading `path`. Not owned.
  const Scan* scan = nullptr;
};

class FURNIHOST_API Sensor : public Stage {
 public:
  ~Sensor() override;
  StageKind Kind() const override { return StageKind::Sensor; }
  // One Scan per pose (or per file). Throws StageError / InputError on bad input.
  virtual std::vector<Scan> Acquire(const SensorRequest& request, const RunContext& ctx) = 0;
};

// ---- segmenter -------------------------------------------------------------------------
class FURNIHOST_API Segmenter : public Stage {
 public:
  ~Segmenter() override;
  StageKind Kind() const override { return StageKind::Segmenter; }
  virtual Segmentation Segment(const Scan& scan, const RunContext& ctx) = 0;
};

// ---- proposer --------------------------------------------------------------------------
// Object proposals: clusters of scan points that may each be one piece of furniture (the
// floor, walls and ceiling removed), with their boxes; the parts of the segmentation (when the
// graph has a segmenter) that lie in each. Voters that recognise whole objects read them from
// SceneParts::proposals.
class FURNIHOST_API Proposer : public Stage {
 public:
  ~Proposer() override;
  StageKind Kind() const override { return StageKind::Proposer; }
  // `seg` may be null (a graph whose proposer takes the sensor directly).
  virtual Proposals Propose(const Scan& scan, const Segmentation* seg, const RunContext& ctx) = 0;
};

// ---- features --------------------------------------------------------------------------
class FURNIHOST_API Features : public Stage {
 public:
  ~Features() override;
  StageKind Kind() const override { return StageKind::Features; }
  // Raw (unnormalised) features, one row per part. The host learns and applies the [0, 1]
  // normaliser (framework/normaliser.hpp).
  virtual FeatureMatrix Compute(const Scan& scan, const Segmentation& seg,
                                const RunContext& ctx) = 0;
};

// ---- voter -----------------------------------------------------------------------------
class FURNIHOST_API Voter : public Stage {
 public:
  ~Voter() override;
  StageKind Kind() const override { return StageKind::Voter; }
  // Learns from the training views and returns the model as JSON (stored in the model file).
  virtual nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext& ctx) = 0;
  // Installs a model returned by Train (possibly after a save/load round trip).
  virtual void Load(const nlohmann::json& model) = 0;
  // Joins the models Train returned for consecutive runs of the catalog's models, given in
  // catalog order, into the model Train returns on all their views (StageNeeds::training_merges).
  // Called only on voters that declare it; the default throws std::logic_error.
  virtual nlohmann::json Merge(const std::vector<nlohmann::json>& parts);
  // Votes with the parts of one or more scenes (fused in the world frame, Scan::pose).
  virtual VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext& ctx) = 0;
};

// ---- fitter ----------------------------------------------------------------------------
struct FitContext {
  std::vector<SceneParts> scenes;
  std::vector<const CatalogModel*> catalog;  // every model of the training catalog
  RunContext run;
};

class FURNIHOST_API Fitter : public Stage {
 public:
  ~Fitter() override;
  StageKind Kind() const override { return StageKind::Fitter; }
  // Optional: precompute per-model data (e.g. dense sampled clouds) once for a catalog.
  // Returned JSON is cached in the model file and passed back to Prepare on later runs.
  virtual nlohmann::json Prepare(const std::vector<const CatalogModel*>& catalog,
                                 const nlohmann::json& cached) {
    (void)catalog;
    (void)cached;
    return nullptr;
  }
  // Takes the detections of the previous stage (voter hypotheses, or another fitter's
  // output) and returns them fitted / verified / refined.
  virtual std::vector<Detection> Fit(const std::vector<Detection>& input, const FitContext& ctx) = 0;
};

}  // namespace furnihost
