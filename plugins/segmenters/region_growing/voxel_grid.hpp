// Compatibility header: the index now lives in the framework (furnihost/voxel_index.hpp).
// features.paper24 / features.reduced still include "voxel_grid.hpp" from this folder and use
// rg::VoxelGrid; it is the framework's VoxelIndex built in parallel with TBB, exactly what it
// was before. New code includes furnihost/voxel_index.hpp directly.
#pragma once
#include <vector>

#include "../common/tbb_for.hpp"
#include "furnihost/voxel_index.hpp"

namespace furnihost::rg {

using furnihost::RadixSortByKey;

class VoxelGrid : public VoxelIndex {
 public:
  void Build(const std::vector<Eigen::Vector3f>& pts, float cell_size) {
    VoxelIndex::Build(pts, cell_size, Anchor::kBoundingBox, TbbFor());
  }
};

}  // namespace furnihost::rg
