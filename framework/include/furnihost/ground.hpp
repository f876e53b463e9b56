// The ground under a scan: one model per scan, estimated once by the host (or known, for
// simulated scans, or fixed by the user; host/ground_estimation.hpp) and handed to every stage
// in Scan::ground. Every height in the pipeline (voter gates, fitter placement, verification,
// plots) is a height above it, never above z = 0.
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
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "furnihost/error.hpp"

namespace furnihost {

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

// The ground as JSON (detections.json): kind, source, plane, and for a height map its grid
// (heights rounded to the millimetre).
FURNIHOST_API nlohmann::json ToJson(const GroundModel& g);

}  // namespace furnihost
