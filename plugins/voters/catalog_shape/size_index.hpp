// voters.catalog_shape, private to the plugin: the index that proposes a class's candidate models
// for a proposal (Vote), so the profile distances, most of a model's cost, are computed for the
// few models whose size can still beat the best energy found.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numeric>
#include <queue>
#include <utility>
#include <vector>

namespace furnihost::catalog_shape {

// A k-d tree over the (ln length, ln width, ln height) of one class's models, each node with the
// bounding box of its models' points. Search visits the nodes best first by a lower bound of the
// energy of any model inside a node's box, and stops once that bound exceeds the best energy
// found: the size terms of the energy alone bound it from below, the other terms being >= 0.
class SizeIndex {
 public:
  using Box = std::array<double, 6>;  // lo[3], hi[3] of ln(length, width, height)

  SizeIndex() = default;
  // Models `ids` (indices into the voter's models) of ln sizes `points`; leaves hold up to
  // `leaf` models.
  SizeIndex(std::vector<int> ids, std::vector<std::array<double, 3>> points, size_t leaf = 8)
      : order_(std::move(ids)), points_(std::move(points)) {
    if (!order_.empty() && order_.size() == points_.size()) Build(0, order_.size(), std::max<size_t>(leaf, 1));
  }

  size_t size() const { return order_.size(); }

  // Visits candidate models: `bound(box)` is a lower bound of the energy of every model whose log
  // sizes lie in `box`, `limit()` the best energy so far; `visit(m)` (m: index into the models)
  // is called for every model of each node whose bound is not above the limit, nodes in
  // increasing order of bound. A NaN bound counts as 0 (the node is visited).
  template <class Bound, class Limit, class Visit>
  void Search(Bound&& bound, Limit&& limit, Visit&& visit) const {
    if (nodes_.empty()) return;
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> open;
    auto push = [&](int k) {
      const double b = bound(nodes_[size_t(k)].box);
      open.push({b >= 0.0 ? b : 0.0, k});
    };
    push(0);
    while (!open.empty()) {
      const auto [b, k] = open.top();
      open.pop();
      if (b > double(limit())) break;  // every node left has a bound at least as high
      const Node& n = nodes_[size_t(k)];
      if (n.left < 0) {
        for (size_t i = n.begin; i < n.end; ++i) visit(size_t(order_[i]));
      } else {
        push(n.left);
        push(n.right);
      }
    }
  }

 private:
  struct Node {
    Box box;
    size_t begin = 0, end = 0;  // the node's models: order_[begin, end)
    int left = -1, right = -1;  // children (-1: a leaf)
  };

  // The node of models [begin, end): split at the median of its box's widest axis.
  int Build(size_t begin, size_t end, size_t leaf) {
    const int k = int(nodes_.size());
    nodes_.push_back({});
    Box box = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
    for (size_t i = begin; i < end; ++i)
      for (int a = 0; a < 3; ++a)
        box[size_t(a)] = std::min(box[size_t(a)], points_[i][size_t(a)]),
        box[size_t(a + 3)] = std::max(box[size_t(a + 3)], points_[i][size_t(a)]);
    nodes_[size_t(k)].box = box;
    nodes_[size_t(k)].begin = begin, nodes_[size_t(k)].end = end;
    if (end - begin <= leaf) return k;
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (box[size_t(a + 3)] - box[size_t(a)] > box[size_t(axis + 3)] - box[size_t(axis)]) axis = a;
    if (!(box[size_t(axis + 3)] > box[size_t(axis)])) return k;  // all at one point: one leaf
    // Sorts the models' points and indices together by the axis, then halves them.
    std::vector<size_t> idx(end - begin);
    std::iota(idx.begin(), idx.end(), begin);
    const size_t mid = (end - begin) / 2;
    std::nth_element(idx.begin(), idx.begin() + long(mid), idx.end(), [&](size_t a, size_t b) {
      return std::make_pair(points_[a][size_t(axis)], order_[a]) < std::make_pair(points_[b][size_t(axis)], order_[b]);
    });
    std::vector<std::array<double, 3>> pts;
    std::vector<int> ord;
    for (size_t i : idx) pts.push_back(points_[i]), ord.push_back(order_[i]);
    std::copy(pts.begin(), pts.end(), points_.begin() + long(begin));
    std::copy(ord.begin(), ord.end(), order_.begin() + long(begin));
    const int left = Build(begin, begin + mid, leaf);
    const int right = Build(begin + mid, end, leaf);
    nodes_[size_t(k)].left = left, nodes_[size_t(k)].right = right;
    return k;
  }

  std::vector<Node> nodes_;
  std::vector<int> order_;                      // model indices, each node's a contiguous range
  std::vector<std::array<double, 3>> points_;   // their ln sizes, in order_'s order
};

}  // namespace furnihost::catalog_shape
