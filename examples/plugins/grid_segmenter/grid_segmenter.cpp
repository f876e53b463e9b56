// segmenters.example_grid — a segmenter example: the points of each cube of a regular grid
// form one part (no normals). Crude, but it shows the whole segmenter contract.
#include <map>
#include <tuple>

#include "furnihost/plugin.hpp"

namespace example {
using namespace furnihost;

struct GridOptions {
  double cell_m = 0.25;  // defaults: the struct's, so the schema and the struct cannot disagree
  int min_points = 10;
};

const ParamBinding<GridOptions>& Binding() {
  static const auto b = ParamBinding<GridOptions>()
                            .Number("cell_m", &GridOptions::cell_m, 0.01, 10, "m", "edge of the grid cubes")
                            .Int("min_points", &GridOptions::min_points, 1, 1e9, "", "smaller parts are discarded");
  return b;
}

class GridSegmenter : public Segmenter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit GridSegmenter(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  Segmentation Segment(const Scan& scan, const RunContext&) override {
    Segmentation seg;  // per point: a normal (NaN = unknown) and a curvature; parts index the points
    seg.normals.assign(scan.points.size(), Eigen::Vector3f::Constant(NAN));
    seg.curvature.assign(scan.points.size(), 0.f);
    std::map<std::tuple<long, long, long>, Part> cells;  // ordered: deterministic part order
    for (size_t i = 0; i < scan.points.size(); ++i) {
      const Eigen::Vector3d c = (scan.points[i].cast<double>() / o_.cell_m).array().floor();
      cells[{long(c.x()), long(c.y()), long(c.z())}].indices.push_back(int(i));
    }
    for (auto& [key, part] : cells) {
      if (int(part.indices.size()) < o_.min_points) {
        seg.discarded_points += int(part.indices.size());
        continue;
      }
      for (int i : part.indices) part.centroid += scan.points[i];
      part.centroid /= float(part.indices.size());
      seg.parts.push_back(std::move(part));
    }
    return seg;
  }

 private:
  GridOptions o_;
};
}  // namespace example

FURNIHOST_PLUGIN(example::GridSegmenter, "segmenters.example_grid", "1.0.0",
                 "example: the points of each grid cube form one part")
