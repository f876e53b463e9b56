// voters.nearest_neighbor — the paper's "NN" baseline (Sect. VII-A): every scene part votes
// only with its nearest training part (kd-tree over all training part features), weight 1
// (or 1 / (1 + feature distance) with weighting = inverse_distance). Accumulation, maxima,
// thresholds and the footprint check are those of voters.hough_vocabulary (plugins/common/voting).
// Implemented as a codebook with one word per training part and one activation, for which
// eq. 4 and 5 give exactly weight 1.
#include <spdlog/spdlog.h>

#include <memory>
#include <numeric>

#include "furnihost/plugin.hpp"
#include "voting/voting.hpp"

namespace furnihost::voters {

namespace {
constexpr const char* kFormat = "voters.nearest_neighbor/3";

enum class Weighting { kUnit, kInverseDistance };  // the choices of "weighting", in order

struct Options {
  Weighting weighting = Weighting::kUnit;
  voting::SelectionOptions sel;
};

// Each parameter declared once; its default is Options{}'s.
const ParamBinding<Options>& Binding() {
  using O = Options;
  static const auto b = [] {
    ParamBinding<O> b;
    b.Enum("weighting", &O::weighting, {"unit", "inverse_distance"},
           "vote weight: 1, or 1 / (1 + feature distance to the nearest training part)")
        .DetectionOnly();
    voting::BindSelection(b, &O::sel);
    return b;
  }();
  return b;
}
}  // namespace

class NearestNeighborVoter : public voting::CodebookVoter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }

  // One activation: eq. 4 and 5 give exactly weight 1 (or the inverse distance).
  // One word per training part (~6000 x 24): bigger leaves search faster in 24-D.
  explicit NearestNeighborVoter(const nlohmann::json& p) : CodebookVoter(kFormat, 32) {
    const Options o = Binding().Parse(p);
    opt_ = o.sel;
    opt_.activations = 1;
    opt_.inverse_distance = o.weighting == Weighting::kInverseDistance;
  }

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext& ctx) override {
    (void)ctx;  // nothing random
    const voting::TrainingParts parts = voting::CollectTrainingParts(views);
    std::vector<int> labels(parts.d.size());
    std::iota(labels.begin(), labels.end(), 0);
    nlohmann::json model = voting::BuildCodebook(parts, parts.features, labels).ToJson(kFormat);
    spdlog::info("nearest_neighbor: {} training parts of {} views", parts.d.size(), views.size());
    Load(model);
    return model;
  }
};

}  // namespace furnihost::voters

FURNIHOST_PLUGIN(furnihost::voters::NearestNeighborVoter, "voters.nearest_neighbor", "1.3.0",
                 "paper's NN baseline: each scene part votes with its nearest training part only")
