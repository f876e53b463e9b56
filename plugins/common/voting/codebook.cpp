// furnihost::voting: the codebook (shape model) and its file format, the selection options and the
// kd-tree over the words.
#include "voting/voting.hpp"

#include <algorithm>
#include <cmath>
#include <nanoflann.hpp>

#include "furnihost/error.hpp"

namespace furnihost::voting {

namespace {

template <class T>
nlohmann::json FlatArray(const std::vector<T>& v) {
  return nlohmann::json(v);
}

}  // namespace

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

}  // namespace furnihost::voting
