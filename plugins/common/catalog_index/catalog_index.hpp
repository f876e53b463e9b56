#pragma once
// furnihost::catalog_index — the catalog models that can be an object's best match, found
// without scoring every model (voters.catalog_shape): a tree over the models' metric sizes and
// shape descriptors, searched best first with a lower bound of the score's energy per node.
//
// A recogniser gives each model an energy E_m (e.g. penalties of the size ratios plus the 1-D
// earth mover's distance of top-view height profiles) and keeps the smallest. The index groups
// the models by size and profile (a k-d tree, leaves of a few models) and keeps per node the
// interval of every field over its models: sizes, a further scalar, and per bin the interval of
// the models' cumulative histograms. Search asks the recogniser for a lower bound of E over a
// node's intervals, visits the nodes in increasing bound, scores the models of each leaf it
// reaches and stops at the first node whose bound exceeds the smallest energy found: every model
// whose energy can be the smallest is scored (ties too), the others never. With a valid bound the
// best model is the one scoring every model finds; the number scored grows with the models that
// come close to the object, not with the catalog (benchmarks/catalog/catalog_scale.py).
#include <array>
#include <cstddef>
#include <functional>
#include <limits>
#include <queue>
#include <utility>
#include <vector>

namespace furnihost::catalog_index {

// One model: its sizes [m] (three fixed meanings, e.g. length, width, height), a further scalar
// its energy depends on, and its shape descriptor as histograms of `bins` bins each: the first
// is the model's own (e.g. seen from all around), the others alternatives (e.g. seen by single
// eyes) that an energy may take instead.
struct Item {
  std::array<float, 3> size{};
  float extra = 0.f;
  std::vector<std::vector<float>> histograms;
};

// The intervals of a node's models: sizes, the scalar, and per bin the cumulative sums of the
// first histograms (first_lo / first_hi) and of every histogram (any_lo / any_hi).
struct Bounds {
  std::array<float, 3> size_lo{}, size_hi{};
  float extra_lo = 0.f, extra_hi = 0.f;
  std::vector<float> first_lo, first_hi, any_lo, any_hi;
};

// Cumulative sums of a histogram, summed in float from the first bin (as a 1-D earth mover's
// distance sums them: shape::ProfileDistance).
void Cumulative(const float* histogram, int bins, float* out);

// A lower bound of sum_i |query_cdf[i] - c[i]| / bins over every c with lo[i] <= c[i] <= hi[i]
// (the 1-D earth mover's distance of the query to any histogram of those cumulative sums),
// computed in float as the distance is: never above the distance computed for such a c.
float EmdLowerBound(const float* query_cdf, const std::vector<float>& lo, const std::vector<float>& hi);

class Index {
 public:
  Index() = default;
  // items: every histogram with `bins` bins. leaf: models per leaf at most.
  Index(const std::vector<Item>& items, int bins, int leaf = 8);
  size_t Size() const { return order_.size(); }
  int Bins() const { return bins_; }

  // Visits models best first: lower_bound(const Bounds&) -> float must not exceed value(i) of
  // any model i under those bounds; value(size_t i) -> float scores model i (its index in the
  // items given to the constructor). Stops when the smallest bound left exceeds the smallest
  // value returned (so every model of the smallest value is visited). Returns the models scored.
  template <class LowerBound, class Value>
  size_t Search(LowerBound&& lower_bound, Value&& value) const;

 private:
  struct Node {
    Bounds bounds;
    int left = -1, right = -1;  // children, or -1 for a leaf
    int begin = 0, end = 0;     // a leaf's models: order_[begin, end)
  };
  int Build(const std::vector<Item>& items, int begin, int end, int leaf);
  int bins_ = 0;
  std::vector<Node> nodes_;
  std::vector<int> order_;  // model indices, leaf after leaf
  std::vector<std::array<float, 4>> key_;  // per model: the split coordinates
};

template <class LowerBound, class Value>
size_t Index::Search(LowerBound&& lower_bound, Value&& value) const {
  if (nodes_.empty()) return 0;
  using Entry = std::pair<float, int>;  // bound, node
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> open;
  open.emplace(lower_bound(nodes_[0].bounds), 0);
  float best = std::numeric_limits<float>::infinity();
  size_t scored = 0;
  while (!open.empty()) {
    const auto [bound, n] = open.top();
    open.pop();
    if (bound > best) break;
    const Node& node = nodes_[size_t(n)];
    if (node.left < 0) {
      for (int k = node.begin; k < node.end; ++k) {
        const float v = value(size_t(order_[size_t(k)]));
        ++scored;
        if (v < best) best = v;
      }
      continue;
    }
    for (const int child : {node.left, node.right}) {
      const float b = lower_bound(nodes_[size_t(child)].bounds);
      if (!(b > best)) open.emplace(b, child);
    }
  }
  return scored;
}

}  // namespace furnihost::catalog_index
