// Parameters of the part features, declared once for features.paper24 and features.reduced.
#pragma once
#include "furnihost/params.hpp"
#include "parts/part_features.hpp"

namespace furnihost::parts {

// Each parameter declared once; its default is PartFeatureOptions{}'s.
inline const ParamBinding<PartFeatureOptions>& PartFeatureBinding() {
  using O = PartFeatureOptions;
  static const auto b =
      ParamBinding<O>()
          .Number("voxel_m", &O::voxel_m, 0.001, 10, "m",
                  "voxel edge of the voxelised volume (features 3 and 9); the paper gives none")
          .Number("boundary_radius_m", &O::boundary_radius_m, 0.001, 10, "m",
                  "neighbourhood of the boundary-point test (feature 1); about 2-3 point spacings")
          .Number("boundary_angle_deg", &O::boundary_angle_deg, 1, 179, "deg",
                  "a point is a boundary point if its neighbours leave an angular gap above this (PCL: 90)")
          .Int("boundary_tests_per_cell", &O::boundary_tests_per_cell, 0, 1e6, "count",
               "feature 1 tests at most this many distinct points per cell of boundary_radius_m (an even sample "
               "standing for the rest), so dense scans cost no more per point; 0 = every point");
  return b;
}

}  // namespace furnihost::parts
