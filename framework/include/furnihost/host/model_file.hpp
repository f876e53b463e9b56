// The model file: what training learned, written once and read by every later detection.
// Layout: the magic line "furnihost-model\n", then CBOR of
//   {"format_version": 2, "training_config": TrainingKey, "catalog_hash": "...",
//    "voters": {tag: {"voter_type", "normaliser", "voter_model"}}, "summary": {...}}.
// Version 1 files are read too: their single-voter layout (the voter's fields at the top, no
// tag) is upgraded on load (TrainedModel::voters under the tag "").
#pragma once
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "furnihost/host/normaliser.hpp"

namespace furnihost {

constexpr int kModelFormatVersion = 2;

// One trained stage's learned model: its features' normaliser and what its Train returned.
struct TrainedVoter {
  std::string voter_type;
  Normaliser normaliser;
  nlohmann::json voter_model;
};

// The learned model: everything detection needs besides the plugins themselves.
struct TrainedModel {
  int format_version = kModelFormatVersion;
  nlohmann::json training_config;  // the graph parts that shape the model (TrainingKey)
  std::string catalog_hash;
  // Each trained stage's model by stage tag. A version 1 file of one voter holds it under ""
  // (its tag was not written): it is the model of the graph's one voter.
  std::map<std::string, TrainedVoter> voters;
  nlohmann::json summary;  // models, and per voter views, parts and meshes (models learned from the mesh alone) per class
  // Time per stage [ms] of the training that made it, by stage tag; not saved in the model file
  // (the same inputs give the same file), so empty for a loaded model.
  nlohmann::json timings_ms;

  // The model of the voter `tag`, or null when the file has none for it.
  FURNIHOST_API const TrainedVoter* FindVoter(const std::string& tag) const;
};

// The first bytes of every model file.
constexpr char kModelMagic[] = "furnihost-model\n";
// Writes atomically (AtomicWrite), in the current format version: kModelMagic, then CBOR.
FURNIHOST_API void SaveModel(const std::string& path, const TrainedModel& model);
// InputError on a missing/corrupt file or another format version (says what to do).
FURNIHOST_API TrainedModel LoadModel(const std::string& path);
// The bytes SaveModel writes, and the model from such bytes (errors name `what`): what MPI
// ranks hand each other.
FURNIHOST_API std::string ModelBytes(const TrainedModel& model);
FURNIHOST_API TrainedModel ModelFromBytes(const std::string& bytes, const std::string& what);
// A model cache replaces only its own kind of file: InputError "<where><path>: ..." unless
// `path` does not exist or is a regular file that starts with the model magic (a corrupt one
// too: it is retrained). Checked before anything is trained (model_cache.cpp).
FURNIHOST_API void CheckModelCacheTarget(const std::string& path, const std::string& where);

}  // namespace furnihost
