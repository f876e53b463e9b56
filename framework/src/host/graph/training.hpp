// Training: the catalog's models scanned by the graph's training sensor, every view run through
// the stages training views pass through (the runners of detection), and each trained stage
// (voter) taught on the views its inputs gave.
#pragma once
#include "executor.hpp"

namespace furnihost::graph {

// InputError when the graph has no training sensor or nothing to train, or the catalog no model.
TrainedModel TrainGraph(const GraphConfig& graph, StageInstances& stages, const Catalog& catalog, const RunContext& ctx);

// TrainGraph in two steps (Pipeline::ScanModel, Pipeline::TrainFromViews): one model's views,
// then the trained stages taught on every model's views in catalog order.
ModelViews ScanModel(const GraphConfig& graph, StageInstances& stages, const Catalog& catalog, size_t index,
                     const RunContext& ctx);
TrainedModel TrainFromViews(const GraphConfig& graph, StageInstances& stages, const Catalog& catalog,
                            std::vector<ModelViews> scanned, const RunContext& ctx);

// Training in runs of models (Pipeline::TrainRun, Pipeline::MergeRuns): whether every trained
// stage merges (StageNeeds::training_merges, and no features to normalise), the trained stages
// taught on the models [begin, end), and runs covering the catalog in order merged into its model.
bool TrainingMerges(const GraphConfig& graph, StageInstances& stages);
TrainedRun TrainRun(const GraphConfig& graph, StageInstances& stages, const Catalog& catalog, size_t begin, size_t end,
                    const RunContext& ctx);
TrainedModel MergeRuns(const GraphConfig& graph, StageInstances& stages, const Catalog& catalog,
                       std::vector<TrainedRun> runs, const RunContext& ctx);

}  // namespace furnihost::graph
