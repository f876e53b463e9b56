// Run records: metrics and run figures to JSON and back (summary.json, run_<name>.json,
// `furnihost compare`), and their flat figures by key.
#include "furnihost/host/evaluation.hpp"

#include <numeric>

#include "eval/internal.hpp"

using nlohmann::json;

namespace furnihost {

using eval_detail::FinishRates;

namespace {

json Num(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

double GetNum(const json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw InputError(where + "/" + key + ": missing");
  const json& v = j[key];
  if (v.is_null()) return NAN;
  if (!v.is_number()) throw InputError(where + "/" + key + ": expected a number or null, got " + v.dump());
  return v.get<double>();
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
          {"rejection", r.rejection},
          {"alignment", r.alignment}};
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
  r.alignment = j.value("alignment", "");
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

json ToJson(const AlignmentFigures& a) {
  return {{"objects", a.objects}, {"aligned", a.aligned}, {"accuracy", Num(a.accuracy)}};
}
AlignmentFigures AlignmentFromJson(const json& j, const std::string& where) {
  AlignmentFigures a;
  if (j.is_null()) return a;
  a.objects = static_cast<int>(GetNum(j, "objects", where));
  a.aligned = static_cast<int>(GetNum(j, "aligned", where));
  a.accuracy = GetNum(j, "accuracy", where);
  return a;
}

void AddAlignmentFigures(std::map<std::string, double>& f, const std::string& prefix, const AlignmentFigures& a) {
  f[prefix + "/alignment/objects"] = a.objects;
  f[prefix + "/alignment/aligned"] = a.aligned;
  f[prefix + "/alignment/accuracy"] = a.accuracy;
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
json ToJson(const std::optional<Reliability>& r) {
  if (!r) return json(nullptr);
  json bins = json::array();
  // Compact rows: [lo, hi, n, mean confidence, share true].
  for (const auto& b : r->bins) bins.push_back({b.lo, b.hi, b.n, Num(b.confidence), Num(b.accuracy)});
  return {{"detections", r->detections}, {"ece", Num(r->ece)},
          {"bin_columns", {"lo", "hi", "n", "confidence", "share_true"}}, {"bins", bins}};
}

std::optional<Reliability> ReliabilityFromJson(const json& j, const std::string& where) {
  if (j.is_null()) return std::nullopt;
  Reliability r;
  r.detections = static_cast<int>(GetNum(j, "detections", where));
  r.ece = j.contains("ece") && j["ece"].is_number() ? j["ece"].get<double>() : NAN;
  if (j.contains("bins") && j["bins"].is_array())
    for (size_t k = 0; k < j["bins"].size(); ++k) {
      const json& b = j["bins"][k];
      if (!b.is_array() || b.size() != 5)
        throw InputError(where + "/bins/" + std::to_string(k) + ": expected 5 numbers");
      auto num = [](const json& v) { return v.is_number() ? v.get<double>() : NAN; };
      r.bins.push_back({num(b[0]), num(b[1]), static_cast<int>(num(b[2])), num(b[3]), num(b[4])});
    }
  return r;
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
                       {"alignment", ToJson(c.alignment)},
                       {"accepted_iou25", ToJson(c.accepted25)},
                       {"reliability", ToJson(c.reliability)},
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
            {"verification", m.fitted ? ToJson(m.verification) : json(nullptr)},
            {"alignment", ToJson(m.alignment)},
            {"accepted_iou25", ToJson(m.accepted25)},
            {"reliability", ToJson(m.reliability)}}},
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
    // Records written before poses were evaluated have no alignment.
    if (c.contains("alignment")) cm.alignment = AlignmentFromJson(c["alignment"], w + "/alignment");
    // Records written before the working point and calibration were evaluated have neither.
    if (c.contains("accepted_iou25")) cm.accepted25 = OperatingPointFromJson(c["accepted_iou25"], w + "/accepted_iou25");
    if (c.contains("reliability")) cm.reliability = ReliabilityFromJson(c["reliability"], w + "/reliability");
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
    if (j["all"].contains("alignment")) m.alignment = AlignmentFromJson(j["all"]["alignment"], where + "/all/alignment");
    if (j["all"].contains("accepted_iou25"))
      m.accepted25 = OperatingPointFromJson(j["all"]["accepted_iou25"], where + "/all/accepted_iou25");
    if (j["all"].contains("reliability"))
      m.reliability = ReliabilityFromJson(j["all"]["reliability"], where + "/all/reliability");
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
  r.wall_ms = j.contains("wall_ms") ? GetNum(j, "wall_ms", where) : NAN;  // absent: eval --reproducible
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
      rec.total_ms = s.contains("total_ms") ? GetNum(s, "total_ms", w) : NAN;
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
    if (c.alignment.objects > 0) AddAlignmentFigures(f, c.cls, c.alignment);
    AddPointFigures(f, c.cls + "/accepted_iou25", c.accepted25);
    if (c.reliability) f[c.cls + "/ece"] = c.reliability->ece;
  }
  f["all/map"] = r.metrics.map;
  f["all/map25"] = r.metrics.map25;
  f["all/map50"] = r.metrics.map50;
  AddPointFigures(f, "all/hypotheses", r.metrics.hypotheses);
  if (r.metrics.fitted) {
    AddPointFigures(f, "all/verified", r.metrics.verified);
    AddVerificationFigures(f, "all", r.metrics.verification);
  }
  if (r.metrics.alignment.objects > 0) AddAlignmentFigures(f, "all", r.metrics.alignment);
  AddPointFigures(f, "all/accepted_iou25", r.metrics.accepted25);
  if (r.metrics.reliability) f["all/ece"] = r.metrics.reliability->ece;
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

}  // namespace furnihost
