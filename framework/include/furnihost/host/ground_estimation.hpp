// Ground estimation: the host finds the ground of every scan once (scan_input.hpp), before any
// stage sees it; the stages read the result, a GroundModel (furnihost/ground.hpp), in
// Scan::ground. Frame: the scan's working frame (metres, z up).
#pragma once
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "furnihost/geometry.hpp"
#include "furnihost/ground.hpp"

namespace furnihost {

// How the host gets the ground of a scan (graph config "ground", CLI --ground). The members
// are the config's keys; the parameters are declared once, in GroundOptionsFromJson's binding
// (host_options.cpp), with their ranges and units.
struct FURNIHOST_API GroundOptions {
  // "auto" (height map when the scan shows enough floor, else a plane, else level), "level",
  // "plane", "height_map" or "fixed" (level at z_m).
  std::string kind = "auto";
  float z_m = 0.f;           // [m] working-frame z of the floor when kind = "fixed"
  float cell_m = 0.15f;      // [m] height-map cell
  float step_m = 0.05f;      // [m] largest floor height step between neighbouring cells
  float min_area_m2 = 0.2f;  // [m2] observed floor below which "auto" falls back to a plane
  // Throws InputError naming the field ("--ground: kind: ...") on a bad value.
  void Check(const std::string& where) const;
};
// The "ground" object of a graph config (null: the defaults); InputError naming
// `where`/<key> on an unknown key or a bad value.
FURNIHOST_API GroundOptions GroundOptionsFromJson(const nlohmann::json& j, const std::string& where);
FURNIHOST_API nlohmann::json ToJson(const GroundOptions& o);

// The ground of a cloud in its own frame (z up). Linear in the number of points (no normals:
// the floor of a cell is the lowest 2 cm height slice holding a floor's density of points).
// Deterministic. Empty or non-finite input: level at 0.
FURNIHOST_API GroundModel EstimateGround(const std::vector<Eigen::Vector3f>& points, const GroundOptions& options);
// The same, its per-voxel normals spread by `pfor`; the same ground.
FURNIHOST_API GroundModel EstimateGround(const std::vector<Eigen::Vector3f>& points, const GroundOptions& options,
                                         const RangeFor& pfor);

// World z of the floor of a level estimate: the mean height of the densest 2 cm slice among
// the lowest 30 % of the points. At most ~200k points are looked at. 0 without finite points.
FURNIHOST_API float EstimateLevelZ(const std::vector<Eigen::Vector3f>& points);
// The floor as a plane tilted at most 10 degrees: RANSAC (fixed seed) over the lowest 30 % of
// the points for the plane with the most points within 2 cm, the level plane competing, then
// least squares over the points within 2 cm of it.
FURNIHOST_API FloorPlane EstimatePlane(const std::vector<Eigen::Vector3f>& points);

}  // namespace furnihost
