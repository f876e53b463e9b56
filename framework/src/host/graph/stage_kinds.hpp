// The stage kinds: one rule per kind, and the only place that says what may feed what.
// Graph validation (ValidateGraph), the graph's queries (GraphConfig::Input, SegmenterOf,
// ChainRoot, Sinks), detection (the executor) and training all read this table.
//
// A rule names the kind's inputs as slots: the kinds that may fill a slot, how many stages
// do, and whether training views pass through it. Its runner is what the executor does with a
// stage of that kind in one run (executor.hpp). Adding a kind is its interface in the SDK
// (stage.hpp), a row in Kinds() and its runner; changing what a kind accepts is its row and,
// when the runner reads the new input, its runner.
#pragma once
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "furnihost/host/config.hpp"

namespace furnihost::graph {

class Run;
struct StageInstance;

// What the executor does with one stage in one run: reads the outputs of the stages its slots
// name from `run`, calls the plugin, and keeps its output in run.Out(stage).
using Runner = void (*)(const StageConfig& stage, StageInstance& instance, Run& run);

// One input of a kind.
struct Slot {
  InputRole role;                // what the runner reads from it
  std::vector<StageKind> kinds;  // the kinds that may fill it
  int min = 0, max = 1;          // how many stages fill it
  bool trains = false;           // training views pass through it on their way to the stage
};

struct KindRule {
  StageKind kind;
  const char* name;          // "segmenter": messages and `furnihost plugins`
  const char* type_prefix;   // "segmenters": plugin types are "<type_prefix>.<name>"
  std::vector<Slot> inputs;  // none: a source (the sensor)
  int min_inputs = 0;        // at least this many inputs over all slots
  const char* takes;         // its inputs in words ("<kind> '<tag>' takes ...")
  bool detections = false;   // gives detections: a chain of them ends in a sink
  bool trained = false;      // learns from the catalog (its model is in the model file)
  bool parts = false;        // gives parts: the stages after it see its segmentation
  Runner run = nullptr;      // null: not run by the executor (the sensor: the scan input reads it)
};

// Every kind, in the order of the StageKind enum.
const std::vector<KindRule>& Kinds();
const KindRule& RuleOf(StageKind kind);
// The slot of `rule` that an input of kind `input` fills, or null when none takes it.
const Slot* SlotFor(const KindRule& rule, StageKind input);

// Checks the inputs of stage `s` against its kind's rule: every input names a stage of
// `by_tag`, of a kind a slot takes, and each slot holds as many as it may. Throws InputError at
// `where` ("file:/stages/tag/inputs").
void CheckInputs(const StageConfig& s, const std::map<std::string, StageConfig>& by_tag, const std::string& where);

// Looks a stage up by tag (null when there is none).
using FindStage = std::function<const StageConfig*(const std::string& tag)>;

// The segmenter whose parts stage `s` sees: itself for a kind that gives parts, else the one
// its inputs see (CheckParts makes them agree), or null. `max_hops` bounds the search.
const StageConfig* SegmenterOf(const StageConfig& s, const FindStage& find, size_t max_hops);

// The inputs of `s` that see parts see those of one segmenter: a voter's features and its
// proposals index the parts of one segmentation, as a fitter's proposals and its voter's.
// Throws InputError at `where`. For an acyclic graph (run after the cycle check).
void CheckParts(const StageConfig& s, const FindStage& find, size_t max_hops, const std::string& where);

}  // namespace furnihost::graph
