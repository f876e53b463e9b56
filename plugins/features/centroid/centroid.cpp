// features.centroid — per part: centroid height, point count, extents (docs/writing-a-plugin.md).
#include "furnihost/plugin.hpp"

namespace furnihost {
struct CentroidOptions {  // one field per parameter; its default is the parameter's
  bool log_count = true;
};

// Every parameter declared once: name, member, (range, unit,) help.
const ParamBinding<CentroidOptions>& Binding() {
  static const auto b = ParamBinding<CentroidOptions>().Bool(
      "log_count", &CentroidOptions::log_count, "use log(1 + point count) instead of the raw count");
  return b;
}

class CentroidFeatures : public Features {  // the stage kind: furnihost/stage.hpp
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit CentroidFeatures(const nlohmann::json& p) : o_(Binding().Parse(p)) {}  // p: validated

  FeatureMatrix Compute(const Scan& scan, const Segmentation& seg, const RunContext&) override {
    FeatureMatrix f;
    f.names = {"centroid_z", "count", "extent_x", "extent_y", "extent_z"};
    f.values.resize(seg.parts.size(), 5);
    for (size_t i = 0; i < seg.parts.size(); ++i) {
      Eigen::AlignedBox3f box;
      for (int idx : seg.parts[i].indices) box.extend(scan.points.at(idx));
      const float n = float(seg.parts[i].indices.size());
      const Eigen::Vector3f ext = n > 0 ? Eigen::Vector3f(box.sizes()) : Eigen::Vector3f(Eigen::Vector3f::Zero());
      f.values.row(i) << seg.parts[i].centroid.z(), o_.log_count ? std::log1p(n) : n, ext.x(), ext.y(), ext.z();
    }
    return f;
  }
 private:
  CentroidOptions o_;
};
}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::CentroidFeatures, "features.centroid", "1.0.0",
                 "example: centroid height, point count and extents of each part")
