#include "furnihost/evaluation.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>

#include "furnihost/io.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace furnihost {

namespace {

constexpr double kPi = 3.14159265358979323846;

[[noreturn]] void Bad(const std::string& file, const std::string& pointer, const std::string& what) {
  throw InputError(file + ":" + pointer + ": " + what);
}

void CheckKeys(const json& o, const std::set<std::string>& known, const std::string& file,
               const std::string& pointer) {
  if (!o.is_object()) Bad(file, pointer.empty() ? "/" : pointer, "expected an object");
  for (const auto& item : o.items()) {
    if (known.count(item.key())) continue;
    std::string list;
    for (const auto& n : known) list += (list.empty() ? "" : ", ") + n;
    Bad(file, pointer + "/" + item.key(), "unknown key (known: " + list + ")");
  }
}

std::string ResolvePath(const fs::path& base, const json& v, const std::string& file, const std::string& pointer,
                        const std::string& what) {
  if (!v.is_string() || v.get<std::string>().empty()) Bad(file, pointer, "expected a path (string), got " + v.dump());
  fs::path p(v.get<std::string>());
  if (p.is_relative()) p = base / p;
  const std::string abs = p.lexically_normal().string();
  try {
    RequireRegularFile(abs, what);
  } catch (const InputError& e) {
    Bad(file, pointer, e.what());
  }
  return abs;
}

json Num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

double GetNum(const json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(where + "/" + key + ": missing");
  const json& v = j[key];
  if (v.is_null()) return NAN;
  if (!v.is_number()) throw InputError(where + "/" + key + ": expected a number or null, got " + v.dump());
  return v.get<double>();
}

double SafeDiv(double a, double b) { return b > 0 ? a / b : NAN; }

}  // namespace

double FoldYawErrorDeg(double raw_deg, std::optional<int> yaw_symmetry) {
  if (!std::isfinite(raw_deg) || !yaw_symmetry || *yaw_symmetry == 1) return raw_deg;
  if (*yaw_symmetry <= 0) return 0.0;
  const double period = 360.0 / *yaw_symmetry;
  const double d = std::fmod(raw_deg, period);
  return std::min(d, period - d);
}

namespace {

// Smallest absolute difference of two angles [rad], in degrees in [0, 180].
double YawErrorDeg(double a, double b) {
  double d = std::fmod(std::abs(a - b), 2 * kPi);
  if (d > kPi) d = 2 * kPi - d;
  return d * 180.0 / kPi;
}

float PlaneDistance(const Eigen::Vector3f& a, const Eigen::Vector3f& b) { return (a - b).head<2>().norm(); }

void FinishRates(VerificationFigures* v) {
  v->tp_kept_rate = SafeDiv(v->tp_kept, v->tp);
  v->fp_removal_rate = SafeDiv(v->fp_removed, v->fp);
}

// One evaluated detection after matching.
struct Scored {
  float score;
  size_t scene, index;  // for a deterministic order among equal scores
  bool tp;
};

struct ErrorAccumulator {
  std::vector<double> centre, yaw;
};

// Counts TPs/FPs of one match and collects the errors of its TPs.
void Accumulate(const std::vector<Detection>& dets, const std::vector<GroundTruthObject>& truth,
                const SceneMatch& m, bool fitted, std::map<std::string, std::pair<int, int>>& tp_fp,
                std::map<std::string, ErrorAccumulator>& errors) {
  for (size_t i = 0; i < dets.size(); ++i) {
    if (m.det_to_gt[i] == SceneMatch::kIgnored) continue;
    auto& c = tp_fp[m.det_class[i]];
    if (m.det_to_gt[i] == SceneMatch::kUnmatched) {
      ++c.second;
      continue;
    }
    ++c.first;
    const GroundTruthObject& g = truth[m.det_to_gt[i]];
    auto& e = errors[m.det_class[i]];
    e.centre.push_back(PlaneDistance(dets[i].center, g.center));
    // Only a fitter estimates yaw; a voter hypothesis' yaw is a placeholder 0.
    if (fitted && !dets[i].model.empty() && g.yaw)
      e.yaw.push_back(FoldYawErrorDeg(YawErrorDeg(dets[i].yaw, *g.yaw), g.yaw_symmetry));
  }
}

OperatingPoint MakePoint(int tp, int fp, int gt, const ErrorAccumulator& e) {
  OperatingPoint p;
  p.tp = tp;
  p.fp = fp;
  p.fn = gt - tp;
  p.precision = SafeDiv(tp, tp + fp);
  p.recall = SafeDiv(tp, gt);
  p.centre_error_m = Summarise(e.centre);
  p.yaw_error_deg = Summarise(e.yaw);
  return p;
}

json ToJson(const ErrorStats& e) { return {{"n", e.n}, {"median", Num(e.median)}, {"p90", Num(e.p90)}}; }
ErrorStats ErrorStatsFromJson(const json& j, const std::string& where) {
  ErrorStats e;
  e.n = static_cast<int>(GetNum(j, "n", where));
  e.median = GetNum(j, "median", where);
  e.p90 = GetNum(j, "p90", where);
  return e;
}

json ToJson(const OperatingPoint& p) {
  return {{"tp", p.tp},
          {"fp", p.fp},
          {"fn", p.fn},
          {"precision", Num(p.precision)},
          {"recall", Num(p.recall)},
          {"centre_error_m", ToJson(p.centre_error_m)},
          {"yaw_error_deg", ToJson(p.yaw_error_deg)}};
}
OperatingPoint OperatingPointFromJson(const json& j, const std::string& where) {
  OperatingPoint p;
  p.tp = static_cast<int>(GetNum(j, "tp", where));
  p.fp = static_cast<int>(GetNum(j, "fp", where));
  p.fn = static_cast<int>(GetNum(j, "fn", where));
  p.precision = GetNum(j, "precision", where);
  p.recall = GetNum(j, "recall", where);
  if (!j.contains("centre_error_m") || !j.contains("yaw_error_deg"))
    throw InputError(where + ": missing centre_error_m / yaw_error_deg");
  p.centre_error_m = ErrorStatsFromJson(j["centre_error_m"], where + "/centre_error_m");
  p.yaw_error_deg = ErrorStatsFromJson(j["yaw_error_deg"], where + "/yaw_error_deg");
  return p;
}

json ToJson(const VerificationFigures& v) {
  return {{"tp", v.tp},
          {"tp_kept", v.tp_kept},
          {"tp_kept_rate", Num(v.tp_kept_rate)},
          {"fp", v.fp},
          {"fp_removed", v.fp_removed},
          {"fp_removal_rate", Num(v.fp_removal_rate)}};
}
VerificationFigures VerificationFromJson(const json& j, const std::string& where) {
  VerificationFigures v;
  v.tp = static_cast<int>(GetNum(j, "tp", where));
  v.tp_kept = static_cast<int>(GetNum(j, "tp_kept", where));
  v.fp = static_cast<int>(GetNum(j, "fp", where));
  v.fp_removed = static_cast<int>(GetNum(j, "fp_removed", where));
  FinishRates(&v);
  return v;
}

json ToJson(const ObjectRecord& r) {
  return {{"scene", r.scene},
          {"index", r.index},
          {"class", r.cls},
          {"gt_model", r.gt_model},
          {"status", r.status},
          {"model", r.model},
          {"centre_error_m", Num(r.centre_error_m)},
          {"yaw_error_deg", Num(r.yaw_error_deg)},
          {"yaw_symmetry", r.yaw_symmetry},
          {"yaw_error_folded_deg", Num(r.yaw_error_folded_deg)},
          {"coverage", Num(r.coverage)},
          {"rejection", r.rejection}};
}
ObjectRecord ObjectRecordFromJson(const json& j, const std::string& where) {
  if (!j.is_object()) throw InputError(where + ": expected an object");
  ObjectRecord r;
  r.scene = j.value("scene", "");
  r.index = static_cast<int>(GetNum(j, "index", where));
  r.cls = j.value("class", "");
  r.gt_model = j.value("gt_model", "");
  r.status = j.value("status", "");
  r.model = j.value("model", "");
  r.centre_error_m = GetNum(j, "centre_error_m", where);
  r.yaw_error_deg = GetNum(j, "yaw_error_deg", where);
  // Records written before yaw symmetries were known: none declared, folded = raw.
  r.yaw_symmetry = -1;
  if (j.contains("yaw_symmetry")) {
    const double y = GetNum(j, "yaw_symmetry", where);
    if (!(y >= -1 && y <= 360)) throw InputError(where + "/yaw_symmetry: expected an integer -1..360");
    r.yaw_symmetry = static_cast<int>(y);
  }
  r.yaw_error_folded_deg = j.contains("yaw_error_folded_deg") ? GetNum(j, "yaw_error_folded_deg", where) : r.yaw_error_deg;
  r.coverage = GetNum(j, "coverage", where);
  r.rejection = j.value("rejection", "");
  return r;
}

json TimingsToJson(const std::vector<std::pair<std::string, double>>& t) {
  json a = json::array();
  for (const auto& [tag, ms] : t) a.push_back({{"stage", tag}, {"ms", ms}});
  return a;
}
std::vector<std::pair<std::string, double>> TimingsFromJson(const json& j, const std::string& where) {
  if (!j.is_array()) throw InputError(where + ": expected a list of {stage, ms}");
  std::vector<std::pair<std::string, double>> t;
  for (size_t i = 0; i < j.size(); ++i) {
    const std::string w = where + "/" + std::to_string(i);
    if (!j[i].is_object() || !j[i].contains("stage") || !j[i]["stage"].is_string())
      throw InputError(w + "/stage: expected a string");
    t.emplace_back(j[i]["stage"].get<std::string>(), GetNum(j[i], "ms", w));
  }
  return t;
}

void AddVerificationFigures(std::map<std::string, double>& f, const std::string& prefix, const VerificationFigures& v) {
  f[prefix + "/verification/tp"] = v.tp;
  f[prefix + "/verification/tp_kept"] = v.tp_kept;
  f[prefix + "/verification/tp_kept_rate"] = v.tp_kept_rate;
  f[prefix + "/verification/fp"] = v.fp;
  f[prefix + "/verification/fp_removed"] = v.fp_removed;
  f[prefix + "/verification/fp_removal_rate"] = v.fp_removal_rate;
}

void AddPointFigures(std::map<std::string, double>& f, const std::string& prefix, const OperatingPoint& p) {
  f[prefix + "/precision"] = p.precision;
  f[prefix + "/recall"] = p.recall;
  f[prefix + "/tp"] = p.tp;
  f[prefix + "/fp"] = p.fp;
  f[prefix + "/centre_error_median_m"] = p.centre_error_m.median;
  f[prefix + "/centre_error_p90_m"] = p.centre_error_m.p90;
  f[prefix + "/yaw_error_median_deg"] = p.yaw_error_deg.median;
  f[prefix + "/yaw_error_p90_deg"] = p.yaw_error_deg.p90;
}

}  // namespace

// ---- dataset -----------------------------------------------------------------------------

std::optional<std::string> ClassMap::Map(const std::string& cls) const {
  std::optional<std::string> to = cls;
  auto it = map.find(cls);
  if (it != map.end()) to = it->second;
  if (!to || std::find(classes.begin(), classes.end(), *to) == classes.end()) return std::nullopt;
  return to;
}

Dataset LoadDataset(const std::string& path) {
  RequireRegularFile(path, "dataset manifest");
  const json j = ReadJson(path);
  if (!j.is_object()) throw InputError(path + ": expected a JSON object with \"scenes\" and \"classes\"");
  CheckKeys(j, {"description", "scenes", "class_map", "classes"}, path, "");
  Dataset d;
  d.path = path;
  const fs::path base = fs::absolute(fs::path(path)).parent_path();
  if (j.contains("description")) {
    if (!j["description"].is_string()) Bad(path, "/description", "expected a string");
    d.description = j["description"].get<std::string>();
  }

  if (!j.contains("classes")) Bad(path, "/classes", "missing (the evaluated classes, e.g. [\"chair\", \"table\"])");
  const json& cl = j["classes"];
  if (!cl.is_array() || cl.empty()) Bad(path, "/classes", "expected a non-empty list of class names");
  for (size_t i = 0; i < cl.size(); ++i) {
    if (!cl[i].is_string() || cl[i].get<std::string>().empty())
      Bad(path, "/classes/" + std::to_string(i), "expected a class name (string), got " + cl[i].dump());
    const std::string c = cl[i].get<std::string>();
    if (std::find(d.classes.classes.begin(), d.classes.classes.end(), c) != d.classes.classes.end())
      Bad(path, "/classes/" + std::to_string(i), "duplicate class \"" + c + "\"");
    d.classes.classes.push_back(c);
  }

  if (j.contains("class_map")) {
    const json& cm = j["class_map"];
    if (!cm.is_object()) Bad(path, "/class_map", "expected an object {\"name\": \"evaluated class\" or null}");
    for (const auto& item : cm.items()) {
      const std::string ptr = "/class_map/" + item.key();
      if (item.value().is_null()) {
        d.classes.map[item.key()] = std::nullopt;
        continue;
      }
      if (!item.value().is_string()) Bad(path, ptr, "expected a class name or null, got " + item.value().dump());
      const std::string to = item.value().get<std::string>();
      if (std::find(d.classes.classes.begin(), d.classes.classes.end(), to) == d.classes.classes.end()) {
        std::string list;
        for (const auto& c : d.classes.classes) list += (list.empty() ? "" : ", ") + c;
        Bad(path, ptr, "\"" + to + "\" is not one of the evaluated classes (" + list + "); use null to ignore a class");
      }
      d.classes.map[item.key()] = to;
    }
  }

  if (!j.contains("scenes")) Bad(path, "/scenes", "missing (a list of {\"scan\", \"gt\"})");
  const json& sc = j["scenes"];
  if (!sc.is_array() || sc.empty()) Bad(path, "/scenes", "expected a non-empty list of {\"scan\", \"gt\"}");
  for (size_t i = 0; i < sc.size(); ++i) {
    const std::string ptr = "/scenes/" + std::to_string(i);
    CheckKeys(sc[i], {"scan", "gt", "origin", "up", "transform", "shift"}, path, ptr);
    if (!sc[i].contains("scan")) Bad(path, ptr + "/scan", "missing (path of the scan file)");
    if (!sc[i].contains("gt")) Bad(path, ptr + "/gt", "missing (path of the *.gt.json file)");
    DatasetScene s;
    s.scan = ResolvePath(base, sc[i]["scan"], path, ptr + "/scan", "scan file");
    s.gt = ResolvePath(base, sc[i]["gt"], path, ptr + "/gt", "ground-truth file");
    if (sc[i].contains("origin")) {
      const json& o = sc[i]["origin"];
      if (!o.is_array() || o.size() != 3 ||
          !std::all_of(o.begin(), o.end(), [](const json& v) { return v.is_number() && std::isfinite(v.get<double>()); }))
        Bad(path, ptr + "/origin", "expected [x, y, z] (3 finite numbers, metres), got " + o.dump());
      s.origin = Eigen::Vector3f(o[0].get<float>(), o[1].get<float>(), o[2].get<float>());
    }
    {
      if (sc[i].contains("up")) {
        if (!sc[i]["up"].is_string()) Bad(path, ptr + "/up", "expected an axis such as \"-y\"");
        s.frame.up = sc[i]["up"].get<std::string>();
        if (s.frame.up != "auto") UpAxisRotation(s.frame.up, path + ":" + ptr + "/up");
      }
      if (sc[i].contains("transform")) {
        if (!sc[i]["transform"].is_string()) Bad(path, ptr + "/transform", "expected a string of 16 or 6 numbers");
        if (sc[i].contains("up")) Bad(path, ptr + "/transform", "give either up or transform, not both");
        s.frame.transform = ParseTransform(sc[i]["transform"].get<std::string>(), path + ":" + ptr + "/transform");
      }
    }
    if (sc[i].contains("shift")) {
      const json& o = sc[i]["shift"];
      if (!o.is_array() || o.size() != 3 ||
          !std::all_of(o.begin(), o.end(), [](const json& v) { return v.is_number() && std::isfinite(v.get<double>()); }))
        Bad(path, ptr + "/shift", "expected [x, y, z] (3 finite numbers), got " + o.dump());
      s.frame.shift.shift = Eigen::Vector3d(o[0].get<double>(), o[1].get<double>(), o[2].get<double>());
    }
    d.scenes.push_back(s);
  }
  return d;
}

std::string HashDataset(const Dataset& d) {
  uint64_t h = kFnvOffset;
  auto add = [&](const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(file + ": cannot read (for the dataset hash)");
    std::vector<char> buf(1 << 20);
    while (in) {
      in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
      h = Fnv1a(buf.data(), static_cast<size_t>(in.gcount()), h);
    }
  };
  add(d.path);
  for (const auto& s : d.scenes) {
    add(s.scan);
    add(s.gt);
  }
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(h));
  return std::string("fnv1a64:") + hex;
}

// ---- matching ----------------------------------------------------------------------------

const char* ToString(WidthConvention w) { return w == WidthConvention::Max ? "max" : "min"; }

std::optional<WidthConvention> ParseWidthConvention(const std::string& s) {
  if (s == "max") return WidthConvention::Max;
  if (s == "min") return WidthConvention::Min;
  return std::nullopt;
}

float MatchRadius(const GroundTruthObject& g, WidthConvention w) {
  const float sx = std::abs(g.size.x()), sy = std::abs(g.size.y());
  return 0.5f * (w == WidthConvention::Max ? std::max(sx, sy) : std::min(sx, sy));
}

SceneMatch MatchScene(const std::vector<Detection>& dets, const std::vector<GroundTruthObject>& truth,
                      const ClassMap& classes, WidthConvention width) {
  SceneMatch m;
  m.det_to_gt.assign(dets.size(), SceneMatch::kUnmatched);
  m.gt_to_det.assign(truth.size(), SceneMatch::kUnmatched);
  m.det_class.resize(dets.size());
  m.gt_class.resize(truth.size());
  for (size_t g = 0; g < truth.size(); ++g) {
    auto c = classes.Map(truth[g].cls);
    if (c) m.gt_class[g] = *c;
    else m.gt_to_det[g] = SceneMatch::kIgnored;
  }
  std::vector<size_t> order;
  for (size_t i = 0; i < dets.size(); ++i) {
    auto c = classes.Map(dets[i].cls);
    if (c) {
      m.det_class[i] = *c;
      order.push_back(i);
    } else {
      m.det_to_gt[i] = SceneMatch::kIgnored;
    }
  }
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dets[a].score > dets[b].score; });
  for (size_t i : order) {
    int best = SceneMatch::kUnmatched;
    float best_dist = 0.f;
    for (size_t g = 0; g < truth.size(); ++g) {
      if (m.gt_to_det[g] != SceneMatch::kUnmatched || m.gt_class[g] != m.det_class[i]) continue;
      const float dist = PlaneDistance(dets[i].center, truth[g].center);
      // Strictly inside, as the paper says "less than half of the width".
      if (!(dist < MatchRadius(truth[g], width))) continue;
      if (best == SceneMatch::kUnmatched || dist < best_dist) {
        best = static_cast<int>(g);
        best_dist = dist;
      }
    }
    if (best != SceneMatch::kUnmatched) {
      m.det_to_gt[i] = best;
      m.gt_to_det[best] = static_cast<int>(i);
    }
  }
  return m;
}

float BoxIou(const Eigen::AlignedBox3f& a, const Eigen::AlignedBox3f& b) {
  if (a.isEmpty() || b.isEmpty()) return 0.f;
  const Eigen::AlignedBox3f i = a.intersection(b);
  if (i.isEmpty()) return 0.f;
  const double vi = double(i.volume()), va = double(a.volume()), vb = double(b.volume());
  const double u = va + vb - vi;
  return u > 0 ? float(vi / u) : 0.f;
}

Eigen::AlignedBox3f GroundTruthBox(const GroundTruthObject& g) {
  return Eigen::AlignedBox3f(g.center - 0.5f * g.size, g.center + 0.5f * g.size);
}

Eigen::AlignedBox3f DetectionBox(const Detection& d) { return d.box ? d.box->Aabb() : Eigen::AlignedBox3f(); }

SceneMatch MatchSceneIou(const std::vector<Detection>& dets, const std::vector<GroundTruthObject>& truth,
                         const ClassMap& classes, float threshold) {
  SceneMatch m;
  m.det_to_gt.assign(dets.size(), SceneMatch::kUnmatched);
  m.gt_to_det.assign(truth.size(), SceneMatch::kUnmatched);
  m.det_class.resize(dets.size());
  m.gt_class.resize(truth.size());
  std::vector<Eigen::AlignedBox3f> gt_box(truth.size());
  for (size_t g = 0; g < truth.size(); ++g) {
    auto c = classes.Map(truth[g].cls);
    if (c) m.gt_class[g] = *c;
    else m.gt_to_det[g] = SceneMatch::kIgnored;
    gt_box[g] = GroundTruthBox(truth[g]);
  }
  std::vector<size_t> order;
  for (size_t i = 0; i < dets.size(); ++i) {
    auto c = classes.Map(dets[i].cls);
    if (c) {
      m.det_class[i] = *c;
      order.push_back(i);
    } else {
      m.det_to_gt[i] = SceneMatch::kIgnored;
    }
  }
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dets[a].score > dets[b].score; });
  for (size_t i : order) {
    const Eigen::AlignedBox3f box = DetectionBox(dets[i]);
    int best = -1;
    float best_iou = -1.f;
    for (size_t g = 0; g < truth.size(); ++g) {
      if (m.gt_class[g] != m.det_class[i] || m.gt_to_det[g] == SceneMatch::kIgnored) continue;
      const float iou = BoxIou(box, gt_box[g]);
      if (iou > best_iou) {
        best_iou = iou;
        best = static_cast<int>(g);
      }
    }
    if (best >= 0 && best_iou >= threshold && m.gt_to_det[best] == SceneMatch::kUnmatched) {
      m.det_to_gt[i] = best;
      m.gt_to_det[best] = static_cast<int>(i);
    }
  }
  return m;
}

// ---- metrics -----------------------------------------------------------------------------

double AveragePrecision(const std::vector<double>& recall, const std::vector<double>& precision) {
  const size_t n = std::min(recall.size(), precision.size());
  if (n == 0) return 0.0;
  std::vector<double> env(precision.begin(), precision.begin() + n);
  for (size_t i = n - 1; i-- > 0;) env[i] = std::max(env[i], env[i + 1]);
  double ap = 0, prev = 0;
  for (size_t i = 0; i < n; ++i) {
    ap += (recall[i] - prev) * env[i];
    prev = recall[i];
  }
  return ap;
}

ErrorStats Summarise(std::vector<double> v) {
  ErrorStats e;
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  e.n = static_cast<int>(v.size());
  if (v.empty()) return e;
  std::sort(v.begin(), v.end());
  auto q = [&](double p) {
    const double pos = p * static_cast<double>(v.size() - 1);
    const size_t lo = static_cast<size_t>(std::floor(pos));
    const size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
  };
  e.median = q(0.5);
  e.p90 = q(0.9);
  return e;
}

EvalMetrics Evaluate(const std::vector<SceneEval>& scenes, const ClassMap& classes, WidthConvention width) {
  EvalMetrics out;
  std::map<std::string, int> gt_count;
  std::map<std::string, std::vector<Scored>> scored, scored25, scored50;
  std::map<std::string, std::pair<int, int>> hyp_counts, ver_counts;
  std::map<std::string, ErrorAccumulator> hyp_err, ver_err;
  std::map<std::string, VerificationFigures> ver_fig;
  for (size_t s = 0; s < scenes.size(); ++s) {
    const SceneEval& se = scenes[s];
    out.fitted = out.fitted || se.fitted;
    const SceneMatch m = MatchScene(se.detections, se.truth, classes, width);
    for (size_t g = 0; g < se.truth.size(); ++g) {
      if (m.gt_class[g].empty()) ++out.ignored_gt[se.truth[g].cls];
      else ++gt_count[m.gt_class[g]];
    }
    for (size_t i = 0; i < se.detections.size(); ++i) {
      if (m.det_to_gt[i] == SceneMatch::kIgnored) {
        ++out.ignored_detections[se.detections[i].cls];
        continue;
      }
      scored[m.det_class[i]].push_back({se.detections[i].score, s, i, m.det_to_gt[i] >= 0});
    }
    for (auto [threshold, target] : {std::pair{0.25f, &scored25}, std::pair{0.5f, &scored50}}) {
      const SceneMatch mi = MatchSceneIou(se.detections, se.truth, classes, threshold);
      for (size_t i = 0; i < se.detections.size(); ++i)
        if (mi.det_to_gt[i] != SceneMatch::kIgnored)
          (*target)[mi.det_class[i]].push_back({se.detections[i].score, s, i, mi.det_to_gt[i] >= 0});
    }
    Accumulate(se.detections, se.truth, m, se.fitted, hyp_counts, hyp_err);
    // Rejected detections leave the set, so the remaining ones are matched on their own: a
    // verified detection may take the gt object a rejected one had taken.
    std::vector<Detection> kept;
    for (const auto& d : se.detections)
      if (d.verified.value_or(true)) kept.push_back(d);
    const SceneMatch mv = MatchScene(kept, se.truth, classes, width);
    Accumulate(kept, se.truth, mv, se.fitted, ver_counts, ver_err);

    // The voter's hypotheses where the voter put them: which were true, and what did the
    // verification do with each.
    std::vector<Detection> placed = se.detections;
    if (se.voter_centres.size() == placed.size())
      for (size_t i = 0; i < placed.size(); ++i) placed[i].center = se.voter_centres[i];
    const SceneMatch mh = MatchScene(placed, se.truth, classes, width);
    if (se.fitted)
      for (size_t i = 0; i < placed.size(); ++i) {
        if (mh.det_to_gt[i] == SceneMatch::kIgnored) continue;
        VerificationFigures& v = ver_fig[mh.det_class[i]];
        const bool ok = se.detections[i].verified.value_or(true);
        if (mh.det_to_gt[i] >= 0) {
          ++v.tp;
          v.tp_kept += ok;
        } else {
          ++v.fp;
          v.fp_removed += !ok;
        }
      }

    // Per object: the verified detection on it, else the hypothesis on it, else nothing.
    std::vector<int> kept_index;
    for (size_t i = 0; i < se.detections.size(); ++i)
      if (se.detections[i].verified.value_or(true)) kept_index.push_back(static_cast<int>(i));
    for (size_t g = 0; g < se.truth.size(); ++g) {
      if (m.gt_class[g].empty()) continue;
      ObjectRecord r;
      r.scene = se.name;
      r.index = static_cast<int>(g);
      r.cls = m.gt_class[g];
      r.gt_model = se.truth[g].model;
      r.yaw_symmetry = se.truth[g].yaw_symmetry.value_or(-1);
      int shown = -1;
      if (mv.gt_to_det[g] >= 0) {
        shown = kept_index[mv.gt_to_det[g]];
        r.status = se.fitted ? "verified" : "hypothesis";
      } else if (mh.gt_to_det[g] >= 0) {
        shown = mh.gt_to_det[g];
        r.status = se.fitted ? "rejected" : "hypothesis";
      } else {
        r.status = "missed";
      }
      if (shown >= 0) {
        const Detection& d = se.detections[shown];
        r.model = d.model;
        r.centre_error_m = PlaneDistance(d.center, se.truth[g].center);
        if (se.fitted && !d.model.empty() && se.truth[g].yaw) {
          r.yaw_error_deg = YawErrorDeg(d.yaw, *se.truth[g].yaw);
          r.yaw_error_folded_deg = FoldYawErrorDeg(r.yaw_error_deg, se.truth[g].yaw_symmetry);
        }
        if (d.coverage) r.coverage = *d.coverage;
        r.rejection = d.Rejection();
      }
      out.objects.push_back(std::move(r));
    }
  }

  int tp_h = 0, fp_h = 0, tp_v = 0, fp_v = 0, gt_all = 0;
  ErrorAccumulator all_h, all_v;
  double ap_sum = 0, ap25_sum = 0, ap50_sum = 0;
  int ap_n = 0;
  // The precision-recall curve of scored detections (one point per distinct score) and its AP.
  auto curve_of = [](std::vector<Scored>& sd, int gt, std::vector<PrPoint>& curve) {
    std::sort(sd.begin(), sd.end(), [](const Scored& a, const Scored& b) {
      if (a.score != b.score) return a.score > b.score;
      return a.scene != b.scene ? a.scene < b.scene : a.index < b.index;
    });
    int tp = 0, fp = 0;
    for (size_t i = 0; i < sd.size(); ++i) {
      (sd[i].tp ? tp : fp)++;
      // Detections with equal scores cannot be separated by a threshold: one point per score.
      if (i + 1 < sd.size() && sd[i + 1].score == sd[i].score) continue;
      curve.push_back({sd[i].score, tp, fp, SafeDiv(tp, tp + fp), SafeDiv(tp, gt)});
    }
    std::vector<double> r, p;
    for (const auto& pt : curve) {
      r.push_back(pt.recall);
      p.push_back(pt.precision);
    }
    return AveragePrecision(r, p);
  };
  for (const std::string& c : classes.classes) {
    ClassMetrics cm;
    cm.cls = c;
    cm.gt = gt_count[c];
    cm.detections = static_cast<int>(scored[c].size());
    const double ap = curve_of(scored[c], cm.gt, cm.curve);
    const double ap25 = curve_of(scored25[c], cm.gt, cm.curve25);
    const double ap50 = curve_of(scored50[c], cm.gt, cm.curve50);
    if (cm.gt > 0) {
      cm.ap = ap;
      cm.ap25 = ap25;
      cm.ap50 = ap50;
      ap_sum += ap;
      ap25_sum += ap25;
      ap50_sum += ap50;
      ++ap_n;
    }
    const auto h = hyp_counts[c];
    cm.hypotheses = MakePoint(h.first, h.second, cm.gt, hyp_err[c]);
    tp_h += h.first;
    fp_h += h.second;
    gt_all += cm.gt;
    all_h.centre.insert(all_h.centre.end(), hyp_err[c].centre.begin(), hyp_err[c].centre.end());
    all_h.yaw.insert(all_h.yaw.end(), hyp_err[c].yaw.begin(), hyp_err[c].yaw.end());
    if (out.fitted) {
      const auto v = ver_counts[c];
      cm.verified = MakePoint(v.first, v.second, cm.gt, ver_err[c]);
      tp_v += v.first;
      fp_v += v.second;
      all_v.centre.insert(all_v.centre.end(), ver_err[c].centre.begin(), ver_err[c].centre.end());
      all_v.yaw.insert(all_v.yaw.end(), ver_err[c].yaw.begin(), ver_err[c].yaw.end());
      VerificationFigures vf = ver_fig[c];
      FinishRates(&vf);
      cm.verification = vf;
      out.verification.tp += vf.tp;
      out.verification.tp_kept += vf.tp_kept;
      out.verification.fp += vf.fp;
      out.verification.fp_removed += vf.fp_removed;
    }
    out.classes.push_back(std::move(cm));
  }
  out.map = ap_n ? ap_sum / ap_n : NAN;
  out.map25 = ap_n ? ap25_sum / ap_n : NAN;
  out.map50 = ap_n ? ap50_sum / ap_n : NAN;
  out.hypotheses = MakePoint(tp_h, fp_h, gt_all, all_h);
  if (out.fitted) out.verified = MakePoint(tp_v, fp_v, gt_all, all_v);
  FinishRates(&out.verification);
  return out;
}

// ---- serialisation ---------------------------------------------------------------------

namespace {
// Compact rows: [score, tp, fp, precision, recall].
json CurveJson(const std::vector<PrPoint>& c) {
  json out = json::array();
  for (const auto& p : c) out.push_back({p.score, p.tp, p.fp, Num(p.precision), Num(p.recall)});
  return out;
}
std::vector<PrPoint> CurveFromJson(const json& rows) {
  std::vector<PrPoint> out;
  if (!rows.is_array()) return out;
  for (const auto& r : rows) {
    if (!r.is_array() || r.size() != 5) continue;
    PrPoint p;
    p.score = r[0].is_number() ? r[0].get<float>() : NAN;
    p.tp = r[1].is_number() ? r[1].get<int>() : 0;
    p.fp = r[2].is_number() ? r[2].get<int>() : 0;
    p.precision = r[3].is_number() ? r[3].get<double>() : NAN;
    p.recall = r[4].is_number() ? r[4].get<double>() : NAN;
    out.push_back(p);
  }
  return out;
}
}  // namespace

json ToJson(const EvalMetrics& m) {
  json classes = json::array();
  for (const auto& c : m.classes) {
    json curve = json::array();
    // Compact rows: [score, tp, fp, precision, recall].
    for (const auto& p : c.curve) curve.push_back({p.score, p.tp, p.fp, Num(p.precision), Num(p.recall)});
    classes.push_back({{"class", c.cls},
                       {"gt", c.gt},
                       {"detections", c.detections},
                       {"ap", Num(c.ap)},
                       {"ap25", Num(c.ap25)},
                       {"ap50", Num(c.ap50)},
                       {"hypotheses", ToJson(c.hypotheses)},
                       {"verified", c.verified ? ToJson(*c.verified) : json(nullptr)},
                       {"verification", c.verification ? ToJson(*c.verification) : json(nullptr)},
                       {"pr_curve_columns", {"score", "tp", "fp", "precision", "recall"}},
                       {"pr_curve", curve},
                       {"pr_curve_iou25", CurveJson(c.curve25)},
                       {"pr_curve_iou50", CurveJson(c.curve50)}});
  }
  json objects = json::array();
  for (const auto& r : m.objects) objects.push_back(ToJson(r));
  return {{"classes", classes},
          {"map", Num(m.map)},
          {"map25", Num(m.map25)},
          {"map50", Num(m.map50)},
          {"fitted", m.fitted},
          {"all",
           {{"hypotheses", ToJson(m.hypotheses)},
            {"verified", m.fitted ? ToJson(m.verified) : json(nullptr)},
            {"verification", m.fitted ? ToJson(m.verification) : json(nullptr)}}},
          {"ignored_gt", m.ignored_gt},
          {"ignored_detections", m.ignored_detections},
          {"objects", objects}};
}

EvalMetrics EvalMetricsFromJson(const json& j, const std::string& where) {
  EvalMetrics m;
  if (!j.is_object() || !j.contains("classes") || !j["classes"].is_array())
    throw InputError(where + "/classes: expected a list");
  for (size_t i = 0; i < j["classes"].size(); ++i) {
    const json& c = j["classes"][i];
    const std::string w = where + "/classes/" + std::to_string(i);
    ClassMetrics cm;
    if (!c.is_object() || !c.contains("class") || !c["class"].is_string()) throw InputError(w + "/class: expected a string");
    cm.cls = c["class"].get<std::string>();
    cm.gt = static_cast<int>(GetNum(c, "gt", w));
    cm.detections = static_cast<int>(GetNum(c, "detections", w));
    cm.ap = GetNum(c, "ap", w);
    // Run records written before the IoU rule have no ap25 / ap50: NaN, not an error.
    auto opt_num = [&](const char* k) { return c.contains(k) && c[k].is_number() ? c[k].get<double>() : NAN; };
    cm.ap25 = opt_num("ap25");
    cm.ap50 = opt_num("ap50");
    if (c.contains("pr_curve_iou25")) cm.curve25 = CurveFromJson(c["pr_curve_iou25"]);
    if (c.contains("pr_curve_iou50")) cm.curve50 = CurveFromJson(c["pr_curve_iou50"]);
    if (!c.contains("hypotheses")) throw InputError(w + "/hypotheses: missing");
    cm.hypotheses = OperatingPointFromJson(c["hypotheses"], w + "/hypotheses");
    if (c.contains("verified") && !c["verified"].is_null())
      cm.verified = OperatingPointFromJson(c["verified"], w + "/verified");
    if (c.contains("verification") && !c["verification"].is_null())
      cm.verification = VerificationFromJson(c["verification"], w + "/verification");
    if (c.contains("pr_curve")) {
      if (!c["pr_curve"].is_array()) throw InputError(w + "/pr_curve: expected a list");
      for (size_t k = 0; k < c["pr_curve"].size(); ++k) {
        const json& p = c["pr_curve"][k];
        if (!p.is_array() || p.size() != 5) throw InputError(w + "/pr_curve/" + std::to_string(k) + ": expected 5 numbers");
        auto num = [](const json& v) { return v.is_number() ? v.get<double>() : NAN; };
        cm.curve.push_back({static_cast<float>(num(p[0])), static_cast<int>(num(p[1])), static_cast<int>(num(p[2])),
                            num(p[3]), num(p[4])});
      }
    }
    m.classes.push_back(std::move(cm));
  }
  m.map = GetNum(j, "map", where);
  m.map25 = j.contains("map25") && j["map25"].is_number() ? j["map25"].get<double>() : NAN;
  m.map50 = j.contains("map50") && j["map50"].is_number() ? j["map50"].get<double>() : NAN;
  m.fitted = j.value("fitted", false);
  if (j.contains("all") && j["all"].is_object()) {
    if (j["all"].contains("hypotheses")) m.hypotheses = OperatingPointFromJson(j["all"]["hypotheses"], where + "/all/hypotheses");
    if (j["all"].contains("verified") && !j["all"]["verified"].is_null())
      m.verified = OperatingPointFromJson(j["all"]["verified"], where + "/all/verified");
    if (j["all"].contains("verification") && !j["all"]["verification"].is_null())
      m.verification = VerificationFromJson(j["all"]["verification"], where + "/all/verification");
  }
  if (j.contains("objects") && j["objects"].is_array())
    for (size_t i = 0; i < j["objects"].size(); ++i)
      m.objects.push_back(ObjectRecordFromJson(j["objects"][i], where + "/objects/" + std::to_string(i)));
  if (j.contains("ignored_gt") && j["ignored_gt"].is_object())
    m.ignored_gt = j["ignored_gt"].get<std::map<std::string, int>>();
  if (j.contains("ignored_detections") && j["ignored_detections"].is_object())
    m.ignored_detections = j["ignored_detections"].get<std::map<std::string, int>>();
  return m;
}

json ToJson(const RunFigures& r) {
  json scenes = json::array();
  for (const auto& s : r.scenes)
    scenes.push_back({{"scan", s.scan}, {"total_ms", s.total_ms}, {"detections", s.detections},
                      {"timings_ms", TimingsToJson(s.timings_ms)}});
  return {{"seed", r.seed},
          {"metrics", ToJson(r.metrics)},
          {"stage_ms", TimingsToJson(r.stage_ms)},
          {"wall_ms", r.wall_ms},
          {"model_ms", r.model_ms},
          {"model_source", r.model_source},
          {"peak_rss_mb", Num(r.peak_rss_mb)},
          {"jobs", r.jobs},
          {"scenes", scenes}};
}

RunFigures RunFiguresFromJson(const json& j, const std::string& where) {
  RunFigures r;
  if (!j.is_object()) throw InputError(where + ": expected an object");
  r.seed = static_cast<uint64_t>(GetNum(j, "seed", where));
  if (!j.contains("metrics")) throw InputError(where + "/metrics: missing");
  r.metrics = EvalMetricsFromJson(j["metrics"], where + "/metrics");
  if (j.contains("stage_ms")) r.stage_ms = TimingsFromJson(j["stage_ms"], where + "/stage_ms");
  r.wall_ms = GetNum(j, "wall_ms", where);
  r.model_ms = j.contains("model_ms") ? GetNum(j, "model_ms", where) : 0.0;
  r.model_source = j.value("model_source", "");
  r.peak_rss_mb = j.contains("peak_rss_mb") ? GetNum(j, "peak_rss_mb", where) : NAN;
  r.jobs = j.value("jobs", 1);
  if (j.contains("scenes") && j["scenes"].is_array()) {
    for (size_t i = 0; i < j["scenes"].size(); ++i) {
      const json& s = j["scenes"][i];
      const std::string w = where + "/scenes/" + std::to_string(i);
      SceneRecord rec;
      rec.scan = s.value("scan", "");
      rec.total_ms = GetNum(s, "total_ms", w);
      rec.detections = s.value("detections", 0);
      if (s.contains("timings_ms")) rec.timings_ms = TimingsFromJson(s["timings_ms"], w + "/timings_ms");
      r.scenes.push_back(std::move(rec));
    }
  }
  return r;
}

json ToJson(const ConfigSummary& s) {
  json runs = json::array();
  for (const auto& r : s.runs) runs.push_back(ToJson(r));
  return {{"name", s.name}, {"graph", s.graph}, {"runs", runs}};
}

ConfigSummary ConfigSummaryFromJson(const json& j, const std::string& where) {
  ConfigSummary s;
  if (!j.is_object() || !j.contains("name") || !j["name"].is_string()) throw InputError(where + "/name: expected a string");
  s.name = j["name"].get<std::string>();
  s.graph = j.value("graph", "");
  if (!j.contains("runs") || !j["runs"].is_array() || j["runs"].empty())
    throw InputError(where + "/runs: expected a non-empty list (one per seed)");
  for (size_t i = 0; i < j["runs"].size(); ++i)
    s.runs.push_back(RunFiguresFromJson(j["runs"][i], where + "/runs/" + std::to_string(i)));
  return s;
}

// ---- figures and report ----------------------------------------------------------------

std::map<std::string, double> FlatFigures(const RunFigures& r) {
  std::map<std::string, double> f;
  for (const auto& c : r.metrics.classes) {
    f[c.cls + "/gt"] = c.gt;
    f[c.cls + "/detections"] = c.detections;
    f[c.cls + "/ap"] = c.ap;
    f[c.cls + "/ap25"] = c.ap25;
    f[c.cls + "/ap50"] = c.ap50;
    AddPointFigures(f, c.cls + "/hypotheses", c.hypotheses);
    if (c.verified) AddPointFigures(f, c.cls + "/verified", *c.verified);
    if (c.verification) AddVerificationFigures(f, c.cls, *c.verification);
  }
  f["all/map"] = r.metrics.map;
  f["all/map25"] = r.metrics.map25;
  f["all/map50"] = r.metrics.map50;
  AddPointFigures(f, "all/hypotheses", r.metrics.hypotheses);
  if (r.metrics.fitted) {
    AddPointFigures(f, "all/verified", r.metrics.verified);
    AddVerificationFigures(f, "all", r.metrics.verification);
  }
  const double n = static_cast<double>(r.scenes.size());
  std::vector<double> scene_ms;
  for (const auto& s : r.scenes) scene_ms.push_back(s.total_ms);
  f["time/scene_ms"] = n > 0 ? std::accumulate(scene_ms.begin(), scene_ms.end(), 0.0) / n : NAN;
  f["time/scene_p90_ms"] = Summarise(scene_ms).p90;
  for (const auto& [tag, ms] : r.stage_ms) f["time/stage/" + tag + "_ms"] = n > 0 ? ms / n : NAN;
  f["time/wall_ms"] = r.wall_ms;
  f["time/model_ms"] = r.model_ms;
  f["memory/peak_rss_mb"] = r.peak_rss_mb;
  return f;
}

MeanStd MeanAndStd(const std::vector<double>& values) {
  MeanStd m;
  std::vector<double> v;
  for (double x : values)
    if (std::isfinite(x)) v.push_back(x);
  m.n = static_cast<int>(v.size());
  if (v.empty()) return m;
  m.mean = std::accumulate(v.begin(), v.end(), 0.0) / m.n;
  double ss = 0;
  for (double x : v) ss += (x - m.mean) * (x - m.mean);
  m.std = m.n > 1 ? std::sqrt(ss / (m.n - 1)) : 0.0;
  return m;
}

namespace {

struct Row {
  std::string label, key;
  int decimals;   // -1: a count (0 decimals for one seed, 1 for a mean over seeds)
  bool optional;  // omitted when no config has a finite value
};

std::string Fixed(double v, int decimals, bool sign = false) {
  if (!std::isfinite(v)) return "n/a";
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(decimals);
  // A difference that rounds to zero prints as 0, without a sign that would suggest a change.
  const double scale = std::pow(10.0, decimals);
  if (std::round(v * scale) == 0) v = 0;
  if (sign && v > 0) o << "+";
  o << v;
  return o.str();
}

std::string Letter(size_t i) {
  return i < 26 ? std::string(1, static_cast<char>('A' + i)) : "C" + std::to_string(i);
}

std::vector<Row> PointRows(const std::string& prefix, const std::string& which) {
  return {{"precision (" + which + ")", prefix + "/" + which + "/precision", 3, which == "verified"},
          {"recall (" + which + ")", prefix + "/" + which + "/recall", 3, which == "verified"},
          {"TP (" + which + ")", prefix + "/" + which + "/tp", -1, which == "verified"},
          {"FP (" + which + ")", prefix + "/" + which + "/fp", -1, which == "verified"},
          {"centre error median [m] (" + which + ")", prefix + "/" + which + "/centre_error_median_m", 3, which == "verified"},
          {"centre error p90 [m] (" + which + ")", prefix + "/" + which + "/centre_error_p90_m", 3, which == "verified"},
          {"yaw error median [deg] (" + which + ")", prefix + "/" + which + "/yaw_error_median_deg", 1, true},
          {"yaw error p90 [deg] (" + which + ")", prefix + "/" + which + "/yaw_error_p90_deg", 1, true}};
}

// Voter hypotheses (at the voter's centres) that verification kept or removed.
std::vector<Row> VerificationRows(const std::string& prefix) {
  const std::string v = prefix + "/verification/";
  return {{"true hypotheses (voter centres)", v + "tp", -1, true},
          {"true hypotheses kept by verification", v + "tp_kept", -1, true},
          {"share of true hypotheses kept", v + "tp_kept_rate", 3, true},
          {"false hypotheses (voter centres)", v + "fp", -1, true},
          {"false hypotheses removed by verification", v + "fp_removed", -1, true},
          {"share of false hypotheses removed", v + "fp_removal_rate", 3, true}};
}

std::string Cell(double v, int decimals) { return std::isfinite(v) ? Fixed(v, decimals) : "–"; }

// Markdown table of the per-object records of one run.
void ObjectTable(std::ostringstream& o, const std::vector<ObjectRecord>& objects) {
  o << "| scene | # | class | gt model | status | fitted model | centre err [m] | yaw err [deg] | gt symmetry | "
       "yaw err, symmetric [deg] | coverage | rejection |\n"
       "|---|---:|---|---|---|---|---:|---:|---:|---:|---:|---|\n";
  for (const auto& r : objects) {
    const std::string sym = r.yaw_symmetry < 0 ? "?" : r.yaw_symmetry == 0 ? "any" : std::to_string(r.yaw_symmetry);
    o << "| " << r.scene << " | " << r.index << " | " << r.cls << " | " << (r.gt_model.empty() ? "?" : r.gt_model)
      << " | " << r.status << " | " << (r.model.empty() ? "–" : r.model) << " | " << Cell(r.centre_error_m, 3) << " | "
      << Cell(r.yaw_error_deg, 1) << " | " << sym << " | " << Cell(r.yaw_error_folded_deg, 1) << " | "
      << Cell(r.coverage, 2) << " | "
      << (r.rejection.empty() ? "" : r.rejection) << " |\n";
  }
  o << "\n";
}

}  // namespace

std::string RenderReport(const std::vector<ConfigSummary>& configs, const ReportInfo& info) {
  std::ostringstream o;
  o << "# " << info.title << "\n\n";
  o << "- dataset: `" << info.dataset << "` (" << info.scenes << " scenes), hash `" << info.dataset_hash << "`\n";
  o << "- matching (paper Sect. VII-A): a detection is a true positive when its class matches and its centre lies "
       "within half the ground-truth object's width of the ground-truth centre on the floor plane (x, y); width "
       "convention **"
    << ToString(info.width) << "**: radius = " << ToString(info.width)
    << "(size x, size y) / 2; greedy by descending score, each ground-truth object matches at most one detection\n";
  o << "- AP25 / AP50 (ScanNet / VoteNet rule, what published detectors report; AP is the paper's rule above): a "
       "detection is a true positive "
       "when the 3D IoU of its axis-aligned box with the ground-truth box of its class that it overlaps most is >= 0.25 "
       "/ >= 0.5 and that object is not taken by a higher-scored detection\n";
  o << "- AP: all-point interpolated (VOC 2010+) area under the precision envelope of the score-threshold sweep; "
       "\"hypotheses\" = every detection the pipeline output (the voter's own threshold), \"verified\" = "
       "detections with verified != false (only when a fitter ran); \"true / false hypotheses\" = the voter's "
       "hypotheses matched at the centres the voter gave them (before fitting), then counted as kept or removed by "
       "the fitter's verification\n";
  size_t max_runs = 0;
  for (const auto& c : configs) max_runs = std::max(max_runs, c.runs.size());
  o << "- values: " << (max_runs > 1 ? "mean ± sample std over the detection seeds" : "one seed per config")
    << "; " << (configs.size() > 1 ? Letter(1) + " − A is the difference of the means" : "") << "\n";
  o << "- configs:\n";
  for (size_t i = 0; i < configs.size(); ++i) {
    o << "  - " << Letter(i) << " = **" << configs[i].name << "** (`" << configs[i].graph << "`), seeds";
    for (const auto& r : configs[i].runs) o << " " << r.seed;
    o << "\n";
  }
  for (const auto& n : info.notes) o << "- " << n << "\n";
  o << "\n";

  // Per config: key -> values over seeds.
  std::vector<std::map<std::string, std::vector<double>>> values(configs.size());
  for (size_t i = 0; i < configs.size(); ++i)
    for (const auto& r : configs[i].runs)
      for (const auto& [k, v] : FlatFigures(r)) values[i][k].push_back(v);
  auto stat = [&](size_t i, const std::string& key) {
    auto it = values[i].find(key);
    return it == values[i].end() ? MeanStd{} : MeanAndStd(it->second);
  };
  // Counts are whole numbers for one seed; their means over seeds are not.
  auto digits = [&](const Row& r) { return r.decimals < 0 ? (max_runs > 1 ? 1 : 0) : r.decimals; };
  auto cell = [&](const MeanStd& m, int decimals) {
    if (m.n == 0) return std::string("n/a");
    std::string s = Fixed(m.mean, decimals);
    if (max_runs > 1) s += " ± " + Fixed(m.std, decimals);
    return s;
  };
  auto table = [&](const std::string& heading, const std::vector<Row>& rows) {
    std::vector<const Row*> shown;
    for (const auto& r : rows) {
      bool any = false;
      for (size_t i = 0; i < configs.size(); ++i) any = any || stat(i, r.key).n > 0;
      if (any || !r.optional) shown.push_back(&r);
    }
    if (shown.empty()) return;
    o << "### " << heading << "\n\n| metric |";
    for (size_t i = 0; i < configs.size(); ++i) {
      o << " " << Letter(i) << ": " << configs[i].name << " |";
      if (i > 0) o << " " << Letter(i) << " − A |";
    }
    o << "\n|---|";
    for (size_t i = 0; i < configs.size(); ++i) o << (i > 0 ? "---:|---:|" : "---:|");
    o << "\n";
    for (const Row* r : shown) {
      o << "| " << r->label << " |";
      const MeanStd a = stat(0, r->key);
      for (size_t i = 0; i < configs.size(); ++i) {
        const MeanStd b = stat(i, r->key);
        o << " " << cell(b, digits(*r)) << " |";
        if (i > 0) o << " " << (a.n && b.n ? Fixed(b.mean - a.mean, digits(*r), true) : std::string("n/a")) << " |";
      }
      o << "\n";
    }
    o << "\n";
  };

  // Classes in the order of the first config that has them.
  std::vector<std::string> classes;
  for (const auto& c : configs)
    for (const auto& r : c.runs)
      for (const auto& cm : r.metrics.classes)
        if (std::find(classes.begin(), classes.end(), cm.cls) == classes.end()) classes.push_back(cm.cls);

  o << "## Detection\n\n";
  for (const auto& cls : classes) {
    int gt = -1, dets = 0;
    for (const auto& c : configs)
      for (const auto& r : c.runs)
        for (const auto& cm : r.metrics.classes)
          if (cm.cls == cls) {
            if (gt < 0) gt = cm.gt;
            dets += cm.detections;
          }
    if (gt <= 0 && dets == 0) {
      o << "### " << cls << "\n\nno ground-truth objects and no detections in any config\n\n";
      continue;
    }
    std::vector<Row> rows = {{"AP25", cls + "/ap25", 3, true},
                             {"AP50", cls + "/ap50", 3, true},
                             {"AP", cls + "/ap", 3, false},
                             {"detections", cls + "/detections", -1, false}};
    for (const auto& which : {"hypotheses", "verified"}) {
      auto pr = PointRows(cls, which);
      rows.insert(rows.end(), pr.begin(), pr.end());
    }
    const auto vr = VerificationRows(cls);
    rows.insert(rows.end(), vr.begin(), vr.end());
    table(cls + " (" + std::to_string(std::max(gt, 0)) + (gt == 1 ? " ground-truth object)" : " ground-truth objects)"), rows);
  }
  std::vector<Row> all = {{"mAP25", "all/map25", 3, true},
                          {"mAP50", "all/map50", 3, true},
                          {"mAP (mean AP over classes with ground truth)", "all/map", 3, false}};
  for (const auto& which : {"hypotheses", "verified"}) {
    auto pr = PointRows("all", which);
    all.insert(all.end(), pr.begin(), pr.end());
  }
  const auto vr = VerificationRows("all");
  all.insert(all.end(), vr.begin(), vr.end());
  table("all classes (micro totals)", all);

  // Per ground-truth object, first seed of each config: what the pipeline made of it.
  for (size_t i = 0; i < configs.size(); ++i) {
    if (configs[i].runs.empty() || configs[i].runs.front().metrics.objects.empty()) continue;
    const RunFigures& r = configs[i].runs.front();
    o << "### per object: " << Letter(i) << " = " << configs[i].name << " (seed " << r.seed << ")\n\n";
    o << "Errors of the detection shown: the verified one on the object, else the rejected hypothesis on it. "
         "Yaw errors: raw, and folded by the turns that map the ground-truth model onto itself (its gt "
         "yaw_symmetry, written by `furnihost simulate` from the mesh: n-fold, any, or ? = not declared, "
         "then not folded); the tables above fold them the same way.\n\n";
    ObjectTable(o, r.metrics.objects);
  }

  // Stage tags in first-seen order.
  std::vector<std::string> stages;
  for (const auto& c : configs)
    for (const auto& r : c.runs)
      for (const auto& [tag, ms] : r.stage_ms)
        if (std::find(stages.begin(), stages.end(), tag) == stages.end()) stages.push_back(tag);
  std::vector<Row> time = {{"scene total [ms] (mean per scene)", "time/scene_ms", 1, false},
                           {"scene total [ms] (p90)", "time/scene_p90_ms", 1, false}};
  for (const auto& s : stages) time.push_back({"stage " + s + " [ms per scene]", "time/stage/" + s + "_ms", 1, true});
  time.push_back({"detection wall clock [ms] (all scenes)", "time/wall_ms", 1, false});
  time.push_back({"model load / training [ms]", "time/model_ms", 1, false});
  time.push_back({"peak resident memory [MB]", "memory/peak_rss_mb", 1, false});
  o << "## Time and memory\n\n";
  table("time per stage and scene, peak memory", time);

  if (!info.plots.empty()) {
    o << "## Precision–recall (recall vs 1 − precision)\n\n";
    for (const auto& p : info.plots) o << "![" << fs::path(p).stem().string() << "](" << p << ")\n";
    o << "\n";
  }
  return o.str();
}

}  // namespace furnihost
