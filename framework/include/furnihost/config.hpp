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
//     "frame": {"canonical": true},             // stages see scans in their canonical frame (frame.hpp)
//     "stages": {                               // an object keyed by tag (not an array) so a
//       "input":   {"type": "sensors.scan_file"},//   merge patch can change one stage's params
//       "segment": {"type": "segmenters.region_growing", "inputs": ["input"], "params": {...}},
//       ...
//     }
//   }
#pragma once
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "furnihost/ground.hpp"
#include "furnihost/registry.hpp"

namespace furnihost {

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
  // Stages see each scan in its canonical frame ("frame": {"canonical": true}, the default;
  // see EstimateCanonicalFrame), else in its z-up frame as given.
  bool canonical_frame = true;
  std::vector<StageConfig> stages;  // in execution (topological) order

  const StageConfig* Find(const std::string& tag) const;
  // The detection chain: input sensor, segmenter, features, voter, fitters (may stop early).
  const StageConfig* FirstOfKind(StageKind kind) const;
  std::vector<const StageConfig*> AllOfKind(StageKind kind) const;
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
// after `extends` and before validation; "ground.KEY=VALUE" sets the ground options. A bad
// override is an InputError naming it ("--set vote.nope=1: ...").
FURNIHOST_API GraphConfig LoadGraph(const std::string& path, const Registry& registry,
                                    const std::vector<std::string>& sets = {});

}  // namespace furnihost
