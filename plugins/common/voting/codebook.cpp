// furnihost::voting: the codebook (shape model) and its file format, the selection options and the
// kd-tree over the words.
#include "voting/voting.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <nanoflann.hpp>

#include "furnihost/error.hpp"
#include "furnihost/hash.hpp"

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
  b.vocabulary_begin = {0, static_cast<int>(words.rows())};
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

Codebook PoolCodebooks(const std::vector<Codebook>& books) {
  if (books.empty()) throw StageError("no vocabularies to pool");
  Codebook b = books.front();
  for (size_t i = 1; i < books.size(); ++i) {
    const Codebook& o = books[i];
    if (o.Dim() != b.Dim() || o.classes.size() != b.classes.size() || o.models != b.models)
      throw StageError("pooled vocabularies differ in their features, classes or models");
    const int words0 = b.Words();
    const int elements0 = static_cast<int>(b.d.size());
    RowMatrixXf words(words0 + o.Words(), b.Dim());
    words << b.words, o.words;
    b.words = std::move(words);
    for (size_t v = 1; v < o.vocabulary_begin.size(); ++v) b.vocabulary_begin.push_back(words0 + o.vocabulary_begin[v]);
    for (size_t k = 1; k < o.element_begin.size(); ++k) b.element_begin.push_back(elements0 + o.element_begin[k]);
    b.d.insert(b.d.end(), o.d.begin(), o.d.end());
    b.element_class.insert(b.element_class.end(), o.element_class.begin(), o.element_class.end());
    b.element_model.insert(b.element_model.end(), o.element_model.begin(), o.element_model.end());
    b.element_view.insert(b.element_view.end(), o.element_view.begin(), o.element_view.end());
    b.element_height.insert(b.element_height.end(), o.element_height.begin(), o.element_height.end());
  }
  b.ComputeNorms();
  return b;
}

Codebook TrainCodebook(const TrainingParts& parts, const KMeansOptions& opt, uint64_t seed,
                       std::vector<double>* inertia) {
  if (opt.vocabularies < 1) throw StageError("vocabularies must be positive");
  std::vector<Codebook> books;
  if (inertia) inertia->clear();
  for (int v = 0; v < opt.vocabularies; ++v) {
    const uint64_t s = opt.vocabularies == 1 ? seed : SplitMix64(SplitMix64(seed) ^ static_cast<uint64_t>(v));
    const KMeansResult km = KMeans(parts.features, opt, s);
    if (inertia) inertia->push_back(km.inertia);
    books.push_back(BuildCodebook(parts, km.centers, km.labels));
  }
  return books.size() == 1 ? std::move(books.front()) : PoolCodebooks(books);
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
  if (Vocabularies() > 1) j["vocabulary_begin"] = vocabulary_begin;
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
    b.vocabulary_begin = j.contains("vocabulary_begin") ? j.at("vocabulary_begin").get<std::vector<int>>()
                                                        : std::vector<int>{0, b.Words()};
    if (b.vocabulary_begin.size() < 2 || b.vocabulary_begin.front() != 0 || b.vocabulary_begin.back() != b.Words() ||
        std::adjacent_find(b.vocabulary_begin.begin(), b.vocabulary_begin.end(), std::greater_equal<int>()) !=
            b.vocabulary_begin.end())
      throw bad("vocabulary_begin does not split the words into non-empty vocabularies");
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
  std::vector<RowMatrixXf> words;  // per vocabulary; the trees refer to these copies
  std::vector<long> offset;        // index of each vocabulary's first word among all words
  std::vector<std::unique_ptr<Tree>> trees;
};

WordIndex::WordIndex(const RowMatrixXf& words, int leaf_size, const std::vector<int>& vocabulary_begin)
    : impl_(std::make_unique<Impl>()) {
  if (words.rows() == 0) throw StageError("voter model has no words");
  const std::vector<int> begin =
      vocabulary_begin.empty() ? std::vector<int>{0, static_cast<int>(words.rows())} : vocabulary_begin;
  const size_t n = begin.size() - 1;
  impl_->words.resize(n);  // sized once: the trees keep references into it
  for (size_t v = 0; v < n; ++v) {
    if (begin[v + 1] <= begin[v] || begin[v + 1] > words.rows()) throw StageError("voter model: bad vocabulary bounds");
    impl_->words[v] = words.middleRows(begin[v], begin[v + 1] - begin[v]);
    impl_->offset.push_back(begin[v]);
    impl_->trees.push_back(std::make_unique<Impl::Tree>(static_cast<size_t>(words.cols()),
                                                        std::cref(impl_->words[v]), leaf_size));  // builds it
  }
}

WordIndex::~WordIndex() = default;

int WordIndex::Vocabularies() const { return static_cast<int>(impl_->trees.size()); }

int WordIndex::Nearest(const float* query, int k, long* indices, float* dist_sq, float max_dist_sq,
                       int vocabulary) const {
  const size_t want = std::min<size_t>(static_cast<size_t>(k), impl_->words[vocabulary].rows());
  if (want == 0) return 0;
  nanoflann::KNNResultSet<float, long> result(want);
  result.init(indices, dist_sq);
  // init() sets the worst distance to +max; a bound in its place prunes every branch farther
  // than it (the tree only offers points closer than worstDist()).
  if (max_dist_sq > 0.f) dist_sq[want - 1] = max_dist_sq;
  impl_->trees[vocabulary]->index->findNeighbors(result, query, nanoflann::SearchParams());
  const int got = static_cast<int>(result.size());
  for (int i = 0; i < got; ++i) indices[i] += impl_->offset[vocabulary];
  return got;
}

}  // namespace furnihost::voting
