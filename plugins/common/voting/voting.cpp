#include "voting/voting.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <nanoflann.hpp>
#include <numeric>
#include <random>
#include <set>

#include "furnihost/error.hpp"
#include "furnihost/geometry.hpp"

namespace furnihost::voting {

namespace {

// Own uniform draw: std::uniform_real_distribution differs between standard libraries, and
// the model file must not depend on which one built the plugin.
double Uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * (1.0 / 9007199254740992.0);
}

size_t UniformIndex(std::mt19937_64& rng, size_t n) {
  return std::min(n - 1, static_cast<size_t>(Uniform01(rng) * static_cast<double>(n)));
}

float SquaredDistance(const float* a, const float* b, int dim) {
  float s = 0.f;
  for (int i = 0; i < dim; ++i) {
    const float t = a[i] - b[i];
    s += t * t;
  }
  return s;
}

float Median(std::vector<float> v) {
  if (v.empty()) return 0.f;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5f * (v[n / 2 - 1] + v[n / 2]);
}

template <class T>
nlohmann::json FlatArray(const std::vector<T>& v) {
  return nlohmann::json(v);
}

}  // namespace

// ---- training data ----------------------------------------------------------------------

TrainingParts CollectTrainingParts(const std::vector<TrainingView>& views) {
  if (views.empty()) throw StageError("no training views to learn from");
  TrainingParts out;
  std::set<std::string> class_names, model_names;
  for (const auto& v : views) {
    if (v.cls.empty()) throw StageError("training view of model '" + v.model_id + "' has no class");
    class_names.insert(v.cls);
    model_names.insert(v.model_id);
  }
  std::map<std::string, int> cls_index, model_index;
  for (const auto& c : class_names) {
    cls_index[c] = static_cast<int>(out.classes.size());
    out.classes.push_back({c, 0.f, 0, 0, 0.f});
  }
  for (const auto& m : model_names) {
    model_index[m] = static_cast<int>(out.models.size());
    out.models.push_back(m);
  }

  // Model width: catalog extents when given, else the widest view's point extents.
  std::vector<float> model_width(out.models.size(), 0.f), model_height(out.models.size(), 0.f);
  std::vector<int> model_class(out.models.size(), -1);
  int dim = -1;
  std::vector<float> rows;
  size_t skipped = 0, no_origin = 0;
  for (const auto& v : views) {
    const int m = model_index[v.model_id];
    const int c = cls_index[v.cls];
    if (model_class[m] >= 0 && model_class[m] != c)
      throw StageError("model '" + v.model_id + "' appears with two classes: " +
                       out.classes[model_class[m]].name + " and " + v.cls);
    model_class[m] = c;
    float w = std::max(v.object_size.x(), v.object_size.y());
    float h = v.object_size.z();
    if ((!(w > 0.f) || !(h > 0.f)) && !v.scan.points.empty()) {
      Eigen::AlignedBox3f box;
      for (const auto& p : v.scan.points) box.extend(p);
      if (!(w > 0.f)) w = std::max(box.sizes().x(), box.sizes().y());
      if (!(h > 0.f)) h = box.max().z();  // catalog models stand on z = 0
    }
    if (std::isfinite(w)) model_width[m] = std::max(model_width[m], w);
    if (std::isfinite(h)) model_height[m] = std::max(model_height[m], h);

    // Viewing frame: x = horizontal direction from the sensor to the object. A simulator that
    // circles a fixed model returns every view in the model frame, where d would be the same
    // vector in all 16 views; turning it into the viewing frame gives each word the rotated
    // copies the paper got by turning the object in front of a fixed sensor (Sect. VII).
    Eigen::Matrix3f to_view = Eigen::Matrix3f::Identity();
    if (v.scan.origin && v.scan.origin->allFinite()) {
      const Eigen::Vector3f look = v.object_centroid - *v.scan.origin;
      if (look.head<2>().norm() > 1e-3f)
        to_view = Eigen::AngleAxisf(-std::atan2(look.y(), look.x()), Eigen::Vector3f::UnitZ()).toRotationMatrix();
    } else {
      ++no_origin;
    }
    const auto& F = v.features.values;
    if (static_cast<size_t>(F.rows()) != v.segmentation.parts.size())
      throw StageError("training view " + std::to_string(v.view) + " of model '" + v.model_id +
                       "' has " + std::to_string(F.rows()) + " feature rows for " +
                       std::to_string(v.segmentation.parts.size()) + " parts");
    if (F.rows() == 0) continue;
    if (dim < 0) {
      dim = static_cast<int>(F.cols());
      out.feature_names = v.features.names;
    } else if (F.cols() != dim) {
      throw StageError("training view " + std::to_string(v.view) + " of model '" + v.model_id +
                       "' has " + std::to_string(F.cols()) + " feature columns, earlier views " +
                       std::to_string(dim));
    }
    for (Eigen::Index i = 0; i < F.rows(); ++i) {
      if (!F.row(i).allFinite() || !v.segmentation.parts[i].centroid.allFinite()) {
        ++skipped;
        continue;
      }
      for (Eigen::Index j = 0; j < F.cols(); ++j) rows.push_back(F(i, j));
      out.d.push_back(to_view * (v.object_centroid - v.segmentation.parts[i].centroid));
      out.height.push_back(v.scan.HeightAboveGround(v.scan.pose * v.segmentation.parts[i].centroid));
      out.cls.push_back(c);
      out.model.push_back(m);
      out.view.push_back(v.view);
      ++out.classes[c].parts;
    }
  }
  if (out.d.empty()) throw StageError("the training views contain no parts with finite features");
  if (skipped) spdlog::warn("voter training: skipped {} parts with non-finite features", skipped);
  if (no_origin)
    spdlog::warn("voter training: {} of {} views have no sensor origin; their shape vectors stay "
                 "in the scan frame", no_origin, views.size());
  out.features = Eigen::Map<RowMatrixXf>(rows.data(), static_cast<Eigen::Index>(out.d.size()), dim);

  for (size_t c = 0; c < out.classes.size(); ++c) {
    std::vector<float> widths;
    for (size_t m = 0; m < out.models.size(); ++m)
      if (model_class[m] == static_cast<int>(c) && model_width[m] > 0.f) widths.push_back(model_width[m]);
    out.classes[c].models = static_cast<int>(
        std::count(model_class.begin(), model_class.end(), static_cast<int>(c)));
    out.classes[c].width = Median(widths);
    for (size_t m = 0; m < out.models.size(); ++m)
      if (model_class[m] == static_cast<int>(c)) out.classes[c].height = std::max(out.classes[c].height, model_height[m]);
    if (!(out.classes[c].width > 0.f))
      throw StageError("class '" + out.classes[c].name +
                       "': no model has a known size (TrainingView::object_size is zero and the "
                       "views have no points)");
  }
  return out;
}

// ---- k-means ----------------------------------------------------------------------------

namespace {

// One k-means run. `centers` K x D on return; labels sized N.
double LloydRun(const RowMatrixXf& X, int k, int max_iterations, std::mt19937_64& rng,
                RowMatrixXf& centers, std::vector<int>& labels, int& iterations) {
  const Eigen::Index n = X.rows();
  const int dim = static_cast<int>(X.cols());
  centers.resize(k, dim);
  std::vector<float> d2(n);

  // k-means++ seeding.
  size_t first = UniformIndex(rng, static_cast<size_t>(n));
  centers.row(0) = X.row(first);
  for (Eigen::Index i = 0; i < n; ++i) d2[i] = SquaredDistance(X.row(i).data(), centers.row(0).data(), dim);
  for (int c = 1; c < k; ++c) {
    double total = 0.0;
    for (float v : d2) total += v;
    size_t pick;
    if (total <= 0.0) {
      pick = UniformIndex(rng, static_cast<size_t>(n));
    } else {
      const double r = Uniform01(rng) * total;
      double acc = 0.0;
      pick = static_cast<size_t>(n - 1);
      for (Eigen::Index i = 0; i < n; ++i) {
        acc += d2[i];
        if (acc > r) {
          pick = static_cast<size_t>(i);
          break;
        }
      }
    }
    centers.row(c) = X.row(pick);
    for (Eigen::Index i = 0; i < n; ++i)
      d2[i] = std::min(d2[i], SquaredDistance(X.row(i).data(), centers.row(c).data(), dim));
  }

  labels.assign(n, -1);
  auto assign = [&]() {
    size_t changed = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      int best = 0;
      float bd = std::numeric_limits<float>::max();
      for (int c = 0; c < k; ++c) {
        const float dd = SquaredDistance(X.row(i).data(), centers.row(c).data(), dim);
        if (dd < bd) {
          bd = dd;
          best = c;
        }
      }
      d2[i] = bd;
      if (labels[i] != best) {
        labels[i] = best;
        ++changed;
      }
    }
    return changed;
  };

  iterations = 0;
  Eigen::MatrixXd sums(k, dim);
  std::vector<int> counts(k);
  for (int it = 0; it < max_iterations; ++it) {
    const size_t changed = assign();
    ++iterations;
    if (it > 0 && changed == 0) break;
    sums.setZero();
    std::fill(counts.begin(), counts.end(), 0);
    for (Eigen::Index i = 0; i < n; ++i) {
      sums.row(labels[i]) += X.row(i).cast<double>();
      ++counts[labels[i]];
    }
    for (int c = 0; c < k; ++c) {
      if (counts[c] > 0) {
        centers.row(c) = (sums.row(c) / counts[c]).cast<float>();
        continue;
      }
      // Empty cluster: restart it at the point worst served by its centre.
      const auto far = std::max_element(d2.begin(), d2.end()) - d2.begin();
      centers.row(c) = X.row(far);
      d2[far] = 0.f;
    }
  }
  assign();
  double inertia = 0.0;
  for (float v : d2) inertia += v;
  return inertia;
}

}  // namespace

KMeansResult KMeans(const RowMatrixXf& data, const KMeansOptions& opt, uint64_t seed) {
  if (data.rows() == 0) throw StageError("k-means: no data");
  if (opt.k < 1 || opt.max_iterations < 1 || opt.restarts < 1)
    throw StageError("k-means: k, max_iterations and restarts must be positive");
  int k = opt.k;
  if (k > data.rows()) {
    spdlog::warn("k-means: k = {} exceeds the {} training parts; using k = {}", k, data.rows(),
                 data.rows());
    k = static_cast<int>(data.rows());
  }
  std::mt19937_64 rng(seed);
  KMeansResult best;
  best.inertia = std::numeric_limits<double>::infinity();
  for (int r = 0; r < opt.restarts; ++r) {
    RowMatrixXf centers;
    std::vector<int> labels;
    int iterations = 0;
    const double inertia = LloydRun(data, k, opt.max_iterations, rng, centers, labels, iterations);
    if (inertia < best.inertia) {
      best.inertia = inertia;
      best.centers = std::move(centers);
      best.labels = std::move(labels);
      best.iterations = iterations;
    }
  }
  // Drop clusters left empty (duplicate seeds on duplicate points) so no word is vacuous.
  std::vector<int> count(best.centers.rows(), 0), remap(best.centers.rows(), -1);
  for (int l : best.labels) ++count[l];
  int kept = 0;
  for (size_t c = 0; c < count.size(); ++c)
    if (count[c] > 0) remap[c] = kept++;
  if (kept < best.centers.rows()) {
    RowMatrixXf centers(kept, best.centers.cols());
    for (size_t c = 0; c < count.size(); ++c)
      if (remap[c] >= 0) centers.row(remap[c]) = best.centers.row(c);
    best.centers = std::move(centers);
    for (int& l : best.labels) l = remap[l];
  }
  return best;
}

// ---- codebook ---------------------------------------------------------------------------

Codebook BuildCodebook(const TrainingParts& parts, const RowMatrixXf& words,
                       const std::vector<int>& labels) {
  Codebook b;
  b.feature_names = parts.feature_names;
  b.words = words;
  b.classes = parts.classes;
  b.models = parts.models;
  const int K = static_cast<int>(words.rows());
  b.element_begin.assign(K + 1, 0);
  for (int l : labels) ++b.element_begin[l + 1];
  std::partial_sum(b.element_begin.begin(), b.element_begin.end(), b.element_begin.begin());
  const size_t n = labels.size();
  b.d.resize(n);
  b.element_class.resize(n);
  b.element_model.resize(n);
  b.element_view.resize(n);
  b.element_height.resize(n);
  std::vector<int> next(b.element_begin.begin(), b.element_begin.end() - 1);
  for (size_t i = 0; i < n; ++i) {
    const int e = next[labels[i]]++;
    b.d[e] = parts.d[i];
    b.element_class[e] = parts.cls[i];
    b.element_model[e] = parts.model[i];
    b.element_view[e] = parts.view[i];
    b.element_height[e] = parts.height[i];
  }
  b.ComputeNorms();
  return b;
}

void Codebook::ComputeNorms() {
  element_norm.assign(d.size(), 0.f);
  std::vector<int> count(classes.size());
  for (int k = 0; k < Words(); ++k) {
    std::fill(count.begin(), count.end(), 0);
    for (int e = element_begin[k]; e < element_begin[k + 1]; ++e) ++count[element_class[e]];
    for (int e = element_begin[k]; e < element_begin[k + 1]; ++e)
      element_norm[e] = 1.f / static_cast<float>(count[element_class[e]]);
  }
}

nlohmann::json Codebook::ToJson(const std::string& format) const {
  nlohmann::json j;
  j["format"] = format;
  j["feature_names"] = feature_names;
  j["dim"] = Dim();
  j["words"] = FlatArray(std::vector<float>(words.data(), words.data() + words.size()));
  nlohmann::json cls = nlohmann::json::array();
  for (const auto& c : classes)
    cls.push_back({{"name", c.name}, {"width", c.width}, {"models", c.models}, {"parts", c.parts},
                   {"height", c.height}});
  j["classes"] = cls;
  j["models"] = models;
  j["element_begin"] = element_begin;
  std::vector<float> flat;
  flat.reserve(d.size() * 3);
  for (const auto& v : d) flat.insert(flat.end(), {v.x(), v.y(), v.z()});
  j["d"] = FlatArray(flat);
  j["class"] = element_class;
  j["model"] = element_model;
  j["view"] = element_view;
  j["height"] = FlatArray(element_height);
  return j;
}

Codebook Codebook::FromJson(const nlohmann::json& j, const std::string& format) {
  auto bad = [](const std::string& what) { return StageError("voter model: " + what); };
  if (!j.is_object() || !j.contains("format"))
    throw bad("not a " + format + " model (no \"format\" field)");
  const std::string got = j.at("format").is_string() ? j.at("format").get<std::string>() : "?";
  if (got != format) throw bad("format is '" + got + "', this voter reads '" + format + "'");
  Codebook b;
  try {
    b.feature_names = j.at("feature_names").get<std::vector<std::string>>();
    const int dim = j.at("dim").get<int>();
    const auto w = j.at("words").get<std::vector<float>>();
    if (dim <= 0 || w.empty() || w.size() % dim) throw bad("words do not match dim");
    b.words = Eigen::Map<const RowMatrixXf>(w.data(), static_cast<Eigen::Index>(w.size() / dim), dim);
    for (const auto& c : j.at("classes"))
      b.classes.push_back({c.at("name").get<std::string>(), c.at("width").get<float>(),
                           c.at("models").get<int>(), c.at("parts").get<int>(), c.at("height").get<float>()});
    b.models = j.at("models").get<std::vector<std::string>>();
    b.element_begin = j.at("element_begin").get<std::vector<int>>();
    const auto flat = j.at("d").get<std::vector<float>>();
    b.element_class = j.at("class").get<std::vector<int>>();
    b.element_model = j.at("model").get<std::vector<int>>();
    b.element_view = j.at("view").get<std::vector<int>>();
    b.element_height = j.at("height").get<std::vector<float>>();
    const size_t n = b.element_class.size();
    if (flat.size() != 3 * n || b.element_model.size() != n || b.element_view.size() != n ||
        b.element_height.size() != n)
      throw bad("element arrays differ in length");
    if (b.element_begin.size() != static_cast<size_t>(b.Words()) + 1 || b.element_begin.front() != 0 ||
        b.element_begin.back() != static_cast<int>(n) ||
        !std::is_sorted(b.element_begin.begin(), b.element_begin.end()))
      throw bad("element_begin does not index the elements");
    for (size_t i = 0; i < n; ++i) {
      if (b.element_class[i] < 0 || b.element_class[i] >= static_cast<int>(b.classes.size()) ||
          b.element_model[i] < 0 || b.element_model[i] >= static_cast<int>(b.models.size()))
        throw bad("element " + std::to_string(i) + " has an invalid class or model index");
      b.d.emplace_back(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
      if (!std::isfinite(b.element_height[i])) throw bad("element " + std::to_string(i) + " has a non-finite height");
    }
  } catch (const nlohmann::json::exception& e) {
    throw bad(std::string("malformed: ") + e.what());
  }
  b.ComputeNorms();
  return b;
}

// ---- options ----------------------------------------------------------------------------

float SelectionOptions::ThresholdFor(const std::string& cls) const {
  const auto it = thresholds.find(cls);
  return it == thresholds.end() ? default_threshold : it->second;
}

// ---- kd-tree over words -----------------------------------------------------------------

struct WordIndex::Impl {
  using Tree = nanoflann::KDTreeEigenMatrixAdaptor<RowMatrixXf, -1, nanoflann::metric_L2, true>;
  RowMatrixXf words;  // the tree refers to this copy
  std::unique_ptr<Tree> tree;
};

WordIndex::WordIndex(const RowMatrixXf& words, int leaf_size) : impl_(std::make_unique<Impl>()) {
  if (words.rows() == 0) throw StageError("voter model has no words");
  impl_->words = words;
  impl_->tree = std::make_unique<Impl::Tree>(static_cast<size_t>(words.cols()),
                                             std::cref(impl_->words), leaf_size);  // builds the tree
}

WordIndex::~WordIndex() = default;

int WordIndex::Nearest(const float* query, int k, long* indices, float* dist_sq, float max_dist_sq) const {
  const size_t want = std::min<size_t>(static_cast<size_t>(k), impl_->words.rows());
  if (want == 0) return 0;
  nanoflann::KNNResultSet<float, long> result(want);
  result.init(indices, dist_sq);
  // init() sets the worst distance to +max; a bound in its place prunes every branch farther
  // than it (the tree only offers points closer than worstDist()).
  if (max_dist_sq > 0.f) dist_sq[want - 1] = max_dist_sq;
  impl_->tree->index->findNeighbors(result, query, nanoflann::SearchParams());
  return static_cast<int>(result.size());
}

// ---- voting and selection ---------------------------------------------------------------

namespace {

struct PartRef {
  int scene, part;
  Eigen::Vector3f world;  // part centroid in the world frame
};

// All votes, grouped by class: class c owns [class_begin[c], class_begin[c + 1]).
struct VoteSet {
  std::vector<float> x, y, z, w;
  std::vector<int> part;  // index into the PartRef list
  std::vector<size_t> class_begin;
};

// Separable Gaussian (normalised kernel, truncated at 3 sigma) on a W x H row-major grid.
void GaussianSmooth(std::vector<float>& g, int W, int H, float sigma_cells) {
  if (!(sigma_cells > 0.f)) return;
  const int r = std::max(1, static_cast<int>(std::ceil(3.f * sigma_cells)));
  std::vector<float> k(2 * r + 1);
  float sum = 0.f;
  for (int i = -r; i <= r; ++i) sum += k[i + r] = std::exp(-0.5f * i * i / (sigma_cells * sigma_cells));
  for (float& v : k) v /= sum;
  std::vector<float> tmp(g.size(), 0.f);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float v = g[static_cast<size_t>(y) * W + x];
      if (v == 0.f) continue;
      for (int i = std::max(-r, -x); i <= std::min(r, W - 1 - x); ++i)
        tmp[static_cast<size_t>(y) * W + x + i] += v * k[i + r];
    }
  std::fill(g.begin(), g.end(), 0.f);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float v = tmp[static_cast<size_t>(y) * W + x];
      if (v == 0.f) continue;
      for (int i = std::max(-r, -y); i <= std::min(r, H - 1 - y); ++i)
        g[static_cast<size_t>(y + i) * W + x] += v * k[i + r];
    }
}

// Running maximum over windows of 2r+1 samples of one line (van Herk / Gil-Werman: three
// comparisons per sample whatever r). Values are >= 0, so padding with 0 changes nothing.
void LineMax(const float* in, size_t stride, int n, int r, float* out, size_t out_stride,
             std::vector<float>& pre, std::vector<float>& suf) {
  const int w = 2 * r + 1;
  const int padded = ((n + 2 * r + w - 1) / w) * w;
  pre.assign(padded, 0.f);
  suf.assign(padded, 0.f);
  auto at = [&](int i) { return (i >= r && i < n + r) ? in[static_cast<size_t>(i - r) * stride] : 0.f; };
  for (int b = 0; b < padded; b += w) {
    pre[b] = at(b);
    for (int i = b + 1; i < b + w; ++i) pre[i] = std::max(pre[i - 1], at(i));
    suf[b + w - 1] = at(b + w - 1);
    for (int i = b + w - 2; i >= b; --i) suf[i] = std::max(suf[i + 1], at(i));
  }
  // Output x covers padded samples [x, x + 2r].
  for (int x = 0; x < n; ++x) out[static_cast<size_t>(x) * out_stride] = std::max(suf[x], pre[x + 2 * r]);
}

// Sliding maximum over a (2r+1) x (2r+1) square.
std::vector<float> MaxFilter(const std::vector<float>& g, int W, int H, int r) {
  std::vector<float> tmp(g.size()), out(g.size()), pre, suf;
  for (int y = 0; y < H; ++y)
    LineMax(&g[static_cast<size_t>(y) * W], 1, W, r, &tmp[static_cast<size_t>(y) * W], 1, pre, suf);
  for (int x = 0; x < W; ++x) LineMax(&tmp[x], W, H, r, &out[x], W, pre, suf);
  return out;
}

// Items bucketed by the cell of a W x H grid on the floor plane (counting sort, items of a
// cell in index order): a disc query visits the items of the cells its bounding square touches.
class FloorBuckets {
 public:
  FloorBuckets(Eigen::Vector2f origin, float cell, int W, int H) : origin_(origin), cell_(cell), W_(W), H_(H) {}

  int CellIndex(float x, float y) const {
    const int ix = std::clamp(static_cast<int>(std::floor((x - origin_.x()) / cell_)), 0, W_ - 1);
    const int iy = std::clamp(static_cast<int>(std::floor((y - origin_.y()) / cell_)), 0, H_ - 1);
    return iy * W_ + ix;
  }

  // Sorts items [0, n) by cell_of(i) (a CellIndex); item i is reported as i + offset.
  template <class CellOf>
  void Build(size_t n, size_t offset, CellOf&& cell_of) {
    start_.assign(static_cast<size_t>(W_) * H_ + 1, 0);
    std::vector<int> cell(n);
    for (size_t i = 0; i < n; ++i) ++start_[(cell[i] = cell_of(i)) + 1];
    std::partial_sum(start_.begin(), start_.end(), start_.begin());
    order_.resize(n);
    std::vector<int> next(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < n; ++i) order_[next[cell[i]]++] = static_cast<int>(i + offset);
  }

  // Calls f(i) for every item in the cells of the square of half side `radius` around (x, y);
  // the caller tests the distance.
  template <class F>
  void ForSquare(double x, double y, double radius, F&& f) const {
    const int x0 = std::max(0, static_cast<int>(std::floor((x - radius - origin_.x()) / cell_)));
    const int x1 = std::min(W_ - 1, static_cast<int>(std::floor((x + radius - origin_.x()) / cell_)));
    const int y0 = std::max(0, static_cast<int>(std::floor((y - radius - origin_.y()) / cell_)));
    const int y1 = std::min(H_ - 1, static_cast<int>(std::floor((y + radius - origin_.y()) / cell_)));
    for (int cy = y0; cy <= y1; ++cy)
      for (int cx = x0; cx <= x1; ++cx) {
        const int c = cy * W_ + cx;
        for (int k = start_[c]; k < start_[c + 1]; ++k) f(order_[k]);
      }
  }

 private:
  Eigen::Vector2f origin_;
  float cell_;
  int W_, H_;
  std::vector<int> start_, order_;
};

// The votes of one class bucketed by grid cell (for disc queries) and summed per cell.
class VoteBuckets {
 public:
  VoteBuckets(const VoteSet& votes, size_t begin, size_t end, Eigen::Vector2f origin, float cell,
              int W, int H)
      : v_(votes), b_(origin, cell, W, H) {
    raw.assign(static_cast<size_t>(W) * H, 0.f);
    b_.Build(end - begin, begin, [&](size_t k) {
      const size_t i = begin + k;
      const int c = b_.CellIndex(votes.x[i], votes.y[i]);
      raw[c] += votes.w[i];
      return c;
    });
  }

  // Calls f(i) for every vote i within `radius` of c (x, y).
  template <class F>
  void ForDisc(const Eigen::Vector2d& c, double radius, F&& f) const {
    const double r2 = radius * radius;
    b_.ForSquare(c.x(), c.y(), radius, [&](int i) {
      const double dx = v_.x[i] - c.x(), dy = v_.y[i] - c.y();
      if (dx * dx + dy * dy <= r2) f(i);
    });
  }

  std::vector<float> raw;  // summed vote weight per cell, row-major W x H

 private:
  const VoteSet& v_;
  FloorBuckets b_;
};

bool FootprintsOverlap(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float size,
                       bool circle) {
  const float dx = a.x() - b.x(), dy = a.y() - b.y();
  if (circle) return dx * dx + dy * dy < size * size;
  return std::abs(dx) < size && std::abs(dy) < size;
}

struct Activation {
  int part;  // index into the PartRef list
  int word;
  float weight;  // p(A_i | f), times 1 / (1 + distance) with inverse_distance
};

// Scan points (world frame) bucketed on the floor plane for the column check; heights are
// taken above the floor.
class ColumnIndex {
 public:
  ColumnIndex(const std::vector<SceneParts>& scenes, float cell) {
    for (const auto& sc : scenes) {
      if (!sc.scan) continue;
      for (const auto& p : sc.scan->points) {
        const Eigen::Vector3f w = sc.scan->pose * p;
        if (!w.allFinite()) continue;
        pts_.emplace_back(w.x(), w.y(), sc.scan->ground ? sc.scan->ground->Above(p) : w.z());
      }
    }
    if (pts_.empty()) return;
    Eigen::Vector2f lo(std::numeric_limits<float>::max(), std::numeric_limits<float>::max());
    Eigen::Vector2f hi = -lo;
    for (const auto& p : pts_) {
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
    // Cap the grid at ~4M cells: far outliers make the cells coarser, not the memory larger.
    cell = std::max(cell, std::max(hi.x() - lo.x(), hi.y() - lo.y()) / 2000.f);
    b_ = std::make_unique<FloorBuckets>(lo, cell, static_cast<int>((hi.x() - lo.x()) / cell) + 1,
                                        static_cast<int>((hi.y() - lo.y()) / cell) + 1);
    b_->Build(pts_.size(), 0, [&](size_t i) { return b_->CellIndex(pts_[i].x(), pts_[i].y()); });
  }

  // Points within `radius` of (x, y): counts of heights in (0.05, top] and above top.
  void Count(float x, float y, float radius, float top, int& object, int& above) const {
    object = above = 0;
    if (!b_) return;
    const float r2 = radius * radius;
    b_->ForSquare(x, y, radius, [&](int i) {
      const Eigen::Vector3f& p = pts_[i];
      const float dx = p.x() - x, dy = p.y() - y;
      if (dx * dx + dy * dy > r2) return;
      if (p.z() > top) ++above;
      else if (p.z() > 0.05f) ++object;
    });
  }

 private:
  std::vector<Eigen::Vector3f> pts_;
  std::unique_ptr<FloorBuckets> b_;
};

// Maxima search, scoring, thresholding and the footprint check for the votes [vb, ve) of
// one class; fills grid.values (grid geometry set by the caller); `keep` (if set) vets each
// hypothesis before the footprint check.
std::vector<Hypothesis> SelectClass(const VoteSet& votes, size_t vb, size_t ve,
                                    const std::vector<PartRef>& parts, const ClassModel& cm,
                                    const SelectionOptions& opt, VoteGrid& grid,
                                    const std::function<bool(const Hypothesis&)>& keep) {
  const int W = grid.width, H = grid.height;
  const Eigen::Vector2f origin = grid.origin;
  const float cell = grid.cell;
  const VoteBuckets buckets(votes, vb, ve, origin, cell, W, H);
  // Summed-area table of the raw weights: an upper bound of any window's score, so
  // candidates that cannot pass the threshold skip the exact disc sum.
  std::vector<double> sat(static_cast<size_t>(W + 1) * (H + 1), 0.0);
  for (int y = 0; y < H; ++y) {
    double row = 0.0;
    for (int x = 0; x < W; ++x) {
      row += buckets.raw[static_cast<size_t>(y) * W + x];
      sat[static_cast<size_t>(y + 1) * (W + 1) + x + 1] = row + sat[static_cast<size_t>(y) * (W + 1) + x + 1];
    }
  }
  auto box_sum = [&](int x0, int y0, int x1, int y1) {  // inclusive cell ranges, clamped
    x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, W - 1), y1 = std::min(y1, H - 1);
    if (x0 > x1 || y0 > y1) return 0.0;
    auto at = [&](int x, int y) { return sat[static_cast<size_t>(y) * (W + 1) + x]; };
    return at(x1 + 1, y1 + 1) - at(x0, y1 + 1) - at(x1 + 1, y0) + at(x0, y0);
  };

  grid.values = buckets.raw;
  GaussianSmooth(grid.values, W, H, opt.smoothing / cell);
  const float half = 0.5f * opt.window_scale * cm.width;  // search and score radius [m]
  const int r = std::max(1, static_cast<int>(std::floor(half / cell)));
  const std::vector<float> mx = MaxFilter(grid.values, W, H, r);
  std::vector<int> cand;
  for (int i = 0; i < W * H; ++i)
    if (grid.values[i] > 0.f && grid.values[i] >= mx[i]) cand.push_back(i);
  std::sort(cand.begin(), cand.end(), [&](int a, int b) {
    return grid.values[a] != grid.values[b] ? grid.values[a] > grid.values[b] : a < b;
  });

  const float threshold = opt.ThresholdFor(cm.name);
  std::vector<Hypothesis> hyps;
  std::vector<double> part_weight(parts.size(), 0.0);
  std::vector<int> touched;
  for (int ci : cand) {
    Eigen::Vector2d ctr(origin.x() + (ci % W + 0.5) * cell, origin.y() + (ci / W + 0.5) * cell);
    // Mean shift onto the raw votes: the grid quantises to a cell, the votes do not.
    for (int it = 0; it < 10 && opt.refine_radius > 0.f; ++it) {
      double sw = 0.0;
      Eigen::Vector2d sp = Eigen::Vector2d::Zero();
      buckets.ForDisc(ctr, opt.refine_radius, [&](int i) {
        sw += votes.w[i];
        sp += votes.w[i] * Eigen::Vector2d(votes.x[i], votes.y[i]);
      });
      if (!(sw > 0.0)) break;
      const Eigen::Vector2d next = sp / sw;
      const double shift = (next - ctr).norm();
      ctr = next;
      if (shift < 1e-5) break;
    }
    const int bx0 = static_cast<int>(std::floor((ctr.x() - half - origin.x()) / cell));
    const int by0 = static_cast<int>(std::floor((ctr.y() - half - origin.y()) / cell));
    const int bx1 = static_cast<int>(std::floor((ctr.x() + half - origin.x()) / cell));
    const int by1 = static_cast<int>(std::floor((ctr.y() + half - origin.y()) / cell));
    if (box_sum(bx0, by0, bx1, by1) < threshold) continue;
    double score = 0.0, zsum = 0.0;
    buckets.ForDisc(ctr, half, [&](int i) {
      score += votes.w[i];
      zsum += static_cast<double>(votes.w[i]) * votes.z[i];
      if (part_weight[votes.part[i]] == 0.0) touched.push_back(votes.part[i]);
      part_weight[votes.part[i]] += votes.w[i];
    });
    if (score >= threshold && score > 0.0) {
      Hypothesis h;
      h.cls = cm.name;
      h.center = Eigen::Vector3f(static_cast<float>(ctr.x()), static_cast<float>(ctr.y()),
                                 static_cast<float>(zsum / score));
      h.score = static_cast<float>(score);
      for (int gp : touched)
        h.support.push_back({parts[gp].scene, parts[gp].part, static_cast<float>(part_weight[gp])});
      std::sort(h.support.begin(), h.support.end(), [](const Support& a, const Support& b) {
        if (a.weight != b.weight) return a.weight > b.weight;
        return a.scene != b.scene ? a.scene < b.scene : a.part < b.part;
      });
      hyps.push_back(std::move(h));
    }
    for (int gp : touched) part_weight[gp] = 0.0;
    touched.clear();
  }

  std::sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) {
    if (a.score != b.score) return a.score > b.score;
    if (a.center.x() != b.center.x()) return a.center.x() < b.center.x();
    return a.center.y() < b.center.y();
  });
  // Maxima that mean shift moved into one window are one maximum (window = search window);
  // then same-class footprints must not overlap (Sect. VI-B), the stronger one wins.
  const float fsize = opt.footprint_scale * cm.width;
  std::vector<Hypothesis> kept;
  for (auto& h : hyps) {
    if (keep && !keep(h)) continue;  // before the footprint check: a dropped one suppresses nothing
    bool drop = false;
    for (const auto& k : kept)
      drop = drop || FootprintsOverlap(h.center, k.center, half, false) ||
             FootprintsOverlap(h.center, k.center, fsize, opt.footprint == "circle");
    if (!drop) kept.push_back(std::move(h));
  }
  return kept;
}

}  // namespace


VoteResult VoteAndSelect(const Codebook& book, const WordIndex& index,
                         const std::vector<SceneParts>& scenes, const SelectionOptions& opt) {
  VoteResult res;
  const int C = static_cast<int>(book.classes.size());
  const int K = book.Words();
  for (const auto& c : book.classes) res.classes.push_back(c.name);
  std::vector<char> active(C, opt.classes.empty() ? 1 : 0);
  for (const auto& name : opt.classes) {
    const auto it = std::find(res.classes.begin(), res.classes.end(), name);
    if (it == res.classes.end()) {
      std::string known;
      for (const auto& c : res.classes) known += (known.empty() ? "" : ", ") + c;
      throw StageError("classes: the model has no class '" + name + "' (it knows: " + known + ")");
    }
    active[it - res.classes.begin()] = 1;
  }
  for (const auto& name : opt.column_clear_classes)
    if (std::find(res.classes.begin(), res.classes.end(), name) == res.classes.end())
      spdlog::warn("voter: column_clear_classes names '{}', a class the model does not have (ignored)", name);

  // ---- activation (eq. 4) ----
  std::vector<PartRef> parts;
  std::vector<Activation> acts;
  std::vector<float> scene_yaw(scenes.size(), 0.f);
  const int dim = book.Dim();
  const int act = std::max(1, opt.activations);
  std::vector<long> idx(act);
  std::vector<float> d2(act), q(dim);
  std::vector<double> wv(act);
  // The word search is bounded a hair above max_distance; the exact cut stays the check below.
  const float bound = opt.max_distance > 0.f ? opt.max_distance * opt.max_distance * 1.0001f : 0.f;
  size_t skipped = 0, out_of_range = 0;
  for (size_t s = 0; s < scenes.size(); ++s) {
    const SceneParts& sc = scenes[s];
    const std::string where = "scene " + std::to_string(s) + ": ";
    if (!sc.scan || !sc.segmentation || !sc.features)
      throw StageError(where + "missing scan, segmentation or features");
    const auto& F = sc.features->values;
    const auto& segs = sc.segmentation->parts;
    if (static_cast<size_t>(F.rows()) != segs.size())
      throw StageError(where + std::to_string(F.rows()) + " feature rows for " +
                       std::to_string(segs.size()) + " parts");
    if (F.rows() > 0 && F.cols() != dim)
      throw StageError(where + "features have " + std::to_string(F.cols()) +
                       " columns, the voter model was trained with " + std::to_string(dim));
    const Eigen::Isometry3f& pose = sc.scan->pose;
    scene_yaw[s] = std::atan2(pose.linear()(1, 0), pose.linear()(0, 0));
    for (Eigen::Index i = 0; i < F.rows(); ++i) {
      if (!F.row(i).allFinite() || !segs[i].centroid.allFinite()) {
        ++skipped;
        continue;
      }
      const auto& ex = sc.features->excess;
      if (opt.max_out_of_range > 0.f && ex.size() == F.rows() && ex[i] > opt.max_out_of_range) {
        ++out_of_range;
        continue;
      }
      for (int j = 0; j < dim; ++j) q[j] = F(i, j);
      const int n = index.Nearest(q.data(), act, idx.data(), d2.data(), bound);
      double wsum = 0.0;
      int used = 0;
      for (int a = 0; a < n; ++a) {
        const double dist = std::sqrt(std::max(0.f, d2[a]));
        if (opt.max_distance > 0.f && dist > opt.max_distance) break;  // nearest first
        d2[a] = static_cast<float>(dist);
        wv[a] = 1.0 / (dist + 1e-6);
        wsum += wv[a];
        ++used;
      }
      if (used == 0) continue;
      const int gpart = static_cast<int>(parts.size());
      parts.push_back({static_cast<int>(s), static_cast<int>(i), pose * segs[i].centroid});
      for (int a = 0; a < used; ++a) {
        float pa = static_cast<float>(wv[a] / wsum);
        if (opt.inverse_distance) pa /= 1.f + d2[a];
        acts.push_back({gpart, static_cast<int>(idx[a]), pa});
      }
    }
  }
  if (skipped) spdlog::warn("voter: skipped {} scene parts with non-finite features", skipped);
  if (out_of_range)
    spdlog::debug("voter: {} scene parts lie more than {} training ranges outside the training features",
                  out_of_range, opt.max_out_of_range);
  // Height consistency: an element votes only when its training part sat at about the scene
  // part's height above the floor (objects stand on the floor).
  const bool gate = opt.height_tolerance > 0.f && !book.element_height.empty();
  const bool column = opt.column_radius > 0.f;
  std::vector<float> part_height(gate ? parts.size() : 0);  // above the scan's ground, once per part
  for (size_t i = 0; i < part_height.size(); ++i) {
    const Scan* sc = scenes[parts[i].scene].scan;
    part_height[i] = sc ? sc->HeightAboveGround(parts[i].world) : parts[i].world.z();
  }
  auto height_ok = [&](int part, int e) {
    return !gate || std::abs(part_height[part] - book.element_height[e]) <= opt.height_tolerance;
  };

  // ---- votes x_v = l + d with weight p(A_i|f) / #(A_i, o) (eq. 5), grouped by class ----
  VoteSet votes;
  votes.class_begin.assign(C + 1, 0);
  if (!gate) {
    std::vector<int> word_class(static_cast<size_t>(K) * C, 0);
    for (int k = 0; k < K; ++k)
      for (int e = book.element_begin[k]; e < book.element_begin[k + 1]; ++e)
        ++word_class[static_cast<size_t>(k) * C + book.element_class[e]];
    for (const auto& a : acts)
      for (int c = 0; c < C; ++c)
        if (active[c]) votes.class_begin[c + 1] += word_class[static_cast<size_t>(a.word) * C + c];
  } else {
    for (const auto& a : acts)
      for (int e = book.element_begin[a.word]; e < book.element_begin[a.word + 1]; ++e)
        if (active[book.element_class[e]] && height_ok(a.part, e)) ++votes.class_begin[book.element_class[e] + 1];
  }
  std::partial_sum(votes.class_begin.begin(), votes.class_begin.end(), votes.class_begin.begin());
  const size_t total = votes.class_begin.back();
  votes.x.resize(total);
  votes.y.resize(total);
  votes.z.resize(total);
  votes.w.resize(total);
  votes.part.resize(total);
  res.votes.resize(total);
  {
    std::vector<size_t> next(votes.class_begin.begin(), votes.class_begin.end() - 1);
    std::vector<Eigen::Vector3f> rd(book.d.size());
    int rd_scene = -1;
    for (const auto& a : acts) {
      const PartRef& pr = parts[a.part];
      if (pr.scene != rd_scene) {  // d turns with the scene sensor's heading
        rd_scene = pr.scene;
        const Eigen::Matrix3f rz =
            Eigen::AngleAxisf(scene_yaw[rd_scene], Eigen::Vector3f::UnitZ()).toRotationMatrix();
        for (size_t e = 0; e < book.d.size(); ++e) rd[e] = rz * book.d[e];
      }
      for (int e = book.element_begin[a.word]; e < book.element_begin[a.word + 1]; ++e) {
        const int c = book.element_class[e];
        if (!active[c] || !height_ok(a.part, e)) continue;
        const size_t i = next[c]++;
        const Eigen::Vector3f x = pr.world + rd[e];
        votes.x[i] = x.x();
        votes.y[i] = x.y();
        votes.z[i] = x.z();
        votes.w[i] = a.weight * book.element_norm[e];
        votes.part[i] = a.part;
        res.votes[i] = Eigen::Vector4f(x.x(), x.y(), static_cast<float>(c), votes.w[i]);
      }
    }
  }

  // ---- accumulation on the floor plane (eq. 6) ----
  float cell = opt.cell;
  Eigen::Vector2f lo(std::numeric_limits<float>::max(), std::numeric_limits<float>::max());
  Eigen::Vector2f hi = -lo;
  for (size_t i = 0; i < total; ++i) {
    lo = lo.cwiseMin(Eigen::Vector2f(votes.x[i], votes.y[i]));
    hi = hi.cwiseMax(Eigen::Vector2f(votes.x[i], votes.y[i]));
  }
  float max_half = 0.f;
  for (int c = 0; c < C; ++c)
    if (active[c]) max_half = std::max(max_half, 0.5f * opt.window_scale * book.classes[c].width);
  const float margin = std::max(max_half, 3.f * opt.smoothing) + opt.cell;
  int W = 0, H = 0;
  Eigen::Vector2f origin = Eigen::Vector2f::Zero();
  if (total > 0) {
    origin = lo - Eigen::Vector2f::Constant(margin);
    const Eigen::Vector2f extent = hi - lo + Eigen::Vector2f::Constant(2 * margin);
    auto dims = [&](float c) {
      W = static_cast<int>(std::ceil(extent.x() / c)) + 1;
      H = static_cast<int>(std::ceil(extent.y() / c)) + 1;
    };
    dims(cell);
    const double cells = static_cast<double>(W) * H;
    if (cells > static_cast<double>(opt.max_grid_cells)) {
      cell *= static_cast<float>(std::sqrt(cells / static_cast<double>(opt.max_grid_cells)) * 1.01);
      dims(cell);
      spdlog::warn("voter: votes span {:.1f} x {:.1f} m; grid cell enlarged to {:.3f} m", extent.x(),
                   extent.y(), cell);
    }
  }

  std::unique_ptr<ColumnIndex> columns;
  if (column) columns = std::make_unique<ColumnIndex>(scenes, opt.column_radius);
  size_t column_dropped = 0;
  for (int c = 0; c < C; ++c) {
    if (!active[c]) continue;
    const ClassModel& cm = book.classes[c];
    const bool clear = opt.column_clear_classes.empty() ||
                       std::find(opt.column_clear_classes.begin(), opt.column_clear_classes.end(), cm.name) !=
                           opt.column_clear_classes.end();
    std::function<bool(const Hypothesis&)> keep;
    if (columns)
      keep = [&, clear](const Hypothesis& h) {
        int object = 0, above = 0;
        columns->Count(h.center.x(), h.center.y(), opt.column_radius, cm.height + opt.column_margin, object, above);
        const bool ok = object >= opt.column_min_points &&
                        (!clear || above <= opt.column_max_above * static_cast<float>(object + above));
        column_dropped += !ok;
        return ok;
      };
    VoteGrid grid;
    grid.cls = book.classes[c].name;
    grid.origin = origin;
    grid.cell = cell;
    grid.width = W;
    grid.height = H;
    const size_t vb = votes.class_begin[c], ve = votes.class_begin[c + 1];
    if (spdlog::should_log(spdlog::level::debug)) {
      double mass = 0.0;
      for (size_t i = vb; i < ve; ++i) mass += votes.w[i];
      spdlog::debug("voter: class {}: {} votes, mass {:.2f}", grid.cls, ve - vb, mass);
    }
    if (vb == ve || W == 0) {
      grid.width = grid.height = 0;
    } else {
      for (auto& h : SelectClass(votes, vb, ve, parts, cm, opt, grid, keep))
        res.hypotheses.push_back(std::move(h));
    }
    res.grids.push_back(std::move(grid));
  }
  if (columns) spdlog::debug("voter: column check dropped {} hypotheses", column_dropped);
  std::stable_sort(res.hypotheses.begin(), res.hypotheses.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
  return res;
}

}  // namespace furnihost::voting
