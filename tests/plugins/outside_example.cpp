// A features plugin built outside framework/ and plugins/: proves the host finds and runs
// a new plugin through --plugin-path without any change to the host.
#include "furnihost/plugin.hpp"

class OutsideExample : public furnihost::Features {
 public:
  static furnihost::ParamSchema Schema() {
    return furnihost::ParamSchema().Number("scale", 1.0, 0.0, 100.0, "multiplies the part size");
  }
  explicit OutsideExample(const nlohmann::json& p) : scale_(p.at("scale").get<float>()) {}
  furnihost::FeatureMatrix Compute(const furnihost::Scan&, const furnihost::Segmentation& seg,
                                   const furnihost::RunContext&) override {
    furnihost::FeatureMatrix f;
    f.names = {"scaled_size"};
    f.values.resize(seg.parts.size(), 1);
    for (size_t i = 0; i < seg.parts.size(); ++i) f.values(i, 0) = scale_ * seg.parts[i].indices.size();
    return f;
  }

 private:
  float scale_;
};

FURNIHOST_PLUGIN(OutsideExample, "features.outside_example", "0.1.0", "test plugin built outside the tree")
