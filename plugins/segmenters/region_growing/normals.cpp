// segmenters.region_growing: the normals (MLS: a 2nd-order height function fitted per point,
// local_fit.hpp), exact or on voxel centroids where the neighbourhood is dense.
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
#include "local_fit.hpp"
#include "region_growing_detail.hpp"

namespace furnihost::rg {

namespace detail {

// Solves the symmetric positive definite 6x6 system A c = y (upper triangle of A given) by
// Cholesky. False when a pivot is not clearly positive (a degenerate neighbourhood).
bool SolveSpd6(const double A[6][6], const double y[6], double c[6]) {
  double L[6][6], inv[6];  // L lower triangular, inv[j] = 1 / L[j][j]
  const double scale = std::max({A[0][0], A[1][1], A[2][2], A[3][3], A[4][4], A[5][5]});
  for (int j = 0; j < 6; ++j) {
    double d = A[j][j];
    for (int k = 0; k < j; ++k) d -= L[j][k] * L[j][k];
    if (!(d > 1e-10 * scale)) return false;
    inv[j] = 1.0 / std::sqrt(d);
    for (int i = j + 1; i < 6; ++i) {
      double v = A[j][i];
      for (int k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
      L[i][j] = v * inv[j];
    }
  }
  double t[6];
  for (int i = 0; i < 6; ++i) {
    double v = y[i];
    for (int k = 0; k < i; ++k) v -= L[i][k] * t[k];
    t[i] = v * inv[i];
  }
  for (int i = 5; i >= 0; --i) {
    double v = t[i];
    for (int k = i + 1; k < 6; ++k) v -= L[k][i] * c[k];
    c[i] = v * inv[i];
  }
  return true;
}

// Two systems at once, system l in lane l: SolveSpd6's operations lane by lane. IEEE addition,
// multiplication, division and square root are correctly rounded, so each lane's c is
// SolveSpd6's bit for bit (RegionGrowing.PairedSolvesAreTheSingleSolves); the two dependency
// chains run side by side (one solve is a chain of 6 square roots and divisions: latency, not
// work). ok[l]: SolveSpd6's answer for system l; a failed lane runs on with NaNs and its c is
// not to be read.
void SolveSpd6Pair(const double (*A0)[6], const double* y0, const double (*A1)[6], const double* y1, double c0[6],
                   double c1[6], bool ok[2]) {
  D2 L[6][6], inv[6];
  const double s0 = std::max({A0[0][0], A0[1][1], A0[2][2], A0[3][3], A0[4][4], A0[5][5]});
  const double s1 = std::max({A1[0][0], A1[1][1], A1[2][2], A1[3][3], A1[4][4], A1[5][5]});
  const double lim0 = 1e-10 * s0, lim1 = 1e-10 * s1;
  ok[0] = ok[1] = true;
  for (int j = 0; j < 6; ++j) {
    D2 d = D2{A0[j][j], A1[j][j]};
    for (int k = 0; k < j; ++k) d -= L[j][k] * L[j][k];
    ok[0] = ok[0] && d[0] > lim0;
    ok[1] = ok[1] && d[1] > lim1;
    inv[j] = D2{1.0, 1.0} / Sqrt2(d);
    for (int i = j + 1; i < 6; ++i) {
      D2 v = D2{A0[j][i], A1[j][i]};
      for (int k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
      L[i][j] = v * inv[j];
    }
  }
  D2 t[6], c[6];
  for (int i = 0; i < 6; ++i) {
    D2 v = D2{y0[i], y1[i]};
    for (int k = 0; k < i; ++k) v -= L[i][k] * t[k];
    t[i] = v * inv[i];
  }
  for (int i = 5; i >= 0; --i) {
    D2 v = t[i];
    for (int k = i + 1; k < 6; ++k) v -= L[k][i] * c[k];
    c[i] = v * inv[i];
  }
  for (int i = 0; i < 6; ++i) c0[i] = c[i][0], c1[i] = c[i][1];
}

// The finite points of a scan shifted by the centre of their bounding box, computed in double:
// float coordinates of a scan in map coordinates (1e5 m) would leave ~8 mm of resolution for
// the squares accumulated below. Every later step works in this frame.
LocalCloud ToLocal(const Points& points) {
  LocalCloud lc;
  Eigen::AlignedBox3d box;
  for (const auto& p : points)
    if (p.allFinite()) box.extend(p.cast<double>());
  if (box.isEmpty()) return lc;
  lc.centre = box.center();
  lc.pts.reserve(points.size());
  lc.input.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) {
      lc.pts.push_back((points[i].cast<double>() - lc.centre).cast<float>());
      lc.input.push_back(int(i));
    }
  return lc;
}

Eigen::Vector3f LocalViewpoint(const LocalCloud& lc, const std::optional<Eigen::Vector3f>& viewpoint) {
  if (viewpoint && viewpoint->allFinite()) return (viewpoint->cast<double>() - lc.centre).cast<float>();
  return Eigen::Vector3f::Zero();  // the bounding-box centre
}

// The centroids of the voxels of edge grid.cell / q inside cell c of `grid` (voxels aligned
// with the cell: the grid is anchored at the points' minimum corner `lo`), one per non-empty
// voxel, in voxel order, with its number of points as w. A centroid lies inside its cell, so the centroids within the radius
// of any point of a cell are among those of the cell's 27 neighbour cells.
struct CentroidScratch {
  std::vector<int> count;
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> used;
};
void CellCentroids(const VoxelIndex& grid, int c, const Eigen::Vector3f& lo, int q, CentroidScratch& w,
                   std::vector<Eigen::Vector4f>& out) {
  const int q3 = q * q * q;
  if (int(w.count.size()) < q3) w.count.assign(size_t(q3), 0), w.sum.assign(size_t(q3), Eigen::Vector3d::Zero());
  w.used.clear();
  const Eigen::Vector3i cc = grid.CellCoords(c);
  const float inv_v = float(q) / grid.cell;
  auto sub = [&](float p, float l, int a) { return std::clamp(int((p - l) * inv_v) - q * cc[a], 0, q - 1); };
  for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
    const int key = sub(grid.x[s], lo.x(), 0) + q * (sub(grid.y[s], lo.y(), 1) + q * sub(grid.z[s], lo.z(), 2));
    if (w.count[key]++ == 0) w.used.push_back(key);
    w.sum[key] += Eigen::Vector3d(grid.x[s], grid.y[s], grid.z[s]);
  }
  std::sort(w.used.begin(), w.used.end());
  out.clear();
  for (int key : w.used) {
    const Eigen::Vector3f centroid = (w.sum[key] / double(w.count[key])).cast<float>();
    out.emplace_back(centroid.x(), centroid.y(), centroid.z(), float(w.count[key]));
    w.count[key] = 0;
    w.sum[key].setZero();
  }
}

// The tight box of each cell's points, 6 floats per cell (min x y z, max x y z).
std::vector<float> CellBoxes(const VoxelIndex& grid) {
  const int cells = grid.NumCells();
  std::vector<float> box(size_t(cells) * 6);
  tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
    for (int c = range.begin(); c != range.end(); ++c) {
      float* b = &box[size_t(c) * 6];
      EmptyBox(b);
      for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) ExtendBox(b, grid.x[s], grid.y[s], grid.z[s]);
    }
  });
  return box;
}

// Normals of `lc` (by local index) with the grid of cell = radius. Per cell, the candidates of
// its 27 neighbour cells are copied once into a contiguous buffer that every point of the cell
// then scans (a tight, vectorisable loop). Cells whose neighbourhood is dense (see
// RegionGrowingOptions::max_normal_points) scan the voxel centroids of those cells instead.
void NormalsLocal(const LocalCloud& lc, const Eigen::Vector3f& view_local, const RegionGrowingOptions& o,
                  Points& normals, std::vector<float>& curvature) {
  const size_t n = lc.pts.size();
  normals.assign(n, Eigen::Vector3f::Constant(kNaN));
  curvature.assign(n, kNaN);
  if (n == 0) return;
  const float r = float(o.normal_radius_m);
  const float inv_r = 1.f / r;
  VoxelIndex grid;
  grid.Build(lc.pts, r, VoxelIndex::Anchor::kBoundingBox, TbbFor());
  const int cells = grid.NumCells();

  // Dense cells and the voxel centroids of every cell next to one.
  const int K = o.max_normal_points;
  const int q = kCentroidVoxelsPerRadius;
  const Eigen::Vector3f lo = grid.Origin();
  std::vector<char> dense(size_t(cells), 0);
  std::vector<std::vector<Eigen::Vector4f>> centroids;
  if (K > 0) {
    const int64_t dense_above = 4 * int64_t(K);
    tbb::parallel_for(tbb::blocked_range<int>(0, cells, 256), [&](const tbb::blocked_range<int>& range) {
      for (int c = range.begin(); c != range.end(); ++c) {
        int64_t m = 0;
        for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k)
          m += grid.cell_start[grid.nb[k] + 1] - grid.cell_start[grid.nb[k]];
        dense[c] = m > dense_above;
      }
    });
    size_t dense_points = 0;
    for (int c = 0; c < cells; ++c)
      if (dense[c]) dense_points += size_t(grid.cell_start[c + 1] - grid.cell_start[c]);
    if (dense_points > 0)
      spdlog::debug("region_growing: {} of {} points in cells denser than {} points per 3x3x3 cells: normals from "
                    "voxel centroids (voxel {:.4f} m)",
                    dense_points, n, dense_above, r / float(q));
    if (dense_points > 0) {
      centroids.resize(size_t(cells));
      tbb::parallel_for(tbb::blocked_range<int>(0, cells, 64), [&](const tbb::blocked_range<int>& range) {
        CentroidScratch w;
        for (int c = range.begin(); c != range.end(); ++c) {
          bool near_dense = false;  // the neighbour relation is symmetric
          for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1] && !near_dense; ++k) near_dense = dense[grid.nb[k]];
          if (near_dense) CellCentroids(grid, c, lo, q, w, centroids[c]);
        }
      });
    }
  }

  const std::vector<float> cell_box = CellBoxes(grid);
  const float r2 = r * r;
  const bool avx2 = simd::UseAvx2();
  tbb::parallel_for(tbb::blocked_range<int>(0, cells, 16), [&](const tbb::blocked_range<int>& range) {
    Neighbours nb;
    std::vector<float> cx, cy, cz, cw;
    std::vector<int> slots, key, start, members, pending, run_first, run_last, run_b, run_e;
    std::vector<float> run_box;  // tight box of each run's points (6 floats)
    std::vector<Eigen::Vector3f> query;
    // Neighbours of p among the m candidates (cx, cy, cz) into nb, scaled by 1/r; with
    // kCentroids also their point counts cw.
    auto collect = [&](auto centroids_tag, const Eigen::Vector3f& p) {
      constexpr bool kCentroids = decltype(centroids_tag)::value;
      const float px = p.x(), py = p.y(), pz = p.z();
      const int m = int(cx.size());
      // Branch-free compaction: every candidate is written, only hits advance the cursor.
      nb.reserve(m);
      int cnt = 0;
      float *nx = nb.x.data(), *ny = nb.y.data(), *nz = nb.z.data(), *nd = nb.d2.data(), *nm = nb.mult.data();
      for (int j = 0; j < m; ++j) {
        const float dx = (cx[j] - px) * inv_r, dy = (cy[j] - py) * inv_r, dz = (cz[j] - pz) * inv_r;
        const float d2 = dx * dx + dy * dy + dz * dz;
        nx[cnt] = dx, ny[cnt] = dy, nz[cnt] = dz, nd[cnt] = d2;
        if constexpr (kCentroids) nm[cnt] = cw[j];
        cnt += d2 < 1.f;
      }
      nb.count = cnt;
    };
    // Fits the neighbourhood in nb around query point qp and gives the slots [first, last) of
    // `list` the normal of that surface at their own positions (NormalAt; a slot at qp itself
    // gets the fit's normal at the query, as before voxels were shared).
    auto fit = [&](auto centroids_tag, const Eigen::Vector3f& qp, const int* first, const int* last) {
      LocalFit f;
      float curv;
      FitPoint<decltype(centroids_tag)::value>(avx2, nb, o.min_fit_points, f, curv);
      for (const int* it = first; it != last; ++it) {
        const int s = *it;
        const Eigen::Vector3f p(grid.x[s], grid.y[s], grid.z[s]);
        Eigen::Vector3f nrm = NormalAt(f, (p - qp) * inv_r);
        if (nrm.dot(view_local - p) < 0) nrm = -nrm;
        const uint32_t i = grid.order[s];
        normals[i] = nrm;
        curvature[i] = curv;
      }
    };
    // Exact fits in pairs: a point's neighbourhood waits (nbs) for the next point's, in this
    // cell or a later one of the range; then both are fitted together (FitSystemPair) and their
    // 6x6 systems solved together (SolveSpd6Pair). The same normals as FitPoint.
    Neighbours nbs[2];
    int queued = 0, queued_slot[2] = {0, 0};
    auto write = [&](const LocalFit& f, float curv, int s) {
      const Eigen::Vector3f p(grid.x[s], grid.y[s], grid.z[s]);
      Eigen::Vector3f nrm = NormalAt(f, Eigen::Vector3f::Zero());  // at the query itself
      if (nrm.dot(view_local - p) < 0) nrm = -nrm;
      const uint32_t i = grid.order[s];
      normals[i] = nrm;
      curvature[i] = curv;
    };
    auto flush = [&] {
      if (queued == 0) return;
      LocalFit f[2];
      float curv[2];
      NormalEquations eq[2];
      bool has[2] = {false, false};
      if (queued == 2) {
        Neighbours* both[2] = {&nbs[0], &nbs[1]};
        FitSystemPair(avx2, both, o.min_fit_points, f, curv, eq, has);
      } else {
        has[0] = FitSystem<false>(avx2, nbs[0], o.min_fit_points, f[0], curv[0], eq[0]);
      }
      if (has[0] && has[1]) {
        double c0[6], c1[6];
        bool ok[2];
        SolveSpd6Pair(eq[0].A, eq[0].y, eq[1].A, eq[1].y, c0, c1, ok);
        FitFinish(ok[0], c0, f[0]);
        FitFinish(ok[1], c1, f[1]);
      } else {
        for (int l = 0; l < queued; ++l)
          if (has[l]) {
            double c[6];
            const bool solved = SolveSpd6(eq[l].A, eq[l].y, c);
            FitFinish(solved, c, f[l]);
          }
      }
      for (int l = 0; l < queued; ++l) write(f[l], curv[l], queued_slot[l]);
      queued = 0;
    };
    // The exact normals of `slots` (points of cell c) from every point of their ball.
    auto exact = [&](int c) {
      // The 27 cells' points are read in place (a copy into one buffer cost more than it
      // saved), as runs of consecutive cells (neighbours along x are stored one after the other,
      // their slots contiguous): up to 9 loops instead of 27, each run with its tight box.
      grid.NeighbourRuns(c, run_first, run_last);
      const size_t runs = run_first.size();
      run_b.resize(runs), run_e.resize(runs), run_box.resize(runs * 6);
      int cands = 0;
      for (size_t k = 0; k < runs; ++k) {
        run_b[k] = grid.cell_start[run_first[k]], run_e[k] = grid.cell_start[run_last[k] + 1];
        cands += run_e[k] - run_b[k];
        float* rb = &run_box[k * 6];
        EmptyBox(rb);
        for (int nc = run_first[k]; nc <= run_last[k]; ++nc) {
          const float* cb = &cell_box[size_t(nc) * 6];
          for (int a = 0; a < 3; ++a) rb[a] = std::min(rb[a], cb[a]), rb[a + 3] = std::max(rb[a + 3], cb[a + 3]);
        }
      }
      // Copies of one point have the same neighbourhood, so one fit serves them all: without
      // this, N identical points (a (0, 0, 0) flood) cost N fits of N neighbours each. Only
      // cells that could hold many copies are sorted; a small cell costs at most its size
      // times its neighbourhood, which the neighbourhood's own points pay for.
      const bool copies = slots.size() > kCopiesCheckedFrom;
      if (copies)
        std::sort(slots.begin(), slots.end(), [&](int a, int b) {
          return std::make_tuple(grid.x[a], grid.y[a], grid.z[a], a) < std::make_tuple(grid.x[b], grid.y[b], grid.z[b], b);
        });
      for (size_t t = 0; t < slots.size(); ++t) {
        const int s = slots[t];
        const Eigen::Vector3f p(grid.x[s], grid.y[s], grid.z[s]);
        if (copies && t > 0) {
          const int prev = slots[t - 1];
          if (grid.x[prev] == p.x() && grid.y[prev] == p.y() && grid.z[prev] == p.z()) {
            flush();  // prev's normal
            normals[grid.order[s]] = normals[grid.order[prev]];
            curvature[grid.order[s]] = curvature[grid.order[prev]];
            continue;
          }
        }
        // The neighbours, skipping the runs whose tight box lies r or farther from p (they
        // hold none: the same neighbours in the same order as scanning all 27 cells).
        Neighbours& nq = nbs[queued];
        nq.reserve(cands);
        int cnt = 0;
        float *nx = nq.x.data(), *ny = nq.y.data(), *nz = nq.z.data(), *nd = nq.d2.data();
        const float *gx = grid.x.data(), *gy = grid.y.data(), *gz = grid.z.data();
        for (size_t k = 0; k < run_b.size(); ++k) {
          if (Far(run_box, int(k), p, r2)) continue;
          cnt = simd::AppendScaledWithin(avx2, gx, gy, gz, run_b[k], run_e[k], p.x(), p.y(), p.z(), inv_r, nx, ny, nz, nd,
                                         cnt);
        }
        nq.count = cnt;
        queued_slot[queued] = s;
        if (++queued == 2) flush();
      }
    };
    for (int c = range.begin(); c != range.end(); ++c) {
      if (!dense[c]) {
        slots.resize(size_t(grid.cell_start[c + 1] - grid.cell_start[c]));
        std::iota(slots.begin(), slots.end(), grid.cell_start[c]);
        exact(c);
        continue;
      }
      // A dense cell: its points by voxel (edge r / q; a counting sort, slot order within a
      // voxel) and each voxel's centroid (summed in slot order in double, as CellCentroids
      // does). The points of a voxel share one fit centred on its centroid, each taking the
      // normal of the fitted surface at its own position, so the fits are bounded by the
      // voxels, not the points: the cost per point stops growing with the density.
      const int b = grid.cell_start[c], e = grid.cell_start[c + 1];
      const Eigen::Vector3i cc = grid.CellCoords(c);
      const float inv_v = float(q) / grid.cell;
      auto sub = [&](float p, float l, int a) { return std::clamp(int((p - l) * inv_v) - q * cc[a], 0, q - 1); };
      const int q3 = q * q * q;
      key.resize(size_t(e - b));
      start.assign(size_t(q3 + 1), 0);
      for (int s = b; s < e; ++s) {
        key[s - b] = sub(grid.x[s], lo.x(), 0) + q * (sub(grid.y[s], lo.y(), 1) + q * sub(grid.z[s], lo.z(), 2));
        ++start[key[s - b] + 1];
      }
      for (int k = 0; k < q3; ++k) start[k + 1] += start[k];
      members.resize(size_t(e - b));
      pending.assign(start.begin(), start.end() - 1);  // write cursor per voxel
      for (int s = b; s < e; ++s) members[pending[key[s - b]]++] = s;
      int nv = 0;  // the non-empty voxels, renumbered
      for (int k = 0; k < q3; ++k)
        if (start[k + 1] > start[k]) start[nv++] = start[k];
      start.resize(size_t(nv) + 1);
      start[nv] = e - b;
      query.resize(size_t(nv));
      for (int v = 0; v < nv; ++v) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int t = start[v]; t < start[v + 1]; ++t)
          sum += Eigen::Vector3d(grid.x[members[t]], grid.y[members[t]], grid.z[members[t]]);
        query[size_t(v)] = (sum / double(start[v + 1] - start[v])).cast<float>();
      }
      // Voxel centroids of the 27 cells; a voxel with fewer than 3 of them in its ball (a clump,
      // e.g. copies of one point) is fitted to every point of its ball instead.
      cx.clear(), cy.clear(), cz.clear(), cw.clear();
      for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k)
        for (const auto& p : centroids[grid.nb[k]])
          cx.push_back(p.x()), cy.push_back(p.y()), cz.push_back(p.z()), cw.push_back(p.w());
      pending.clear();
      for (int v = 0; v < nv; ++v) {
        collect(std::true_type(), query[size_t(v)]);
        if (nb.count < 3)
          pending.push_back(v);
        else
          fit(std::true_type(), query[size_t(v)], members.data() + start[v], members.data() + start[v + 1]);
      }
      if (pending.empty()) continue;
      grid.GatherNeighbourhood(c, cx, cy, cz);
      for (int v : pending) {
        collect(std::false_type(), query[size_t(v)]);
        fit(std::false_type(), query[size_t(v)], members.data() + start[v], members.data() + start[v + 1]);
      }
    }
    flush();  // the last point's fit, if it waits for a pair
  });
}

}  // namespace detail

using detail::kNaN;
using detail::LocalCloud;
using detail::LocalViewpoint;
using detail::NormalsLocal;
using detail::ToLocal;

NormalResult EstimateNormals(const Points& points, const std::optional<Eigen::Vector3f>& viewpoint,
                             const RegionGrowingOptions& o) {
  o.Check();
  const LocalCloud lc = ToLocal(points);
  Points nl;
  std::vector<float> cl;
  NormalsLocal(lc, LocalViewpoint(lc, viewpoint), o, nl, cl);
  NormalResult res;
  res.normals.assign(points.size(), Eigen::Vector3f::Constant(kNaN));
  res.curvature.assign(points.size(), kNaN);
  for (size_t k = 0; k < lc.input.size(); ++k) {
    res.normals[lc.input[k]] = nl[k];
    res.curvature[lc.input[k]] = cl[k];
  }
  return res;
}

}  // namespace furnihost::rg
