// The paper's segmenter (Sect. III) as plain functions, so the plugin, its tests and the
// benchmark call the same code: MLS normals from a 2nd-order height function, then region
// growing against the seed normal, then distance-only regrouping of the small parts.
#pragma once
#include <optional>

#include "furnihost/types.hpp"

namespace furnihost::rg {

struct RegionGrowingOptions {
  double normal_radius_m = 0.03;  // neighbourhood of the height-function fit [m] (paper: 3 cm)
  double distance_m = 0.05;       // delta: a point joins a part within this of one of its points [m] (paper: 5 cm)
  double angle_deg = 40.0;        // alpha: max angle between a point's and the seed's normal [deg] (paper: 40)
  int min_points = 10;            // smaller parts are regrouped by distance, then discarded (paper: 10)
  int min_fit_points = 6;         // fewer neighbours (query included) than this: PCA normal, no polynomial
  // Density-adaptive normals: where the radius ball would hold more than about this many
  // points, a point's normal is fitted to the centroids of a voxel grid of edge
  // normal_radius_m / 4 (about 50 in a planar ball, each weighted by its number of points)
  // instead of to every point of its ball, so the cost per point stops growing with the
  // density. Decided per cell of the normal grid (edge normal_radius_m): adaptive when its
  // 3x3x3 cells hold more than 4 K points (a planar ball holds about a third of them).
  // 0: always exact. The default keeps every cloud up to the density of configs/paper.json's
  // training views (0.25 deg at 2 m: up to 1413 points in 3x3x3 cells of 8 cm) exact, so its
  // model and detections do not change; a lower limit is faster on dense rooms but switches on
  // in those views (benchmarks/speed measures it).
  int max_normal_points = 400;
  // false: a normal and its opposite count as parallel (|cos|), robust when no sensor origin
  // gives the normals a consistent sign (e.g. ScanNet meshes). true: signed angle.
  bool signed_normals = false;
  // Dense scans (at least 2 points per non-empty sub-cell of edge distance_m / 2) grow sub-cell
  // by sub-cell: any two points of a sub-cell are within distance_m, so its admitted points
  // join together. The same parts as growing point by point (false), in time about linear in
  // the points whatever the density.
  bool growth_by_sub_cells = true;
  // Sparse scans (grown point by point) first list every point's neighbours within distance_m,
  // in parallel after the normals, so the serial growth reads a member's list instead of
  // scanning its 27 cells: the same parts. Only while the candidate pairs (points times the
  // points of their 27 cells) stay within this many per point, so a clump of copies cannot make
  // the lists quadratic; beyond it, or at 0, the growth scans the cells.
  int max_list_candidates = 96;
  void Check() const;  // throws StageError naming the bad field
};

// Per-point normals (unit, scan frame) and curvature lambda0 / (lambda0 + lambda1 + lambda2).
// NaN where the radius neighbourhood holds fewer than 3 points (query included) or the point
// is not finite. Normals point towards `viewpoint` (scan frame) when given, otherwise towards
// the centre of the scan's bounding box (a room seen from inside; the sign is only a
// convention then and unreliable on thin parts, which is why the growing uses |cos| by
// default). The accuracy of the order-2 fit: exact on noise-free planes, < 1 deg on a
// 0.5 m sphere at 1 cm spacing; with 1 mm noise ~1 deg inside a surface but up to ~25 deg in
// corners, where the quadratic extrapolates from a one-sided neighbourhood.
// Dense neighbourhoods (see max_normal_points) fit the voxel centroids instead, each weighted
// by its number of points (as that many points at the centroid), once per voxel: the fit is
// centred on the voxel's centroid and each point of the voxel takes the normal of the fitted
// height function at its own position, so a dense scan costs one fit per voxel, not per point
// (3.7 M points of a 0.09 deg room: 3.2 M in dense cells, ~0.5 M voxels). A voxel whose
// centroid ball holds fewer than 3 centroids (a clump smaller than two voxels) is fitted to
// every point of its ball.
struct NormalResult {
  Points normals;
  std::vector<float> curvature;
};
NormalResult EstimateNormals(const Points& points, const std::optional<Eigen::Vector3f>& viewpoint,
                             const RegionGrowingOptions& o);

// Wall-clock timings of one Segment call [ms], for the benchmark and debug logs. normals_ms
// includes the growing's grid, built concurrently with the normals, and the neighbour lists,
// built concurrently with the seed order; growing_ms is the growth itself.
struct SegmentTimings {
  double normals_ms = 0, growing_ms = 0;
  const char* growth = "";  // how the parts grew: "sub-cells" (dense), "lists" or "cells" (sparse)
};

// Full segmentation. A point joins a part when it lies within distance_m of one of the part's
// points and its normal is within angle_deg of the part's SEED normal (|cos| unless
// signed_normals). Seeds are the unlabelled points of lowest curvature (NaN last; ties in a
// fixed spatial order, so results do not depend on threads). Parts below min_points are
// released and regrouped among themselves by distance alone; groups still below min_points
// are discarded (counted in discarded_points with the non-finite points, and logged).
// Parts are ordered by creation (normal-grown first, regrouped after); indices inside a part
// are ascending.
Segmentation Segment(const Scan& scan, const RegionGrowingOptions& o, SegmentTimings* timings = nullptr);

namespace detail {
// The normals' 6x6 solves, here for their tests. SolveSpd6: Cholesky solve of A c = y, A
// symmetric positive definite (its upper triangle read); false when a pivot is not clearly
// positive. SolveSpd6Pair: two systems at once, each lane's c and ok[l] bit for bit SolveSpd6's.
bool SolveSpd6(const double A[6][6], const double y[6], double c[6]);
void SolveSpd6Pair(const double (*A0)[6], const double* y0, const double (*A1)[6], const double* y1, double c0[6],
                   double c1[6], bool ok[2]);
}  // namespace detail

}  // namespace furnihost::rg
