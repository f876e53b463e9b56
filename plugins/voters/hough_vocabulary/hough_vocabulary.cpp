// voters.hough_vocabulary — the paper's voter (Sect. V-B, VI-A, VI-B): a k-means vocabulary of
// part features, a shape model per training part, probabilistic Hough voting on the floor
// plane and hypothesis selection. See plugins/common/voting/voting.hpp for frames, weights and
// the score.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <memory>

#include "furnihost/plugin.hpp"
#include "voting/voting.hpp"

namespace furnihost::voters {

namespace {
constexpr const char* kFormat = "voters.hough_vocabulary/3";

struct Options {
  voting::KMeansOptions km;
  voting::SelectionOptions sel;
};

// Each parameter declared once; its default is Options{}'s.
const ParamBinding<Options>& Binding() {
  using O = Options;
  static const auto b = [] {
    ParamBinding<O> b;
    b.Int("k", [](O& o) -> int& { return o.km.k; }, 1, 100000, "count",
          "vocabulary size: k-means clusters over training part features (paper: 40)")
        .Int("max_iterations", [](O& o) -> int& { return o.km.max_iterations; }, 1, 100000, "count",
             "Lloyd iterations per k-means run")
        .Int("restarts", [](O& o) -> int& { return o.km.restarts; }, 1, 1000, "count",
             "k-means runs from different k-means++ seeds; the lowest inertia wins")
        .Int("vocabularies", [](O& o) -> int& { return o.km.vocabularies; }, 1, 100, "count",
             "k-means vocabularies from different seeds, pooled: a part activates its nearest words in each, "
             "each weighs 1 / vocabularies (1 = one vocabulary, paper)")
        .Int("activations", [](O& o) -> int& { return o.sel.activations; }, 1, 1000, "count",
             "words activated per scene part (paper: 2)")
        .DetectionOnly();
    voting::BindSelection(b, &O::sel);
    return b;
  }();
  return b;
}
}  // namespace

class HoughVocabularyVoter : public voting::CodebookVoter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }

  explicit HoughVocabularyVoter(const nlohmann::json& p) : CodebookVoter(kFormat, 10) {
    const Options o = Binding().Parse(p);
    km_ = o.km;
    opt_ = o.sel;
  }

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext& ctx) override {
    const auto t0 = std::chrono::steady_clock::now();
    const voting::TrainingParts parts = voting::CollectTrainingParts(views);
    std::vector<double> inertia;
    const voting::Codebook book = voting::TrainCodebook(parts, km_, ctx.seed, &inertia);
    nlohmann::json model = book.ToJson(kFormat);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const auto [lo, hi] = std::minmax_element(inertia.begin(), inertia.end());
    spdlog::info("hough_vocabulary: {} words in {} vocabularies from {} parts of {} views (inertia {:.3f} .. {:.3f}, "
                 "{:.0f} ms)", book.Words(), book.Vocabularies(), parts.d.size(), views.size(), *lo, *hi, ms);
    // Installing through Load keeps Train-then-Vote identical to a save/load round trip.
    Load(model);
    return model;
  }

 private:
  voting::KMeansOptions km_;
};

}  // namespace furnihost::voters

FURNIHOST_PLUGIN(furnihost::voters::HoughVocabularyVoter, "voters.hough_vocabulary", "1.4.0",
                 "k-means vocabulary of parts + probabilistic Hough voting (Mozos et al. Sect. V-VI)")
