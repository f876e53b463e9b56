#include "furnihost/host/normaliser.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace furnihost {

Normaliser Normaliser::Fit(const std::vector<const FeatureMatrix*>& training) {
  Normaliser n;
  for (const FeatureMatrix* f : training) {
    if (!f || f->values.rows() == 0) continue;
    if (n.min.size() == 0) {
      n.min = f->values.colwise().minCoeff().transpose();
      n.max = f->values.colwise().maxCoeff().transpose();
      continue;
    }
    if (f->values.cols() != n.min.size())
      throw StageError("normaliser: feature matrices have different widths (" +
                       std::to_string(f->values.cols()) + " vs " + std::to_string(n.min.size()) + ")",
                       false);
    n.min = n.min.cwiseMin(f->values.colwise().minCoeff().transpose());
    n.max = n.max.cwiseMax(f->values.colwise().maxCoeff().transpose());
  }
  return n;
}

size_t Normaliser::Apply(FeatureMatrix& f) const {
  if (f.values.rows() == 0) return 0;
  if (f.values.cols() != min.size())
    throw InputError("feature width " + std::to_string(f.values.cols()) +
                     " differs from the trained normaliser's " + std::to_string(min.size()) +
                     " (model trained with another features plugin?)");
  size_t clamped = 0;
  f.excess = Eigen::VectorXf::Zero(f.values.rows());
  for (Eigen::Index c = 0; c < f.values.cols(); ++c) {
    const float range = max[c] - min[c];
    for (Eigen::Index r = 0; r < f.values.rows(); ++r) {
      float v = f.values(r, c);
      float x = range > 0 ? (v - min[c]) / range : 0.f;
      if (!(x >= 0.f)) {  // also catches NaN (no excess: the value is unknown, not large)
        if (x < 0.f) f.excess[r] = std::max(f.excess[r], -x);
        x = 0.f;
        ++clamped;
      } else if (x > 1.f) {
        f.excess[r] = std::max(f.excess[r], std::isfinite(x) ? x - 1.f : std::numeric_limits<float>::max());
        x = 1.f;
        ++clamped;
      } else if (range <= 0 && v != min[c]) {  // a constant training column: any other value is outside
        f.excess[r] = std::max(f.excess[r], 1.f);
      }
      f.values(r, c) = x;
    }
  }
  return clamped;
}

nlohmann::json Normaliser::ToJson() const {
  return {{"min", std::vector<float>(min.data(), min.data() + min.size())},
          {"max", std::vector<float>(max.data(), max.data() + max.size())}};
}

Normaliser Normaliser::FromJson(const nlohmann::json& j) {
  auto lo = j.at("min").get<std::vector<float>>();
  auto hi = j.at("max").get<std::vector<float>>();
  if (lo.size() != hi.size()) throw InputError("normaliser: min and max differ in length");
  Normaliser n;
  n.min = Eigen::Map<Eigen::VectorXf>(lo.data(), lo.size());
  n.max = Eigen::Map<Eigen::VectorXf>(hi.data(), hi.size());
  return n;
}

}  // namespace furnihost
