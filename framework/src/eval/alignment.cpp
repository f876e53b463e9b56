// The Scan2CAD alignment rule on an evaluated detection and a ground-truth object (Aligned,
// AlignmentMiss).
#include <cmath>
#include <cstdio>
#include <string>

#include "furnihost/host/evaluation.hpp"

namespace furnihost {

namespace {

// Smallest absolute difference of two angles [rad], in degrees in [0, 180].
double TurnDeg(double a, double b) {
  double d = std::fmod(std::abs(a - b), 2 * M_PI);
  if (d > M_PI) d = 2 * M_PI - d;
  return d * 180.0 / M_PI;
}

}  // namespace

std::string AlignmentMiss(const Detection& d, const GroundTruthObject& g, const AlignmentRule& rule) {
  char b[64];
  if (!g.yaw) return "no yaw in the ground truth";
  if (d.model.empty() || !d.box) return "no model placed";
  const double centre = (d.box->center - g.center).norm();
  if (centre > rule.centre_m) {
    std::snprintf(b, sizeof b, "centre %.2f m off", centre);
    return b;
  }
  const double yaw = FoldYawErrorDeg(TurnDeg(d.yaw, *g.yaw), g.yaw_symmetry);
  if (yaw > rule.yaw_deg) {
    std::snprintf(b, sizeof b, "facing %.0f deg off", yaw);
    return b;
  }
  const Eigen::Vector3f det = d.box->Aabb().sizes(), obj = g.size;
  double ratio = 0;
  for (int k = 0; k < 3; ++k) {
    if (!(obj[k] > 0.f)) return "no size in the ground truth";
    ratio += double(det[k]) / double(obj[k]);
  }
  const double scale = std::abs(ratio / 3.0 - 1.0);
  if (scale > rule.scale) {
    std::snprintf(b, sizeof b, "size %.0f %% off", 100.0 * scale);
    return b;
  }
  return "";
}

bool Aligned(const Detection& d, const GroundTruthObject& g, const AlignmentRule& rule) {
  return AlignmentMiss(d, g, rule).empty();
}

}  // namespace furnihost
