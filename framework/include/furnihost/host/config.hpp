// Graph configs: JSON files naming the stages, their parameters and connections, the catalog
// to train from and the model cache. Variants `extends` a base and apply a JSON merge patch.
//
//   {
//     "extends": "paper.json",                  // optional, relative to this file
//     "description": "...",
//     "seed": 42,
//     "catalog": "../data/catalog/catalog.json",  // relative to the file that sets it
//     "model_cache": "../furnihost-out/models/paper.fhm",
//     "training": {"sensor": "simulate"},       // tag of the sensor stage that scans the catalog
//     "ground": {"kind": "auto"},               // each scan's floor: auto | level | plane | height_map |
//                                               //   fixed (+ "z_m"); "cell_m", "step_m", "min_area_m2"
//     "frame": {"canonical": true, "level": false},  // canonical: stages see scans in their canonical frame;
//                                                  // level: a tilted up axis levelled on the floor (frame.hpp)
//     "ensemble": {"runs": 5, "jitter_m": 0.0005, "join_iou": 0.3},  // detection run on the scan and on
//                                                  // runs - 1 jittered copies, the runs' detections fused
//                                                  // (FuseDetections); runs 1 (the default): once
//     "calibration": {"file": "calibration/scannet.json", "min_confidence": 0.5},  // each detection's
//                                                  // confidence (calibration.hpp); accepted at min_confidence
//     "stages": {                               // an object keyed by tag (not an array) so a
//       "input":   {"type": "sensors.scan_file"},//   merge patch can change one stage's params
//       "segment": {"type": "segmenters.region_growing", "inputs": ["input"], "params": {...}},
//       ...
//     }
//   }
//
// The stages form a graph: each stage gets the outputs of the stages its `inputs` name, and
// one output may feed several stages (a proposer feeding a voter and a fitter, a voter feeding
// two fitter chains, two segmenters side by side on the one input sensor, each with its own
// features and voter). What each kind takes is its rule in the kinds' table
// (framework/src/host/graph/stage_kinds.cpp):
//   sensor    -> (none)                 the one detection sensor (plus the training sensor)
//   segmenter -> sensor
//   proposer  -> sensor or segmenter
//   features  -> segmenter
//   voter     -> features, proposer or one of each
//   fitter    -> voter or fitter        (a chain; fitters may fan out), and optionally a
//                proposer whose proposals it sees instead of its voter's
// The inputs of a stage that see parts see those of one segmenter. Every voter or fitter that
// no fitter takes is a sink; the detections are those of every sink, each naming its sink
// ("chain") when there are several. Training trains every voter on the views of the training
// sensor through its own segmenter and features.
#pragma once
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "furnihost/host/calibration.hpp"
#include "furnihost/host/ground_estimation.hpp"
#include "furnihost/params.hpp"
#include "furnihost/host/registry.hpp"

namespace furnihost {

// The kinds' names: "segmenter" for StageKind::Segmenter; the kind of a plugin type name
// ("segmenters.x" -> Segmenter, "proposals.x" -> Proposer), nullopt for another prefix; the
// prefixes in words ("sensors., segmenters., ...") for messages.
FURNIHOST_API const char* ToString(StageKind kind);
FURNIHOST_API std::optional<StageKind> KindFromTypeName(const std::string& type);
FURNIHOST_API std::string KindTypePrefixes();

// What a stage reads from one of its inputs (the slots of its kind's rule).
enum class InputRole {
  Scan,        // the scans, as the sensor gave them
  Parts,       // a segmentation of each scan
  Features,    // a feature matrix per scan
  Proposals,   // object proposals per scan
  Detections,  // the detections of a voter or fitter
};

// Test-time ensembling ("ensemble" key): Pipeline::Detect runs the chain on the scan as read and
// on `runs` - 1 copies jittered by `jitter_m` (Gaussian, JitterPoints), and fuses the runs'
// detections (FuseDetections, boxes joined at AABB IoU >= `join_iou`). A real scan's decisions
// flip under noise far below its sensor's; a detection found in every run keeps its score and
// one found in a single run keeps 1/runs of it.
struct EnsembleOptions {
  int runs = 1;
  double jitter_m = 0.0005;
  double join_iou = 0.3;
};

// How stages see each scan ("frame" key): in its canonical frame (`canonical`, the default; see
// EstimateCanonicalFrame), else in its z-up frame as given; `level` levels a tilted up axis on
// the floor (FrameOptions::level).
struct FrameSection {
  bool canonical = true;
  bool level = false;
};

// The graph's calibration ("calibration" key): the calibration file (calibration.hpp; relative to
// the config that names it) and the confidence at which detections are accepted. Without a
// file, detections carry no confidence and the stages' thresholds decide.
struct CalibrationSection {
  std::string file;
  double min_confidence = 0.5;
  // "PART:WHOLE" class pairs (Calibration::DropParts): a PART reading inside an accepted WHOLE
  // that is more probable than the PART readings inside it together is a part of it.
  std::vector<std::string> part_of;
  std::vector<std::pair<std::string, std::string>> part_pairs;  // part_of as (part, whole), parsed once
  double part_share = 0.5;  // share of a PART reading's box inside the WHOLE's that makes it inside
};

// The host's own sections of a graph config ("ground", "frame", "ensemble", "calibration"; null: the
// defaults), each parameter declared once with its range and unit (host_options.cpp), as a
// plugin's are. InputError naming `where`/<key> on an unknown key or a bad value; a "comment"
// key is allowed. `furnihost plugins` lists them (HostSectionSchemas).
FURNIHOST_API FrameSection FrameSectionFromJson(const nlohmann::json& j, const std::string& where);
FURNIHOST_API EnsembleOptions EnsembleOptionsFromJson(const nlohmann::json& j, const std::string& where);
FURNIHOST_API CalibrationSection CalibrationSectionFromJson(const nlohmann::json& j, const std::string& where);
FURNIHOST_API nlohmann::json ToJson(const FrameSection& f);
FURNIHOST_API nlohmann::json ToJson(const EnsembleOptions& e);
FURNIHOST_API nlohmann::json ToJson(const CalibrationSection& c);
// Each host section's name and schema, for listings.
FURNIHOST_API std::vector<std::pair<std::string, ParamSchema>> HostSectionSchemas();

struct StageConfig {
  std::string tag;
  std::string type;
  std::string version;  // the plugin's version (part of the model cache key)
  StageKind kind;
  std::vector<std::string> inputs;
  nlohmann::json params;  // resolved: every default filled
  nlohmann::json training_params;  // params without the detection-only ones (model cache key)
  std::string pointer;    // "/stages/<tag>"
};

struct FURNIHOST_API GraphConfig {
  std::string path;        // the file given by the user
  nlohmann::json resolved; // the whole config after extends + defaults
  uint64_t seed = 42;
  std::string catalog;     // absolute or empty
  std::string model_cache; // absolute or empty
  std::string training_sensor;  // tag, or empty
  GroundOptions ground;         // how the pipeline gets each scan's ground ("ground" key)
  FrameSection frame;           // "frame" key
  EnsembleOptions ensemble;  // "ensemble" key
  CalibrationSection calibration;  // "calibration" key
  std::shared_ptr<const Calibration> calibration_map;  // calibration.file read; null without
  std::vector<StageConfig> stages;  // in execution (topological) order

  const StageConfig* Find(const std::string& tag) const;
  // Stages of a kind in execution order, the training sensor left out.
  const StageConfig* FirstOfKind(StageKind kind) const;
  std::vector<const StageConfig*> AllOfKind(StageKind kind) const;
  // The stage of kind `kind` among the inputs of `s` (a stage takes at most one of each), or null.
  const StageConfig* InputOfKind(const StageConfig& s, StageKind kind) const;
  // The stage in the slot `role` of the inputs of `s` (the first when the slot holds several), or null.
  const StageConfig* Input(const StageConfig& s, InputRole role) const;
  // The segmenter whose parts `s` sees (itself for a segmenter), or null.
  const StageConfig* SegmenterOf(const StageConfig& s) const;
  // The stage at the root of the chain of detections `s` is on (a voter is its own root).
  const StageConfig* ChainRoot(const StageConfig& s) const;
  // The stages that learn from the catalog (voters), in execution order.
  std::vector<const StageConfig*> Trained() const;
  // The stages whose detections are the graph's output, in execution order: every stage that
  // gives detections and that no stage takes as its detections.
  std::vector<const StageConfig*> Sinks() const;
};

// Reads `path`, resolves `extends` (with loop detection), applies merge patches, makes
// relative paths absolute.
FURNIHOST_API nlohmann::json LoadConfigJson(const std::string& path);

// RFC 7386 JSON merge patch.
FURNIHOST_API nlohmann::json MergePatch(nlohmann::json target, const nlohmann::json& patch);

// Validates the whole graph against the registry: unknown keys, unknown plugins (lists the
// known ones), parameters (via each plugin's schema), inputs and kind of each connection,
// cycles. Throws InputError naming "file:/json/pointer".
FURNIHOST_API GraphConfig ValidateGraph(const std::string& path, const nlohmann::json& config,
                                        const Registry& registry);

// `sets`: command-line overrides "TAG.PARAM=VALUE" (VALUE is JSON: 0.2, true, "text" or an
// object; anything that is not JSON is taken as a string), applied to the stage TAG's params
// after `extends` and before validation; "ground.KEY=VALUE" sets the ground options (and
// "frame.KEY=VALUE", "ensemble.KEY=VALUE", "calibration.KEY=VALUE" theirs). A bad
// override is an InputError naming it ("--set vote.nope=1: ...").
FURNIHOST_API GraphConfig LoadGraph(const std::string& path, const Registry& registry,
                                    const std::vector<std::string>& sets = {});

}  // namespace furnihost
