#include "furnihost/host/detections.hpp"

#include <cmath>

namespace furnihost {

Detection TransformDetection(Detection d, const Eigen::Isometry3f& t) {
  const float turn = std::atan2(t.linear()(1, 0), t.linear()(0, 0));
  auto wrap = [](float a) { return std::remainder(a, float(2 * M_PI)); };
  d.center = t * d.center;
  d.yaw = wrap(d.yaw + turn);
  d.model_pose = t * d.model_pose;
  if (d.box) {
    d.box->center = t * d.box->center;
    d.box->yaw = wrap(d.box->yaw + turn);
  }
  return d;
}

namespace {
nlohmann::json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
}  // namespace

nlohmann::json DetectionToJson(const Detection& d, const Scan* scan) {
  const ScanFrame frame = scan ? scan->frame : ScanFrame{};
  // World (fused) frame -> the scan's working frame -> its file's frame.
  const Eigen::Isometry3f to_scan = scan ? scan->pose.inverse() : Eigen::Isometry3f::Identity();
  auto P = [&](const Eigen::Vector3f& w) { return Vec(frame.ToFile(to_scan * w)); };
  auto D = [&](const Eigen::Vector3f& w) { return Vec(frame.DirectionToFile(to_scan.linear() * w)); };
  // The way it faces (its model's front, Detection::yaw): yaw counter-clockwise from +x of the
  // scan's z-up frame (before the canonical turn), and "facing" as a direction of the file's own
  // axes (null without a model).
  const Eigen::Vector3f facing_w(std::cos(d.yaw), std::sin(d.yaw), 0.f);
  const Eigen::Vector3d facing_up = frame.canonical.linear().transpose() * (to_scan.linear() * facing_w).cast<double>();
  const double yaw = std::atan2(facing_up.y(), facing_up.x());
  nlohmann::json j = {{"class", d.cls},
                      {"center", P(d.center)},
                      {"yaw", yaw},
                      {"yaw_deg", yaw * 180.0 / M_PI},
                      {"facing", d.model.empty() ? nlohmann::json(nullptr) : D(facing_w)},
                      {"score", d.score},
                      {"confidence", d.confidence ? nlohmann::json(*d.confidence) : nlohmann::json(nullptr)},
                      {"model", d.model.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.model)},
                      {"verified", d.verified ? nlohmann::json(*d.verified) : nlohmann::json(nullptr)}};
  if (d.coverage) j["coverage"] = *d.coverage;
  j["free_space_ratio"] = d.free_space_ratio ? nlohmann::json(*d.free_space_ratio) : nlohmann::json(nullptr);
  if (d.rms) j["rms_m"] = *d.rms;
  if (d.iterations) j["iterations"] = d.iterations;
  if (!d.checks.empty()) {
    nlohmann::json checks = nlohmann::json::array();
    for (const Check& c : d.checks)
      checks.push_back({{"name", c.name}, {"value", c.value}, {"limit", c.limit},
                        {"test", c.at_least ? ">=" : "<="}, {"passed", c.passed}});
    j["checks"] = checks;
  }
  if (const std::string why = d.Rejection(); !why.empty()) j["rejection"] = why;
  if (!d.notes.empty()) j["notes"] = d.notes;
  if (!d.chain.empty()) j["chain"] = d.chain;
  if (scan && scan->ground) j["height_above_ground"] = scan->HeightAboveGround(d.center);
  if (d.box) {
    const OrientedBox& b = *d.box;
    nlohmann::json corners = nlohmann::json::array();
    Eigen::AlignedBox3d aabb;
    for (const auto& c : b.Corners()) {
      corners.push_back(P(c));
      aabb.extend(frame.ToFile(to_scan * c));
    }
    const Eigen::Vector3f ax(std::cos(b.yaw), std::sin(b.yaw), 0.f), ay(-std::sin(b.yaw), std::cos(b.yaw), 0.f);
    j["box"] = {{"source", d.box_source},
                {"center", P(b.center)},
                {"size", {b.size.x(), b.size.y(), b.size.z()}},
                {"yaw", b.yaw},
                {"axes", {D(ax), D(ay), D(Eigen::Vector3f::UnitZ())}},
                {"corners", corners},
                {"aabb", {{"min", Vec(aabb.min())}, {"max", Vec(aabb.max())}}}};
    if (scan && scan->ground) j["box"]["bottom_above_ground"] = scan->HeightAboveGround(b.center) - 0.5f * b.size.z();
  }
  if (!d.evidence.empty()) j["evidence"] = d.evidence;
  nlohmann::json sup = nlohmann::json::array();
  for (const auto& s : d.support) sup.push_back({{"scene", s.scene}, {"part", s.part}, {"weight", s.weight}});
  j["supporting_parts"] = sup;
  return j;
}

}  // namespace furnihost
