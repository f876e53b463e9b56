// voters.esf_catalog — the global-descriptor baseline of issue 20: recognises object proposals
// (proposals.<name>) by nearest neighbours of their ESF descriptor (Wohlkinger & Vincze 2011,
// PCL's ESFEstimation, 640 bins; the 3DNet approach: classes learned from web CAD models) among
// the descriptors of the catalog's simulated training views, optionally times a metric-size
// agreement with the class's catalog models. One detection per proposal and class with votes,
// the proposal's box, non-maximum suppressed per class; the same outputs as voters.catalog_shape,
// so the two compare in one `furnihost eval`.
//
// Score of class c for a proposal (descriptor q, footprint L x W with L >= W, top T above the
// ground), over the training views v (descriptor e_v, class c_v):
//   d_v   = L1(q, e_v)  (or chi-squared, `distance`)
//   vote_c = (1/k) * sum over the k nearest views v with c_v = c of exp(-d_v / tau)
//   E_c   = min over the class's catalog models m of
//           [ln(L / L_m)^2 + ln(W / W_m)^2 + ln(T / H_m)^2] / (2 sig_size^2)
//   score_c = vote_c * exp(-E_c)^size_weight
// tau = kernel_scale * the catalog's own typical descriptor distance (the median, over the
// training views, of the distance to the nearest view of another model), so the score does not
// depend on how alike a catalog's models happen to be. vote_c is a distance-weighted share that
// is not renormalised: a proposal unlike every training view (a wall piece, clutter) scores low
// for every class instead of 1 for whichever class its nearest views happen to have, which is
// what ranking (AP) needs.
//
// Why L1: the histograms sum to 1 (L1 is twice the total variation, bounded, every bin counted
// alike); chi-squared divides by the bins' sums and so weighs the near-empty bins, which are the
// noisiest on the partial, noisy views of real scans. `distance` chi2 is there to measure it.
//
// Why the size term: ESF normalises by the cloud's extent, so a doll's chair and a sofa of the
// same outline look alike; the metric size survives the gap between simulated and real views
// (on real segments the size alone names the class more often than ESF's nearest neighbour).
// It is a baseline beside voters.catalog_shape: docs/experiments/2026-12-02-esf-baseline.md
// compares them (`furnihost eval --graph configs/scannet.json --graph configs/scannet_esf.json
// --dataset benchmarks/scannet_dev.json`).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/plugin.hpp"
#include "decision/decision_params.hpp"
#include "shape/shape.hpp"

// PCL's ESFEstimation (1.13) seeds the C library's one shared generator with the wall clock at
// every call (srand(time(nullptr))) and draws its 20000 point triples with rand(): two runs never
// give the same descriptor, and the scenes an eval runs in parallel share that generator. So its
// implementation is instantiated here, for an output type of this file only (libpcl_features'
// own instantiations are not touched), with those two calls routed to a generator per thread
// that EsfDescriptor seeds for every cloud. The EsfCatalog determinism tests fail if a PCL
// update changes how ESF draws.
#include <cstdlib>
#include <ctime>
#include <pcl/common/distances.h>
#include <pcl/common/transforms.h>
#include <pcl/features/esf.h>
#include <pcl/point_types.h>

namespace furnihost::esf_random {
inline thread_local std::mt19937 generator;
inline int Draw() { return static_cast<int>(generator() >> 1); }  // in [0, 2^31): as rand()
}  // namespace furnihost::esf_random

#define srand(seed) static_cast<void>(0)
#define rand() ::furnihost::esf_random::Draw()
#include <pcl/features/impl/esf.hpp>
#undef rand
#undef srand

namespace furnihost {
namespace {

constexpr int kBins = 640;
// Descriptors are stored as integer parts per million of their unit sum: a bin of 1e-6 is far
// below the distances compared (0.1-1), and CBOR keeps most bins in 1-3 bytes.
constexpr double kStoreScale = 1e6;

struct EsfHistogram {  // PCL's ESFSignature640, but this file's own type (see above)
  float histogram[kBins];
};

uint64_t Mix(uint64_t h, uint64_t v) {  // splitmix64 of the combination
  h ^= v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
  h = (h ^ (h >> 30)) * 0xbf58476d1ce4e5b9ull;
  h = (h ^ (h >> 27)) * 0x94d049bb133111ebull;
  return h ^ (h >> 31);
}

uint64_t Fnv(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

// The ESF descriptor of a cloud (unit sum), drawn with a generator seeded by `seed`. Empty when
// the cloud is degenerate (fewer than 3 points, or all in one spot: ESF scales by the extent).
class EsfDescriptor {
 public:
  std::vector<float> operator()(const Points& points, uint64_t seed) {
    if (points.size() < 3) return {};
    Eigen::Vector3f lo = points[0], hi = points[0];
    for (const auto& p : points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    if ((hi - lo).maxCoeff() < 1e-3f) return {};
    auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    cloud->reserve(points.size());
    for (const auto& p : points) cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    esf_random::generator.seed(static_cast<uint32_t>(seed ^ (seed >> 32)));
    pcl::PointCloud<EsfHistogram> out;
    estimator_.setInputCloud(cloud);
    estimator_.compute(out);
    if (out.size() != 1) return {};
    std::vector<float> d(out[0].histogram, out[0].histogram + kBins);
    for (float v : d)
      if (!std::isfinite(v) || v < 0.f) return {};
    return d;
  }

 private:
  pcl::ESFEstimation<pcl::PointXYZ, EsfHistogram> estimator_;  // holds a 64^3 grid: reused
};

struct Model {
  std::string id, cls;  // cls: the output class (after class_map)
  float length = 0, width = 0, height = 0;
  bool wide = true;  // the model's x extent (width) is its length
};

// Each parameter declared once (Binding()); its default is Options{}'s. Real values are doubles
// so that the schema, `furnihost plugins` and the run records show 0.02, not 0.0199999996.
struct Options {
  std::map<std::string, std::string> class_map;  // catalog class -> output class
  double voxel_m = 0.02;      // training views and proposals are downsampled to this
  int k = 5;                  // nearest training views that vote
  bool chi2 = false;          // descriptor distance: chi-squared instead of L1
  double kernel_scale = 1.;   // tau in units of the catalog's typical descriptor distance
  double size_weight = 1.;    // exponent of the size factor (0 = ESF votes only)
  double sig_size = 0.3;      // spread of the log size ratios
  int min_points = 50;        // proposals with fewer points (after downsampling) are skipped
  // thresholds, default_threshold, min_score, nms_iou, nms_whole_ratio
  DecisionOptions decision{{}, 0., 1e-4, 0.25, 0.};
};

const ParamBinding<Options>& Binding() {
  using O = Options;
  static const auto b = BindDecision(
      ParamBinding<O>()
          .Object("class_map", nlohmann::json::object(),
                  "catalog class -> detected class, e.g. {\"armchair\": \"chair\", \"desk\": \"table\"}: the views "
                  "of merged classes vote as one class",
                  ClassMapParser<O>(&O::class_map))
          .DetectionOnly()
          .Number("voxel_m", &O::voxel_m, 0, 1, "m",
                  "voxel edge the training views and the proposals are downsampled to before ESF (the scans' "
                  "density); 0 = as they are")
          .Int("k", &O::k, 1, 1000, "count", "nearest training views that vote")
          .DetectionOnly()
          .Enum("distance", &O::chi2, {"l1", "chi2"},
                "descriptor distance: l1 (bounded, every bin alike) or chi2 (weighs near-empty bins more)")
          .DetectionOnly()
          .Number("kernel_scale", &O::kernel_scale, 1e-3, 100, "1",
                  "vote weight exp(-d / tau), tau = this x the catalog's median distance from a view to the nearest "
                  "view of another model")
          .DetectionOnly()
          .Number("size_weight", &O::size_weight, 0, 100, "1",
                  "exponent of the size factor exp(-E_size) in the score (0 = ESF votes only)")
          .DetectionOnly()
          .Number("sig_size", &O::sig_size, 1e-3, 100, "1",
                  "spread of ln(proposal length, width, top height / the class's nearest catalog model's)")
          .DetectionOnly()
          .Int("min_points", &O::min_points, 3, 10000000, "count",
               "proposals with fewer points after voxel_m downsampling are skipped")
          .DetectionOnly(),
      [](O& o) -> DecisionOptions& { return o.decision; }, {"in [0, 1]", "", true});
  return b;
}

class EsfCatalogVoter : public Voter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }

  explicit EsfCatalogVoter(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext& ctx) override {
    // One entry per model: its catalog size and the descriptors of its views, in view order.
    std::map<std::string, nlohmann::json> by_model;
    std::vector<std::string> order;
    EsfDescriptor esf;
    size_t described = 0;
    for (const auto& v : views) {
      auto [it, fresh] = by_model.try_emplace(v.model_id);
      if (fresh) {
        order.push_back(v.model_id);
        const Eigen::Vector3f s = v.object_size;
        it->second = {{"id", v.model_id}, {"class", v.cls}, {"size", {s.x(), s.y(), s.z()}},
                      {"esf", nlohmann::json::array()}};
      }
      Points w(v.scan.points.size());
      for (size_t i = 0; i < w.size(); ++i) w[i] = v.scan.pose * v.scan.points[i];
      const Points pts = VoxelDownsample(w, static_cast<float>(o_.voxel_m));
      // Fewer than 10 points: a view that missed the model (nothing to describe).
      const std::vector<float> d =
          pts.size() < 10 ? std::vector<float>{}
                          : esf(pts, Mix(Mix(ctx.seed, Fnv(v.model_id)), static_cast<uint64_t>(v.view)));
      if (d.empty()) {
        spdlog::debug("esf_catalog: view {} of {} skipped ({} points)", v.view, v.model_id, pts.size());
        continue;
      }
      std::vector<uint32_t> q(kBins);
      for (int b = 0; b < kBins; ++b) q[size_t(b)] = static_cast<uint32_t>(std::lround(double(d[size_t(b)]) * kStoreScale));
      it->second["esf"].push_back(std::move(q));
      ++described;
    }
    if (!described) throw StageError("voters.esf_catalog: no training view with 10 or more points to describe", false);
    nlohmann::json models = nlohmann::json::array();
    for (const auto& id : order)
      if (!by_model[id]["esf"].empty()) models.push_back(std::move(by_model[id]));
    spdlog::info("esf_catalog: {} ESF descriptors of {} models", described, models.size());
    return {{"format", "esf_catalog/1"}, {"voxel_m", o_.voxel_m}, {"bins", kBins}, {"models", models}};
  }

  void Load(const nlohmann::json& m) override {
    if (!m.is_object() || !m.contains("format") || m["format"] != "esf_catalog/1")
      throw InputError("not a voters.esf_catalog model (format esf_catalog/1)");
    if (!m.contains("bins") || m["bins"] != kBins)
      throw InputError("esf_catalog model: expected " + std::to_string(kBins) + "-bin ESF descriptors");
    if (!m.contains("voxel_m") || !m["voxel_m"].is_number() || !(m["voxel_m"].get<double>() >= 0.0))
      throw InputError("esf_catalog model: bad voxel_m");
    if (!m.contains("models") || !m["models"].is_array()) throw InputError("esf_catalog model: no models array");
    models_.clear();
    view_model_.clear();
    std::vector<std::vector<float>> desc;
    for (const auto& j : m["models"]) {
      if (!j.is_object() || !j.contains("id") || !j["id"].is_string() || !j.contains("class") ||
          !j["class"].is_string() || !j.contains("size") || !j.contains("esf") || !j["esf"].is_array())
        throw InputError("esf_catalog model: a model without id, class, size or esf");
      Model md;
      md.id = j["id"].get<std::string>();
      const std::string cls = j["class"].get<std::string>();
      auto it = o_.class_map.find(cls);
      md.cls = it == o_.class_map.end() ? cls : it->second;
      const auto& size = j["size"];
      if (!size.is_array() || size.size() != 3) throw InputError("esf_catalog model " + md.id + ": bad size");
      for (const auto& v : size)
        if (!v.is_number() || !(v.get<double>() > 0.0) || !std::isfinite(v.get<double>()))
          throw InputError("esf_catalog model " + md.id + ": bad size");
      const float sx = size[0].get<float>(), sy = size[1].get<float>();
      md.length = std::max(sx, sy);
      md.width = std::min(sx, sy);
      md.height = size[2].get<float>();
      md.wide = sx >= sy;
      for (const auto& e : j["esf"]) {
        if (!e.is_array() || e.size() != size_t(kBins))
          throw InputError("esf_catalog model " + md.id + ": a descriptor without " + std::to_string(kBins) + " bins");
        std::vector<float> d(kBins);
        double sum = 0;
        for (int b = 0; b < kBins; ++b) {
          const auto& v = e[size_t(b)];
          if (!v.is_number_integer() || v.get<int64_t>() < 0) throw InputError("esf_catalog model " + md.id + ": descriptor bins must be counts >= 0");
          d[size_t(b)] = static_cast<float>(v.get<double>() / kStoreScale);
          sum += d[size_t(b)];
        }
        if (std::abs(sum - 1.0) > 0.01)
          throw InputError("esf_catalog model " + md.id + ": a descriptor does not sum to 1 (not ESF)");
        desc.push_back(std::move(d));
        view_model_.push_back(int(models_.size()));
      }
      models_.push_back(md);
    }
    if (desc.empty()) throw InputError("esf_catalog model: no descriptors");
    model_voxel_ = m["voxel_m"].get<float>();
    views_.resize(kBins, Eigen::Index(desc.size()));
    for (size_t v = 0; v < desc.size(); ++v) views_.col(Eigen::Index(v)) = Eigen::Map<const Eigen::VectorXf>(desc[v].data(), kBins);
    classes_.clear();
    for (const auto& md : models_)
      if (std::find(classes_.begin(), classes_.end(), md.cls) == classes_.end()) classes_.push_back(md.cls);
    view_class_.resize(desc.size());
    for (size_t v = 0; v < desc.size(); ++v)
      view_class_[v] = int(std::find(classes_.begin(), classes_.end(), models_[size_t(view_model_[v])].cls) - classes_.begin());
    // The catalog's own descriptor scale: per view the distance to the nearest view of another
    // model (of the same model when the catalog has only one), the median over the views.
    std::vector<float> nearest(desc.size(), INFINITY), nearest_same(desc.size(), INFINITY);
    for (size_t a = 0; a < desc.size(); ++a)
      for (size_t b = a + 1; b < desc.size(); ++b) {
        const float d = Distance(views_.col(Eigen::Index(a)), Eigen::Index(b));
        auto& na = view_model_[a] == view_model_[b] ? nearest_same : nearest;
        na[a] = std::min(na[a], d);
        na[b] = std::min(na[b], d);
      }
    std::vector<float> ds;
    for (size_t v = 0; v < desc.size(); ++v)
      if (std::isfinite(nearest[v])) ds.push_back(nearest[v]);
    if (ds.empty())
      for (size_t v = 0; v < desc.size(); ++v)
        if (std::isfinite(nearest_same[v])) ds.push_back(nearest_same[v]);
    float scale = 1.f;
    if (!ds.empty()) {
      std::nth_element(ds.begin(), ds.begin() + ds.size() / 2, ds.end());
      scale = std::max(ds[ds.size() / 2], 1e-6f);
    }
    tau_ = static_cast<float>(o_.kernel_scale * scale);
    spdlog::info("esf_catalog: {} views of {} models, {} classes; typical {} distance {:.4f}, tau {:.4f}", desc.size(),
                 models_.size(), classes_.size(), o_.chi2 ? "chi2" : "L1", scale, tau_);
  }

  VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext& ctx) override {
    VoteResult out;
    out.classes = classes_;
    if (models_.empty()) throw StageError("voters.esf_catalog: no model loaded", false);
    EsfDescriptor esf;
    const size_t C = classes_.size(), V = view_model_.size();
    const size_t k = std::min(size_t(o_.k), V);
    for (size_t s = 0; s < scenes.size(); ++s) {
      const SceneParts& sc = scenes[s];
      if (!sc.proposals || !sc.scan) {
        if (s == 0 && !sc.proposals)
          throw InputError("voters.esf_catalog recognises proposals: give it a proposer as input (e.g. proposals.clusters)");
        continue;
      }
      const Scan& scan = *sc.scan;
      const auto& items = sc.proposals->items;
      const size_t n = items.size();
      std::vector<std::vector<float>> score(C, std::vector<float>(n, 0.f));
      std::vector<std::vector<int>> best_model(C, std::vector<int>(n, -1));
      std::vector<std::vector<std::map<std::string, float>>> evidence(C, std::vector<std::map<std::string, float>>(n));
      std::vector<shape::Footprint> foot(n);
      std::vector<float> dist(V);
      std::vector<size_t> rank(V);
      for (size_t i = 0; i < n; ++i) {
        const Proposal& p = items[i];
        Points raw(p.indices.size());
        std::vector<Eigen::Vector2f> xy(p.indices.size());
        for (size_t j = 0; j < p.indices.size(); ++j) {
          raw[j] = scan.points[size_t(p.indices[j])];
          xy[j] = raw[j].head<2>();
        }
        const Points pts = VoxelDownsample(raw, model_voxel_);
        if (pts.size() < size_t(o_.min_points)) continue;
        const std::vector<float> q = esf(pts, Mix(Mix(ctx.seed, s), i));
        if (q.empty()) continue;
        const Eigen::Map<const Eigen::VectorXf> qv(q.data(), kBins);
        for (size_t v = 0; v < V; ++v) dist[v] = Distance(qv, Eigen::Index(v));
        std::iota(rank.begin(), rank.end(), size_t(0));
        std::partial_sort(rank.begin(), rank.begin() + std::ptrdiff_t(k), rank.end(), [&](size_t a, size_t b) {
          return dist[a] < dist[b] || (dist[a] == dist[b] && a < b);
        });
        std::vector<float> vote(C, 0.f), nearest(C, INFINITY);
        std::vector<int> votes(C, 0), nearest_view(C, -1);
        for (size_t r = 0; r < k; ++r) {
          const size_t v = rank[r];
          vote[size_t(view_class_[v])] += std::exp(-dist[v] / tau_) / float(k);
          ++votes[size_t(view_class_[v])];
        }
        for (size_t v = 0; v < V; ++v) {
          const size_t c = size_t(view_class_[v]);
          if (dist[v] < nearest[c]) nearest[c] = dist[v], nearest_view[c] = int(v);
        }
        const float vote_sum = std::accumulate(vote.begin(), vote.end(), 0.f);
        // Metric size: the proposal's footprint and top against each model of the class.
        foot[i] = shape::OrientedFootprint(xy);
        const float L = std::max(foot[i].length, 0.02f), W = std::max(foot[i].width, 0.02f);
        const float T = std::max(p.box.max().z() - p.ground_z, 0.02f);
        for (size_t c = 0; c < C; ++c) {
          if (votes[c] == 0) continue;  // no neighbour of this class: no candidate
          float e_size = INFINITY;
          int size_model = -1;
          for (size_t m = 0; m < models_.size(); ++m) {
            const Model& md = models_[m];
            if (md.cls != classes_[c]) continue;
            const float dl = std::log(L / md.length), dw = std::log(W / md.width), dt = std::log(T / md.height);
            const float e = (dl * dl + dw * dw + dt * dt) / static_cast<float>(2 * o_.sig_size * o_.sig_size);
            if (e < e_size) e_size = e, size_model = int(m);
          }
          const float size_factor = std::exp(-e_size);
          score[c][i] = vote[c] * (o_.size_weight > 0.0 ? std::pow(size_factor, static_cast<float>(o_.size_weight)) : 1.f);
          // The model shown: the size's best when the size counts, else the nearest view's.
          best_model[c][i] = o_.size_weight > 0.0 ? size_model : view_model_[size_t(nearest_view[c])];
          evidence[c][i] = {{"length_m", L},
                            {"width_m", W},
                            {"top_m", T},
                            {"points", float(pts.size())},
                            {"esf_vote", vote[c]},
                            {"esf_share", vote_sum > 0.f ? vote[c] / vote_sum : 0.f},
                            {"esf_neighbours", float(votes[c])},
                            {"esf_nearest", nearest[c]},
                            {"esf_nearest_any", dist[rank[0]]},
                            {"esf_tau", tau_},
                            {"e_size", e_size},
                            {"size_factor", size_factor}};
          if (spdlog::should_log(spdlog::level::trace) && score[c][i] >= o_.decision.min_score)
            spdlog::trace("esf_catalog: {} {} L {:.3f} W {:.3f} T {:.3f} vote {:.4f} ({} of {}) nearest {:.4f} size {:.4f} -> {:.4f}",
                          p.how, classes_[c], L, W, T, vote[c], votes[c], k, nearest[c], size_factor, score[c][i]);
        }
      }
      // Non-maximum suppression per class by box IoU, then the hypotheses.
      for (size_t c = 0; c < C; ++c) {
        std::vector<size_t> order;
        for (size_t i = 0; i < n; ++i)
          if (score[c][i] >= o_.decision.min_score && best_model[c][i] >= 0) order.push_back(i);
        const auto thr = o_.decision.thresholds.find(classes_[c]);
        const DecisionOptions& d = o_.decision;
        const float t = thr == d.thresholds.end() ? static_cast<float>(d.default_threshold) : thr->second;
        for (size_t i : shape::SuppressOverlaps(std::move(order), score[c], items, static_cast<float>(d.nms_iou),
                                                  static_cast<float>(d.nms_whole_ratio))) {
          const Model& md = models_[size_t(best_model[c][i])];
          out.hypotheses.push_back(shape::ProposalHypothesis(classes_[c], score[c][i], t, items[i], int(i), int(s),
                                                             foot[i], md.id, md.wide, scan.pose));
          out.hypotheses.back().evidence = std::move(evidence[c][i]);
        }
      }
    }
    return out;
  }

 private:
  // Distance of a descriptor to training view v.
  template <class Q>
  float Distance(const Q& q, Eigen::Index v) const {
    const auto e = views_.col(v);
    if (!o_.chi2) return (q - e).cwiseAbs().sum();
    float d = 0.f;
    for (Eigen::Index b = 0; b < kBins; ++b) {
      const float s = q[b] + e[b];
      if (s > 0.f) d += (q[b] - e[b]) * (q[b] - e[b]) / s;
    }
    return d;
  }

  Options o_;
  std::vector<Model> models_;
  std::vector<std::string> classes_;
  Eigen::MatrixXf views_;         // kBins x views: the training descriptors
  std::vector<int> view_model_;   // per view: index into models_
  std::vector<int> view_class_;   // per view: index into classes_
  float model_voxel_ = 0.02f;     // the voxel the training views were described at
  float tau_ = 1.f;
};

}  // namespace
}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::EsfCatalogVoter, "voters.esf_catalog", "1.1.0",
                 "recognises object proposals by k nearest ESF descriptors of the catalog's simulated views, times "
                 "their metric-size agreement with the class's catalog models")
