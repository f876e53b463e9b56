// What segmenters.cgal_region_growing and segmenters.cgal_efficient_ransac share: the local
// frame, CGAL's normal estimation, the surface-variation curvature and the normal orientation.
// Header-only in furnihost::segmentation (it includes CGAL, which the framework headers must
// not, and each CGAL plugin stays one translation unit).
//
// Frames: LocalFrame holds the finite points of a scan shifted by the centre of their bounding
// box (computed in double), so map-coordinate scans keep their precision; every quantity below
// is in that frame. Units: metres.
#pragma once
#include <CGAL/jet_estimate_normals.h>
#include <CGAL/pca_estimate_normals.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "furnihost/types.hpp"
#include "furnihost/voxel_index.hpp"
#include "parallel/tbb_for.hpp"

namespace furnihost::cgal_common {

// M finite points of an N-point scan.
struct LocalFrame {
  std::vector<int> ids;                   // M: scan index of local point k
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();  // scan frame = local + shift
  std::vector<Eigen::Vector3d> points;    // M: local coordinates, double
  std::vector<Eigen::Vector3f> local;     // M: the same rounded to float (curvature, grids)
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();  // normals face it: the sensor when known, else the scan origin
};

inline LocalFrame MakeLocalFrame(const Scan& scan) {
  LocalFrame f;
  f.ids.reserve(scan.points.size());
  Eigen::AlignedBox3d box;
  for (size_t i = 0; i < scan.points.size(); ++i)
    if (scan.points[i].allFinite()) {
      f.ids.push_back(int(i));
      box.extend(scan.points[i].cast<double>());
    }
  if (f.ids.empty()) return f;
  f.shift = box.center();
  const size_t m = f.ids.size();
  f.points.resize(m);
  f.local.resize(m);
  for (size_t k = 0; k < m; ++k) {
    f.points[k] = scan.points[f.ids[k]].cast<double>() - f.shift;
    f.local[k] = f.points[k].cast<float>();
  }
  // Towards the sensor when known, else towards the scan frame's origin (as PCL does).
  f.eye = (scan.origin ? Eigen::Vector3d(scan.origin->cast<double>()) : Eigen::Vector3d(Eigen::Vector3d::Zero())) -
          f.shift;
  return f;
}

// CGAL's normals of `points` in a radius: "jet" (2nd-order jet = the paper's bivariate
// polynomial over the tangent plane, unweighted) or "pca". `cap` limits the neighbourhood
// (0 = none). Run inside the caller's task arena; unoriented, may be zero or NaN.
template <class Range, class PointMap, class NormalMap>
void EstimateNormals(Range& points, const std::string& method, double radius_m, unsigned cap) {
  const auto np = CGAL::parameters::point_map(PointMap()).normal_map(NormalMap()).neighbor_radius(radius_m);
  if (method == "jet")
    CGAL::jet_estimate_normals<CGAL::Parallel_if_available_tag>(points, cap, np.degree_fitting(2));
  else
    CGAL::pca_estimate_normals<CGAL::Parallel_if_available_tag>(points, cap, np);
}

// Calls f(t) for every slot t of `index` (built on `local`) whose point lies in the CLOSED ball
// |p - q| <= radius (radius <= index.cell) around q, the point in slot s; t = s included.
template <class F>
void ForEachInClosedBall(const VoxelIndex& index, const std::vector<Eigen::Vector3f>& local, int s, float radius,
                         F&& f) {
  const float r2 = radius * radius;
  const Eigen::Vector3f& q = local[index.order[s]];
  const int c = index.cell_of[s];
  for (int k = index.nb_start[c]; k < index.nb_start[c + 1]; ++k) {
    const int nc = index.nb[k];
    for (int t = index.cell_start[nc]; t < index.cell_start[nc + 1]; ++t)
      if ((local[index.order[t]] - q).squaredNorm() <= r2) f(t);
  }
}

// Surface variation lambda0 / (lambda0 + lambda1 + lambda2) of the closed radius
// neighbourhood (query included), the paper's curvature, of every local point: `curvature`
// (M) gets it and `enough` (M) 1 where the neighbourhood holds >= 3 points (curvature stays
// as given elsewhere). Centred two-pass covariance in double: the neighbourhood is small, the
// scan may not be. The sums visit the neighbour cells x-major (x, then y, then z) of a
// world-anchored grid, the points of a cell in index order: the order of the plugins' own
// grid before furnihost::VoxelIndex replaced it, so the curvature (and the seed order it
// decides) did not change by a bit.
inline void SurfaceVariation(const std::vector<Eigen::Vector3f>& local, float radius,
                             std::vector<float>& curvature, std::vector<char>& enough) {
  VoxelIndex index;
  index.Build(local, radius, VoxelIndex::Anchor::kWorld, TbbFor());
  const float r2 = radius * radius;
  tbb::parallel_for(tbb::blocked_range<int>(0, index.NumCells(), 64), [&](const tbb::blocked_range<int>& range) {
    std::vector<int> cells;
    for (int c = range.begin(); c != range.end(); ++c) {
      cells.assign(index.nb.begin() + index.nb_start[c], index.nb.begin() + index.nb_start[c + 1]);
      std::sort(cells.begin(), cells.end(), [&](int a, int b) {
        const Eigen::Vector3i ca = index.CellCoords(a), cb = index.CellCoords(b);
        return std::lexicographical_compare(ca.data(), ca.data() + 3, cb.data(), cb.data() + 3);
      });
      for (int s = index.cell_start[c]; s < index.cell_start[c + 1]; ++s) {
        const size_t k = index.order[s];
        const Eigen::Vector3f& q = local[k];
        auto each = [&](auto&& f) {
          for (int nc : cells)
            for (int t = index.cell_start[nc]; t < index.cell_start[nc + 1]; ++t) {
              const Eigen::Vector3f& p = local[index.order[t]];
              if ((p - q).squaredNorm() <= r2) f(p);
            }
        };
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        int cnt = 0;
        each([&](const Eigen::Vector3f& p) {
          mean += p.cast<double>();
          ++cnt;
        });
        if (cnt < 3) continue;
        mean /= cnt;
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        each([&](const Eigen::Vector3f& p) {
          const Eigen::Vector3d d = p.cast<double>() - mean;
          cov.noalias() += d * d.transpose();
        });
        const Eigen::Vector3d ev =
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov, Eigen::EigenvaluesOnly).eigenvalues();
        const double tr = ev.sum();
        curvature[k] = tr > 0 ? float(std::max(0.0, ev[0]) / tr) : 0.f;
        enough[k] = 1;
      }
    }
  });
}

// The unit normal of a CGAL estimate (nx, ny, nz) at local point `p`, flipped to face `eye`.
// False for a degenerate estimate (zero or non-finite): the caller gives CGAL a valid vector
// and reports NaN.
inline bool OrientedUnitNormal(double nx, double ny, double nz, const Eigen::Vector3d& p, const Eigen::Vector3d& eye,
                               Eigen::Vector3d& out) {
  Eigen::Vector3d v(nx, ny, nz);
  const double len = v.norm();
  if (!(len > 0) || !v.allFinite()) return false;
  v /= len;
  if (v.dot(eye - p) < 0) v = -v;
  out = v;
  return true;
}

}  // namespace furnihost::cgal_common
