// features.paper24 — the 24 part features of paper Sect. V-A (the column table and every
// interpretation of the paper's text are documented in parts/part_features.hpp).
#include <tbb/task_arena.h>

#include "furnihost/plugin.hpp"
#include "parts/part_features.hpp"
#include "parts/part_features_schema.hpp"

namespace furnihost {

class Paper24Features : public Features {
 public:
  static ParamSchema Schema() { return parts::PartFeatureBinding().Schema(); }
  explicit Paper24Features(const nlohmann::json& p) : o_(parts::PartFeatureBinding().Parse(p)) {}

  FeatureMatrix Compute(const Scan& scan, const Segmentation& seg, const RunContext& ctx) override {
    tbb::task_arena arena(ctx.threads > 0 ? ctx.threads : tbb::task_arena::automatic);
    FeatureMatrix f;
    arena.execute([&] { f = parts::ComputePaper24(scan, seg, o_); });
    return f;
  }

 private:
  parts::PartFeatureOptions o_;
};

}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::Paper24Features, "features.paper24", "1.0.0",
                 "paper Sect. V-A: 24 geometric features per part (boundary, curvature, volume, eigen, extents)")
