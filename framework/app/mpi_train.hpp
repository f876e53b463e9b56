// Training shared among the ranks of a World (mpi_world.hpp): each rank scans its share of the
// catalog models (Pipeline::ScanModel: the training sensor's views, segmented and described),
// rank 0 gathers every model's views in catalog order, trains the voters (TrainFromViews) and
// writes the model; every rank gets the model. The model is the one process's byte for byte:
// a model's views depend on the model, the graph and the seed only, whichever rank scans them.
// When every voter of the graph merges (Pipeline::TrainingMerges: each learns every model on its
// own), each rank also trains its voters on a run of consecutive models, and rank 0 merges the
// runs: the voters' own work (a catalog of thousands of meshes) is shared as well.
#pragma once
#include "furnihost/host/detector.hpp"
#include "furnihost/host/pipeline.hpp"
#include "mpi_world.hpp"

namespace furnihost::app {

// Pipeline::Train over the world (one rank: Train itself). Every rank calls it; every rank
// returns the model.
TrainedModel TrainShared(const World& world, Pipeline& pipeline, const Catalog& catalog, const RunContext& ctx);

// EnsureModel over the world: rank 0 loads the graph's model cache when it is valid (and not
// `force`), else the ranks train it (TrainShared) and rank 0 writes the cache. Every rank
// returns the model.
TrainedModel EnsureModelShared(const World& world, Pipeline& pipeline, const Catalog& catalog, const RunContext& ctx,
                               bool force);

// Under mpirun (world.Shared()), sets `options.ensure_model` to EnsureModelShared over `world`,
// so a Detector's training is shared among the ranks; outside, leaves the options alone.
// `world` outlives the detector (World::Get()).
void ShareTraining(const World& world, DetectorOptions& options);

}  // namespace furnihost::app
