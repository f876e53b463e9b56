// furnihost::voting: k-means (k-means++ seeding, Lloyd iterations) with the project's own uniform
// draws, so the model file does not depend on the standard library.
#include "voting/voting.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>

#include "furnihost/error.hpp"

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

}  // namespace

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

}  // namespace furnihost::voting
