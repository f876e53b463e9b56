// Meshes built from boxes for tests: furniture shapes whose geometry a test knows exactly.
#pragma once
#include "furnihost/types.hpp"

namespace furnihost::testing {

// An axis-aligned box [lo, hi] as 12 triangles appended to `m`, wound so their normals face out.
inline void AddBox(Mesh& m, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  const int b = int(m.vertices.size());
  for (int i = 0; i < 8; ++i)
    m.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  const int q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    m.triangles.emplace_back(b + f[0], b + f[1], b + f[2]);
    m.triangles.emplace_back(b + f[0], b + f[2], b + f[3]);
  }
}

}  // namespace furnihost::testing
