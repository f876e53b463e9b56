// Hand-built training views and scenes for the voter tests and benchmark: parts are reduced
// to a centroid, a few points around it and a synthetic feature vector, so the geometry of
// every vote is known in advance.
#pragma once
#include <Eigen/Geometry>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "furnihost/stage.hpp"
#include "furnihost/types.hpp"

namespace furnihost::synth {

// A part type of a class: its feature prototype and its centroid relative to the object
// centroid, in the object's (= training sensor's) frame [m].
struct PartType {
  std::vector<float> feature;
  Eigen::Vector3f offset = Eigen::Vector3f::Zero();
};

struct ClassSpec {
  std::string cls;
  Eigen::Vector3f size = Eigen::Vector3f::Ones();  // extents of model 0 [m]
  std::vector<PartType> parts;
};

constexpr int kDim = 8;

inline std::vector<float> Proto(int a, int b) {
  std::vector<float> f(kDim, 0.1f);
  f[a] = 0.9f;
  f[b] = 0.7f;
  return f;
}

// A chair: seat, back and four legs sharing one feature prototype. Width 0.5 m.
inline ClassSpec Chair() {
  ClassSpec c{"chair", {0.5f, 0.5f, 0.9f}, {}};
  c.parts.push_back({Proto(0, 1), {0.f, 0.f, 0.f}});
  c.parts.push_back({Proto(2, 3), {-0.22f, 0.f, 0.3f}});
  for (float sx : {-0.2f, 0.2f})
    for (float sy : {-0.2f, 0.2f}) c.parts.push_back({Proto(4, 5), {sx, sy, -0.25f}});
  return c;
}

// A table: top and four legs. Width 1.2 m.
inline ClassSpec Table() {
  ClassSpec c{"table", {1.2f, 0.8f, 0.75f}, {}};
  c.parts.push_back({Proto(6, 7), {0.f, 0.f, 0.3f}});
  for (float sx : {-0.55f, 0.55f})
    for (float sy : {-0.35f, 0.35f}) c.parts.push_back({Proto(1, 6), {sx, sy, -0.1f}});
  return c;
}

inline float Jitter(std::mt19937_64& rng, float amplitude) {
  return amplitude * (2.f * static_cast<float>(rng() >> 40) / static_cast<float>(1 << 24) - 1.f);
}

// Adds a part at `centroid` (scan frame) with 20 points on a 2 cm spread, so plots show it.
inline void AddPart(Scan& scan, Segmentation& seg, const Eigen::Vector3f& centroid) {
  Part part;
  part.centroid = centroid;
  for (int i = 0; i < 20; ++i) {
    const float a = 0.314159f * i;
    part.indices.push_back(static_cast<int>(scan.points.size()));
    scan.points.push_back(centroid + Eigen::Vector3f(0.02f * std::cos(a), 0.02f * std::sin(a), 0.f));
  }
  seg.parts.push_back(part);
}

// `models` models per class (model m scales the offsets by 1 + 0.04 m), `views` views each.
// Every view shows the object in the same orientation, seen from a sensor 2 m away along -x
// (so the viewing frame is the scan frame); the features carry uniform noise of +-`noise`
// per dimension. The object centroid sits at (0, 0, 0.45) in the view's frame.
inline std::vector<TrainingView> MakeViews(const std::vector<ClassSpec>& classes, int models,
                                           int views, float noise, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<TrainingView> out;
  for (const auto& spec : classes)
    for (int m = 0; m < models; ++m)
      for (int v = 0; v < views; ++v) {
        const float scale = 1.f + 0.04f * m;
        TrainingView tv;
        tv.cls = spec.cls;
        tv.model_id = spec.cls + "_" + std::to_string(m);
        tv.view = v;
        tv.object_centroid = Eigen::Vector3f(0.f, 0.f, 0.45f);
        tv.scan.origin = Eigen::Vector3f(-2.f, 0.f, 1.5f);  // looking along +x: viewing frame = scan frame
        tv.object_size = spec.size * scale;
        tv.features.values.resize(static_cast<Eigen::Index>(spec.parts.size()), kDim);
        for (size_t p = 0; p < spec.parts.size(); ++p) {
          AddPart(tv.scan, tv.segmentation, tv.object_centroid + scale * spec.parts[p].offset);
          for (int j = 0; j < kDim; ++j)
            tv.features.values(static_cast<Eigen::Index>(p), j) = spec.parts[p].feature[j] + Jitter(rng, noise);
        }
        for (int j = 0; j < kDim; ++j) tv.features.names.push_back("f" + std::to_string(j));
        out.push_back(std::move(tv));
      }
  return out;
}

struct SceneObject {
  ClassSpec spec;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // object centroid, world frame [m]
  std::vector<int> skip;                             // part types left out (occlusion)
};

// One scan of `objects` taken with sensor pose `pose` (scan -> world). Objects face the
// sensor as in training, i.e. their offsets turn with the sensor's yaw. Owns its data.
struct Scene {
  Scan scan;
  Segmentation seg;
  FeatureMatrix features;
  std::vector<int> object_of_part;  // index into the objects, per part
  SceneParts Parts() const { return {&scan, &seg, &features}; }
};

inline Scene MakeScene(const std::vector<SceneObject>& objects, const Eigen::Isometry3f& pose,
                       float noise, uint64_t seed) {
  std::mt19937_64 rng(seed);
  Scene s;
  s.scan.pose = pose;
  s.scan.source = "synthetic";
  const float yaw = std::atan2(pose.linear()(1, 0), pose.linear()(0, 0));
  const Eigen::Matrix3f rz = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  std::vector<std::vector<float>> rows;
  for (size_t o = 0; o < objects.size(); ++o)
    for (size_t p = 0; p < objects[o].spec.parts.size(); ++p) {
      bool skip = false;
      for (int k : objects[o].skip) skip = skip || k == static_cast<int>(p);
      if (skip) continue;
      const Eigen::Vector3f world = objects[o].center + rz * objects[o].spec.parts[p].offset;
      AddPart(s.scan, s.seg, pose.inverse() * world);
      std::vector<float> f = objects[o].spec.parts[p].feature;
      for (float& x : f) x += Jitter(rng, noise);
      rows.push_back(f);
      s.object_of_part.push_back(static_cast<int>(o));
    }
  s.features.values.resize(static_cast<Eigen::Index>(rows.size()), kDim);
  for (size_t i = 0; i < rows.size(); ++i)
    for (int j = 0; j < kDim; ++j) s.features.values(static_cast<Eigen::Index>(i), j) = rows[i][j];
  for (int j = 0; j < kDim; ++j) s.features.names.push_back("f" + std::to_string(j));
  return s;
}

inline Eigen::Isometry3f Pose(float x, float y, float yaw) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.translate(Eigen::Vector3f(x, y, 0.f));
  t.rotate(Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()));
  return t;
}

}  // namespace furnihost::synth
