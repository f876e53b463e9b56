// Figures of matched detections: precision-recall curves, average precision, operating
// points, error statistics, verification figures and per-object records (Evaluate).
#include "furnihost/host/evaluation.hpp"

#include <algorithm>
#include <map>

#include "eval/internal.hpp"

namespace furnihost {

using eval_detail::FinishRates;
using eval_detail::PlaneDistance;
using eval_detail::SafeDiv;

double FoldYawErrorDeg(double raw_deg, std::optional<int> yaw_symmetry) {
  if (!std::isfinite(raw_deg) || !yaw_symmetry || *yaw_symmetry == 1) return raw_deg;
  if (*yaw_symmetry <= 0) return 0.0;
  const double period = 360.0 / *yaw_symmetry;
  const double d = std::fmod(raw_deg, period);
  return std::min(d, period - d);
}

namespace {

constexpr double kPi = 3.14159265358979323846;

// Smallest absolute difference of two angles [rad], in degrees in [0, 180].
double YawErrorDeg(double a, double b) {
  double d = std::fmod(std::abs(a - b), 2 * kPi);
  if (d > kPi) d = 2 * kPi - d;
  return d * 180.0 / kPi;
}

// One evaluated detection after matching.
struct Scored {
  float score;
  size_t scene, index;  // for a deterministic order among equal scores
  bool tp;
  std::optional<float> confidence = std::nullopt;
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

// Scan2CAD alignment of the accepted detections of one scene, per evaluated class: each gt
// object with a yaw counts; detections in descending score take the nearest object of their
// class they align (Aligned), each object once.
void AccumulateAlignment(const std::vector<Detection>& dets, const std::vector<GroundTruthObject>& truth,
                         const ClassMap& classes, std::map<std::string, AlignmentFigures>& out) {
  std::vector<std::optional<std::string>> gt_class(truth.size());
  for (size_t g = 0; g < truth.size(); ++g) {
    gt_class[g] = classes.Map(truth[g].cls);
    if (gt_class[g] && truth[g].yaw) ++out[*gt_class[g]].objects;
  }
  std::vector<size_t> order(dets.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dets[a].score > dets[b].score; });
  std::vector<char> taken(truth.size(), 0);
  for (size_t i : order) {
    const auto c = classes.Map(dets[i].cls);
    if (!c) continue;
    int best = -1;
    float best_d = INFINITY;
    for (size_t g = 0; g < truth.size(); ++g) {
      if (taken[g] || gt_class[g] != c || !Aligned(dets[i], truth[g])) continue;
      const float d = (dets[i].box->center - truth[g].center).norm();
      if (d < best_d) best = int(g), best_d = d;
    }
    if (best < 0) continue;
    taken[size_t(best)] = 1;
    ++out[*c].aligned;
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

// The scene's ground truth, each object without a yaw_symmetry of its own given its evaluated
// class's (ClassMap::yaw_symmetry), when the dataset declares one.
std::vector<GroundTruthObject> WithClassSymmetry(std::vector<GroundTruthObject> truth, const ClassMap& classes) {
  for (auto& g : truth)
    if (!g.yaw_symmetry)
      if (const auto c = classes.Map(g.cls))
        if (const auto it = classes.yaw_symmetry.find(*c); it != classes.yaw_symmetry.end()) g.yaw_symmetry = it->second;
  return truth;
}

}  // namespace

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

Reliability MakeReliability(const std::vector<std::pair<float, bool>>& confidence_true, int bins) {
  Reliability r;
  r.bins.resize(size_t(std::max(bins, 1)));
  std::vector<double> sum_conf(r.bins.size(), 0.0), sum_true(r.bins.size(), 0.0);
  for (size_t b = 0; b < r.bins.size(); ++b) {
    r.bins[b].lo = double(b) / double(r.bins.size());
    r.bins[b].hi = double(b + 1) / double(r.bins.size());
  }
  for (const auto& [c, t] : confidence_true) {
    if (!std::isfinite(c)) continue;
    const size_t b = std::min(r.bins.size() - 1, size_t(std::max(0.0, double(c)) * double(r.bins.size())));
    ++r.bins[b].n;
    sum_conf[b] += c;
    sum_true[b] += t ? 1.0 : 0.0;
    ++r.detections;
  }
  if (r.detections == 0) return r;
  double ece = 0;
  for (size_t b = 0; b < r.bins.size(); ++b) {
    Reliability::Bin& x = r.bins[b];
    if (x.n == 0) continue;
    x.confidence = sum_conf[b] / x.n;
    x.accuracy = sum_true[b] / x.n;
    ece += x.n * std::abs(x.accuracy - x.confidence);
  }
  r.ece = ece / r.detections;
  return r;
}

EvalMetrics Evaluate(const std::vector<SceneEval>& scenes, const ClassMap& classes, WidthConvention width) {
  EvalMetrics out;
  std::map<std::string, int> gt_count;
  std::map<std::string, std::vector<Scored>> scored, scored25, scored50;
  std::map<std::string, std::pair<int, int>> hyp_counts, ver_counts;
  std::map<std::string, ErrorAccumulator> hyp_err, ver_err;
  std::map<std::string, VerificationFigures> ver_fig;
  std::map<std::string, AlignmentFigures> alignment;
  std::map<std::string, std::pair<int, int>> acc25_counts;
  std::map<std::string, ErrorAccumulator> acc25_err;
  for (size_t s = 0; s < scenes.size(); ++s) {
    const SceneEval& se = scenes[s];
    const std::vector<GroundTruthObject> truth = WithClassSymmetry(se.truth, classes);
    out.fitted = out.fitted || se.fitted;
    const SceneMatch m = MatchScene(se.detections, truth, classes, width);
    for (size_t g = 0; g < truth.size(); ++g) {
      if (m.gt_class[g].empty()) ++out.ignored_gt[truth[g].cls];
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
      const SceneMatch mi = MatchSceneIou(se.detections, truth, classes, threshold);
      for (size_t i = 0; i < se.detections.size(); ++i)
        if (mi.det_to_gt[i] != SceneMatch::kIgnored)
          (*target)[mi.det_class[i]].push_back(
              {se.detections[i].score, s, i, mi.det_to_gt[i] >= 0, se.detections[i].confidence});
    }
    Accumulate(se.detections, truth, m, se.fitted, hyp_counts, hyp_err);
    // Rejected detections leave the set, so the remaining ones are matched on their own: a
    // verified detection may take the gt object a rejected one had taken.
    std::vector<Detection> kept;
    for (const auto& d : se.detections)
      if (d.verified.value_or(true)) kept.push_back(d);
    const SceneMatch mv = MatchScene(kept, truth, classes, width);
    Accumulate(kept, truth, mv, se.fitted, ver_counts, ver_err);
    AccumulateAlignment(kept, truth, classes, alignment);
    Accumulate(kept, truth, MatchSceneIou(kept, truth, classes, 0.25f), se.fitted, acc25_counts, acc25_err);

    // The voter's hypotheses where the voter put them: which were true, and what did the
    // verification do with each.
    std::vector<Detection> placed = se.detections;
    if (se.voter_centres.size() == placed.size())
      for (size_t i = 0; i < placed.size(); ++i) placed[i].center = se.voter_centres[i];
    const SceneMatch mh = MatchScene(placed, truth, classes, width);
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
    for (size_t g = 0; g < truth.size(); ++g) {
      if (m.gt_class[g].empty()) continue;
      ObjectRecord r;
      r.scene = se.name;
      r.index = static_cast<int>(g);
      r.cls = m.gt_class[g];
      r.gt_model = truth[g].model;
      r.yaw_symmetry = truth[g].yaw_symmetry.value_or(-1);
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
        r.centre_error_m = PlaneDistance(d.center, truth[g].center);
        if (se.fitted && !d.model.empty() && truth[g].yaw) {
          r.yaw_error_deg = YawErrorDeg(d.yaw, *truth[g].yaw);
          r.yaw_error_folded_deg = FoldYawErrorDeg(r.yaw_error_deg, truth[g].yaw_symmetry);
        }
        if (d.coverage) r.coverage = *d.coverage;
        r.rejection = d.Rejection();
        if (truth[g].yaw) {
          const std::string miss = AlignmentMiss(d, truth[g]);
          r.alignment = miss.empty() ? "aligned" : miss;
        }
      }
      out.objects.push_back(std::move(r));
    }
  }

  int tp_h = 0, fp_h = 0, tp_v = 0, fp_v = 0, tp_a = 0, fp_a = 0, gt_all = 0;
  ErrorAccumulator all_h, all_v;
  std::vector<std::pair<float, bool>> all_conf;
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
    const auto a = acc25_counts[c];
    cm.accepted25 = MakePoint(a.first, a.second, cm.gt, acc25_err[c]);
    tp_a += a.first;
    fp_a += a.second;
    std::vector<std::pair<float, bool>> conf;
    for (const Scored& x : scored25[c])
      if (x.confidence) conf.emplace_back(*x.confidence, x.tp);
    if (!conf.empty()) {
      cm.reliability = MakeReliability(conf);
      all_conf.insert(all_conf.end(), conf.begin(), conf.end());
    }
    tp_h += h.first;
    fp_h += h.second;
    gt_all += cm.gt;
    all_h.centre.insert(all_h.centre.end(), hyp_err[c].centre.begin(), hyp_err[c].centre.end());
    all_h.yaw.insert(all_h.yaw.end(), hyp_err[c].yaw.begin(), hyp_err[c].yaw.end());
    cm.alignment = alignment[c];
    cm.alignment.accuracy = SafeDiv(cm.alignment.aligned, cm.alignment.objects);
    out.alignment.objects += cm.alignment.objects;
    out.alignment.aligned += cm.alignment.aligned;
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
  out.accepted25 = MakePoint(tp_a, fp_a, gt_all, ErrorAccumulator{});
  if (!all_conf.empty()) out.reliability = MakeReliability(all_conf);
  if (out.fitted) out.verified = MakePoint(tp_v, fp_v, gt_all, all_v);
  FinishRates(&out.verification);
  out.alignment.accuracy = SafeDiv(out.alignment.aligned, out.alignment.objects);
  return out;
}

}  // namespace furnihost
