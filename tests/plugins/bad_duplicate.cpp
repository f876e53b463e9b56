// Reuses the type name of a shipped plugin: the first one found wins, this one is refused.
#include "furnihost/plugin.hpp"

class Duplicate : public furnihost::Features {
 public:
  static furnihost::ParamSchema Schema() { return {}; }
  explicit Duplicate(const nlohmann::json&) {}
  furnihost::FeatureMatrix Compute(const furnihost::Scan&, const furnihost::Segmentation&,
                                   const furnihost::RunContext&) override {
    return {};
  }
};

FURNIHOST_PLUGIN(Duplicate, "features.centroid", "9.9.9", "duplicate type name")
