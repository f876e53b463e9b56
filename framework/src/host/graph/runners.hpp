// The runner of each stage kind (stage_kinds.cpp names them in the kinds' table): what the
// executor does with one stage in one run (executor.hpp).
#pragma once
#include "executor.hpp"

namespace furnihost::graph {

void RunSegmenter(const StageConfig& s, StageInstance& instance, Run& run);
void RunProposer(const StageConfig& s, StageInstance& instance, Run& run);
void RunFeatures(const StageConfig& s, StageInstance& instance, Run& run);
void RunVoter(const StageConfig& s, StageInstance& instance, Run& run);
void RunFitter(const StageConfig& s, StageInstance& instance, Run& run);

}  // namespace furnihost::graph
