// voters.example_class_mean — a voter example: training keeps the mean feature vector of each
// class's parts; each scene part then votes for the class whose mean is nearest (one
// hypothesis per part, at its centroid). The model is JSON tagged with a format string.
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "furnihost/plugin.hpp"

namespace example {
using namespace furnihost;

// Bump the number whenever the model's layout changes: Load refuses other formats, and the
// host retrains instead of using a stale cached model.
constexpr const char* kFormat = "voters.example_class_mean/1";

struct ClassMeanOptions {
  double max_distance = 0.5;
};

const ParamBinding<ClassMeanOptions>& Binding() {
  static const auto b = ParamBinding<ClassMeanOptions>()
                            .Number("max_distance", &ClassMeanOptions::max_distance, 0, 10, "",
                                    "parts farther from every class mean (normalised features) do not vote")
                            .DetectionOnly();  // not in the model cache key: changing it does not retrain
  return b;
}

class ClassMeanVoter : public Voter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit ClassMeanVoter(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext&) override {
    std::map<std::string, std::pair<Eigen::VectorXd, int>> sums;  // class -> (sum of rows, rows)
    for (const TrainingView& v : views)
      for (Eigen::Index r = 0; r < v.features.values.rows(); ++r) {
        auto& [sum, n] = sums[v.cls];
        if (n == 0) sum = Eigen::VectorXd::Zero(v.features.values.cols());
        sum += v.features.values.row(r).transpose().cast<double>();
        ++n;
      }
    if (sums.empty()) throw StageError("no training parts");
    nlohmann::json model = {{"format", kFormat}, {"features", views.front().features.names}};
    for (const auto& [cls, sum] : sums) {
      const Eigen::VectorXd mean = sum.first / sum.second;
      model["classes"][cls] = std::vector<double>(mean.data(), mean.data() + mean.size());
    }
    Load(model);  // Train-then-Vote behaves exactly like a save/load round trip
    return model;
  }

  void Load(const nlohmann::json& model) override {
    if (model.value("format", "") != kFormat) throw StageError(std::string("model is not ") + kFormat);
    features_ = model.at("features").get<std::vector<std::string>>();
    means_.clear();
    for (const auto& [cls, mean] : model.at("classes").items()) {
      const auto v = mean.get<std::vector<double>>();
      means_[cls] = Eigen::Map<const Eigen::VectorXd>(v.data(), Eigen::Index(v.size())).cast<float>();
    }
  }

  VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext&) override {
    if (means_.empty()) throw StageError("voter has no model: Train or Load it first");
    VoteResult out;
    for (const auto& [cls, mean] : means_) out.classes.push_back(cls);
    for (size_t s = 0; s < scenes.size(); ++s) {
      const FeatureMatrix& f = *scenes[s].features;  // normalised like the training features
      if (f.names != features_) throw StageError("scene features differ from the model's");
      for (Eigen::Index r = 0; r < f.values.rows(); ++r) {
        std::string best;
        float best_d = INFINITY;
        for (const auto& [cls, mean] : means_) {
          const float d = (f.values.row(r).transpose() - mean).norm();
          if (d < best_d) best_d = d, best = cls;
        }
        if (best_d > o_.max_distance) continue;
        Hypothesis h;  // world frame: the scan's pose maps its points there
        h.cls = best;
        h.center = scenes[s].scan->pose * scenes[s].segmentation->parts[size_t(r)].centroid;
        h.score = 1.f / (1.f + best_d);
        h.scene = int(s);
        h.support.push_back({int(s), int(r), h.score});
        out.hypotheses.push_back(std::move(h));
      }
    }
    return out;
  }

 private:
  ClassMeanOptions o_;
  std::vector<std::string> features_;
  std::map<std::string, Eigen::VectorXf> means_;
};
}  // namespace example

FURNIHOST_PLUGIN(example::ClassMeanVoter, "voters.example_class_mean", "1.0.0",
                 "example: each part votes for the class with the nearest mean training features")
