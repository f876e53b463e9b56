// The model cache: which model a graph needs (its training key), whether a model file serves
// it, and getting one (the cache when it serves, else training).
#pragma once
#include <nlohmann/json.hpp>
#include <string>

#include "furnihost/host/catalog.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/model_file.hpp"

namespace furnihost {

class Pipeline;

// The subset of a resolved graph that determines the trained model: the seed, the training
// sensor and, for each trained stage (voter) by tag, the segmenter, features and voter (type,
// version, params without the detection-only ones) it learns through:
//   {seed, training_sensor, voters: {tag: {segmenter, features, voter}}}.
FURNIHOST_API nlohmann::json TrainingKey(const GraphConfig& graph);

// "" when `model` serves `graph` with the catalog of hash `catalog_hash`, else one line saying
// what differs. A version 1 file's untagged voter serves a graph of one voter of any tag.
FURNIHOST_API std::string Incompatibility(const TrainedModel& model, const GraphConfig& graph,
                                          const std::string& catalog_hash);

// Resolves the model for a graph: loads the cache when compatible, otherwise trains and
// writes it (atomically). `force` retrains.
FURNIHOST_API TrainedModel EnsureModel(Pipeline& pipeline, const Catalog& catalog,
                                       const RunContext& ctx, bool force = false);

}  // namespace furnihost
