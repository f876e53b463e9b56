// Helpers shared by the evaluation sources (src/eval/); not installed, not part of any API.
#pragma once
#include <Eigen/Core>
#include <cmath>

#include "furnihost/host/evaluation.hpp"

namespace furnihost::eval_detail {

inline double SafeDiv(double a, double b) { return b > 0 ? a / b : NAN; }

// Distance on the floor plane (x, y) [m]: matching and centre errors ignore height.
inline float PlaneDistance(const Eigen::Vector3f& a, const Eigen::Vector3f& b) { return (a - b).head<2>().norm(); }

inline void FinishRates(VerificationFigures* v) {
  v->tp_kept_rate = SafeDiv(v->tp_kept, v->tp);
  v->fp_removal_rate = SafeDiv(v->fp_removed, v->fp);
}

}  // namespace furnihost::eval_detail
