// The ground model every stage reads (Scan::ground). Estimating it is the host's
// (host/ground_estimation.hpp).
#include "furnihost/ground.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

namespace furnihost {

const char* ToString(GroundKind k) {
  switch (k) {
    case GroundKind::Level: return "level";
    case GroundKind::Plane: return "plane";
    case GroundKind::HeightMap: return "height_map";
  }
  return "?";
}

float GroundModel::HeightAt(float x, float y) const {
  if (kind != GroundKind::HeightMap || width <= 0 || height <= 0) return plane.HeightAt(x, y);
  // Bilinear between cell centres, clamped to the border cells.
  const float fx = std::clamp((x - origin.x()) / cell - 0.5f, 0.f, float(width - 1));
  const float fy = std::clamp((y - origin.y()) / cell - 0.5f, 0.f, float(height - 1));
  if (!std::isfinite(fx) || !std::isfinite(fy)) return plane.HeightAt(x, y);
  const int x0 = std::min(int(fx), width - 1), y0 = std::min(int(fy), height - 1);
  const int x1 = std::min(x0 + 1, width - 1), y1 = std::min(y0 + 1, height - 1);
  const float tx = fx - float(x0), ty = fy - float(y0);
  auto h = [&](int ix, int iy) { return heights[size_t(iy) * size_t(width) + size_t(ix)]; };
  return (1 - ty) * ((1 - tx) * h(x0, y0) + tx * h(x1, y0)) + ty * ((1 - tx) * h(x0, y1) + tx * h(x1, y1));
}

GroundModel GroundModel::Level(float z, const std::string& source) {
  GroundModel g;
  g.kind = GroundKind::Level;
  g.source = source;
  g.plane = {0.f, 0.f, z};
  return g;
}

GroundModel GroundModel::Tilted(const FloorPlane& plane, const std::string& source) {
  GroundModel g;
  g.kind = GroundKind::Plane;
  g.source = source;
  g.plane = plane;
  return g;
}

nlohmann::json ToJson(const GroundModel& g) {
  auto mm = [](double v) { return std::round(v * 1000.0) / 1000.0; };
  nlohmann::json j = {{"kind", ToString(g.kind)},
                      {"source", g.source},
                      {"plane", {{"a", mm(g.plane.a)}, {"b", mm(g.plane.b)}, {"c", mm(g.plane.c)}}}};
  if (g.kind == GroundKind::HeightMap) {
    nlohmann::json h = nlohmann::json::array();
    for (float v : g.heights) h.push_back(mm(v));
    j["height_map"] = {{"origin", {mm(g.origin.x()), mm(g.origin.y())}},
                       {"cell_m", g.cell},
                       {"width", g.width},
                       {"height", g.height},
                       {"observed_area_m2", mm(g.observed_area_m2)},
                       {"heights", h},
                       {"observed", g.observed}};
  }
  return j;
}

}  // namespace furnihost
