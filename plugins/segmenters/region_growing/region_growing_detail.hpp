// segmenters.region_growing, private to the folder: what the normals (normals.cpp) and the
// growth (region_growing_core.cpp) share: the scan in a local frame, the cells' tight boxes and
// the normals of a local cloud.
#pragma once

#include <algorithm>
#include <cstddef>
#include <limits>
#include <optional>
#include <vector>

#include "furnihost/voxel_index.hpp"
#include "region_growing_core.hpp"

namespace furnihost::rg::detail {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
// Cells with more points than this are checked for copies of one point (NormalsLocal).
constexpr size_t kCopiesCheckedFrom = 32;
// Dense cells fit voxel centroids, voxel edge = normal radius / this: ~50 centroids in a planar
// ball (pi 4^2), ~2.5x fewer than the fewest points a dense cell's ball holds on average. The
// points of one such voxel share one fit.
constexpr int kCentroidVoxelsPerRadius = 4;

// The finite points of a scan shifted by the centre of their bounding box, computed in double:
// float coordinates of a scan in map coordinates (1e5 m) would leave ~8 mm of resolution for
// the squares accumulated below. Every later step works in this frame.
struct LocalCloud {
  Points pts;                 // finite points, local frame
  std::vector<int> input;     // input index of each local point
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
};

LocalCloud ToLocal(const Points& points);

// The viewpoint in the local frame of lc (its bounding-box centre when there is none).
Eigen::Vector3f LocalViewpoint(const LocalCloud& lc, const std::optional<Eigen::Vector3f>& viewpoint);

// Boxes as 6 floats (min x y z, max x y z): empty, grown by a point, and the squared gap
// between two (0 where they touch or overlap).
inline void EmptyBox(float* b) {
  b[0] = b[1] = b[2] = std::numeric_limits<float>::infinity();
  b[3] = b[4] = b[5] = -std::numeric_limits<float>::infinity();
}
inline void ExtendBox(float* b, float x, float y, float z) {
  b[0] = std::min(b[0], x), b[1] = std::min(b[1], y), b[2] = std::min(b[2], z);
  b[3] = std::max(b[3], x), b[4] = std::max(b[4], y), b[5] = std::max(b[5], z);
}
inline float BoxGap2(const float* a, const float* b) {
  const float dx = std::max(std::max(a[0] - b[3], b[0] - a[3]), 0.f);
  const float dy = std::max(std::max(a[1] - b[4], b[1] - a[4]), 0.f);
  const float dz = std::max(std::max(a[2] - b[5], b[2] - a[5]), 0.f);
  return dx * dx + dy * dy + dz * dz;
}

// Each cell's tight box (6 floats, as EmptyBox) of the points it holds.
std::vector<float> CellBoxes(const VoxelIndex& grid);

// True when cell c's tight box lies at squared distance >= d2 from p: none of its points is
// closer (in float too: per axis the box's gap is never above a point's, and rounding is
// monotonic).
// Called per point and neighbour cell in the normals and per member and neighbour cell in the
// growth: forced inline, branch-free (std::max over an initializer list stayed an out-of-line
// call, 2 % of a dense room's samples).
[[gnu::always_inline]] inline bool Far(const std::vector<float>& box, int c, const Eigen::Vector3f& p, float d2) {
  const float* b = &box[size_t(c) * 6];
  const float dx = std::max(std::max(b[0] - p.x(), 0.f), p.x() - b[3]);
  const float dy = std::max(std::max(b[1] - p.y(), 0.f), p.y() - b[4]);
  const float dz = std::max(std::max(b[2] - p.z(), 0.f), p.z() - b[5]);
  return dx * dx + dy * dy + dz * dz >= d2;
}

// Normals of `lc` (by local index) with the grid of cell = radius. Per cell, the candidates of
// its 27 neighbour cells are copied once into a contiguous buffer that every point of the cell
// then scans (a tight, vectorisable loop). Cells whose neighbourhood is dense (see
// RegionGrowingOptions::max_normal_points) scan the voxel centroids of those cells instead.
void NormalsLocal(const LocalCloud& lc, const Eigen::Vector3f& view_local, const RegionGrowingOptions& o,
                  Points& normals, std::vector<float>& curvature);

}  // namespace furnihost::rg::detail
