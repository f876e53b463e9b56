#include "catalog_index/catalog_index.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace furnihost::catalog_index {

void Cumulative(const float* histogram, int bins, float* out) {
  float c = 0.f;
  for (int i = 0; i < bins; ++i) out[i] = c += histogram[i];
}

float EmdLowerBound(const float* q, const std::vector<float>& lo, const std::vector<float>& hi) {
  // |q - c| >= q - hi when q > hi, >= lo - q when q < lo, >= 0 inside; float subtraction and
  // the running sum round monotonically, so the float result stays below the float distance.
  const int bins = int(lo.size());
  float d = 0.f;
  for (int i = 0; i < bins; ++i) d += q[i] > hi[size_t(i)] ? q[i] - hi[size_t(i)] : q[i] < lo[size_t(i)] ? lo[size_t(i)] - q[i] : 0.f;
  return d / float(bins);
}

namespace {

// The coordinates the tree splits on, in about the units of a recogniser's energy: the sizes'
// logarithms over typical spreads (heights tighter), and the mean of the first histogram (a
// lower bound of the earth mover's distance of two histograms) over a typical profile spread.
std::array<float, 4> Key(const Item& it, int bins) {
  std::array<float, 4> k{};
  const float spread[3] = {0.3f, 0.3f, 0.15f};
  for (int a = 0; a < 3; ++a) k[size_t(a)] = std::log(std::max(it.size[size_t(a)], 1e-6f)) / spread[a];
  float mass = 0.f, mean = 0.f;
  if (!it.histograms.empty())
    for (int i = 0; i < bins; ++i) {
      mass += it.histograms[0][size_t(i)];
      mean += it.histograms[0][size_t(i)] * (float(i) + 0.5f) / float(bins);
    }
  k[3] = (mass > 0.f ? mean / mass : 0.f) / 0.05f;
  return k;
}

}  // namespace

Index::Index(const std::vector<Item>& items, int bins, int leaf) : bins_(bins) {
  order_.resize(items.size());
  std::iota(order_.begin(), order_.end(), 0);
  key_.resize(items.size());
  for (size_t i = 0; i < items.size(); ++i) key_[i] = Key(items[i], bins);
  if (!items.empty()) Build(items, 0, int(items.size()), std::max(1, leaf));
}

int Index::Build(const std::vector<Item>& items, int begin, int end, int leaf) {
  const int id = int(nodes_.size());
  nodes_.emplace_back();
  // The node's intervals.
  Bounds b;
  const float inf = std::numeric_limits<float>::infinity();
  b.size_lo.fill(inf), b.size_hi.fill(-inf);
  b.extra_lo = inf, b.extra_hi = -inf;
  b.first_lo.assign(size_t(bins_), inf), b.first_hi.assign(size_t(bins_), -inf);
  b.any_lo = b.first_lo, b.any_hi = b.first_hi;
  std::vector<float> cdf(static_cast<size_t>(bins_));
  for (int k = begin; k < end; ++k) {
    const Item& it = items[size_t(order_[size_t(k)])];
    for (int a = 0; a < 3; ++a)
      b.size_lo[size_t(a)] = std::min(b.size_lo[size_t(a)], it.size[size_t(a)]),
      b.size_hi[size_t(a)] = std::max(b.size_hi[size_t(a)], it.size[size_t(a)]);
    b.extra_lo = std::min(b.extra_lo, it.extra), b.extra_hi = std::max(b.extra_hi, it.extra);
    for (size_t h = 0; h < it.histograms.size(); ++h) {
      Cumulative(it.histograms[h].data(), bins_, cdf.data());
      for (size_t i = 0; i < size_t(bins_); ++i) {
        if (h == 0) b.first_lo[i] = std::min(b.first_lo[i], cdf[i]), b.first_hi[i] = std::max(b.first_hi[i], cdf[i]);
        b.any_lo[i] = std::min(b.any_lo[i], cdf[i]), b.any_hi[i] = std::max(b.any_hi[i], cdf[i]);
      }
    }
  }
  nodes_[size_t(id)].bounds = std::move(b);
  if (end - begin <= leaf) {
    nodes_[size_t(id)].begin = begin, nodes_[size_t(id)].end = end;
    return id;
  }
  // Split at the median of the widest coordinate.
  int dim = 0;
  float widest = -1.f;
  for (int d = 0; d < 4; ++d) {
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (int k = begin; k < end; ++k) {
      const float v = key_[size_t(order_[size_t(k)])][size_t(d)];
      lo = std::min(lo, v), hi = std::max(hi, v);
    }
    if (hi - lo > widest) widest = hi - lo, dim = d;
  }
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](int a, int c) {
    const float ka = key_[size_t(a)][size_t(dim)], kc = key_[size_t(c)][size_t(dim)];
    return ka < kc || (ka == kc && a < c);
  });
  const int left = Build(items, begin, mid, leaf);
  const int right = Build(items, mid, end, leaf);
  nodes_[size_t(id)].left = left, nodes_[size_t(id)].right = right;
  return id;
}

}  // namespace furnihost::catalog_index
