// Per-column min/max normaliser to [0, 1], learned on training features and applied unchanged
// at detection time.
#pragma once
#include <nlohmann/json.hpp>

#include "furnihost/types.hpp"

namespace furnihost {

struct FURNIHOST_API Normaliser {
  Eigen::VectorXf min, max;

  static Normaliser Fit(const std::vector<const FeatureMatrix*>& training);
  // Maps each column to [0, 1]; values outside the training range are clamped. Returns the
  // number of clamped values. Constant columns map to 0. Fills features.excess.
  size_t Apply(FeatureMatrix& features) const;
  nlohmann::json ToJson() const;
  static Normaliser FromJson(const nlohmann::json& j);
};

}  // namespace furnihost
