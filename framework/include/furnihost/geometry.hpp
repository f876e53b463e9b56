// Small geometry helpers shared by host and plugins.
#pragma once
#include "furnihost/types.hpp"

namespace furnihost {

// Voxel-grid downsampling: one point (the centroid, summed in double) per occupied cubic voxel
// of edge `voxel` metres. The grid is anchored at the frame's origin (voxel (i, j, k) covers
// [i, i+1) * voxel, ...), never at the cloud's own minimum, so two clouds in one frame (a
// training view of sensors.simulated_laser and a scan of sensors.scan_file) share voxels.
// Order follows the first point of each voxel, so results depend only on the input order.
// Also returns, if `kept` is given, for each output point the index of the first input point.
// voxel <= 0: the points unchanged.
FURNIHOST_API Points VoxelDownsample(const Points& points, float voxel, std::vector<int>* kept = nullptr);

// Isometry for an upright pose: translation (x, y, z), rotation yaw [rad] about +z.
FURNIHOST_API Eigen::Isometry3f UprightPose(float x, float y, float z, float yaw);

// World z of the floor under the scans (each mapped by its pose): the mean height of the
// densest 2 cm slice among the lowest 30 % of the points (a floor is the largest horizontal
// surface at the bottom of a room). 0 when there are no finite points. At most ~200k points
// per scan are looked at.
FURNIHOST_API float EstimateFloorZ(const std::vector<const Scan*>& scans);

}  // namespace furnihost

namespace furnihost {
// Area-weighted uniform sampling of a mesh surface: about `per_m2` points per square metre
// (at least one per triangle with area), deterministic for `seed`. Face normals to `normals`.
FURNIHOST_API Points SampleSurface(const Mesh& mesh, float per_m2, uint64_t seed, Points* normals = nullptr);
// A distinct, stable colour per class name (chair blue, table red, cabinet yellow, ...).
FURNIHOST_API std::array<uint8_t, 3> ClassColor(const std::string& cls);
}  // namespace furnihost
