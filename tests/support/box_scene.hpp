// Test scene shared by the segmenter tests (segmenters.pcl_region_growing): a closed box floating above a
// floor, every face sampled on a regular grid, with Gaussian noise. Each point carries the
// index of the plane it was sampled from, so a segmentation can be scored against it.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::testing {

struct BoxScene {
  Scan scan;
  std::vector<int> face;  // per point: 0 = floor, 1..6 = box faces
  int faces = 7;
};

// Box [x0, x0 + size.x] x [y0, ...] x [z0, ...] above a square floor of side `floor_side`
// centred under it; `step` [m] grid spacing, `noise` [m] standard deviation, `offset`
// added to every coordinate (map-coordinate scans).
inline BoxScene MakeBoxScene(float step = 0.01f, float noise = 0.001f, uint64_t seed = 7,
                             Eigen::Vector3f offset = Eigen::Vector3f::Zero()) {
  const Eigen::Vector3f lo(-0.3f, -0.2f, 0.2f), hi(0.3f, 0.2f, 0.7f);
  const float floor_half = 0.8f;
  BoxScene s;
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> gauss(0.f, noise);
  auto add = [&](const Eigen::Vector3f& p, int f) {
    s.scan.points.push_back(p + Eigen::Vector3f(gauss(rng), gauss(rng), gauss(rng)) + offset);
    s.face.push_back(f);
  };
  // A grid on the axis-aligned rectangle where coordinate `axis` is `value`.
  auto rect = [&](int axis, float value, const Eigen::Vector3f& a, const Eigen::Vector3f& b, int f) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const int nu = int(std::lround((b[u] - a[u]) / step)), nv = int(std::lround((b[v] - a[v]) / step));
    for (int i = 0; i <= nu; ++i)
      for (int j = 0; j <= nv; ++j) {
        Eigen::Vector3f p;
        p[axis] = value;
        p[u] = a[u] + (b[u] - a[u]) * float(i) / float(nu);
        p[v] = a[v] + (b[v] - a[v]) * float(j) / float(nv);
        add(p, f);
      }
  };
  rect(2, 0.f, Eigen::Vector3f(-floor_half, -floor_half, 0), Eigen::Vector3f(floor_half, floor_half, 0), 0);
  // Box faces share their edges; a shared edge point goes to the first face only.
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      Eigen::Vector3f a = lo, b = hi;
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      // Shrink the later axes' faces by one step so the edges are sampled once.
      for (int w : {u, v})
        if (w < axis) {
          a[w] += step;
          b[w] -= step;
        }
      rect(axis, side ? hi[axis] : lo[axis], a, b, 1 + axis * 2 + side);
    }
  s.scan.source = "synthetic box scene";
  s.scan.origin = Eigen::Vector3f(1.5f, -1.2f, 1.4f) + offset;
  return s;
}

struct FaceScore {
  int large_parts = 0;  // parts with at least `large` points
  std::vector<double> recall, purity;  // per face: share of the face in its best part, and
                                       // share of that part coming from the face
  std::vector<int> best_part;
};

inline FaceScore ScoreFaces(const BoxScene& s, const Segmentation& seg, int large) {
  FaceScore r;
  std::vector<int> face_size(s.faces, 0);
  for (int f : s.face) ++face_size[f];
  r.recall.assign(s.faces, 0.0);
  r.purity.assign(s.faces, 0.0);
  r.best_part.assign(s.faces, -1);
  for (size_t p = 0; p < seg.parts.size(); ++p) {
    const auto& idx = seg.parts[p].indices;
    if (int(idx.size()) >= large) ++r.large_parts;
    std::map<int, int> count;
    for (int i : idx) ++count[s.face[i]];
    for (const auto& [f, c] : count) {
      const double recall = double(c) / face_size[f];
      if (recall > r.recall[f]) {
        r.recall[f] = recall;
        r.purity[f] = double(c) / double(idx.size());
        r.best_part[f] = int(p);
      }
    }
  }
  return r;
}

// Output-shape invariants every segmenter must keep.
inline void ExpectWellFormed(const Scan& scan, const Segmentation& seg) {
  const size_t n = scan.points.size();
  ASSERT_EQ(seg.normals.size(), n);
  ASSERT_EQ(seg.curvature.size(), n);
  std::vector<char> seen(n, 0);
  size_t assigned = 0;
  for (const auto& part : seg.parts) {
    ASSERT_FALSE(part.indices.empty());
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int i : part.indices) {
      ASSERT_GE(i, 0);
      ASSERT_LT(size_t(i), n);
      ASSERT_FALSE(seen[i]) << "point " << i << " is in two parts";
      seen[i] = 1;
      c += scan.points[i].cast<double>();
    }
    assigned += part.indices.size();
    c /= double(part.indices.size());
    // Relative tolerance: map-coordinate scans keep only float precision in the centroid.
    EXPECT_LT((c - part.centroid.cast<double>()).norm(), 1e-5 * (1.0 + c.norm()));
  }
  EXPECT_EQ(size_t(seg.discarded_points), n - assigned);
  for (size_t i = 0; i < n; ++i)
    if (seg.normals[i].allFinite()) {
      EXPECT_NEAR(seg.normals[i].norm(), 1.f, 1e-3f) << i;
    }
}

}  // namespace furnihost::testing
