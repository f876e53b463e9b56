// Training: the catalog's models scanned by the graph's training sensor, every view run through
// the stages training views pass through (the runners of detection), and each trained stage
// (voter) taught on the views its inputs gave.
#pragma once
#include "executor.hpp"

namespace furnihost::graph {

// InputError when the graph has no training sensor or nothing to train, or the catalog no model.
TrainedModel TrainGraph(const GraphConfig& graph, StageInstances& stages, const Catalog& catalog, const RunContext& ctx);

}  // namespace furnihost::graph
