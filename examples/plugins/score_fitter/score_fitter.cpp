// fitters.example_score — a fitter example: verifies each detection of the previous stage by
// its voter score alone (a real fitter places catalog models, see fitters.ransac_upright).
#include "furnihost/plugin.hpp"

namespace example {
using namespace furnihost;

struct ScoreOptions {
  double min_score = 1.0;
};

const ParamBinding<ScoreOptions>& Binding() {
  static const auto b = ParamBinding<ScoreOptions>().Number(
      "min_score", &ScoreOptions::min_score, 0, std::nullopt, "", "detections scoring lower are rejected");
  return b;
}

class ScoreFitter : public Fitter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit ScoreFitter(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  // ctx holds the scenes' parts and the catalog; Prepare() (optional) caches per-model data.
  std::vector<Detection> Fit(const std::vector<Detection>& input, const FitContext&) override {
    std::vector<Detection> out = input;  // rejected ones are kept, marked (the report shows why)
    for (Detection& d : out) {  // each test goes into d.checks; the report names the failed one
      d.checks.push_back(Check::AtLeast("min_score", d.score, o_.min_score));
      d.verified = d.checks.back().passed;
    }
    return out;
  }

 private:
  ScoreOptions o_;
};
}  // namespace example

FURNIHOST_PLUGIN(example::ScoreFitter, "fitters.example_score", "1.0.0",
                 "example: accepts detections scoring at least min_score")
