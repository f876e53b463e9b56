// features.reduced — the paper's "Re" ablation: the features of Sect. V-A without features 4
// (eigenvalue ratios), 7 (extents) and 8 (variance/extent ratios), i.e. 9 of the 24 columns
// (see parts/part_features.hpp, shared with features.paper24).
#include <tbb/task_arena.h>

#include "furnihost/plugin.hpp"
#include "parts/part_features.hpp"
#include "parts/part_features_schema.hpp"

namespace furnihost {

class ReducedFeatures : public Features {
 public:
  static ParamSchema Schema() { return parts::PartFeatureBinding().Schema(); }
  explicit ReducedFeatures(const nlohmann::json& p) : o_(parts::PartFeatureBinding().Parse(p)) {}

  FeatureMatrix Compute(const Scan& scan, const Segmentation& seg, const RunContext& ctx) override {
    tbb::task_arena arena(ctx.threads > 0 ? ctx.threads : tbb::task_arena::automatic);
    FeatureMatrix f;
    arena.execute([&] { f = parts::ComputeReduced(scan, seg, o_); });
    return f;
  }

 private:
  parts::PartFeatureOptions o_;
};

}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::ReducedFeatures, "features.reduced", "1.0.0",
                 "paper's Re ablation: the paper24 features without 4, 7 and 8 (9 columns)")
