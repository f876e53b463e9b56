// features.centroid — the smallest honest features plugin: per part its centroid height,
// point count and axis-aligned extents. An example to copy (docs/writing-a-plugin.md), and a
// weak baseline against features.paper24.
#include "furnihost/plugin.hpp"

namespace furnihost {

class CentroidFeatures : public Features {
 public:
  static ParamSchema Schema() {
    return ParamSchema().Bool("log_count", true, "use log(1 + point count) instead of the raw count");
  }
  explicit CentroidFeatures(const nlohmann::json& p) : log_count_(p.at("log_count").get<bool>()) {}

  FeatureMatrix Compute(const Scan& scan, const Segmentation& seg, const RunContext&) override {
    FeatureMatrix f;
    f.names = {"centroid_z", "count", "extent_x", "extent_y", "extent_z"};
    f.values.resize(seg.parts.size(), 5);
    for (size_t i = 0; i < seg.parts.size(); ++i) {
      Eigen::AlignedBox3f box;
      for (int idx : seg.parts[i].indices) box.extend(scan.points.at(idx));
      const float n = static_cast<float>(seg.parts[i].indices.size());
      const Eigen::Vector3f ext = seg.parts[i].indices.empty() ? Eigen::Vector3f(Eigen::Vector3f::Zero()) : Eigen::Vector3f(box.sizes());
      f.values.row(i) << seg.parts[i].centroid.z(), log_count_ ? std::log1p(n) : n, ext.x(), ext.y(), ext.z();
    }
    return f;
  }

 private:
  bool log_count_;
};

}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::CentroidFeatures, "features.centroid", "1.0.0",
                 "example: centroid height, point count and extents of each part")
