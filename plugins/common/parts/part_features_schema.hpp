// Parameters of the part features, declared once for features.paper24 and features.reduced.
#pragma once
#include "furnihost/params.hpp"
#include "parts/part_features.hpp"

namespace furnihost::parts {

inline ParamSchema PartFeatureSchema() {
  ParamSchema s;
  s.Number("voxel_m", 0.02, 0.001, 10.0,
           "voxel edge of the voxelised volume (features 3 and 9) [m]; the paper gives none");
  s.Number("boundary_radius_m", 0.03, 0.001, 10.0,
           "neighbourhood of the boundary-point test (feature 1) [m]; about 2-3 point spacings");
  s.Number("boundary_angle_deg", 90.0, 1.0, 179.0,
           "a point is a boundary point if its neighbours leave an angular gap above this [deg] (PCL: 90)");
  return s;
}

inline PartFeatureOptions PartFeatureOptionsFrom(const nlohmann::json& p) {
  PartFeatureOptions o;
  o.voxel_m = p.at("voxel_m").get<double>();
  o.boundary_radius_m = p.at("boundary_radius_m").get<double>();
  o.boundary_angle_deg = p.at("boundary_angle_deg").get<double>();
  o.Check();
  return o;
}

}  // namespace furnihost::parts
