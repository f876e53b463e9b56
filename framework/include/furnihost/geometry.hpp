// Small geometry helpers shared by host and plugins.
#pragma once
#include <functional>

#include "furnihost/types.hpp"

namespace furnihost {

// Runs body(b, e) over disjoint sub-ranges covering [begin, end), in parallel or not (the host
// passes one over tbb::parallel_for: the SDK itself has no thread pool). What is computed with
// it must not depend on the partition.
using RangeFor = std::function<void(size_t begin, size_t end, const std::function<void(size_t, size_t)>& body)>;
// The RangeFor of one pass in the calling thread.
inline void SerialRange(size_t begin, size_t end, const std::function<void(size_t, size_t)>& body) {
  if (begin < end) body(begin, end);
}

// Voxel-grid downsampling: one point (the centroid, summed in double) per occupied cubic voxel
// of edge `voxel` metres. The grid is anchored at the frame's origin (voxel (i, j, k) covers
// [i, i+1) * voxel, ...), never at the cloud's own minimum, so two clouds in one frame (a
// training view of sensors.simulated_laser and a scan of sensors.scan_file) share voxels.
// Order follows the first point of each voxel, so results depend only on the input order.
// Also returns, if `kept` is given, for each output point the index of the first input point.
// voxel <= 0: the points unchanged.
FURNIHOST_API Points VoxelDownsample(const Points& points, float voxel, std::vector<int>* kept = nullptr);

// The distinct positions of `points` in order of first appearance (exact copies only: bit
// patterns compared, -0 equal to +0) and, in `of` when given, each point's index among them.
// An open-addressing hash table over the bits: linear time whatever the copies (a driver's
// (0, 0, 0) for every invalid return).
FURNIHOST_API Points GroupEqualPoints(const Points& points, std::vector<uint32_t>* of = nullptr);
// The points of each group from each point's group `of` (< groups): group u's are
// members[start[u] .. start[u + 1]), ascending (a counting sort; linear time).
FURNIHOST_API void GroupMembers(const std::vector<uint32_t>& of, size_t groups, std::vector<uint32_t>& start,
                                std::vector<uint32_t>& members);

// Coarse surface normals in linear time: the points' voxel-grid centroids (edge `voxel`), each
// with the normal (PCA, sign arbitrary) of the centroids in its 3x3x3 voxel neighbourhood, and
// whether that neighbourhood is flat (smallest eigenvalue < 5 % of the middle one, >= 5
// centroids). `voxel_of[i]` = the voxel of input point i. For ground and up-axis estimates,
// where a normal per 5 cm is plenty and no stage's segmentation exists yet.
struct VoxelNormals {
  Points centroids, normals;
  std::vector<uint8_t> flat;
  std::vector<int> voxel_of;
};
FURNIHOST_API VoxelNormals EstimateVoxelNormals(const Points& points, float voxel);
// The same, the per-voxel plane fits spread by `pfor`; bit-identical results.
FURNIHOST_API VoxelNormals EstimateVoxelNormals(const Points& points, float voxel, const RangeFor& pfor);

// Adds Gaussian noise of standard deviation `sigma` [m] to each coordinate of every finite
// point other than (0, 0, 0) (a driver's invalid return stays invalid; NaN stays NaN). Each
// point's noise comes from `seed` and its index alone (SplitMix64, Box-Muller): the same for a
// seed whatever the threads. `furnihost eval --jitter`: how far the figures move when the scan
// moves by far less than its sensor's noise.
// `axes`: the noise is drawn along its columns (noise n is added as axes * n), so a cloud given
// in another frame gets the same noise in the scene when `axes` maps that frame's axes there.
FURNIHOST_API void JitterPoints(Points& points, float sigma, uint64_t seed,
                                const Eigen::Matrix3f& axes = Eigen::Matrix3f::Identity());

// Isometry for an upright pose: translation (x, y, z), rotation yaw [rad] about +z.
FURNIHOST_API Eigen::Isometry3f UprightPose(float x, float y, float z, float yaw);

// Convex hull of 2D points (Andrew's monotone chain), counter-clockwise, without collinear
// points; fewer than 3 distinct points come back as they are (sorted, deduplicated).
FURNIHOST_API std::vector<Eigen::Vector2f> ConvexHull2D(std::vector<Eigen::Vector2f> points);

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
