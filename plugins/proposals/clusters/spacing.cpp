// proposals.clusters: the points proposed on: each distinct point once, thinned to thin_spacing_m on a
// seeded random subset, and the spacing the radii scale with.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <numeric>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/plugin.hpp"
#include "furnihost/voxel_index.hpp"
#include "shape/shape.hpp"
#include "clusters.hpp"

namespace furnihost::clusters {

Proposals ClusterProposer::Propose(const Scan& scan, const Segmentation*, const RunContext& ctx) {
  const size_t n = scan.points.size();
  // The points proposed on: each distinct point once (a duplicate adds no surface, and the
  // spacing the radii scale with would shrink), then, past max_points, a random subset of them.
  std::vector<uint32_t> of;
  const size_t groups = GroupEqualPoints(scan.points, &of).size();
  std::vector<uint32_t> chosen;  // the first point of each distinct position (they come in that order)
  chosen.reserve(groups);
  for (size_t i = 0; i < n; ++i)
    if (of[i] == chosen.size()) chosen.push_back(uint32_t(i));
  const size_t distinct = chosen.size();
  // A random subset is the points whose seeded hashes of their index are the smallest (O(n); the
  // same for the same scan and seed; a smaller subset is part of a larger one).
  std::vector<std::pair<uint64_t, uint32_t>> key;
  auto smallest = [&](size_t m) {
    if (key.empty()) {
      key.resize(chosen.size());
      for (size_t k = 0; k < chosen.size(); ++k) key[k] = {SubsetKey(ctx.seed, chosen[k]), chosen[k]};
    }
    std::nth_element(key.begin(), key.begin() + long(m), key.end());
  };
  size_t m = distinct;
  // A scan with nothing to leave out (no copies, no more points than max_points, at most
  // kSpacingSample) is measured by the proposals' own spacing: one pass unless it is too dense.
  float measured = 0.f;
  if (o_.thin_spacing > 0.f && distinct == n && n <= kSpacingSample &&
      (o_.max_points <= 0 || n <= size_t(o_.max_points))) {
    Proposals out = ProposeAll(scan, &measured);
    if (measured == 0.f) return out;
  }
  if (o_.thin_spacing > 0.f && distinct >= 10) {
    // The spacing of a random subset of m points, measured on the subset's points in a random
    // choice of 0.5 m cells that hold about kSpacingSample points of the scan (all of them when
    // there are no more); m searched for where it reaches thin_spacing. No formula gives it:
    // the spacing of a random share k of a sample grows as 1/sqrt(k) for points strewn at
    // random, slower for a mesh's regular vertices, faster for clumped passes.
    const std::vector<uint32_t> cells = CellSample(scan.points, chosen, ctx.seed);
    std::vector<uint64_t> cell_key(cells.size());
    for (size_t k = 0; k < cells.size(); ++k) cell_key[k] = SubsetKey(ctx.seed, chosen[cells[k]]);
    auto spacing_of = [&](size_t count) {
      uint64_t below = ~0ull;  // the subset: the keys below the count-th smallest
      if (count < distinct) {
        smallest(count);
        below = key[count].first;
      }
      Points pts;
      for (size_t k = 0; k < cells.size(); ++k)
        if (count == distinct || cell_key[k] < below) pts.push_back(scan.points[chosen[cells[k]]]);
      return SampleSpacing(pts);
    };
    const float sp_all = measured > 0.f ? measured : spacing_of(distinct);
    float sp = sp_all;
    if (sp_all > 0.f && sp_all < o_.thin_spacing) {
      // The largest subset found at or above thin_spacing: bracketed by quarters, then 6
      // geometric bisections (about 2 % of the count).
      size_t hi = distinct, lo = distinct;
      float sp_lo = sp_all;
      while (lo > 10 && sp_lo < o_.thin_spacing) {
        hi = lo;
        lo = std::max<size_t>(10, lo / 4);
        sp_lo = spacing_of(lo);
      }
      for (int it = 0; it < 6 && hi > lo + 1; ++it) {
        const size_t mid = std::clamp<size_t>(size_t(std::sqrt(double(lo) * double(hi))), lo + 1, hi - 1);
        const float s_mid = spacing_of(mid);
        if (s_mid >= o_.thin_spacing) lo = mid, sp_lo = s_mid;
        else hi = mid;
      }
      m = lo;
      sp = sp_lo;
    }
    spdlog::debug("proposals.clusters: {} distinct points, spacing {:.4f} m (on {} of them in 0.5 m cells){}", distinct,
                  sp_all, cells.size(),
                  m < distinct ? fmt::format(": thinned to {} points, spacing {:.4f} m", m, sp) : std::string());
  }
  if (o_.max_points > 0) m = std::min(m, size_t(o_.max_points));
  if (m < chosen.size()) {
    smallest(m);
    chosen.resize(m);
    for (size_t k = 0; k < m; ++k) chosen[k] = key[k].second;
    std::sort(chosen.begin(), chosen.end());
  }
  if (chosen.size() == n) return ProposeAll(scan);
  Scan sub;  // what the proposals need of the scan; its own neighbours (the pipeline's are of all points)
  sub.source = scan.source;
  sub.origin = scan.origin;
  sub.pose = scan.pose;
  sub.frame = scan.frame;
  sub.ground = scan.ground;
  sub.points.reserve(chosen.size());
  for (uint32_t i : chosen) sub.points.push_back(scan.points[i]);
  spdlog::debug("proposals.clusters: {} points, {} distinct, proposing on {}", n, distinct, m);
  Proposals out = ProposeAll(sub);
  for (auto& q : out.items)
    for (int& i : q.indices) i = int(chosen[size_t(i)]);
  std::vector<uint8_t> removed(n, 0);  // the points left out: not reported
  if (out.removed.size() == chosen.size())
    for (size_t k = 0; k < chosen.size(); ++k) removed[chosen[k]] = out.removed[k];
  if (n >= 10) out.removed = std::move(removed);
  return out;
}

// The positions in `chosen` of the points that lie in a seeded random choice of kSpacingCell cells
// holding at least kSpacingSample of them together (every position when there are no more).
std::vector<uint32_t> ClusterProposer::CellSample(const Points& points, const std::vector<uint32_t>& chosen, uint64_t seed) {
  std::vector<uint32_t> out;
  if (chosen.size() <= kSpacingSample) {
    out.resize(chosen.size());
    std::iota(out.begin(), out.end(), 0u);
    return out;
  }
  // Each point's cell, hashed once: the key both counts and picks by.
  const uint64_t base = SplitMix64(seed ^ 0x63656c6cull);  // "cell"
  std::vector<uint64_t> cell_of(chosen.size());
  std::unordered_map<uint64_t, size_t> count;
  for (size_t k = 0; k < chosen.size(); ++k) {
    const Eigen::Vector3f& p = points[chosen[k]];
    uint64_t h = base;
    for (int a = 0; a < 3; ++a) h = SplitMix64(h ^ uint64_t(int64_t(std::floor(double(p[a]) / kSpacingCell))));
    cell_of[k] = h;
    ++count[h];
  }
  std::vector<std::pair<uint64_t, size_t>> cells(count.begin(), count.end());
  std::sort(cells.begin(), cells.end());  // by the cells' hashes: a random order
  std::unordered_set<uint64_t> take;
  size_t total = 0;
  for (const auto& [h, c] : cells) {
    if (total >= kSpacingSample) break;
    take.insert(h);
    total += c;
  }
  out.reserve(total);
  for (size_t k = 0; k < chosen.size(); ++k)
    if (take.count(cell_of[k])) out.push_back(uint32_t(k));
  return out;
}

// The spacing of `points` as ProposeAll measures it (the nearest other point, at least 0.45 x
// the 4th nearest; medians over every 10th point).
float ClusterProposer::SampleSpacing(const Points& points) {
  if (points.size() < 10) return 0.f;
  shape::KnnIndex index(points);
  const size_t q = (points.size() + 9) / 10;
  std::vector<float> nn(q), nn4(q);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, q, 256), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<uint32_t> idx;
    std::vector<float> d2;
    for (size_t k = r.begin(); k != r.end(); ++k) {
      index.Query(points[k * 10], 5, idx, d2);
      // Copies of the query point (distance 0) are not its neighbours: distinct points here.
      nn[k] = d2.size() > 1 ? std::sqrt(d2[1]) : 0.f;
      nn4[k] = d2.size() > 4 ? std::sqrt(d2[4]) : 0.f;
    }
  });
  return std::max(shape::MedianSpacing(nn, 1), kSpacingPerNn4 * shape::MedianSpacing(nn4, 1));
}

}  // namespace furnihost::clusters
