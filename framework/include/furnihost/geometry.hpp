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

// World z of the floor under the scans (each mapped by its pose), assumed level: the mean
// height of the densest 2 cm slice among the lowest 30 % of the points (a floor is the largest
// horizontal surface at the bottom of a room). 0 when there are no finite points. At most
// ~200k points per scan are looked at.
FURNIHOST_API float EstimateFloorZ(const std::vector<const Scan*>& scans);

// A floor plane z = a x + b y + c in the world frame.
struct FloorPlane {
  float a = 0.f, b = 0.f, c = 0.f;
  float HeightAt(float x, float y) const { return a * x + b * y + c; }
  // Height of p above the plane, measured along z.
  float Above(const Eigen::Vector3f& p) const { return p.z() - HeightAt(p.x(), p.y()); }
};

// The floor under the scans as a plane tilted at most 10 degrees: reconstructions drift (a
// ScanNet dev room's floor spans 0.35 m of height; a level estimate there is 0.25 m off on
// average, this plane 6 mm). RANSAC (fixed seed, deterministic) over the lowest 30 % of the
// points for the plane with the most points within 2 cm, the level plane of EstimateFloorZ
// competing, then least squares over the points within 2 cm of it. z = 0 when there are no
// finite points.
FURNIHOST_API FloorPlane EstimateFloorPlane(const std::vector<const Scan*>& scans);

// The floor a stage's `floor` parameter names: "fixed" = level at `fixed_z`, "plane" =
// EstimateFloorPlane, anything else ("auto") = level at EstimateFloorZ.
FURNIHOST_API FloorPlane FloorByMode(const std::string& mode, const std::vector<const Scan*>& scans, float fixed_z);

}  // namespace furnihost

namespace furnihost {
// Area-weighted uniform sampling of a mesh surface: about `per_m2` points per square metre
// (at least one per triangle with area), deterministic for `seed`. Face normals to `normals`.
FURNIHOST_API Points SampleSurface(const Mesh& mesh, float per_m2, uint64_t seed, Points* normals = nullptr);
// The turns about the vertical axis through the origin (a catalog model's frame: bounding-box
// bottom centre) that map the mesh onto itself: 0 = every turn (round, sampled at 30 and 45
// degrees), 4 = quarter turns, 2 = half turns, 1 = none. "Onto itself": at least 95 % of
// ~6000 surface samples, turned, lie within `tolerance` [m] (cells of that edge, neighbours
// included) of the unturned samples. A chest whose handles stick out 1 cm is 2-fold at 2 cm;
// a bookcase (open front, closed back) or a chair is 1-fold. Deterministic.
FURNIHOST_API int YawSymmetry(const Mesh& mesh, float tolerance = 0.02f);
// A distinct, stable colour per class name (chair blue, table red, cabinet yellow, ...).
FURNIHOST_API std::array<uint8_t, 3> ClassColor(const std::string& cls);
}  // namespace furnihost
