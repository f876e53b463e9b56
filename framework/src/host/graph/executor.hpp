// The graph executor: runs a graph's stages in execution (topological) order, each through its
// kind's runner (stage_kinds.hpp), on the scans of one run. A detection runs every stage; a
// training view runs the stages training views pass through on their way to the voters.
#pragma once
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "furnihost/host/catalog.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/pipeline.hpp"
#include "furnihost/stage.hpp"

namespace furnihost::graph {

// Calls `f` for stage `s` and rethrows any exception with the stage tag and type in front
// (while the plugin's library is loaded: Boost.DLL's rule for exceptions of plugin code).
template <class F>
auto CallStage(const StageConfig& s, F&& f) -> decltype(f()) {
  const std::string who = "stage '" + s.tag + "' (" + s.type + "): ";
  try {
    return f();
  } catch (const InputError& e) {
    throw InputError(who + e.what());
  } catch (const StageError& e) {
    throw StageError(who + e.what(), e.IsInputError());
  } catch (const std::bad_alloc&) {
    throw StageError(who + "out of memory", false);
  } catch (const std::exception& e) {
    throw StageError(who + e.what(), false);
  } catch (...) {
    throw StageError(who + "unknown exception", false);
  }
}

// A stage's plugin, and what its runner keeps from run to run.
struct StageInstance {
  std::shared_ptr<Stage> plugin;
  std::string loaded_model;  // a trained stage: the id of the model its plugin has loaded

  // The plugin as its kind's interface (StageError naming the stage when it is not one).
  template <class T>
  T& As(const StageConfig& s) const {
    T* t = dynamic_cast<T*>(plugin.get());
    if (!t) throw StageError("stage '" + s.tag + "' (" + s.type + "): not a " + ToString(s.kind) + " plugin", false);
    return *t;
  }
};
// The stages of a graph, created once and reused for every run, by tag.
struct StageInstances {
  std::map<std::string, StageInstance> by_tag;
  StageInstance& at(const std::string& tag) { return by_tag.at(tag); }
};

// What one stage gave in one run.
struct StageOutput {
  std::vector<Segmentation> segmentations;  // one per scan
  std::vector<Proposals> proposals;         // one per scan
  std::vector<FeatureMatrix> features;      // one per scan: raw; a voter's: its input, normalised
  std::vector<SceneParts> scenes;           // a voter's: what it voted with (and its fitters fit)
  VoteResult votes;
  std::vector<Detection> detections;
  bool ran = false;      // gave detections (a voter with a model, a fitter with a catalog)
  bool decided = false;  // its detections are accepted or rejected
};

// One run of a graph's stages on a set of scans. Outputs are kept by stage tag until the run ends.
class Run {
 public:
  Run(const GraphConfig& graph, const std::vector<Scan>& scans, const RunContext& ctx)
      : graph(graph), scans(scans), ctx(ctx) {}

  const GraphConfig& graph;
  const std::vector<Scan>& scans;
  const RunContext& ctx;
  const TrainedModel* model = nullptr;  // what trained stages run with; null: they do not run
  const Catalog* catalog = nullptr;     // what fitters fit to; null: they do not run
  bool log = true;                      // a line per scan and stage (detection; training is quiet)
  bool voted = false;                   // a voter ran
  size_t clamped_features = 0;          // features outside the training range, clamped
  StageTimes timings_ms;                                   // stage tag -> ms, in order
  std::map<std::string, FitContext> fit_contexts;          // by the chain (voter and proposer) fitters fit

  StageOutput& Out(const StageConfig& s) { return out_[s.tag]; }
  const StageOutput& Of(const StageConfig& s) const { return out_.at(s.tag); }
  bool Has(const StageConfig& s) const { return out_.count(s.tag) > 0; }
  // The segmentation of scan `i` that stage `s` sees, or null.
  const Segmentation* Parts(const StageConfig& s, size_t i) const;
  void Timed(const std::string& tag, double ms) { AddTime(timings_ms, tag, ms); }
  // The typical catalog size of each class (TypicalClassSizes), computed once per run.
  const std::map<std::string, Eigen::Vector3f>& ClassSizes();

 private:
  std::map<std::string, StageOutput> out_;
  std::optional<std::map<std::string, Eigen::Vector3f>> class_sizes_;
};

// Runs the stages of `run.graph` that `only` holds (every stage when null), in execution order.
void RunStages(Run& run, StageInstances& instances, const std::set<std::string>* only = nullptr);

// The stages training views pass through to the graph's trained stages (their segmenters and
// features, by the slots marked `trains`).
std::set<std::string> TrainingStages(const GraphConfig& graph);

// The run's product: every sink's detections (a sink that did not run gives those of the last
// stage of its chain that did), and the outputs of the first sink's chain as the result's
// single-chain fields.
void CollectResult(Run& run, Pipeline::Result& result);

}  // namespace furnihost::graph
