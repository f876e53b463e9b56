#include "report.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>

namespace fs = std::filesystem;

namespace furnihost::app {

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

// The Scan2CAD alignment of the accepted detections.
std::vector<Row> AlignmentRows(const std::string& prefix) {
  return {{"alignment accuracy (Scan2CAD rule)", prefix + "/alignment/accuracy", 3, true},
          {"ground-truth objects with a yaw", prefix + "/alignment/objects", -1, true}};
}

// The working point by the ScanNet rule, and how well confidences are calibrated.
std::vector<Row> WorkingPointRows(const std::string& prefix) {
  return {{"precision (accepted, IoU 0.25)", prefix + "/accepted_iou25/precision", 3, false},
          {"recall (accepted, IoU 0.25)", prefix + "/accepted_iou25/recall", 3, false},
          {"expected calibration error (confidence)", prefix + "/ece", 3, true}};
}

std::string Cell(double v, int decimals) { return std::isfinite(v) ? Fixed(v, decimals) : "–"; }

// Markdown table of the per-object records of one run.
void ObjectTable(std::ostringstream& o, const std::vector<ObjectRecord>& objects) {
  o << "| scene | # | class | gt model | status | fitted model | centre err [m] | yaw err [deg] | gt symmetry | "
       "yaw err, symmetric [deg] | coverage | rejection | alignment (Scan2CAD rule) |\n"
       "|---|---:|---|---|---|---|---:|---:|---:|---:|---:|---|---|\n";
  for (const auto& r : objects) {
    const std::string sym = r.yaw_symmetry < 0 ? "?" : r.yaw_symmetry == 0 ? "any" : std::to_string(r.yaw_symmetry);
    o << "| " << r.scene << " | " << r.index << " | " << r.cls << " | " << (r.gt_model.empty() ? "?" : r.gt_model)
      << " | " << r.status << " | " << (r.model.empty() ? "–" : r.model) << " | " << Cell(r.centre_error_m, 3) << " | "
      << Cell(r.yaw_error_deg, 1) << " | " << sym << " | " << Cell(r.yaw_error_folded_deg, 1) << " | "
      << Cell(r.coverage, 2) << " | "
      << (r.rejection.empty() ? "" : r.rejection) << " | " << r.alignment << " |\n";
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
  o << "- alignment accuracy (Scan2CAD rule): the share of ground-truth objects with a known yaw that an accepted "
       "detection of their class aligns: box centre within 0.2 m, facing within 20 deg (folded by the object's "
       "turn symmetry), mean extent ratio within 20 % of 1\n";
  o << "- accepted, IoU 0.25: the detections the graph accepts (verified != false; a calibrated graph's at its "
       "min_confidence) matched on their own by the ScanNet rule: the working point's precision and recall; "
       "expected calibration error: the detection-weighted mean |share true - mean confidence| over 10 "
       "confidence bins, true by AP25's matching (reliability_<class>.svg/.png)\n";
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
    const auto wr = WorkingPointRows(cls);
    rows.insert(rows.end(), wr.begin(), wr.end());
    for (const auto& which : {"hypotheses", "verified"}) {
      auto pr = PointRows(cls, which);
      rows.insert(rows.end(), pr.begin(), pr.end());
    }
    const auto vr = VerificationRows(cls);
    rows.insert(rows.end(), vr.begin(), vr.end());
    const auto ar = AlignmentRows(cls);
    rows.insert(rows.end(), ar.begin(), ar.end());
    table(cls + " (" + std::to_string(std::max(gt, 0)) + (gt == 1 ? " ground-truth object)" : " ground-truth objects)"), rows);
  }
  std::vector<Row> all = {{"mAP25", "all/map25", 3, true},
                          {"mAP50", "all/map50", 3, true},
                          {"mAP (mean AP over classes with ground truth)", "all/map", 3, false}};
  const auto wr = WorkingPointRows("all");
  all.insert(all.end(), wr.begin(), wr.end());
  for (const auto& which : {"hypotheses", "verified"}) {
    auto pr = PointRows("all", which);
    all.insert(all.end(), pr.begin(), pr.end());
  }
  const auto vr = VerificationRows("all");
  all.insert(all.end(), vr.begin(), vr.end());
  const auto ar = AlignmentRows("all");
  all.insert(all.end(), ar.begin(), ar.end());
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

  if (!info.measurements) {
    if (!info.plots.empty()) {
      o << "## Precision–recall (recall vs 1 − precision)\n\n";
      for (const auto& p : info.plots) o << "![" << fs::path(p).stem().string() << "](" << p << ")\n";
      o << "\n";
    }
    return o.str();
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

}  // namespace furnihost::app
