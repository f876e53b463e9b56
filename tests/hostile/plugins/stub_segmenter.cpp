// segmenters.hostile_stub — test-only: one part per occupied floor cell (x, y grid), so the
// hostile-input runner can drive a whole detection chain (train, model cache, vote) without
// depending on the real segmenters. Not for real use.
#include <cmath>
#include <map>

#include "furnihost/plugin.hpp"

namespace furnihost {

class StubSegmenter : public Segmenter {
 public:
  static ParamSchema Schema() {
    return ParamSchema()
        .Number("cell_m", 0.25, 0.01, 10.0, "floor cell edge [m]; each occupied cell is one part")
        .Int("min_points", 3, 1, 1e6, "cells with fewer points are discarded");
  }
  explicit StubSegmenter(const nlohmann::json& p)
      : cell_(p.at("cell_m").get<float>()), min_points_(p.at("min_points").get<int>()) {}

  Segmentation Segment(const Scan& scan, const RunContext&) override {
    // Ordered map: parts come out in cell order, independent of hashing (determinism).
    std::map<std::pair<long long, long long>, std::vector<int>> cells;
    for (size_t i = 0; i < scan.points.size(); ++i) {
      const auto& p = scan.points[i];
      cells[{static_cast<long long>(std::floor(p.x() / cell_)), static_cast<long long>(std::floor(p.y() / cell_))}]
          .push_back(static_cast<int>(i));
    }
    Segmentation s;
    for (auto& [key, idx] : cells) {
      if (static_cast<int>(idx.size()) < min_points_) {
        s.discarded_points += static_cast<int>(idx.size());
        continue;
      }
      Part part;
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int i : idx) c += scan.points[i].cast<double>();
      part.centroid = (c / static_cast<double>(idx.size())).cast<float>();
      part.indices = std::move(idx);
      s.parts.push_back(std::move(part));
    }
    return s;
  }

 private:
  float cell_;
  int min_points_;
};

}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::StubSegmenter, "segmenters.hostile_stub", "0.1.0",
                 "test only: one part per occupied floor cell")
