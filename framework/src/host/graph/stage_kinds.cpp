#include "stage_kinds.hpp"

#include <algorithm>

#include "runners.hpp"

namespace furnihost {

namespace graph {

using K = StageKind;
using R = InputRole;

const std::vector<KindRule>& Kinds() {
  // name, type prefix, input slots {role, kinds, min, max, trains}, min inputs, takes (words),
  // detections, trained, parts, runner.
  static const std::vector<KindRule> kinds = {
      {K::Sensor, "sensor", "sensors", {}, 0, "no inputs", false, false, false, nullptr},
      {K::Segmenter, "segmenter", "segmenters", {{R::Scan, {K::Sensor}, 1, 1, true}}, 1, "one sensor stage",
       false, false, true, RunSegmenter},
      {K::Features, "features", "features", {{R::Parts, {K::Segmenter}, 1, 1, true}}, 1, "one segmenter stage",
       false, false, false, RunFeatures},
      {K::Voter, "voter", "voters",
       {{R::Features, {K::Features}, 0, 1, true}, {R::Proposals, {K::Proposer}, 0, 1, false}}, 1,
       "a features stage, a proposer, or one of each", true, true, false, RunVoter},
      {K::Fitter, "fitter", "fitters",
       {{R::Detections, {K::Voter, K::Fitter}, 1, 1, false}, {R::Proposals, {K::Proposer}, 0, 1, false}}, 1,
       "the detections of one voter or fitter, and optionally one proposer", true, false, false, RunFitter},
      {K::Proposer, "proposer", "proposals", {{R::Parts, {K::Segmenter, K::Sensor}, 1, 1, false}}, 1,
       "one segmenter or sensor stage", false, false, false, RunProposer},
  };
  return kinds;
}

const KindRule& RuleOf(StageKind kind) {
  for (const auto& k : Kinds())
    if (k.kind == kind) return k;
  throw std::logic_error("stage kind without a rule");
}

const Slot* SlotFor(const KindRule& rule, StageKind input) {
  for (const auto& slot : rule.inputs)
    if (std::find(slot.kinds.begin(), slot.kinds.end(), input) != slot.kinds.end()) return &slot;
  return nullptr;
}

void CheckInputs(const StageConfig& s, const std::map<std::string, StageConfig>& by_tag, const std::string& where) {
  const KindRule& rule = RuleOf(s.kind);
  const std::string who = std::string(rule.name) + " '" + s.tag + "'";
  std::vector<int> filled(rule.inputs.size(), 0);
  for (size_t i = 0; i < s.inputs.size(); ++i) {
    const std::string at = where + "/" + std::to_string(i);
    auto in = by_tag.find(s.inputs[i]);
    if (in == by_tag.end()) {
      std::string tags;
      for (const auto& [t, _] : by_tag) tags += (tags.empty() ? "" : ", ") + t;
      throw InputError(at + ": unknown stage '" + s.inputs[i] + "'; stages: " + tags);
    }
    if (rule.inputs.empty()) throw InputError(where + ": " + who + " takes " + rule.takes);
    const Slot* slot = SlotFor(rule, in->second.kind);
    if (!slot)
      throw InputError(at + ": kind mismatch: " + who + " cannot take " + RuleOf(in->second.kind).name + " '" +
                       in->first + "' (" + in->second.type + ")");
    ++filled[size_t(slot - rule.inputs.data())];
  }
  bool ok = int(s.inputs.size()) >= rule.min_inputs;
  for (size_t k = 0; k < rule.inputs.size(); ++k) ok = ok && filled[k] >= rule.inputs[k].min && filled[k] <= rule.inputs[k].max;
  if (!ok) throw InputError(where + ": " + who + " takes " + rule.takes);
}

const StageConfig* SegmenterOf(const StageConfig& s, const FindStage& find, size_t max_hops) {
  if (RuleOf(s.kind).parts) return &s;
  if (max_hops == 0) return nullptr;
  for (const auto& tag : s.inputs)
    if (const StageConfig* in = find(tag))
      if (const StageConfig* seg = SegmenterOf(*in, find, max_hops - 1)) return seg;
  return nullptr;
}

void CheckParts(const StageConfig& s, const FindStage& find, size_t max_hops, const std::string& where) {
  if (RuleOf(s.kind).parts) return;
  const StageConfig *first = nullptr, *first_seg = nullptr;
  for (const auto& tag : s.inputs) {
    const StageConfig* in = find(tag);
    const StageConfig* seg = in ? SegmenterOf(*in, find, max_hops) : nullptr;
    if (!seg) continue;
    if (!first_seg) {
      first = in, first_seg = seg;
    } else if (seg != first_seg) {
      auto named = [](const StageConfig& c, const StageConfig& g) {
        return std::string(RuleOf(c.kind).name) + " '" + c.tag + "' (parts of segmenter '" + g.tag + "')";
      };
      throw InputError(where + ": " + RuleOf(s.kind).name + " '" + s.tag + "' takes " + named(*first, *first_seg) +
                       " and " + named(*in, *seg) + "; both must come from one segmenter");
    }
  }
}

}  // namespace graph

const char* ToString(StageKind kind) { return graph::RuleOf(kind).name; }

std::optional<StageKind> KindFromTypeName(const std::string& type) {
  const size_t dot = type.find('.');
  if (dot == std::string::npos || dot + 1 >= type.size()) return std::nullopt;
  for (const auto& k : graph::Kinds())
    if (type.compare(0, dot, k.type_prefix) == 0 && std::char_traits<char>::length(k.type_prefix) == dot) return k.kind;
  return std::nullopt;
}

std::string KindTypePrefixes() {
  std::string s;
  for (const auto& k : graph::Kinds()) s += (s.empty() ? "" : ", ") + std::string(k.type_prefix) + ".";
  return s;
}

}  // namespace furnihost
