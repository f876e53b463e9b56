#include "furnihost/host/pipeline.hpp"

#include <algorithm>

#include "host/graph/executor.hpp"
#include "host/graph/training.hpp"

namespace furnihost {

Pipeline::Pipeline(const GraphConfig& graph, const Registry& registry)
    : graph_(graph), stages_(std::make_shared<graph::StageInstances>()) {
  input_ = graph_.FirstOfKind(StageKind::Sensor);  // validation allows one detection sensor
  for (const auto& s : graph_.stages) {
    auto plugin = graph::CallStage(s, [&] { return registry.Create(s.type, s.params); });
    neighbours_ = std::max(neighbours_, plugin->Needs().neighbours);
    stages_->by_tag[s.tag].plugin = std::move(plugin);
  }
}

bool Pipeline::HasDetectionChain() const { return !graph_.Sinks().empty(); }

std::vector<std::string> Pipeline::MissingStages() const {
  auto any = [&](StageKind k) { return !graph_.AllOfKind(k).empty(); };
  std::vector<std::string> m;
  if (!input_) m.push_back("sensor (scan reader)");
  // A recogniser of proposals needs neither part features nor a fitter to decide.
  const bool voter = any(StageKind::Voter), recogniser = any(StageKind::Proposer) && voter;
  if (!any(StageKind::Segmenter) && !recogniser) m.push_back("segmenter");
  if (!any(StageKind::Features) && !recogniser) m.push_back("features");
  if (!voter) m.push_back("voter");
  if (!any(StageKind::Fitter) && !recogniser) m.push_back("fitter");
  return m;
}

TrainedModel Pipeline::Train(const Catalog& catalog, const RunContext& ctx) {
  return graph::TrainGraph(graph_, *stages_, catalog, ctx);
}

ModelViews Pipeline::ScanModel(const Catalog& catalog, size_t index, const RunContext& ctx) {
  return graph::ScanModel(graph_, *stages_, catalog, index, ctx);
}

TrainedModel Pipeline::TrainFromViews(const Catalog& catalog, std::vector<ModelViews> scanned, const RunContext& ctx) {
  return graph::TrainFromViews(graph_, *stages_, catalog, std::move(scanned), ctx);
}

bool Pipeline::TrainingMerges() const { return graph::TrainingMerges(graph_, *stages_); }

TrainedRun Pipeline::TrainRun(const Catalog& catalog, size_t begin, size_t end, const RunContext& ctx) {
  return graph::TrainRun(graph_, *stages_, catalog, begin, end, ctx);
}

TrainedModel Pipeline::MergeRuns(const Catalog& catalog, std::vector<TrainedRun> runs, const RunContext& ctx) {
  return graph::MergeRuns(graph_, *stages_, catalog, std::move(runs), ctx);
}

Pipeline::Result Pipeline::DetectOnce(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                                      const Catalog* catalog, const RunContext& ctx,
                                      const std::function<void()>& before_stages, const RunJitter& jitter) {
  if (!input_) throw InputError(graph_.path + ": the graph has no input sensor stage (e.g. sensors.scan_file)");
  Result r;
  auto& sensor = stages_->at(input_->tag).As<Sensor>(*input_);
  SceneScans read = ReadScenes(scenes, graph_, *input_, sensor, neighbours_, jitter, ctx, r.timings_ms);
  r.scans = std::move(read.scans);
  r.world_to_user = read.world_to_user;
  if (before_stages) before_stages();
  graph::Run run(graph_, r.scans, ctx);
  run.model = model;
  run.catalog = catalog;
  run.timings_ms = std::move(r.timings_ms);
  graph::RunStages(run, *stages_);
  r.timings_ms = std::move(run.timings_ms);
  graph::CollectResult(run, r);
  return r;
}

}  // namespace furnihost
