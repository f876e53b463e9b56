// Per-scan occupancy grids (paper Sect. VI-C, [33]: free / occupied / unknown voxels) and the
// free-space test of a fitted model.
//
// Frame: the scan frame (Scan::points and Scan::origin as stored, metres).
#pragma once
#include <memory>

#include "furnihost/types.hpp"

namespace octomap {
class OcTree;
}

namespace furnihost::ransac_upright {

struct OccupancyOptions {
  double resolution = 0.05;  // voxel edge [m]
  double max_range = 0.0;    // [m]; rays longer than this only clear free space; 0 = unlimited
  void Check() const;
};

struct OccupancyStats {
  size_t rays = 0;           // distinct endpoint voxels traced (the discretised rays)
  size_t occupied = 0, free = 0;  // leaf voxels inserted
  double ms_keys = 0, ms_rays = 0, ms_insert = 0;
};

// Builds the grid of one scan seen from `origin`. Rays are discretised to one per distinct
// endpoint voxel and traced in parallel (TBB, in the caller's arena) outside OctoMap; OctoMap
// receives the leaves once, as its own binary tree stream with uniform octants pruned. A voxel hit by any point
// is occupied even if another ray passes through it (OctoMap's own rule for one scan).
std::shared_ptr<const octomap::OcTree> BuildOccupancy(const Points& points,
                                                      const Eigen::Vector3f& origin,
                                                      const OccupancyOptions& options,
                                                      OccupancyStats* stats = nullptr);

struct FreeSpaceOptions {
  // Model points farther than this behind the model's own front surface (seen from the
  // sensor) are self-occluded and not tested [m].
  float visibility_margin = 0.03f;
  // Each visible point is pushed this far away from the sensor before the look-up, so a model
  // surface that sits just in front of the measured one (fit error, voxelisation) is not
  // counted as free [m].
  float free_margin = 0.05f;
  float point_spacing = 0.01f;  // model point spacing [m]; sets the self-occlusion raster
  // 1: a point is in free space only when its voxel and the six face neighbours are free;
  // 0: its voxel alone decides.
  int erosion = 1;
};

struct FreeSpaceCount {
  int visible = 0;  // model points visible from the origin (not self-occluded)
  int free = 0;     // of those, in voxels known to be free
};

// `model_points` are already in the scan frame.
FreeSpaceCount CountFreeSpace(const octomap::OcTree& grid, const Points& model_points,
                              const Eigen::Vector3f& origin, const FreeSpaceOptions& options);

}  // namespace furnihost::ransac_upright
