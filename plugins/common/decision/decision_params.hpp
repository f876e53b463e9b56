#pragma once
// The decision parameters every voter (and fitters.ransac_upright's synthesis) shares: the
// per-class operating score, the score below which a candidate is not reported, and the
// per-class non-maximum suppression. Declared here once, with one range and one help text each;
// each plugin keeps its own defaults (read from its options struct, as ParamBinding does).
//
//   struct MyOptions { DecisionOptions decision{{}, 0.5, 1e-4, 0.25, 0}; ... };
//   BindDecision(binding, [](MyOptions& o) -> DecisionOptions& { return o.decision; }, "score in [0, 1]");
//
// A plugin whose members are not in a DecisionOptions passes a DecisionFields of accessors
// (member pointers or callables returning a reference); absent parameters are nullptr.
#include <cstddef>
#include <map>
#include <string>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "furnihost/error.hpp"
#include "furnihost/params.hpp"

namespace furnihost {

struct DecisionOptions {
  std::map<std::string, float> thresholds;  // operating score per detected class
  double default_threshold = 0.;            // operating score of classes not in thresholds
  double min_score = 0.;                    // candidates scoring lower are not reported
  double nms_iou = 0.;                      // per-class suppression by box IoU
  double nms_whole_ratio = 0.;              // a whole object beside its better-scoring fragment (0 = off)
};

// Accessors of the decision parameters a plugin has; std::nullptr_t = the plugin has no such parameter.
template <class T, class D, class S = std::nullptr_t, class I = std::nullptr_t, class W = std::nullptr_t>
struct DecisionFields {
  T thresholds;
  D default_threshold;
  S min_score = nullptr;
  I nms_iou = nullptr;
  W nms_whole_ratio = nullptr;
};
template <class T, class D, class S = std::nullptr_t, class I = std::nullptr_t, class W = std::nullptr_t>
DecisionFields(T, D, S = nullptr, I = nullptr, W = nullptr) -> DecisionFields<T, D, S, I, W>;

struct DecisionHelp {
  std::string score;   // what the plugin's score is, e.g. "in [0, 1]" or "about the number of agreeing key points"
  std::string prefix;  // put before every help text (e.g. "synthesis: ")
  bool detection_only = true;  // the parameters do not change the trained model
};

// The parser of a voter's class_map Object parameter (catalog class -> detected class, the
// classes its thresholds name): fills the std::map<std::string, std::string> member `m`; a
// value that is not a non-empty string is an InputError naming class_map/<key>.
template <class O, class M>
typename ParamBinding<O>::ObjectFn ClassMapParser(M m) {
  return [m](O& o, const nlohmann::json& j) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (!it->is_string() || it->get<std::string>().empty())
        throw InputError("class_map/" + it.key() + ": expected a class name");
      param_detail::Field(o, m)[it.key()] = it->get<std::string>();
    }
  };
}

// Declares thresholds, default_threshold and, where the plugin has them, min_score, nms_iou and
// nms_whole_ratio, in that order. Ranges: scores and thresholds >= 0 (each plugin's score has
// its own scale), min_score and nms_iou in [0, 1], nms_whole_ratio >= 0.
template <class O, class T, class D, class S, class I, class W>
ParamBinding<O>& BindDecision(ParamBinding<O>& b, const DecisionFields<T, D, S, I, W>& f, const DecisionHelp& h) {
  const auto only = [&]() {
    if (h.detection_only) b.DetectionOnly();
  };
  const std::string score = h.score.empty() ? "" : " (score " + h.score + ")";
  b.NumberMap("thresholds", f.thresholds, 0, std::nullopt, "1",
              h.prefix + "operating score per detected class: candidates scoring at or above it are accepted" + score);
  only();
  b.Number("default_threshold", f.default_threshold, 0, std::nullopt, "1",
           h.prefix + "operating score of classes not in thresholds");
  only();
  if constexpr (!std::is_null_pointer_v<S>) {
    b.Number("min_score", f.min_score, 0, 1, "1", h.prefix + "candidates scoring lower are not reported");
    only();
  }
  if constexpr (!std::is_null_pointer_v<I>) {
    b.Number("nms_iou", f.nms_iou, 0, 1, "1",
             h.prefix + "a candidate overlapping a better one of its class by more box IoU is dropped");
    only();
  }
  if constexpr (!std::is_null_pointer_v<W>) {
    b.Number("nms_whole_ratio", f.nms_whole_ratio, 0, 1000, "1",
             h.prefix + "a candidate whose box holds >= 90 % of a better one's and is at least this many times its "
                        "volume is kept beside it (0 = plain IoU suppression): a fragment of an object (the lower "
                        "half of a wall cabinet, which fits a smaller catalog model) may score better than the whole");
    only();
  }
  return b;
}

// The same for a plugin whose decision parameters are one DecisionOptions member (`m` returns a
// reference to it); `all` = it has min_score, nms_iou and nms_whole_ratio too.
template <class O, class M>
ParamBinding<O>& BindDecision(ParamBinding<O>& b, M m, const DecisionHelp& h) {
  const auto at = [m](auto member) {
    return [m, member](O& o) -> auto& { return param_detail::Field(o, m).*member; };
  };
  return BindDecision(b,
                      DecisionFields{at(&DecisionOptions::thresholds), at(&DecisionOptions::default_threshold),
                                     at(&DecisionOptions::min_score), at(&DecisionOptions::nms_iou),
                                     at(&DecisionOptions::nms_whole_ratio)},
                      h);
}

}  // namespace furnihost
