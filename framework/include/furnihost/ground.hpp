// The ground under a scan: one model per scan, estimated once by the pipeline (or known, for
// simulated scans, or fixed by the user) and handed to every stage in Scan::ground. Every
// height in the pipeline (voter gates, fitter placement, verification, plots) is a height
// above it, never above z = 0.
//
// Frame: the scan's working frame (metres, z up; see Scan::frame for how it relates to the
// file's own coordinates). Kinds:
//   level      z = c everywhere (a flat floor);
//   plane      z = a x + b y + c (a tilted floor: drifted reconstructions, a mis-levelled sensor);
//   height_map a floor height per cell of a regular grid on the floor plane, for floors that are
//              warped (ScanNet reconstructions bend by up to 0.4 m across a room); cells where the
//              floor is hidden (under furniture, beyond the view) are filled from their neighbours.
#pragma once
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "furnihost/error.hpp"

namespace furnihost {

// Runs body(b, e) over disjoint sub-ranges covering [begin, end), in parallel or not (the host
// passes one over tbb::parallel_for: the SDK itself has no thread pool). What is computed with
// it must not depend on the partition.
using RangeFor = std::function<void(size_t begin, size_t end, const std::function<void(size_t, size_t)>& body)>;
// The RangeFor of one pass in the calling thread.
inline void SerialRange(size_t begin, size_t end, const std::function<void(size_t, size_t)>& body) {
  if (begin < end) body(begin, end);
}

// A floor plane z = a x + b y + c.
struct FloorPlane {
  float a = 0.f, b = 0.f, c = 0.f;
  float HeightAt(float x, float y) const { return a * x + b * y + c; }
  // Height of p above the plane, measured along z.
  float Above(const Eigen::Vector3f& p) const { return p.z() - HeightAt(p.x(), p.y()); }
};

enum class GroundKind { Level, Plane, HeightMap };
FURNIHOST_API const char* ToString(GroundKind k);  // "level", "plane", "height_map"

struct FURNIHOST_API GroundModel {
  GroundKind kind = GroundKind::Level;
  // "estimated" (from the scan's points), "fixed" (given by the user) or "known" (a simulated
  // scan: the floor the objects were placed on).
  std::string source = "fixed";
  FloorPlane plane;  // level (a = b = 0), plane; for a height map the least-squares plane of its observed cells
  // Height map: cell (ix, iy) is centred at origin + (ix + 0.5, iy + 0.5) * cell; row-major
  // (index iy * width + ix). Heights between cell centres are interpolated bilinearly and
  // clamped to the border cells outside the grid.
  Eigen::Vector2f origin = Eigen::Vector2f::Zero();
  float cell = 0.f;
  int width = 0, height = 0;
  std::vector<float> heights;
  std::vector<uint8_t> observed;  // 1 = floor seen in the cell, 0 = filled from neighbours
  float observed_area_m2 = 0.f;   // floor area seen (height map: observed cells; else 0)

  // World z of the ground at (x, y).
  float HeightAt(float x, float y) const;
  // Height of p above the ground, along z.
  float Above(const Eigen::Vector3f& p) const { return p.z() - HeightAt(p.x(), p.y()); }

  static GroundModel Level(float z, const std::string& source);
  static GroundModel Tilted(const FloorPlane& plane, const std::string& source);
};

// How the pipeline gets the ground of a scan (graph config "ground", CLI --ground).
struct FURNIHOST_API GroundOptions {
  // "auto" (height map when the scan shows enough floor, else a plane, else level), "level",
  // "plane", "height_map" or "fixed" (level at fixed_z).
  std::string kind = "auto";
  float fixed_z = 0.f;      // [m] working-frame z of the floor when kind = "fixed"
  float cell = 0.15f;       // [m] height-map cell
  float step = 0.05f;       // [m] largest floor height step between neighbouring cells
  float min_area = 0.2f;    // [m2] observed floor below which "auto" falls back to a plane
  // Throws InputError naming the field ("ground.kind: ...") on a bad value.
  void Check(const std::string& where) const;
};
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

// The ground as JSON (detections.json): kind, source, plane, and for a height map its grid
// (heights rounded to the millimetre).
FURNIHOST_API nlohmann::json ToJson(const GroundModel& g);

}  // namespace furnihost
