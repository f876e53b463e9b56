// furnihost::voting below the plugins: k-means on separated blobs (recovery, determinism for a
// seed, the reported inertia), the word index against brute force, and the codebook (element
// order and norms, JSON round trip, format tag check).
#include "voting/voting.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <random>

#include "furnihost/error.hpp"

namespace furnihost::voting {
namespace {

// `per` points around each centre, uniform noise of half-width `noise`.
RowMatrixXf Blobs(const std::vector<std::vector<float>>& centres, int per, float noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-noise, noise);
  const int dim = static_cast<int>(centres.front().size());
  RowMatrixXf data(static_cast<int>(centres.size()) * per, dim);
  for (size_t c = 0; c < centres.size(); ++c)
    for (int i = 0; i < per; ++i)
      for (int j = 0; j < dim; ++j) data(static_cast<int>(c) * per + i, j) = centres[c][j] + u(rng);
  return data;
}

TEST(KMeans, RecoversSeparatedBlobs) {
  const std::vector<std::vector<float>> centres = {{0.1f, 0.1f}, {0.9f, 0.1f}, {0.5f, 0.9f}};
  const RowMatrixXf data = Blobs(centres, 30, 0.05f, 1);
  KMeansOptions opt;
  opt.k = 3;
  const KMeansResult r = KMeans(data, opt, 7);
  ASSERT_EQ(r.centers.rows(), 3);
  ASSERT_EQ(r.labels.size(), size_t(data.rows()));
  for (const auto& c : centres) {
    float best = 1e9f;
    for (int k = 0; k < 3; ++k) best = std::min(best, (r.centers.row(k) - Eigen::RowVector2f(c[0], c[1])).norm());
    EXPECT_LT(best, 0.03f) << "centre " << c[0] << ", " << c[1];
  }
  for (int b = 0; b < 3; ++b)  // one label per blob
    for (int i = 1; i < 30; ++i) EXPECT_EQ(r.labels[b * 30 + i], r.labels[b * 30]);
  double inertia = 0.0;
  for (int i = 0; i < data.rows(); ++i) inertia += (data.row(i) - r.centers.row(r.labels[i])).squaredNorm();
  EXPECT_NEAR(r.inertia, inertia, 1e-6 * std::max(1.0, inertia));
}

TEST(KMeans, DeterministicForASeed) {
  const RowMatrixXf data = Blobs({{0.f, 0.f, 0.f}, {1.f, 1.f, 1.f}, {0.f, 1.f, 0.5f}, {1.f, 0.f, 0.2f}}, 25, 0.3f, 2);
  KMeansOptions opt;
  opt.k = 5;
  const KMeansResult a = KMeans(data, opt, 11), b = KMeans(data, opt, 11);
  EXPECT_EQ(a.labels, b.labels);
  EXPECT_TRUE(a.centers == b.centers);
  EXPECT_EQ(a.inertia, b.inertia);
}

TEST(KMeans, ClearErrors) {
  KMeansOptions opt;
  EXPECT_THROW(KMeans(RowMatrixXf(0, 3), opt, 1), StageError);
  opt.k = 0;
  EXPECT_THROW(KMeans(RowMatrixXf::Zero(4, 3), opt, 1), StageError);
}

TEST(WordIndex, AgreesWithBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  RowMatrixXf words(300, 24);
  for (int i = 0; i < words.rows(); ++i)
    for (int j = 0; j < words.cols(); ++j) words(i, j) = u(rng);
  const WordIndex index(words);
  std::vector<float> q(24);
  for (int t = 0; t < 20; ++t) {
    for (auto& v : q) v = u(rng);
    std::vector<std::pair<float, long>> all;
    for (int i = 0; i < words.rows(); ++i)
      all.emplace_back((words.row(i) - Eigen::Map<const Eigen::RowVectorXf>(q.data(), 24)).squaredNorm(), i);
    std::sort(all.begin(), all.end());
    long idx[3];
    float d2[3];
    ASSERT_EQ(index.Nearest(q.data(), 3, idx, d2), 3);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(idx[k], all[k].second) << "query " << t << " rank " << k;
      EXPECT_NEAR(d2[k], all[k].first, 1e-5f);
    }
    // A bound below the nearest distance leaves nothing.
    EXPECT_EQ(index.Nearest(q.data(), 3, idx, d2, 0.5f * all[0].first), 0);
  }
}

// Six parts of two classes and two models, assigned to two words.
TrainingParts SixParts() {
  TrainingParts p;
  p.feature_names = {"a", "b"};
  p.features = RowMatrixXf(6, 2);
  p.features << 0.1f, 0.1f, 0.2f, 0.1f, 0.9f, 0.8f, 0.8f, 0.9f, 0.15f, 0.2f, 0.85f, 0.85f;
  for (int i = 0; i < 6; ++i) p.d.emplace_back(0.1f * i, -0.05f * i, 0.3f);
  p.height = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f};
  p.cls = {0, 0, 1, 1, 1, 0};
  p.model = {0, 0, 1, 1, 1, 0};
  p.view = {0, 1, 0, 1, 2, 2};
  p.classes = {{"chair", 0.5f, 1, 3, 0.9f}, {"table", 1.2f, 1, 3, 0.75f}};
  p.models = {"chair_1", "table_1"};
  return p;
}

TEST(Codebook, ElementsGroupedByWordWithPerClassNorms) {
  const TrainingParts p = SixParts();
  RowMatrixXf words(2, 2);
  words << 0.15f, 0.13f, 0.85f, 0.85f;
  const std::vector<int> labels = {0, 0, 1, 1, 0, 1};
  const Codebook b = BuildCodebook(p, words, labels);
  ASSERT_EQ(b.Words(), 2);
  EXPECT_EQ(b.element_begin, (std::vector<int>{0, 3, 6}));
  // Word 0 holds parts 0, 1, 4 (in order): classes 0, 0, 1.
  EXPECT_EQ(b.element_class, (std::vector<int>{0, 0, 1, 1, 1, 0}));
  EXPECT_EQ(b.element_view, (std::vector<int>{0, 1, 2, 0, 1, 2}));
  EXPECT_FLOAT_EQ(b.element_height[2], 0.5f);
  EXPECT_TRUE(b.d[2].isApprox(p.d[4]));
  // 1 / #(word, class): word 0 has two chair elements and one table element.
  const std::vector<float> norm = {0.5f, 0.5f, 1.f, 0.5f, 0.5f, 1.f};
  for (size_t e = 0; e < norm.size(); ++e) EXPECT_FLOAT_EQ(b.element_norm[e], norm[e]) << e;
}

TEST(Codebook, JsonRoundTripAndFormatCheck) {
  const TrainingParts p = SixParts();
  const std::vector<int> labels = {0, 1, 2, 3, 4, 5};
  const Codebook a = BuildCodebook(p, p.features, labels);
  const nlohmann::json j = a.ToJson("test/1");
  const Codebook b = Codebook::FromJson(j, "test/1");
  EXPECT_EQ(b.feature_names, a.feature_names);
  EXPECT_TRUE(b.words == a.words);
  EXPECT_EQ(b.models, a.models);
  ASSERT_EQ(b.classes.size(), a.classes.size());
  for (size_t c = 0; c < a.classes.size(); ++c) {
    EXPECT_EQ(b.classes[c].name, a.classes[c].name);
    EXPECT_EQ(b.classes[c].width, a.classes[c].width);
    EXPECT_EQ(b.classes[c].height, a.classes[c].height);
  }
  EXPECT_EQ(b.element_begin, a.element_begin);
  EXPECT_EQ(b.element_class, a.element_class);
  EXPECT_EQ(b.element_model, a.element_model);
  EXPECT_EQ(b.element_view, a.element_view);
  EXPECT_EQ(b.element_height, a.element_height);
  EXPECT_EQ(b.element_norm, a.element_norm);
  ASSERT_EQ(b.d.size(), a.d.size());
  for (size_t e = 0; e < a.d.size(); ++e) EXPECT_TRUE(b.d[e] == a.d[e]) << e;
  EXPECT_THROW(Codebook::FromJson(j, "test/2"), StageError);
  EXPECT_THROW(Codebook::FromJson(nlohmann::json::object(), "test/1"), StageError);
}

// Two vocabularies of the same parts pooled: words and elements follow each other, each
// vocabulary's elements are all the parts, its norms its own, and the JSON keeps the split.
TEST(Codebook, PooledVocabulariesKeepTheirWordsAndElements) {
  const TrainingParts p = SixParts();
  RowMatrixXf two(2, 2), three(3, 2);
  two << 0.15f, 0.13f, 0.85f, 0.85f;
  three << 0.1f, 0.1f, 0.5f, 0.5f, 0.9f, 0.9f;
  const Codebook a = BuildCodebook(p, two, {0, 0, 1, 1, 0, 1});
  const Codebook b = BuildCodebook(p, three, {0, 0, 2, 2, 1, 1});
  const Codebook pooled = PoolCodebooks({a, b});
  ASSERT_EQ(pooled.Vocabularies(), 2);
  EXPECT_EQ(pooled.vocabulary_begin, (std::vector<int>{0, 2, 5}));
  EXPECT_EQ(pooled.element_begin, (std::vector<int>{0, 3, 6, 8, 10, 12}));
  EXPECT_TRUE(pooled.words.row(3) == three.row(1));
  for (int e = 0; e < 6; ++e) EXPECT_EQ(pooled.element_norm[e], a.element_norm[e]) << e;
  for (int e = 0; e < 6; ++e) EXPECT_EQ(pooled.element_norm[6 + e], b.element_norm[e]) << e;
  const Codebook back = Codebook::FromJson(pooled.ToJson("test/1"), "test/1");
  EXPECT_EQ(back.vocabulary_begin, pooled.vocabulary_begin);
  EXPECT_EQ(back.element_class, pooled.element_class);
  EXPECT_EQ(Codebook::FromJson(a.ToJson("test/1"), "test/1").vocabulary_begin, (std::vector<int>{0, 2}));
  nlohmann::json bad = pooled.ToJson("test/1");
  bad["vocabulary_begin"] = {0, 5, 5};
  EXPECT_THROW(Codebook::FromJson(bad, "test/1"), StageError);

  // The index answers within one vocabulary, with indices into all words.
  const WordIndex index(pooled.words, 10, pooled.vocabulary_begin);
  ASSERT_EQ(index.Vocabularies(), 2);
  const float q[2] = {0.4f, 0.42f};
  long idx[2];
  float d2[2];
  ASSERT_EQ(index.Nearest(q, 1, idx, d2, 0.f, 0), 1);
  EXPECT_EQ(idx[0], 0);
  ASSERT_EQ(index.Nearest(q, 1, idx, d2, 0.f, 1), 1);
  EXPECT_EQ(idx[0], 3);
}

// k-means' restarts keep the lowest inertia: on uneven blobs, where single runs from different
// seeds end in different local minima, the best of 20 restarts reaches the same objective from
// any seed (within 1 %).
TEST(KMeans, RestartsAgreeOnTheObjectiveAcrossSeeds) {
  std::vector<std::vector<float>> centres;
  for (int c = 0; c < 12; ++c) centres.push_back({0.1f * (c % 4), 0.3f * (c / 4), 0.05f * c});
  const RowMatrixXf data = Blobs(centres, 20, 0.08f, 3);
  KMeansOptions opt;
  opt.k = 7;
  auto spread = [&](int restarts) {
    opt.restarts = restarts;
    double lo = 1e30, hi = 0.0;
    for (uint64_t seed = 1; seed <= 6; ++seed) {
      const double in = KMeans(data, opt, seed).inertia;
      lo = std::min(lo, in), hi = std::max(hi, in);
    }
    return (hi - lo) / lo;
  };
  const double one = spread(1), twenty = spread(20);
  std::printf("relative inertia spread over 6 seeds: 1 run %.4f, best of 20 %.4f\n", one, twenty);
  EXPECT_LT(twenty, 0.01);
  EXPECT_LT(twenty, 0.5 * one);
}

}  // namespace
}  // namespace furnihost::voting
