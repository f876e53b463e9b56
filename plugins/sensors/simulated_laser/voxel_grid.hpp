// Voxel-grid downsampling for density matching (issue 3, item 4).
//
// The grid is anchored at the world origin (voxel (i, j, k) covers [i, i+1) * voxel_m, ...),
// never at the cloud's own minimum, so a training view and a scene scan downsampled with the
// same voxel_m see the same cells. Each occupied voxel yields the centroid of its points;
// output order is the order in which voxels are first met, so the result depends only on the
// input order (deterministic, no hashing order leaks out).
//
// Header-only so the host can offer the identical operation for file scans.
#pragma once
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace furnihost::voxel {

struct Downsampled {
  std::vector<Eigen::Vector3f> points;  // one centroid per occupied voxel
  std::vector<size_t> representative;   // index (into the input) of each voxel's first point
};

// points: N input points [m]; voxel_m > 0.
inline Downsampled Downsample(const std::vector<Eigen::Vector3f>& points, float voxel_m) {
  Downsampled out;
  if (!(voxel_m > 0.f)) {
    out.points = points;
    out.representative.resize(points.size());
    for (size_t i = 0; i < points.size(); ++i) out.representative[i] = i;
    return out;
  }
  // 21 bits per axis: +-1e6 cells, i.e. +-20 km at 1 cm voxels.
  auto key = [voxel_m](const Eigen::Vector3f& p) {
    auto cell = [voxel_m](float c) {
      return static_cast<uint64_t>(static_cast<int64_t>(std::floor(c / voxel_m)) + (1 << 20)) &
             0x1FFFFFull;
    };
    return cell(p.x()) | (cell(p.y()) << 21) | (cell(p.z()) << 42);
  };
  std::unordered_map<uint64_t, size_t> slot;
  slot.reserve(points.size() / 2 + 1);
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count;
  for (size_t i = 0; i < points.size(); ++i) {
    auto [it, fresh] = slot.emplace(key(points[i]), sum.size());
    if (fresh) {
      sum.emplace_back(Eigen::Vector3d::Zero());
      count.push_back(0);
      out.representative.push_back(i);
    }
    sum[it->second] += points[i].cast<double>();
    ++count[it->second];
  }
  out.points.reserve(sum.size());
  for (size_t s = 0; s < sum.size(); ++s) out.points.push_back((sum[s] / count[s]).cast<float>());
  return out;
}

}  // namespace furnihost::voxel
