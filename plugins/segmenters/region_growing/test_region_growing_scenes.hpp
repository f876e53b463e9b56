// Scenes and helpers of the segmenters.region_growing tests: the segmenter through the registry,
// angles, random spheres and quads, a box's faces with a ball, and parts compared point for point.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "furnihost/stage.hpp"
#include "region_growing_core.hpp"
#include "test_support.hpp"

namespace rg_test {

using furnihost::Points;
using furnihost::Scan;
using furnihost::Segmentation;
using furnihost::Segmenter;
namespace rg = furnihost::rg;

constexpr double kPi = 3.14159265358979323846;

inline std::shared_ptr<Segmenter> MakeSegmenter(const nlohmann::json& params = nlohmann::json::object()) {
  static auto reg = furnihost::testing::MakeRegistry();
  const auto* entry = reg->Find("segmenters.region_growing");
  EXPECT_NE(entry, nullptr) << "plugin not found in " << furnihost::testing::PluginDir();
  return reg->CreateAs<Segmenter>("segmenters.region_growing", entry->params.Resolve(params, "test"));
}

inline Segmentation RunSeg(const Scan& scan, const nlohmann::json& params = nlohmann::json::object()) {
  furnihost::RunContext ctx;
  ctx.threads = 2;
  return MakeSegmenter(params)->Segment(scan, ctx);
}

// In double and via atan2: acos of a float dot product near 1 is off by ~0.02 deg.
inline double AngleDeg(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  const Eigen::Vector3d x = a.cast<double>(), y = b.cast<double>();
  return std::atan2(x.cross(y).norm(), x.dot(y)) * 180.0 / kPi;
}

// Uniform random points on a sphere of radius r around c, about `density` points per m^2.
inline Points Sphere(const Eigen::Vector3f& c, float r, float density, std::mt19937_64& rng) {
  std::normal_distribution<float> g(0.f, 1.f);
  const int n = int(4 * kPi * r * r * density);
  Points pts;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3f d(g(rng), g(rng), g(rng));
    pts.push_back(c + r * d.normalized());
  }
  return pts;
}

// Uniform random points on the parallelogram o + s a + t b, s, t in [0, 1].
inline void AddQuad(Points& pts, std::vector<int>* face, int id, const Eigen::Vector3f& o, const Eigen::Vector3f& a,
             const Eigen::Vector3f& b, float density, std::mt19937_64& rng) {
  std::uniform_real_distribution<float> u(0.f, 1.f);
  const int n = int(a.cross(b).norm() * density);
  for (int i = 0; i < n; ++i) {
    pts.push_back(o + u(rng) * a + u(rng) * b);
    if (face) face->push_back(id);
  }
}

// The first `faces` of a box's bottom, top, front and back faces (corner lo, edges X, Y, Z) and
// a ball, `d` points per m2, with Gaussian noise of `sigma` on every coordinate.
inline Scan FacesAndBall(uint64_t seed, const Eigen::Vector3f& lo, const Eigen::Vector3f& X, const Eigen::Vector3f& Y,
                  const Eigen::Vector3f& Z, int faces, const Eigen::Vector3f& centre, float radius, float d,
                  float sigma) {
  std::mt19937_64 rng(seed);
  Scan scan;
  const Eigen::Vector3f o[4] = {lo, lo + Z, lo, lo + Y}, a[4] = {X, X, X, X}, b[4] = {Y, Y, Z, Z};
  for (int f = 0; f < faces; ++f) AddQuad(scan.points, nullptr, 0, o[f], a[f], b[f], d, rng);
  const Points ball = Sphere(centre, radius, d, rng);
  scan.points.insert(scan.points.end(), ball.begin(), ball.end());
  std::normal_distribution<float> noise(0.f, sigma);
  for (auto& p : scan.points) p += Eigen::Vector3f(noise(rng), noise(rng), noise(rng));
  return scan;
}

// The same parts, point for point, with the same centroids, and the same discarded points.
inline void ExpectSameParts(const Segmentation& a, const Segmentation& b) {
  ASSERT_EQ(a.parts.size(), b.parts.size());
  for (size_t k = 0; k < a.parts.size(); ++k) {
    EXPECT_EQ(a.parts[k].indices, b.parts[k].indices) << "part " << k;
    EXPECT_EQ(a.parts[k].centroid, b.parts[k].centroid) << "part " << k;
  }
  EXPECT_EQ(a.discarded_points, b.discarded_points);
}

}  // namespace rg_test
