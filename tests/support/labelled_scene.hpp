// Test scaffolding shared by the tests of segmenters.cgal_region_growing and
// segmenters.cgal_efficient_ransac: creating the segmenter through the registry, and a
// labelled floor + wall + cylinder scene. (The box scene every segmenter is compared on is
// tests/support/box_scene.hpp.)
#pragma once
#include <cmath>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace furnihost::testing {

// `type` created through the registry with `params` over its declared defaults.
inline std::shared_ptr<Segmenter> MakeSegmenter(const Registry& reg, const std::string& type,
                                                const nlohmann::json& params = nlohmann::json::object()) {
  const PluginEntry* e = reg.Find(type);
  if (!e) throw std::runtime_error(type + " not found in " + PluginDir());
  return reg.CreateAs<Segmenter>(type, e->params.Resolve(params, "test"));
}

// A scan whose points carry the label of the surface they were sampled from.
struct LabelledScene {
  Scan scan;
  std::vector<int> label;
  std::mt19937_64 rng;
  std::normal_distribution<float> noise{0.f, 0.001f};  // 1 mm on each coordinate
  Eigen::Vector3f offset = Eigen::Vector3f::Zero();    // added to every point (map coordinates)

  // Appends p + noise + offset with label l.
  void Add(const Eigen::Vector3f& p, int l) {
    scan.points.push_back(p + Eigen::Vector3f(noise(rng), noise(rng), noise(rng)) + offset);
    label.push_back(l);
  }
};

// Floor (label 0, 1.2 x 1.2 m at z = 0) + wall (label 1, x = 0.8, 1.2 m wide, z 0.1..1.0)
// + vertical cylinder (label 2, r = 0.15 m, axis at (-0.3, 0), z 0.2..0.8): 1 cm spacing,
// 1 mm noise; sensor origin at (0, -1.5, 1.2). All shifted by `offset`. Callers may Add more.
inline LabelledScene MakeFloorWallCylinder(uint64_t seed, const Eigen::Vector3f& offset = Eigen::Vector3f::Zero()) {
  LabelledScene s;
  s.rng.seed(seed);
  s.offset = offset;
  for (int i = 0; i <= 120; ++i)
    for (int j = 0; j <= 120; ++j) s.Add({-0.6f + 0.01f * i, -0.6f + 0.01f * j, 0.f}, 0);
  for (int j = 0; j <= 120; ++j)
    for (int k = 10; k <= 100; ++k) s.Add({0.8f, -0.6f + 0.01f * j, 0.01f * k}, 1);
  const int around = int(std::lround(2 * M_PI * 0.15 / 0.01));
  for (int a = 0; a < around; ++a)
    for (int k = 20; k <= 80; ++k) {
      const float t = float(2 * M_PI * a / around);
      s.Add({-0.3f + 0.15f * std::cos(t), 0.15f * std::sin(t), 0.01f * k}, 2);
    }
  s.scan.origin = Eigen::Vector3f(0.f, -1.5f, 1.2f) + offset;
  return s;
}

}  // namespace furnihost::testing
