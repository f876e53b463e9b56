// segmenters.region_growing: the growth (parts grown from seeds against the seed's normal, then
// small parts regrouped by distance), by points, sub-cells or per-point neighbour lists.
#include "region_growing_core.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Eigenvalues>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <numeric>
#include <tuple>
#include <type_traits>

#include "furnihost/log.hpp"
#include "furnihost/voxel_index.hpp"
#include "parallel/tbb_for.hpp"
#include "simd/left_pack.hpp"
#include "region_growing_detail.hpp"

namespace furnihost::rg {

namespace {

using detail::BoxGap2;
using detail::CellBoxes;
using detail::EmptyBox;
using detail::ExtendBox;
using detail::Far;
using detail::kNaN;
using detail::LocalCloud;
using detail::LocalViewpoint;
using detail::NormalsLocal;
using detail::ToLocal;

// Whether the growth walks sub-cells: the growth's grid (cells of delta) with each cell split
// into 2 x 2 x 2 cubes of edge delta / 2 (see Segment). Its non-empty sub-cells are numbered
// cell after cell (cell c's are [sub_first[c], sub_first[c + 1])); Segment then gives each a
// contiguous range of its cell's slots and a tight box. Sized by the non-empty sub-cells, not 8
// per cell: a sparse scan has about one point per sub-cell.
// Sparse scans grow point by point, each cell its own sub-cell: sub-cells pay only where they
// hold several points (the 1M-point demo room ~4, 3.7M ~11). Fewer than 2 points per cell
// (the demo room's 5 cm cells) or per non-empty sub-cell (ScanNet's) count as sparse.
// True (grow by sub-cells) with half_of (each slot's sub-cell in its cell) and sub_first's
// counts filled; false leaves both empty.
bool CountSubCells(const VoxelIndex& grid, bool allowed, std::vector<uint8_t>& half_of,
                   std::vector<uint32_t>& sub_first) {
  const size_t n = grid.x.size();
  const int cells = grid.NumCells();
  if (!allowed || n < 2 * size_t(cells)) return false;
  const Eigen::Vector3f lo = grid.Origin();
  const float inv_half = 2.f / grid.cell;
  sub_first.assign(size_t(cells) + 1, 0);
  half_of.resize(n);
  tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
    for (int c = range.begin(); c != range.end(); ++c) {
      const Eigen::Vector3i cc = grid.CellCoords(c);
      auto half = [&](float p, float l, int a) { return std::clamp(int((p - l) * inv_half) - 2 * cc[a], 0, 1); };
      unsigned used = 0;
      for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
        const int h = half(grid.x[s], lo.x(), 0) + 2 * half(grid.y[s], lo.y(), 1) + 4 * half(grid.z[s], lo.z(), 2);
        half_of[s] = uint8_t(h);
        used |= 1u << h;
      }
      sub_first[size_t(c) + 1] = uint32_t(__builtin_popcount(used));
    }
  });
  for (int c = 0; c < cells; ++c) sub_first[size_t(c) + 1] += sub_first[size_t(c)];
  if (n >= 2 * size_t(sub_first[size_t(cells)])) return true;
  half_of.clear();
  sub_first.clear();
  return false;
}

// Every slot's neighbours within sqrt(delta2) in `grid` (itself excluded), by slot: slot s's
// are nb[start[s], start[s + 1]), in neighbour-cell then slot order. Built in chunks of cells
// (contiguous slots) in parallel. Not built (false) when the candidate pairs, each point times
// the points of its 27 cells, exceed max_per_point per point.
struct NeighbourLists {
  std::vector<uint32_t> start, nb;
};
bool BuildNeighbourLists(const VoxelIndex& grid, float delta2, int max_per_point, NeighbourLists& out) {
  const int cells = grid.NumCells();
  const size_t n = grid.x.size();
  if (max_per_point <= 0 || n == 0) return false;
  auto count_of = [&](int c) { return int64_t(grid.cell_start[c + 1] - grid.cell_start[c]); };
  const int64_t pairs = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, cells, 1024), int64_t(0),
      [&](const tbb::blocked_range<int>& range, int64_t acc) {
        for (int c = range.begin(); c != range.end(); ++c) {
          int64_t around = 0;
          for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k) around += count_of(grid.nb[k]);
          acc += count_of(c) * around;
        }
        return acc;
      },
      std::plus<int64_t>());
  if (pairs > int64_t(max_per_point) * int64_t(n)) return false;
  constexpr int kChunk = 512;
  const int chunks = (cells + kChunk - 1) / kChunk;
  std::vector<std::vector<uint32_t>> lists(static_cast<size_t>(chunks));
  out.start.assign(n + 1, 0);
  const bool avx2 = simd::UseAvx2();
  tbb::parallel_for(tbb::blocked_range<int>(0, chunks, 1), [&](const tbb::blocked_range<int>& range) {
    std::vector<int> run_b, run_e;
    for (int ch = range.begin(); ch != range.end(); ++ch) {
      auto& list = lists[size_t(ch)];
      size_t used = 0;
      for (int c = ch * kChunk; c < std::min(cells, (ch + 1) * kChunk); ++c) {
        // The 27 cells as up to 9 runs of contiguous slots.
        const int cands = grid.NeighbourSlotRuns(c, run_b, run_e);
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
          const size_t room = used + size_t(cands) + simd::kAppendSlack;
          if (list.size() < room) list.resize(std::max(2 * list.size(), room));
          uint32_t* w = list.data() + used;
          int cnt = 0;
          const float px = grid.x[s], py = grid.y[s], pz = grid.z[s];
          for (size_t r = 0; r < run_b.size(); ++r)
            cnt = simd::AppendSlotsWithin(avx2, grid.x.data(), grid.y.data(), grid.z.data(), run_b[r], run_e[r], px, py,
                                          pz, delta2, s, w, cnt);
          used += size_t(cnt);
          out.start[size_t(s) + 1] = uint32_t(cnt);
        }
      }
      list.resize(used);
    }
  });
  for (size_t s = 0; s < n; ++s) out.start[s + 1] += out.start[s];
  out.nb.resize(out.start[n]);
  tbb::parallel_for(tbb::blocked_range<int>(0, chunks, 1), [&](const tbb::blocked_range<int>& range) {
    for (int ch = range.begin(); ch != range.end(); ++ch) {
      const auto& list = lists[size_t(ch)];
      std::copy(list.begin(), list.end(), out.nb.begin() + out.start[size_t(grid.cell_start[ch * kChunk])]);
    }
  });
  return true;
}

}  // namespace

void RegionGrowingOptions::Check() const {
  if (!(normal_radius_m > 0)) throw StageError("normal_radius_m must be > 0");
  if (!(distance_m > 0)) throw StageError("distance_m must be > 0");
  if (!(angle_deg >= 0 && angle_deg <= 180)) throw StageError("angle_deg must be in [0, 180]");
  if (min_points < 1) throw StageError("min_points must be >= 1");
  if (min_fit_points < 3) throw StageError("min_fit_points must be >= 3");
  if (max_normal_points < 0) throw StageError("max_normal_points must be >= 0 (0: always exact)");
  if (max_list_candidates < 0) throw StageError("max_list_candidates must be >= 0 (0: never list)");
}

Segmentation Segment(const Scan& scan, const RegionGrowingOptions& o, SegmentTimings* timings) {
  o.Check();
  Stopwatch watch;
  const LocalCloud lc = ToLocal(scan.points);
  const size_t n = lc.pts.size();
  Points normals_local;
  std::vector<float> curv_local;
  // The growing runs on a grid with cells of delta, so a point's candidates are the slices of
  // its 27 neighbour cells. Built beside the normals: it needs only the points.
  const float delta = float(o.distance_m);
  const float delta2 = delta * delta;
  VoxelIndex grid;
  // Dense scans grow by sub-cells (CountSubCells), sparse ones from neighbour lists when they
  // are affordable, else point by point over the cells.
  bool by_sub = false, listed = false;
  std::vector<uint8_t> half_of;
  std::vector<uint32_t> sub_first;
  NeighbourLists lists;
  tbb::parallel_invoke([&] { NormalsLocal(lc, LocalViewpoint(lc, scan.origin), o, normals_local, curv_local); },
                       [&] {
                         grid.Build(lc.pts, delta, VoxelIndex::Anchor::kBoundingBox, TbbFor());
                         by_sub = CountSubCells(grid, o.growth_by_sub_cells, half_of, sub_first);
                       });
  // The growth's neighbour lists need only its grid; the normals in scan order, the normals by
  // slot and the seed order need only the normals: side by side.
  Segmentation seg;
  std::vector<float> nx, ny, nz;
  std::vector<uint32_t> seeds;
  tbb::parallel_invoke(
      [&] {
        if (!by_sub) listed = BuildNeighbourLists(grid, delta2, o.max_list_candidates, lists);
      },
      [&] {
        seg.normals.assign(scan.points.size(), Eigen::Vector3f::Constant(kNaN));
        seg.curvature.assign(scan.points.size(), kNaN);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16384), [&](const tbb::blocked_range<size_t>& r) {
          for (size_t k = r.begin(); k != r.end(); ++k) {
            seg.normals[lc.input[k]] = normals_local[k];
            seg.curvature[lc.input[k]] = curv_local[k];
          }
        });
        nx.resize(n), ny.resize(n), nz.resize(n);
        std::vector<uint64_t> seed_key(n);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16384), [&](const tbb::blocked_range<size_t>& r) {
          for (size_t s = r.begin(); s != r.end(); ++s) {
            const uint32_t i = grid.order[s];
            nx[s] = normals_local[i].x();
            ny[s] = normals_local[i].y();
            nz[s] = normals_local[i].z();
            // Non-negative floats order like their bit patterns; NaN curvature seeds last.
            const float c = curv_local[i];
            uint32_t bits = 0xffffffffu;
            if (std::isfinite(c)) {
              const float cc = std::max(0.f, c);
              std::memcpy(&bits, &cc, 4);
            }
            seed_key[s] = bits;
          }
        });
        // Seeds by increasing curvature; ties keep slot order, so deterministic.
        seeds = SortedByKey(seed_key, 32, TbbFor());
      });
  const double normals_ms = watch.Ms();
  seg.discarded_points = int(scan.points.size() - n);  // non-finite points never join a part
  if (n == 0) return seg;

  const float cos_a = float(std::cos(o.angle_deg * M_PI / 180.0));
  const bool signed_normals = o.signed_normals;
  std::vector<int> label(n, -1);
  const int cells = grid.NumCells();

  // Sub-cells: each cell of delta split into 2 x 2 x 2 cubes of edge delta / 2, so that any two
  // points of one sub-cell lie within 0.87 delta of each other. A region is the connected
  // component, under "within delta", of the seed and the points its normal admits (admission
  // depends on the point and the seed only), so the admitted free points of a sub-cell join a
  // region together, and the growth walks sub-cells: a sub-cell joins when one of its admitted
  // free points lies within delta of a member of a joined neighbour. The same parts as growing
  // point by point; a dense scan costs a walk over its sub-cells instead of a scan of every
  // member's neighbourhood (3.7M-point room: growing 2.5 s -> see the commit).
  if (!by_sub) {
    sub_first.resize(size_t(cells) + 1);
    for (int c = 0; c <= cells; ++c) sub_first[size_t(c)] = uint32_t(c);
  }
  const size_t subs = sub_first[size_t(cells)];
  std::vector<uint32_t> sub_of(by_sub ? n : 0), sub_start(subs);
  std::vector<float> sub_box(by_sub ? subs * 6 : 0);
  if (by_sub) {
    tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
      for (int c = range.begin(); c != range.end(); ++c) {
        int count[8] = {0, 0, 0, 0, 0, 0, 0, 0}, id[8];
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) ++count[half_of[s]];
        uint32_t k = sub_first[size_t(c)], at = uint32_t(grid.cell_start[c]);
        for (int h = 0; h < 8; ++h) {
          id[h] = count[h] ? int(k) : -1;
          if (!count[h]) continue;
          sub_start[k] = at;
          EmptyBox(&sub_box[size_t(k) * 6]);
          at += uint32_t(count[h]), ++k;
        }
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
          const uint32_t q = uint32_t(id[half_of[s]]);
          sub_of[s] = q;
          ExtendBox(&sub_box[size_t(q) * 6], grid.x[s], grid.y[s], grid.z[s]);
        }
      }
    });
    half_of.clear();
    half_of.shrink_to_fit();
  } else {
    for (int c = 0; c < cells; ++c) sub_start[size_t(c)] = uint32_t(grid.cell_start[c]);
  }
  auto sub_cell = [&](uint32_t s) { return by_sub ? size_t(sub_of[s]) : size_t(grid.cell_of[s]); };
  // Unlabelled slots of each sub-cell are kept at the front of its range of `free_slots`
  // (swap-remove on labelling), in slot order after a reset; free_in_cell counts a cell's.
  // (Not needed when growing from the lists.)
  std::vector<uint32_t> free_in_sub(listed ? 0 : subs), free_slots(listed ? 0 : n), pos(listed ? 0 : n);
  std::vector<int> free_in_cell(listed ? 0 : size_t(cells), 0);
  auto reset_free = [&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
      for (int c = range.begin(); c != range.end(); ++c) {
        const uint32_t k0 = sub_first[size_t(c)], k1 = sub_first[size_t(c) + 1];
        for (uint32_t k = k0; k < k1; ++k) free_in_sub[k] = 0;
        int free_here = 0;
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s)
          if (label[s] == -1) {
            const uint32_t k = uint32_t(sub_cell(uint32_t(s))), w = sub_start[k] + free_in_sub[k]++;
            free_slots[w] = uint32_t(s), pos[s] = w, ++free_here;
          }
        free_in_cell[c] = free_here;
        uint32_t used[8];
        for (uint32_t k = k0; k < k1; ++k) used[k - k0] = free_in_sub[k];
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s)
          if (label[s] != -1) {
            const uint32_t k = uint32_t(sub_cell(uint32_t(s))), w = sub_start[k] + used[k - k0]++;
            free_slots[w] = uint32_t(s), pos[s] = w;
          }
      }
    });
  };
  auto take = [&](uint32_t q) {
    const size_t k = sub_cell(q);
    --free_in_cell[grid.cell_of[q]];
    const uint32_t last = sub_start[k] + --free_in_sub[k];
    const uint32_t moved = free_slots[last];
    free_slots[pos[q]] = moved;
    pos[moved] = pos[q];
    free_slots[last] = q;
    pos[q] = last;
  };
  if (!listed) reset_free();
  std::vector<uint32_t> members;  // slots of all parts, part after part
  std::vector<size_t> part_begin{0};
  members.reserve(n);

  // Cells' tight boxes: a neighbour cell at delta or farther from a joined sub-cell's members
  // holds none of their neighbours.
  const std::vector<float> box = listed ? std::vector<float>() : CellBoxes(grid);

  // Growth from `seed` over unlabelled slots accepted by `admit`, point by point (breadth
  // first; sparse scans).
  auto grow_points = [&](uint32_t seed, int id, auto&& admit) {
    const size_t begin = members.size();
    label[seed] = id;
    take(seed);
    members.push_back(seed);
    for (size_t head = begin; head < members.size(); ++head) {
      const uint32_t p = members[head];
      const float px = grid.x[p], py = grid.y[p], pz = grid.z[p];
      const int c = grid.cell_of[p];
      for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k) {
        const int nc = grid.nb[k];
        if (free_in_cell[nc] == 0 || Far(box, nc, Eigen::Vector3f(px, py, pz), delta2)) continue;
        const uint32_t kc = sub_first[size_t(nc)];  // the cell's one sub-cell
        for (uint32_t i = sub_start[kc]; i < sub_start[kc] + free_in_sub[kc];) {
          const uint32_t q = free_slots[i];
          const float dx = grid.x[q] - px, dy = grid.y[q] - py, dz = grid.z[q] - pz;
          if (dx * dx + dy * dy + dz * dz >= delta2 || !admit(q)) {
            ++i;
            continue;
          }
          label[q] = id;
          take(q);  // moves another free slot to position i: look at i again
          members.push_back(q);
        }
      }
    }
  };

  // Growth from `seed` over unlabelled slots accepted by `admit`, sub-cell by sub-cell.
  struct Joined {
    size_t begin, end;  // a sub-cell's members in `members`
    int cell;           // the cell it lies in
  };
  std::vector<Joined> joined;
  std::vector<int> joined_in(by_sub ? subs : 0, -1);  // the region a sub-cell last joined
  // The same from the neighbour lists (sparse scans): a member's free neighbours are read
  // from its list. The same parts: a part is the seed's connected component of admitted points.
  // (Raw pointers: through the vectors, each push_back would make the compiler reload them.)
  auto grow_listed = [&](uint32_t seed, int id, auto&& admit) {
    int* const lab = label.data();
    const uint32_t *const start = lists.start.data(), *const nbs = lists.nb.data();
    const size_t begin = members.size();
    lab[seed] = id;
    members.push_back(seed);
    for (size_t head = begin; head < members.size(); ++head) {
      const uint32_t p = members[head];
      for (uint32_t j = start[p], e = start[size_t(p) + 1]; j < e; ++j) {
        const uint32_t q = nbs[j];
        if (lab[q] != -1 || !admit(q)) continue;
        lab[q] = id;
        members.push_back(q);
      }
    }
  };
  auto grow = [&](uint32_t seed, int id, auto&& admit) {
    if (listed) return grow_listed(seed, id, admit);
    if (!by_sub) return grow_points(seed, id, admit);
    joined.clear();
    auto join = [&](size_t k, int cell, size_t mb) {
      joined_in[k] = id;
      for (uint32_t i = sub_start[k]; i < sub_start[k] + free_in_sub[k];) {
        const uint32_t q = free_slots[i];
        if (!admit(q)) {
          ++i;
          continue;
        }
        label[q] = id;
        take(q);  // moves another free slot to position i: look at i again
        members.push_back(q);
      }
      joined.push_back({mb, members.size(), cell});
    };
    const size_t begin = members.size();
    label[seed] = id;
    take(seed);
    members.push_back(seed);
    join(sub_cell(seed), grid.cell_of[seed], begin);
    for (size_t h = 0; h < joined.size(); ++h) {
      const Joined a = joined[h];
      float mbox[6];
      EmptyBox(mbox);
      for (size_t t = a.begin; t < a.end; ++t) ExtendBox(mbox, grid.x[members[t]], grid.y[members[t]], grid.z[members[t]]);
      const int c = a.cell;
      const bool one = a.end - a.begin == 1;  // sparse scans: most sub-cells hold one point
      for (int kk = grid.nb_start[c]; kk < grid.nb_start[c + 1]; ++kk) {
        const int nc = grid.nb[kk];
        if (free_in_cell[nc] == 0 || BoxGap2(mbox, &box[size_t(nc) * 6]) >= delta2) continue;
        for (size_t k = sub_first[size_t(nc)]; k < sub_first[size_t(nc) + 1]; ++k) {
          const uint32_t nf = free_in_sub[k];
          if (nf == 0 || joined_in[k] == id || (nf > 1 && BoxGap2(mbox, &sub_box[k * 6]) >= delta2)) continue;
          bool hit = false;
          for (uint32_t i = sub_start[k]; i < sub_start[k] + nf && !hit; ++i) {
            const uint32_t q = free_slots[i];
            if (!one) {
              const float qb[6] = {grid.x[q], grid.y[q], grid.z[q], grid.x[q], grid.y[q], grid.z[q]};
              if (BoxGap2(mbox, qb) >= delta2) continue;
            }
            if (!admit(q)) continue;
            for (size_t t = a.begin; t < a.end; ++t) {
              const uint32_t m = members[t];
              const float dx = grid.x[q] - grid.x[m], dy = grid.y[q] - grid.y[m], dz = grid.z[q] - grid.z[m];
              if (dx * dx + dy * dy + dz * dz < delta2) {
                hit = true;
                break;
              }
            }
          }
          if (hit) join(k, nc, members.size());
        }
      }
    }
  };

  // Pass 1: normal-based growing. A seed without a normal stays alone (and is regrouped).
  int parts = 0;
  for (uint32_t seed : seeds) {
    if (label[seed] != -1) continue;
    const float sx = nx[seed], sy = ny[seed], sz = nz[seed];
    const bool seed_ok = std::isfinite(sx);
    const float *const fx = nx.data(), *const fy = ny.data(), *const fz = nz.data();
    grow(seed, parts, [=](int q) {  // by value: kept in registers
      if (!seed_ok) return false;
      const float d = fx[q] * sx + fy[q] * sy + fz[q] * sz;  // NaN normals compare false
      return signed_normals ? d >= cos_a : std::fabs(d) >= cos_a;
    });
    part_begin.push_back(members.size());
    ++parts;
  }

  // Pass 2: parts below min_points are released and regrouped among themselves by distance.
  std::vector<uint32_t> pool;
  std::vector<std::pair<size_t, size_t>> kept;  // [begin, end) ranges into members
  for (int p = 0; p < parts; ++p) {
    const size_t b = part_begin[p], e = part_begin[p + 1];
    if (int(e - b) >= o.min_points) {
      kept.emplace_back(b, e);
      continue;
    }
    for (size_t k = b; k < e; ++k) pool.push_back(members[k]);
  }
  std::sort(pool.begin(), pool.end());
  // Pass 1 labelled every slot, so after this only the pool is unlabelled and the distance-only
  // growth below cannot reach into the kept parts.
  for (uint32_t s : pool) label[s] = -1;
  if (!listed) reset_free();
  int regrouped = 0, discarded = 0;
  std::vector<std::pair<size_t, size_t>> regroup_parts;
  for (uint32_t s : pool) {
    if (label[s] != -1) continue;
    const size_t b = members.size();
    grow(s, parts + int(regroup_parts.size()), [](int) { return true; });
    const size_t e = members.size();
    if (int(e - b) >= o.min_points) {
      regroup_parts.emplace_back(b, e);
      regrouped += int(e - b);
    } else {
      discarded += int(e - b);
    }
  }
  const double growing_ms = watch.Ms() - normals_ms;

  // A part's points in input order (so its centroid's sum does not depend on the growth's order).
  auto emit = [&](size_t b, size_t e, Part& part) {
    std::vector<uint32_t> local(e - b);
    for (size_t k = b; k < e; ++k) local[k - b] = grid.order[members[k]];
    std::sort(local.begin(), local.end());
    part.indices.reserve(e - b);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (uint32_t i : local) {
      part.indices.push_back(lc.input[i]);
      sum += lc.pts[i].cast<double>();
    }
    part.centroid = (sum / double(e - b) + lc.centre).cast<float>();
  };
  kept.insert(kept.end(), regroup_parts.begin(), regroup_parts.end());
  seg.parts.resize(kept.size());
  tbb::parallel_for(size_t(0), kept.size(), [&](size_t p) { emit(kept[p].first, kept[p].second, seg.parts[p]); });
  seg.discarded_points += discarded;
  if (discarded > 0 || pool.size() > 0)
    spdlog::info("region_growing: {} parts; {} points of parts below {} regrouped into {} parts, {} discarded",
                 seg.parts.size(), pool.size(), o.min_points, regroup_parts.size(), discarded);
  if (timings) {
    timings->normals_ms = normals_ms;
    timings->growing_ms = growing_ms;
    timings->growth = by_sub ? "sub-cells" : listed ? "lists" : "cells";
  }
  return seg;
}

}  // namespace furnihost::rg
