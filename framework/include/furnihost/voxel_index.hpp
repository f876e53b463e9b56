// A static cubic-cell index for fixed-radius neighbourhoods (header-only, Eigen and the
// standard library only). Used by segmenters.region_growing, segmenters.cgal_region_growing,
// segmenters.cgal_efficient_ransac and the part features (features.paper24 / reduced).
//
// Why not a k-d tree: every query of a caller has the same radius, so with cells of that edge
// the neighbours of any point lie in the 3x3x3 cells around it. The points are reordered cell
// by cell (a stable radix sort of the cell keys), which makes every cell a contiguous slice of
// the sorted coordinate arrays: a query scans at most 27 slices of structure-of-arrays floats,
// and queries issued cell by cell touch the same memory again and again.
// bench_region_growing (neighbours/*): the 3 cm neighbourhoods of all points of a 1M-point
// room, build included, take 74 ms with this index and 865 ms with a nanoflann 1.4.3 k-d tree
// (2 threads).
//
// Frames: the caller passes points in a LOCAL frame (a few hundred metres at most; shift map
// coordinates before, in double), because cell keys are computed in float. Units: metres.
// Shapes: N points, C non-empty cells. A "slot" is a position in the cell-sorted order.
//   order[s]      N    input index of the point in slot s
//   x, y, z       N    coordinates by slot
//   cell_of[s]    N    cell of slot s
//   cell_start    C+1  slots of cell c are [cell_start[c], cell_start[c+1]); within a cell the
//                      slots keep the input order
//   nb_start, nb  C+1, <= 27 C   (CSR) non-empty cells within one cell step of c, c included,
//                      in increasing key order (z, then y, then x)
//
// Parallelism without a dependency: Build takes a `parallel_for` callable,
//   pfor(size_t begin, size_t end, size_t grain, body)   calling body(size_t b, size_t e)
// over disjoint sub-ranges covering [begin, end). SerialFor (the default) runs it in place; a
// caller with TBB passes an adaptor over tbb::parallel_for (see
// plugins/common/parallel/tbb_for.hpp). The result never depends on the partition.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "furnihost/error.hpp"

namespace furnihost {

// Runs body(begin, end) in the calling thread.
struct SerialFor {
  template <class Body>
  void operator()(size_t begin, size_t end, size_t /*grain*/, Body&& body) const {
    if (begin < end) body(begin, end);
  }
};

// Stable LSD radix sort of `idx` by `key[idx]` over the low `bits` bits. Stability makes ties
// keep their input order, so results never depend on thread timing.
inline void RadixSortByKey(const std::vector<uint64_t>& key, int bits, std::vector<uint32_t>& idx) {
  constexpr int kDigit = 11;
  constexpr size_t kBuckets = size_t(1) << kDigit;
  std::vector<uint32_t> tmp(idx.size());
  std::vector<size_t> count(kBuckets);
  for (int shift = 0; shift < bits; shift += kDigit) {
    std::fill(count.begin(), count.end(), 0);
    for (uint32_t i : idx) ++count[(key[i] >> shift) & (kBuckets - 1)];
    size_t sum = 0;
    for (auto& c : count) {
      const size_t t = c;
      c = sum;
      sum += t;
    }
    for (uint32_t i : idx) tmp[count[(key[i] >> shift) & (kBuckets - 1)]++] = i;
    idx.swap(tmp);
  }
}

// 0 .. n-1 by increasing key[i] < 2^bits, ties in index order (stable: results never depend
// on thread timing). Up to 32 key bits, each key and its index are packed in one word (key
// high, index low) and the words sorted by their key bits, LSD, 11 bits a pass: every pass
// reads its input in order (RadixSortByKey reads key[idx] at random, most of a 3.7M-point
// cloud's sort), in parallel over fixed chunks (per-chunk counts, then each chunk scatters to
// its own offsets, so the same order whatever the threads). Wider keys: RadixSortByKey.
template <class ParallelFor = SerialFor>
std::vector<uint32_t> SortedByKey(const std::vector<uint64_t>& key, int bits, const ParallelFor& pfor = ParallelFor()) {
  const size_t n = key.size();
  std::vector<uint32_t> idx(n);
  if (bits > 32) {
    for (size_t i = 0; i < n; ++i) idx[i] = uint32_t(i);
    RadixSortByKey(key, bits, idx);
    return idx;
  }
  std::vector<uint64_t> packed(n), tmp(n);
  pfor(size_t(0), n, size_t(16384), [&](size_t b, size_t e) {
    for (size_t i = b; i != e; ++i) packed[i] = (key[i] << 32) | uint64_t(i);
  });
  constexpr int kDigit = 11;
  constexpr size_t kBuckets = size_t(1) << kDigit;
  const size_t chunks = std::clamp<size_t>(n / 65536, 1, 16), per = (n + chunks - 1) / chunks;
  std::vector<size_t> count(chunks * kBuckets);
  for (int shift = 32; shift < 32 + bits; shift += kDigit) {
    pfor(size_t(0), chunks, size_t(1), [&](size_t cb, size_t ce) {
      for (size_t ch = cb; ch < ce; ++ch) {
        size_t* cnt = &count[ch * kBuckets];
        std::fill(cnt, cnt + kBuckets, 0);
        for (size_t i = ch * per; i < std::min(n, (ch + 1) * per); ++i) ++cnt[(packed[i] >> shift) & (kBuckets - 1)];
      }
    });
    size_t sum = 0;
    for (size_t b = 0; b < kBuckets; ++b)
      for (size_t ch = 0; ch < chunks; ++ch) {
        const size_t t = count[ch * kBuckets + b];
        count[ch * kBuckets + b] = sum;
        sum += t;
      }
    pfor(size_t(0), chunks, size_t(1), [&](size_t cb, size_t ce) {
      for (size_t ch = cb; ch < ce; ++ch) {
        size_t* at = &count[ch * kBuckets];
        for (size_t i = ch * per; i < std::min(n, (ch + 1) * per); ++i)
          tmp[at[(packed[i] >> shift) & (kBuckets - 1)]++] = packed[i];
      }
    });
    packed.swap(tmp);
  }
  pfor(size_t(0), n, size_t(16384), [&](size_t b, size_t e) {
    for (size_t i = b; i != e; ++i) idx[i] = uint32_t(packed[i]);
  });
  return idx;
}

class VoxelIndex {
 public:
  // Where cell boundaries lie. kBoundingBox: at the points' minimum corner + k * cell (cell
  // (i, j, k) holds (p - min) / cell truncated). kWorld: at k * cell in the caller's frame
  // (floor(p / cell) with the float reciprocal), so two clouds in one frame share cells. Both
  // find the same neighbours; only the grouping into cells, hence the visiting order, differs.
  enum class Anchor { kBoundingBox, kWorld };

  std::vector<uint32_t> order;
  std::vector<float> x, y, z;
  std::vector<int> cell_of;
  std::vector<int> cell_start;
  std::vector<int> nb_start, nb;
  float cell = 0.f;

  size_t size() const { return order.size(); }
  int NumCells() const { return int(cell_start.size()) - 1; }

  // `pts`: N finite points (the caller drops non-finite ones). `cell_size` [m] > 0: the query
  // radius the index will serve. Throws StageError for a bad cell size or more than 2^20 cells
  // along an axis.
  template <class ParallelFor = SerialFor>
  void Build(const std::vector<Eigen::Vector3f>& pts, float cell_size, Anchor anchor = Anchor::kBoundingBox,
             const ParallelFor& pfor = ParallelFor()) {
    cell = cell_size;
    anchor_ = anchor;
    const size_t n = pts.size();
    order.clear();  // SortedByKey below gives it its n entries
    x.resize(n);
    y.resize(n);
    z.resize(n);
    cell_of.resize(n);
    cell_start.assign(1, 0);
    nb_start.assign(1, 0);
    nb.clear();
    cell_keys_.clear();
    if (n == 0) return;
    if (!(cell_size > 0.f)) throw StageError("voxel index: cell size must be > 0");

    Eigen::Vector3f lo = pts[0], hi = pts[0];
    for (const auto& p : pts) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    lo_ = lo;
    const float inv = 1.f / cell_size;
    for (int a = 0; a < 3; ++a) {
      double cells;
      if (anchor == Anchor::kWorld) {
        // p * inv rounds monotonically, so the extreme cells are those of the extreme points.
        base_[a] = int64_t(std::floor(lo[a] * inv));
        cells = std::floor(double(hi[a] * inv)) - double(base_[a]) + 1.0;
      } else {
        cells = std::floor(double(hi[a] - lo[a]) * inv) + 1.0;
      }
      if (!(cells <= double(1 << 20)))
        throw StageError("voxel index: the points span " + std::to_string(hi[a] - lo[a]) +
                         " m, more than 2^20 cells of " + std::to_string(cell_size) + " m");
      dim_[a] = int64_t(cells);
    }
    std::vector<uint64_t> key(n);
    pfor(size_t(0), n, size_t(16384), [&](size_t b, size_t e) {
      for (size_t i = b; i != e; ++i) key[i] = KeyOf(pts[i]);
    });
    int bits = 1;
    while (bits < 63 && (uint64_t(1) << bits) < uint64_t(dim_[0] * dim_[1] * dim_[2])) ++bits;
    order = SortedByKey(key, bits, pfor);

    for (size_t s = 0; s < n; ++s) {
      const uint64_t k = key[order[s]];
      if (s == 0 || k != cell_keys_.back()) {
        if (s != 0) cell_start.push_back(int(s));
        cell_keys_.push_back(k);
      }
      cell_of[s] = int(cell_keys_.size()) - 1;
    }
    cell_start.push_back(int(n));
    pfor(size_t(0), n, size_t(16384), [&](size_t b, size_t e) {
      for (size_t s = b; s != e; ++s) {
        const auto& p = pts[order[s]];
        x[s] = p.x();
        y[s] = p.y();
        z[s] = p.z();
      }
    });
    BuildNeighbours(pfor);
  }

  // The minimum corner of the points (kBoundingBox: cell (i, j, k) starts at Origin() + (i, j,
  // k) * cell), for callers that place finer cells on the same lattice.
  const Eigen::Vector3f& Origin() const { return lo_; }

  // Integer coordinates of cell c, counted from the index's first cell along each axis.
  Eigen::Vector3i CellCoords(int c) const {
    const uint64_t k = cell_keys_[size_t(c)];
    return Eigen::Vector3i(int(k % uint64_t(dim_[0])), int((k / uint64_t(dim_[0])) % uint64_t(dim_[1])),
                           int(k / uint64_t(dim_[0] * dim_[1])));
  }

  // slot_of[i] = slot of input point i (the inverse of `order`), for callers that query by
  // input index.
  std::vector<uint32_t> SlotOfInput() const {
    std::vector<uint32_t> slot_of(order.size());
    for (size_t s = 0; s < order.size(); ++s) slot_of[order[s]] = uint32_t(s);
    return slot_of;
  }

  // Replaces x/y/z with the coordinates of every point in the cells around cell `c` (c
  // included), slot order: a contiguous copy for branch-free distance loops over one cell's
  // points.
  void GatherNeighbourhood(int c, std::vector<float>& gx, std::vector<float>& gy, std::vector<float>& gz) const {
    gx.clear(), gy.clear(), gz.clear();
    for (int k = nb_start[c]; k < nb_start[c + 1]; ++k) {
      const int nc = nb[k];
      const int b = cell_start[nc], e = cell_start[nc + 1];
      gx.insert(gx.end(), x.begin() + b, x.begin() + e);
      gy.insert(gy.end(), y.begin() + b, y.begin() + e);
      gz.insert(gz.end(), z.begin() + b, z.begin() + e);
    }
  }

  // The cells around cell c (c included) as runs of consecutive cells: neighbours along x are
  // consecutive cells and their slots contiguous, so the up to 27 cells form up to 9 runs. Run r
  // is cells [first[r], last[r]], slots [cell_start[first[r]], cell_start[last[r] + 1]), in the
  // order of nb: a loop over the runs' slots meets the points in the order of one over nb's
  // cells, with a third of the loops (their exits are what a sparse scan's loops mispredict).
  void NeighbourRuns(int c, std::vector<int>& first, std::vector<int>& last) const {
    first.clear(), last.clear();
    for (int k = nb_start[c]; k < nb_start[c + 1]; ++k) {
      if (!last.empty() && last.back() + 1 == nb[k])
        last.back() = nb[k];
      else
        first.push_back(nb[k]), last.push_back(nb[k]);
    }
  }

  // The same runs as slot ranges [begin[r], end[r]); returns the number of slots they hold.
  int NeighbourSlotRuns(int c, std::vector<int>& begin, std::vector<int>& end) const {
    NeighbourRuns(c, begin, end);
    int slots = 0;
    for (size_t r = 0; r < begin.size(); ++r) {
      begin[r] = cell_start[begin[r]], end[r] = cell_start[end[r] + 1];
      slots += end[r] - begin[r];
    }
    return slots;
  }

  // Calls f(slot, dx, dy, dz, d2) for every point with d2 = |p - q|^2 < radius^2, radius <=
  // cell, q = (px, py, pz) in cell `c` (e.g. one of its points). Includes the query itself.
  template <class F>
  void ForEachWithin(int c, float px, float py, float pz, float radius, F&& f) const {
    const float r2 = radius * radius;
    for (int k = nb_start[c]; k < nb_start[c + 1]; ++k) {
      const int nc = nb[k];
      for (int s = cell_start[nc]; s < cell_start[nc + 1]; ++s) {
        const float dx = x[s] - px, dy = y[s] - py, dz = z[s] - pz;
        const float d2 = dx * dx + dy * dy + dz * dz;
        if (d2 < r2) f(s, dx, dy, dz, d2);
      }
    }
  }

 private:
  uint64_t Pack(int64_t ix, int64_t iy, int64_t iz) const {
    return uint64_t(ix + dim_[0] * (iy + dim_[1] * iz));
  }
  uint64_t KeyOf(const Eigen::Vector3f& p) const {
    const float inv = 1.f / cell;
    int64_t c[3];
    for (int a = 0; a < 3; ++a) {
      const int64_t i = anchor_ == Anchor::kWorld ? int64_t(std::floor(p[a] * inv)) - base_[a]
                                                  : int64_t((p[a] - lo_[a]) * inv);
      c[a] = std::min<int64_t>(dim_[a] - 1, std::max<int64_t>(0, i));
    }
    return Pack(c[0], c[1], c[2]);
  }

  // Cells (ix-1..ix+1, iy+dy, iz+dz) have consecutive keys, so the neighbours of a cell are
  // 9 runs of at most 3 keys. The first key of run (dy, dz) is key(c) - 1 + const(dy, dz) (one
  // more at the x border), which never decreases as c walks the sorted cells: each of the 9
  // runs keeps a cursor that only moves forward (galloping when it has far to go), instead of
  // 9 binary searches per cell.
  template <class ParallelFor>
  void BuildNeighbours(const ParallelFor& pfor) {
    const int cells = NumCells();
    constexpr int kChunk = 2048;
    const int chunks = (cells + kChunk - 1) / kChunk;
    std::vector<std::vector<int>> lists(static_cast<size_t>(chunks));
    std::vector<int> count(cells);
    // The keys with 3 sentinels above every key: the cursors and the look-ahead of 3 below
    // need no end checks. Branch-free where the branches were unpredictable (a cursor steps
    // 0-2 cells per cell, a row holds 0-3 neighbours), which sparse scans hit most.
    std::vector<uint64_t> keys(cell_keys_);
    keys.insert(keys.end(), 3, std::numeric_limits<uint64_t>::max());
    const uint64_t* key = keys.data();
    pfor(size_t(0), size_t(chunks), size_t(1), [&](size_t ch_begin, size_t ch_end) {
      for (int ch = int(ch_begin); ch < int(ch_end); ++ch) {
        auto& list = lists[ch];
        const int c_end = std::min(cells, (ch + 1) * kChunk);
        list.resize(size_t(c_end - ch * kChunk) * 27);
        int* out = list.data();
        size_t used = 0;
        int cursor[9];
        bool started[9] = {};
        for (int c = ch * kChunk; c < c_end; ++c) {
          const size_t before = used;
          const uint64_t k = key[c];
          const int64_t ix = int64_t(k % uint64_t(dim_[0]));
          const int64_t iy = int64_t((k / uint64_t(dim_[0])) % uint64_t(dim_[1]));
          const int64_t iz = int64_t(k / uint64_t(dim_[0] * dim_[1]));
          for (int64_t dz = -1; dz <= 1; ++dz) {
            if (iz + dz < 0 || iz + dz >= dim_[2]) continue;
            for (int64_t dy = -1; dy <= 1; ++dy) {
              if (iy + dy < 0 || iy + dy >= dim_[1]) continue;
              const int run = int((dz + 1) * 3 + (dy + 1));
              const uint64_t first = Pack(std::max<int64_t>(0, ix - 1), iy + dy, iz + dz);
              const uint64_t last = Pack(std::min<int64_t>(dim_[0] - 1, ix + 1), iy + dy, iz + dz);
              int& it = cursor[run];
              if (!started[run]) {
                it = int(std::lower_bound(key, key + cells, first) - key);
                started[run] = true;
              } else {
                it += int(key[it] < first);
                it += int(key[it] < first);
                if (key[it] < first) it = int(std::lower_bound(key + it, key + cells, first) - key);
              }
              // key[it] >= first; the (at most 3) cells up to `last` follow it.
              for (int j = 0; j < 3; ++j) {
                out[used] = it + j;
                used += size_t(key[it + j] <= last);
              }
            }
          }
          count[c] = int(used - before);
        }
        list.resize(used);
      }
    });
    nb_start.resize(cells + 1);
    nb_start[0] = 0;
    for (int c = 0; c < cells; ++c) nb_start[c + 1] = nb_start[c] + count[c];
    nb.resize(nb_start[cells]);
    pfor(size_t(0), size_t(chunks), size_t(1), [&](size_t ch_begin, size_t ch_end) {
      for (size_t ch = ch_begin; ch < ch_end; ++ch)
        std::copy(lists[ch].begin(), lists[ch].end(), nb.begin() + nb_start[ch * kChunk]);
    });
  }

  Anchor anchor_ = Anchor::kBoundingBox;
  Eigen::Vector3f lo_ = Eigen::Vector3f::Zero();
  int64_t base_[3] = {0, 0, 0};
  int64_t dim_[3] = {1, 1, 1};
  std::vector<uint64_t> cell_keys_;
};

}  // namespace furnihost
