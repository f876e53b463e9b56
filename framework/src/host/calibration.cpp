#include "furnihost/host/calibration.hpp"

#include <algorithm>
#include <cmath>

#include "furnihost/error.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/host/io.hpp"
#include "sdk/shown.hpp"

namespace furnihost {

namespace {

bool KnownFeature(const std::string& f) {
  return f == "log_score" || (f.rfind("evidence:", 0) == 0 && f.size() > 9) ||
         (f.rfind("log_evidence:", 0) == 0 && f.size() > 13);
}

double FeatureValue(const std::string& f, const Detection& d) {
  auto evidence = [&](const std::string& name) {
    const auto it = d.evidence.find(name);
    return it == d.evidence.end() ? 0.0 : double(it->second);
  };
  if (f == "log_score") return std::log(std::max(double(d.score), 1e-6));
  if (f.rfind("log_evidence:", 0) == 0) return std::log(std::max(evidence(f.substr(13)), 1e-6));
  return evidence(f.substr(9));  // "evidence:NAME"
}

double Number(const nlohmann::json& j, const std::string& where) {
  if (!j.is_number() || !std::isfinite(j.get<double>()))
    throw InputError(where + ": expected a finite number, got " + detail::Shown(j));
  return j.get<double>();
}

}  // namespace

Calibration Calibration::Load(const std::string& path) {
  const nlohmann::json j = ReadJson(path);
  const std::string w = path + ":";
  if (!j.is_object()) throw InputError(w + " expected a JSON object, got " + detail::Shown(j));
  if (!j.contains("furnihost_calibration") || j["furnihost_calibration"] != 1)
    throw InputError(w + "/furnihost_calibration: expected 1 (a calibration file of scripts/calibrate.py)");
  if (j.value("method", std::string()) != "logistic")
    throw InputError(w + "/method: expected \"logistic\", got " + detail::Shown(j.value("method", nlohmann::json())));
  if (!j.contains("classes") || !j["classes"].is_object() || j["classes"].empty())
    throw InputError(w + "/classes: expected an object of class maps");
  Calibration c;
  c.path_ = path;
  c.fitted_on_ = j.value("fitted_on", nlohmann::json());
  for (auto it = j["classes"].begin(); it != j["classes"].end(); ++it) {
    const std::string at = w + "/classes/" + it.key();
    const nlohmann::json& m = it.value();
    if (!m.is_object()) throw InputError(at + ": expected an object, got " + detail::Shown(m));
    ClassMap cm;
    const nlohmann::json features = m.value("features", nlohmann::json::array({"log_score"}));
    if (!features.is_array()) throw InputError(at + "/features: expected an array, got " + detail::Shown(features));
    for (size_t k = 0; k < features.size(); ++k) {
      if (!features[k].is_string() || !KnownFeature(features[k].get<std::string>()))
        throw InputError(at + "/features/" + std::to_string(k) +
                         ": expected log_score, evidence:NAME or log_evidence:NAME, got " + detail::Shown(features[k]));
      cm.features.push_back(features[k].get<std::string>());
    }
    if (!m.contains("coef") || !m["coef"].is_array() || m["coef"].size() != cm.features.size())
      throw InputError(at + "/coef: expected an array of " + std::to_string(cm.features.size()) +
                       " numbers (one per feature)");
    for (size_t k = 0; k < cm.features.size(); ++k)
      cm.coef.push_back(Number(m["coef"][k], at + "/coef/" + std::to_string(k)));
    if (!m.contains("intercept")) throw InputError(at + "/intercept: missing");
    cm.intercept = Number(m["intercept"], at + "/intercept");
    c.classes_[it.key()] = std::move(cm);
  }
  return c;
}

std::optional<float> Calibration::Confidence(const Detection& d) const {
  const auto it = classes_.find(d.cls);
  if (it == classes_.end()) return std::nullopt;
  const ClassMap& m = it->second;
  double z = m.intercept;
  for (size_t k = 0; k < m.features.size(); ++k) z += m.coef[k] * FeatureValue(m.features[k], d);
  // The logistic function, without overflow for either sign of z.
  const double p = z >= 0 ? 1.0 / (1.0 + std::exp(-z)) : std::exp(z) / (1.0 + std::exp(z));
  return float(p);
}

void Calibration::Apply(std::vector<Detection>& detections, double min_confidence) const {
  for (Detection& d : detections) {
    d.confidence = Confidence(d);
    if (!d.confidence) continue;
    const Check decided = Check::AtLeast("confidence", *d.confidence, min_confidence);
    bool replaced = false;
    for (Check& c : d.checks)
      if (c.name == "score") {
        c = decided;
        replaced = true;
      }
    if (!replaced) d.checks.push_back(decided);
    d.verified = FirstFailure(d.checks).empty();
  }
}

std::vector<std::pair<std::string, std::string>> PartOfPairs(const std::vector<std::string>& items,
                                                             const std::string& where) {
  auto trim = [](std::string t) {
    const size_t a = t.find_first_not_of(" \t"), b = t.find_last_not_of(" \t");
    return a == std::string::npos ? std::string() : t.substr(a, b - a + 1);
  };
  std::vector<std::pair<std::string, std::string>> pairs;
  for (const std::string& item : items) {
    const size_t colon = item.find(':');
    const std::string part = colon == std::string::npos ? std::string() : trim(item.substr(0, colon));
    const std::string whole = colon == std::string::npos ? std::string() : trim(item.substr(colon + 1));
    if (part.empty() || whole.empty() || whole.find(':') != std::string::npos || part == whole)
      throw InputError(where + ": expected PART:WHOLE pairs of two classes (\"chair:sofa\"), got \"" + item + "\"");
    pairs.emplace_back(part, whole);
  }
  return pairs;
}

size_t DropParts(std::vector<Detection>& detections, const std::vector<std::pair<std::string, std::string>>& part_of,
                 double share) {
  if (part_of.empty()) return 0;
  std::vector<Eigen::AlignedBox3f> box(detections.size());
  for (size_t i = 0; i < detections.size(); ++i) box[i] = DetectionBox(detections[i]);
  auto volume = [](const Eigen::AlignedBox3f& b) { return b.isEmpty() ? 0.0 : double(b.volume()); };
  std::vector<char> drop(detections.size(), 0);
  for (const auto& [part, whole] : part_of) {
    for (size_t w = 0; w < detections.size(); ++w) {
      const Detection& W = detections[w];
      if (W.cls != whole || !W.confidence || !W.verified.value_or(false) || volume(box[w]) <= 0) continue;
      std::vector<size_t> inside;
      for (size_t p = 0; p < detections.size(); ++p) {
        const Detection& P = detections[p];
        if (P.cls != part || !P.confidence) continue;
        const double v = volume(box[p]);
        if (v > 0 && volume(box[p].intersection(box[w])) >= share * v) inside.push_back(p);
      }
      if (inside.empty()) continue;
      // The parts' joint probability: the most probable readings that are not one another's.
      std::stable_sort(inside.begin(), inside.end(),
                       [&](size_t a, size_t b) { return *detections[a].confidence > *detections[b].confidence; });
      std::vector<size_t> chosen;
      double together = 0;
      for (size_t p : inside) {
        bool apart = true;
        for (size_t q : chosen) apart = apart && BoxIou(box[p], box[q]) < 0.25f;
        if (!apart) continue;
        chosen.push_back(p);
        together += *detections[p].confidence;
      }
      if (together > double(*W.confidence)) continue;
      for (size_t p : inside) drop[p] = 1;
    }
  }
  size_t n = 0, kept = 0;
  for (size_t i = 0; i < detections.size(); ++i) {
    if (drop[i]) {
      ++n;
      continue;
    }
    if (kept != i) detections[kept] = std::move(detections[i]);
    ++kept;
  }
  detections.resize(kept);
  return n;
}

}  // namespace furnihost
