// voters.hostile_stub — test-only: learns the mean feature row of each class and, in a scene,
// votes one hypothesis per class at the mean centroid of the parts nearest that class. Its
// Load() checks the model strictly (a tampered model file must give a clear StageError).
#include <map>

#include "furnihost/plugin.hpp"

namespace furnihost {

class StubVoter : public Voter {
 public:
  static ParamSchema Schema() {
    return ParamSchema().Number("min_score", 1.0, 0.0, 1e9, "hypotheses need at least this many parts");
  }
  explicit StubVoter(const nlohmann::json& p) : min_score_(p.at("min_score").get<float>()) {}

  nlohmann::json Train(const std::vector<TrainingView>& views, const RunContext&) override {
    std::map<std::string, std::pair<Eigen::VectorXd, int>> acc;
    for (const auto& v : views) {
      for (Eigen::Index r = 0; r < v.features.values.rows(); ++r) {
        auto& [sum, n] = acc[v.cls];
        if (n == 0) sum = Eigen::VectorXd::Zero(v.features.values.cols());
        sum += v.features.values.row(r).transpose().cast<double>();
        ++n;
      }
    }
    nlohmann::json classes = nlohmann::json::object();
    for (const auto& [cls, sn] : acc) {
      std::vector<double> mean(sn.first.size());
      for (Eigen::Index i = 0; i < sn.first.size(); ++i) mean[i] = sn.first[i] / sn.second;
      classes[cls] = mean;
    }
    return {{"stub_model", 1}, {"classes", classes}};
  }

  void Load(const nlohmann::json& model) override {
    if (!model.is_object() || model.value("stub_model", 0) != 1 || !model.contains("classes") ||
        !model["classes"].is_object() || model["classes"].empty())
      throw StageError("model: not a voters.hostile_stub model (retrain)");
    means_.clear();
    long width = -1;
    for (const auto& [cls, m] : model["classes"].items()) {
      if (!m.is_array() || m.empty()) throw StageError("model: class " + cls + ": expected a feature row");
      Eigen::VectorXf v(m.size());
      for (size_t i = 0; i < m.size(); ++i) {
        if (!m[i].is_number()) throw StageError("model: class " + cls + ": non-numeric feature");
        v[i] = m[i].get<float>();
      }
      if (width >= 0 && v.size() != width) throw StageError("model: classes have different feature widths");
      width = v.size();
      means_[cls] = v;
    }
  }

  VoteResult Vote(const std::vector<SceneParts>& scenes, const RunContext&) override {
    if (means_.empty()) throw StageError("Vote called before Load", false);
    std::map<std::string, Hypothesis> by_class;
    std::map<std::string, Eigen::Vector3d> sums;
    for (size_t s = 0; s < scenes.size(); ++s) {
      const auto& f = scenes[s].features->values;
      for (Eigen::Index r = 0; r < f.rows(); ++r) {
        if (f.cols() != means_.begin()->second.size())
          throw StageError("feature width differs from the model's");
        const std::string* best = nullptr;
        float best_d = 0.f;
        for (const auto& [cls, m] : means_) {
          const float d = (f.row(r).transpose() - m).squaredNorm();
          if (!best || d < best_d) best = &cls, best_d = d;
        }
        auto& h = by_class[*best];
        h.cls = *best;
        h.score += 1.f;
        h.support.push_back({static_cast<int>(s), static_cast<int>(r), 1.f});
        auto it = sums.try_emplace(*best, Eigen::Vector3d::Zero()).first;
        it->second += (scenes[s].scan->pose * scenes[s].segmentation->parts[r].centroid).cast<double>();
      }
    }
    VoteResult out;
    for (auto& [cls, h] : by_class) {
      if (h.score < min_score_) continue;
      h.center = (sums[cls] / h.score).cast<float>();
      out.hypotheses.push_back(h);
    }
    return out;
  }

 private:
  float min_score_;
  std::map<std::string, Eigen::VectorXf> means_;
};

}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::StubVoter, "voters.hostile_stub", "0.1.0",
                 "test only: nearest class mean of part features")
