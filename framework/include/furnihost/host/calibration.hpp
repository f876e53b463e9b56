// A graph's calibration: per class, the map from a detection's raw score (and evidence) to the
// probability that it is a true positive at 3D IoU >= 0.25 (the file scripts/calibrate.py
// writes, docs/calibration.md). The host applies it to every detection of a calibrated graph:
// the detection gets its `confidence`, and its "score" check becomes a "confidence" check at the
// graph's min_confidence, the one working point of every class and graph.
#pragma once
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost {

class FURNIHOST_API Calibration {
 public:
  // A logistic map: confidence = 1 / (1 + exp(-(intercept + sum_k coef[k] * feature_k))), a
  // feature being "log_score" (ln of the raw score, floored at 1e-6), "evidence:NAME" (the
  // detection's evidence NAME, 0 without) or "log_evidence:NAME" (its ln, floored at 1e-6).
  struct ClassMap {
    std::vector<std::string> features;
    std::vector<double> coef;
    double intercept = 0;
  };

  // Reads a calibration file; InputError naming the file and the field on anything malformed.
  static Calibration Load(const std::string& path);

  const std::string& Path() const { return path_; }
  // What the map was fitted on, as the file records it ("fitted_on"; null when absent).
  const nlohmann::json& FittedOn() const { return fitted_on_; }
  const std::map<std::string, ClassMap>& Classes() const { return classes_; }

  // The detection's confidence, or nullopt when its class has no map.
  std::optional<float> Confidence(const Detection& d) const;

  // Sets each detection's confidence and decides it at `min_confidence`: its "score" check
  // becomes a "confidence" check (added when it had none), and it is accepted (verified) when
  // every check passes, a fitter's own checks included. Detections of classes without a map
  // keep their thresholds' verdict and get no confidence.
  void Apply(std::vector<Detection>& detections, double min_confidence) const;

 private:
  std::string path_;
  nlohmann::json fitted_on_;
  std::map<std::string, ClassMap> classes_;
};

// calibration.part_of's "PART:WHOLE" items as (part, whole) class pairs, names trimmed;
// InputError naming `where` on an item that is not two different names around one colon.
FURNIHOST_API std::vector<std::pair<std::string, std::string>> PartOfPairs(const std::vector<std::string>& items,
                                                                          const std::string& where);

// One object, one reading, where one class's objects are made of parts that read as another
// class (a sofa's seats as armchairs): for each (part, whole) pair, every accepted detection of
// the whole class (verified, with a confidence) takes the detections of the part class whose
// boxes lie inside its box (at least `share` of a part's box volume). When the whole is at least
// as probable as those parts together (the most probable non-overlapping ones, 3D IoU < 0.25,
// their confidences summed), they are parts of it and are dropped; else all stay. Needs
// confidences (Calibration::Apply first); returns how many were dropped. The order of the rest
// is kept.
FURNIHOST_API size_t DropParts(std::vector<Detection>& detections,
                               const std::vector<std::pair<std::string, std::string>>& part_of, double share);

}  // namespace furnihost
