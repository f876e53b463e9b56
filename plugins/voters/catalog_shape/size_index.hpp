// voters.catalog_shape, private to the plugin: the index that proposes a class's candidate models
// for a proposal (Vote), so that the energy is computed for the few models that can still beat
// the best energy found.
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

// A k-d tree over one class's models, each model a box in kDims coordinates (Vote's: ln length,
// ln width, ln height, open floor share, and the range of its profiles' ChunkSums), each
// node with the bounding box of its models' boxes. Search visits the nodes best first by a lower
// bound of the energy of any model inside a node's box, and stops once that bound exceeds the
// best energy found.
class SizeIndex {
 public:
  static constexpr size_t kDims = 5;
  using Box = std::array<double, 2 * kDims>;  // lo[kDims], hi[kDims]

  SizeIndex() = default;
  // Models `ids` (indices into the voter's models) of boxes `boxes`; leaves hold up to `leaf`
  // models. A node splits across the axis where its box is widest in units of `scale` (per
  // coordinate: how fast the energy grows along it).
  SizeIndex(std::vector<int> ids, std::vector<Box> boxes, const std::array<double, kDims>& scale, size_t leaf = 8)
      : order_(std::move(ids)), boxes_(std::move(boxes)), scale_(scale) {
    if (!order_.empty() && order_.size() == boxes_.size()) Build(0, order_.size(), std::max<size_t>(leaf, 1));
  }

  size_t size() const { return order_.size(); }

  // Visits candidate models: `bound(box)` is a lower bound of the energy of every model whose box
  // lies in `box`, `limit()` the best energy so far; `visit(m)` (m: index into the models) is
  // called for every model of each node whose bound is not above the limit, nodes in increasing
  // order of bound. A NaN bound counts as 0 (the node is visited).
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

  // The node of models [begin, end): split at the median centre along its box's widest axis.
  int Build(size_t begin, size_t end, size_t leaf) {
    const int k = int(nodes_.size());
    nodes_.push_back({});
    Box box;
    for (size_t a = 0; a < kDims; ++a) box[a] = INFINITY, box[a + kDims] = -INFINITY;
    for (size_t i = begin; i < end; ++i)
      for (size_t a = 0; a < kDims; ++a)
        box[a] = std::min(box[a], boxes_[i][a]), box[a + kDims] = std::max(box[a + kDims], boxes_[i][a + kDims]);
    nodes_[size_t(k)].box = box;
    nodes_[size_t(k)].begin = begin, nodes_[size_t(k)].end = end;
    if (end - begin <= leaf) return k;
    size_t axis = 0;
    for (size_t a = 1; a < kDims; ++a)
      if ((box[a + kDims] - box[a]) * scale_[a] > (box[axis + kDims] - box[axis]) * scale_[axis]) axis = a;
    if (!(box[axis + kDims] > box[axis])) return k;  // all at one point: one leaf
    auto centre = [&](size_t i) { return boxes_[i][axis] + boxes_[i][axis + kDims]; };
    std::vector<size_t> idx(end - begin);
    std::iota(idx.begin(), idx.end(), begin);
    const size_t mid = (end - begin) / 2;
    std::nth_element(idx.begin(), idx.begin() + long(mid), idx.end(), [&](size_t a, size_t b) {
      return std::make_pair(centre(a), order_[a]) < std::make_pair(centre(b), order_[b]);
    });
    std::vector<Box> bx;
    std::vector<int> ord;
    for (size_t i : idx) bx.push_back(boxes_[i]), ord.push_back(order_[i]);
    std::copy(bx.begin(), bx.end(), boxes_.begin() + long(begin));
    std::copy(ord.begin(), ord.end(), order_.begin() + long(begin));
    const int left = Build(begin, begin + mid, leaf);
    const int right = Build(begin + mid, end, leaf);
    nodes_[size_t(k)].left = left, nodes_[size_t(k)].right = right;
    return k;
  }

  std::vector<Node> nodes_;
  std::vector<int> order_;  // model indices, each node's a contiguous range
  std::vector<Box> boxes_;  // their boxes, in order_'s order
  std::array<double, kDims> scale_{};
};

}  // namespace furnihost::catalog_shape
