#include "executor.hpp"

#include "stage_kinds.hpp"

namespace furnihost::graph {

const Segmentation* Run::Parts(const StageConfig& s, size_t i) const {
  const StageConfig* seg = graph.SegmenterOf(s);
  return seg ? &Of(*seg).segmentations.at(i) : nullptr;
}

const std::map<std::string, Eigen::Vector3f>& Run::ClassSizes() {
  if (!class_sizes_) class_sizes_ = catalog ? TypicalClassSizes(*catalog) : std::map<std::string, Eigen::Vector3f>();
  return *class_sizes_;
}

void RunStages(Run& run, StageInstances& instances, const std::set<std::string>* only) {
  for (const StageConfig& s : run.graph.stages) {
    const KindRule& rule = RuleOf(s.kind);
    if (!rule.run || (only && !only->count(s.tag))) continue;
    run.Out(s);  // every stage run has an output, empty when it had nothing to work with
    rule.run(s, instances.at(s.tag), run);
  }
}

std::set<std::string> TrainingStages(const GraphConfig& graph) {
  std::set<std::string> stages;
  std::function<void(const StageConfig&)> take = [&](const StageConfig& s) {
    const KindRule& rule = RuleOf(s.kind);
    for (const auto& tag : s.inputs) {
      const StageConfig* in = graph.Find(tag);
      const Slot* slot = in ? SlotFor(rule, in->kind) : nullptr;
      if (!slot || !slot->trains || !RuleOf(in->kind).run || !stages.insert(in->tag).second) continue;
      take(*in);
    }
  };
  for (const StageConfig* s : graph.Trained()) take(*s);
  return stages;
}

void CollectResult(Run& run, Pipeline::Result& r) {
  const GraphConfig& g = run.graph;
  // The sinks' detections. A sink that did not run (a fitter without a catalog, a voter
  // without a model) gives those of the last stage of its chain that did, once.
  const auto sinks = g.Sinks();
  std::set<std::string> given;
  for (const StageConfig* sink : sinks) {
    const StageConfig* c = sink;
    for (size_t hops = 0; c && !run.Of(*c).ran && hops <= g.stages.size(); ++hops) c = g.Input(*c, InputRole::Detections);
    if (!c || !run.Of(*c).ran || !given.insert(c->tag).second) continue;
    StageOutput& o = run.Out(*c);
    r.sinks.push_back(c->tag);
    r.fitted = r.fitted || o.decided;
    for (auto& d : o.detections) {
      if (sinks.size() > 1) d.chain = c->tag;
      r.detections.push_back(std::move(d));
    }
  }
  // Each placed model's front gives the way its object faces, whichever model it is.
  if (run.catalog) SetFacing(r.detections, *run.catalog);
  // The single-chain fields: the outputs of the stages the first sink takes, directly or not
  // (every stage's, without a sink), the first of each in execution order; the features are
  // those its voter voted with (normalised), else the raw ones.
  std::set<std::string> chain;
  std::function<void(const StageConfig&)> up = [&](const StageConfig& s) {
    if (!chain.insert(s.tag).second) return;
    for (const auto& tag : s.inputs)
      if (const StageConfig* in = g.Find(tag)) up(*in);
  };
  if (!sinks.empty()) up(*sinks.front());
  bool votes = false;
  for (const StageConfig& s : g.stages) {
    if (!run.Has(s) || (!sinks.empty() && !chain.count(s.tag))) continue;
    StageOutput& o = run.Out(s);
    if (r.segmentations.empty()) r.segmentations = std::move(o.segmentations);
    if (r.proposals.empty()) r.proposals = std::move(o.proposals);
    if (!o.features.empty()) r.features = std::move(o.features);
    if (!votes && o.ran && !g.Input(s, InputRole::Detections)) {
      r.votes = std::move(o.votes);
      votes = true;
    }
  }
  r.voted = run.voted;
  r.clamped_features += run.clamped_features;
}

}  // namespace furnihost::graph
