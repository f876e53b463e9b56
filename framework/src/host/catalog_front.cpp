// Which way a catalog model faces (EstimateFront) and which way a detection faces (FacingYaw,
// SetFacing): the catalog's "front" where it gives one, else the side of the mesh that is most
// open to a horizontal look.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "furnihost/host/catalog.hpp"
#include "furnihost/geometry.hpp"

namespace furnihost {

namespace {

// "+x" / "-y" for a unit axis of the model frame, else the vector.
std::string AxisName(const Eigen::Vector3f& d) {
  for (int a = 0; a < 2; ++a)
    for (int s : {1, -1})
      if (std::abs(d[a] - float(s)) < 1e-4f) return std::string(s > 0 ? "+" : "-") + (a == 0 ? "x" : "y");
  char b[48];
  std::snprintf(b, sizeof b, "(%.3f, %.3f)", double(d.x()), double(d.y()));
  return b;
}

}  // namespace

FrontEstimate EstimateFront(const Mesh& mesh) {
  FrontEstimate e;
  const Eigen::AlignedBox3f box = mesh.Bounds();
  const Eigen::Vector3f ext = box.sizes();
  if (mesh.triangles.empty() || !(ext.minCoeff() > 0.f) || !ext.allFinite()) {
    e.ambiguous = true;
    e.how = "estimated -y: the mesh has no extent to look into";
    return e;
  }
  // Occupancy of the mesh's surface in cells of ~1/32 of its largest extent (1.5-6 cm): a seat, a
  // back, a shelf are several cells; every catalog load runs this for each model without a front.
  const float cell = std::clamp(ext.maxCoeff() / 32.f, 0.015f, 0.06f);
  const std::array<int, 3> n = {std::max(1, int(std::ceil(ext.x() / cell))), std::max(1, int(std::ceil(ext.y() / cell))),
                                std::max(1, int(std::ceil(ext.z() / cell)))};
  std::vector<uint8_t> occ(size_t(n[0]) * size_t(n[1]) * size_t(n[2]), 0);
  auto at = [&](int x, int y, int z) -> uint8_t& { return occ[(size_t(z) * size_t(n[1]) + size_t(y)) * size_t(n[0]) + size_t(x)]; };
  const Points samples = SampleSurface(mesh, 3.f / (cell * cell), 7);
  // Where its top quarter stands, as a share of the half extents from the box centre: a seat's
  // back, a desk's hutch (the front is away from it).
  Eigen::Vector2d high = Eigen::Vector2d::Zero();
  long n_high = 0;
  const Eigen::Vector3f mid = box.center();
  for (const auto& p : samples) {
    std::array<int, 3> c;
    for (int k = 0; k < 3; ++k) c[size_t(k)] = std::clamp(int((p[k] - box.min()[k]) / cell), 0, n[size_t(k)] - 1);
    at(c[0], c[1], c[2]) = 1;
    if (p.z() > box.min().z() + 0.75f * ext.z()) {
      high += Eigen::Vector2d((p.x() - mid.x()) / (0.5 * ext.x()), (p.y() - mid.y()) / (0.5 * ext.y()));
      ++n_high;
    }
  }
  if (n_high > 0) high /= double(n_high);
  // Per horizontal axis: rays through the box along it, one per cell of the face across it
  // (the other horizontal axis by height); each enters from both ends. How deep a ray gets
  // before it meets the surface, as a share of the box's extent along the axis, averaged over
  // the rays that meet it (a ray that meets nothing is the same from both ends). A chair's front
  // lets rays run over the seat to the back; its back stops them at once. So do a sofa's, a
  // bookcase's (shelves against the back panel), a desk's (knee space against the modesty panel).
  std::array<double, 2> from_minus{}, from_plus{};
  for (int a = 0; a < 2; ++a) {
    const int b = 1 - a;
    double sum_minus = 0, sum_plus = 0;
    long rays = 0;
    for (int z = 0; z < n[2]; ++z)
      for (int u = 0; u < n[size_t(b)]; ++u) {
        int first = -1, last = -1;
        for (int t = 0; t < n[size_t(a)]; ++t) {
          const uint8_t o = a == 0 ? at(t, u, z) : at(u, t, z);
          if (!o) continue;
          if (first < 0) first = t;
          last = t;
        }
        if (first < 0) continue;
        ++rays;
        sum_minus += double(first) / n[size_t(a)];
        sum_plus += double(n[size_t(a)] - 1 - last) / n[size_t(a)];
      }
    if (rays > 0) from_minus[size_t(a)] = sum_minus / double(rays), from_plus[size_t(a)] = sum_plus / double(rays);
  }
  // Per axis: how much more open its + end is than its - end, and how far from the + end its top
  // stands; a ray that stops at a shell it looks into from both ends (a bucket seat) says little,
  // the top's side then decides.
  const std::array<double, 2> open = {from_plus[0] - from_minus[0] - high.x(), from_plus[1] - from_minus[1] - high.y()};
  // Long furniture (a sofa, a desk, a cabinet) faces across its length; a chair may face along
  // either axis: the more open of the two decides.
  const float longer = std::max(ext.x(), ext.y()), shorter = std::min(ext.x(), ext.y());
  int axis = std::abs(open[0]) > std::abs(open[1]) ? 0 : 1;
  const bool elongated = longer >= 1.3f * shorter;
  if (elongated) axis = ext.x() >= ext.y() ? 1 : 0;
  // Below this difference neither end is more open (a closed chest, a table).
  constexpr double kMargin = 0.03;
  char b[200];
  std::snprintf(b, sizeof b, "open depth +x %.2f -x %.2f +y %.2f -y %.2f, top at %+.2f %+.2f%s", from_plus[0],
                from_minus[0], from_plus[1], from_minus[1], high.x(), high.y(), elongated ? ", faces across its length" : "");
  if (std::abs(open[size_t(axis)]) < kMargin) {
    // The catalog frame's depth axis (-y), or -x across a model long along y.
    e.ambiguous = true;
    e.front = elongated && ext.y() > ext.x() ? Eigen::Vector3f(-1.f, 0.f, 0.f) : Eigen::Vector3f(0.f, -1.f, 0.f);
    e.how = "estimated " + AxisName(e.front) + " (no side more open: " + b + ")";
    return e;
  }
  e.front = Eigen::Vector3f::Zero();
  e.front[axis] = open[size_t(axis)] > 0 ? 1.f : -1.f;
  e.how = "estimated " + AxisName(e.front) + " (" + b + ")";
  return e;
}

float FacingYaw(const Eigen::Isometry3f& model_pose, const Eigen::Vector3f& front) {
  const Eigen::Vector3f d = model_pose.linear() * front;
  return std::atan2(d.y(), d.x());
}

void SetFacing(std::vector<Detection>& detections, const Catalog& catalog) {
  for (auto& d : detections) {
    if (d.model.empty() || d.model_pose.matrix() == Eigen::Matrix4f::Identity()) continue;
    if (const ModelFront* f = catalog.FrontOf(d.model)) d.yaw = FacingYaw(d.model_pose, f->front);
  }
}

}  // namespace furnihost
