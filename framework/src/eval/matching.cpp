// Matching detections with ground truth: the paper's centre-distance rule and the ScanNet box-IoU rule.
#include "furnihost/host/evaluation.hpp"

#include <algorithm>

#include "eval/internal.hpp"

namespace furnihost {

using eval_detail::PlaneDistance;

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

namespace {

// Both rules start alike: every object and detection gets its evaluation class (or is ignored:
// a class the dataset does not evaluate), all unmatched; returns the evaluated detections'
// indices by descending score (stable: ties keep their order).
std::vector<size_t> Classify(const std::vector<Detection>& dets, const std::vector<GroundTruthObject>& truth,
                             const ClassMap& classes, SceneMatch* m) {
  m->det_to_gt.assign(dets.size(), SceneMatch::kUnmatched);
  m->gt_to_det.assign(truth.size(), SceneMatch::kUnmatched);
  m->det_class.resize(dets.size());
  m->gt_class.resize(truth.size());
  for (size_t g = 0; g < truth.size(); ++g) {
    auto c = classes.Map(truth[g].cls);
    if (c) m->gt_class[g] = *c;
    else m->gt_to_det[g] = SceneMatch::kIgnored;
  }
  std::vector<size_t> order;
  for (size_t i = 0; i < dets.size(); ++i) {
    auto c = classes.Map(dets[i].cls);
    if (c) {
      m->det_class[i] = *c;
      order.push_back(i);
    } else {
      m->det_to_gt[i] = SceneMatch::kIgnored;
    }
  }
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return dets[a].score > dets[b].score; });
  return order;
}

}  // namespace

SceneMatch MatchScene(const std::vector<Detection>& dets, const std::vector<GroundTruthObject>& truth,
                      const ClassMap& classes, WidthConvention width) {
  SceneMatch m;
  const std::vector<size_t> order = Classify(dets, truth, classes, &m);
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
  const std::vector<size_t> order = Classify(dets, truth, classes, &m);
  std::vector<Eigen::AlignedBox3f> gt_box(truth.size());
  for (size_t g = 0; g < truth.size(); ++g) gt_box[g] = GroundTruthBox(truth[g]);
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

}  // namespace furnihost
