// Point-sampled synthetic furniture for the voters.pcl_ism test and benchmark: objects are
// unions of boxes whose faces are sampled on a grid with Gaussian noise; a "view" keeps the
// faces that look at the sensor (no occlusion between boxes). Metres, z up, object frame =
// footprint centre on the floor.
#pragma once
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::ism_synth {

struct Box {
  Eigen::Vector3f centre, half;
};

struct Shape {
  std::string cls;
  Eigen::Vector3f size;  // bounding-box extents [m]
  std::vector<Box> boxes;
};

// An L-shaped chair: seat, back, four legs. 0.5 x 0.5 x 0.95 m.
inline Shape Chair() {
  Shape s{"chair", {0.5f, 0.5f, 0.95f}, {}};
  s.boxes.push_back({{0.f, 0.f, 0.45f}, {0.25f, 0.25f, 0.025f}});
  s.boxes.push_back({{-0.225f, 0.f, 0.71f}, {0.025f, 0.25f, 0.24f}});
  for (float x : {-0.2f, 0.2f})
    for (float y : {-0.2f, 0.2f}) s.boxes.push_back({{x, y, 0.2125f}, {0.02f, 0.02f, 0.2125f}});
  return s;
}

// A table: top and four legs. 1.2 x 0.8 x 0.75 m.
inline Shape Table() {
  Shape s{"table", {1.2f, 0.8f, 0.75f}, {}};
  s.boxes.push_back({{0.f, 0.f, 0.72f}, {0.6f, 0.4f, 0.03f}});
  for (float x : {-0.55f, 0.55f})
    for (float y : {-0.35f, 0.35f}) s.boxes.push_back({{x, y, 0.345f}, {0.03f, 0.03f, 0.345f}});
  return s;
}

// Samples the faces of `boxes` (placed by `pose`) that face `sensor`, every `step` metres,
// with Gaussian noise of `noise` metres along the face normal.
inline void SampleVisible(const std::vector<Box>& boxes, const Eigen::Isometry3f& pose,
                          const Eigen::Vector3f& sensor, float step, float noise, std::mt19937_64& rng,
                          Points& out, std::vector<int>* box_of_point = nullptr) {
  std::normal_distribution<float> gauss(0.f, noise > 0.f ? noise : 1.f);  // noise 0: exact faces
  for (size_t b = 0; b < boxes.size(); ++b) {
    const Box& box = boxes[b];
    for (int axis = 0; axis < 3; ++axis) {
      for (float sign : {-1.f, 1.f}) {
        Eigen::Vector3f n = Eigen::Vector3f::Zero();
        n[axis] = sign;
        const Eigen::Vector3f face = box.centre + sign * box.half[axis] * n;
        const Eigen::Vector3f wn = pose.linear() * n;
        if (wn.dot(sensor - pose * face) <= 0.f) continue;
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        const int nu = std::max(1, static_cast<int>(std::ceil(2.f * box.half[u] / step)));
        const int nv = std::max(1, static_cast<int>(std::ceil(2.f * box.half[v] / step)));
        for (int i = 0; i <= nu; ++i)
          for (int j = 0; j <= nv; ++j) {
            Eigen::Vector3f p = face;
            p[u] += box.half[u] * (2.f * i / nu - 1.f);
            p[v] += box.half[v] * (2.f * j / nv - 1.f);
            out.push_back(pose * p + wn * (noise > 0.f ? gauss(rng) : 0.f));
            if (box_of_point) box_of_point->push_back(static_cast<int>(b));
          }
      }
    }
  }
}

inline Eigen::Isometry3f Placement(float x, float y, float yaw) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.translation() = Eigen::Vector3f(x, y, 0.f);
  t.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  return t;
}

// `per_shape` views of each shape from sensors on a circle (radius 3 m, height 1.5 m) around
// it, as the training sensor would see a catalog model placed at the origin.
inline std::vector<TrainingView> MakeViews(const std::vector<Shape>& shapes, int per_shape, float step,
                                           uint64_t seed, float noise = 0.003f) {
  std::mt19937_64 rng(seed);
  std::vector<TrainingView> views;
  for (const auto& s : shapes)
    for (int v = 0; v < per_shape; ++v) {
      const float a = 6.2831853f * (static_cast<float>(v) + 0.25f) / static_cast<float>(per_shape);
      TrainingView tv;
      tv.cls = s.cls;
      tv.model_id = s.cls + "_0";
      tv.view = v;
      tv.object_size = s.size;
      tv.scan.origin = Eigen::Vector3f(3.f * std::cos(a), 3.f * std::sin(a), 1.5f);
      SampleVisible(s.boxes, Eigen::Isometry3f::Identity(), *tv.scan.origin, step, noise, rng, tv.scan.points);
      Eigen::Vector3f c = Eigen::Vector3f::Zero();
      for (const auto& p : tv.scan.points) c += p;
      tv.object_centroid = c / static_cast<float>(tv.scan.points.size());
      views.push_back(std::move(tv));
    }
  return views;
}

struct Placed {
  Shape shape;
  Eigen::Isometry3f pose;
};

// A room: the objects, a floor (x, y in [0, room_x] x [0, room_y]) when floor_step > 0, seen
// from `sensor`. Parts of the returned segmentation = one per box, plus the floor.
struct Room {
  Scan scan;
  Segmentation seg;
  std::vector<int> part_object;         // object index of each part, -1 = floor
  std::vector<Eigen::Vector3f> centre;  // per object: centroid of its points (what ISM locates)
};

inline Room MakeRoom(const std::vector<Placed>& objects, const Eigen::Vector3f& sensor, float step,
                     float floor_step, float room_x, float room_y, uint64_t seed) {
  std::mt19937_64 rng(seed);
  Room r;
  r.scan.origin = sensor;
  for (size_t o = 0; o < objects.size(); ++o) {
    std::vector<int> box_of;
    const size_t first = r.scan.points.size();
    SampleVisible(objects[o].shape.boxes, objects[o].pose, sensor, step, 0.003f, rng, r.scan.points, &box_of);
    Eigen::Vector3f c = Eigen::Vector3f::Zero();
    for (size_t k = first; k < r.scan.points.size(); ++k) c += r.scan.points[k];
    r.centre.push_back(c / static_cast<float>(r.scan.points.size() - first));
    std::vector<Part> parts(objects[o].shape.boxes.size());
    for (size_t k = 0; k < box_of.size(); ++k) parts[box_of[k]].indices.push_back(static_cast<int>(first + k));
    for (auto& p : parts) {
      if (p.indices.empty()) continue;
      for (int i : p.indices) p.centroid += r.scan.points[i];
      p.centroid /= static_cast<float>(p.indices.size());
      r.seg.parts.push_back(p);
      r.part_object.push_back(static_cast<int>(o));
    }
  }
  if (floor_step > 0.f) {
    std::normal_distribution<float> gauss(0.f, 0.003f);
    Part floor;
    for (float x = 0.f; x <= room_x; x += floor_step)
      for (float y = 0.f; y <= room_y; y += floor_step) {
        floor.indices.push_back(static_cast<int>(r.scan.points.size()));
        r.scan.points.emplace_back(x, y, gauss(rng));
        floor.centroid += r.scan.points.back();
      }
    floor.centroid /= static_cast<float>(floor.indices.size());
    r.seg.parts.push_back(floor);
    r.part_object.push_back(-1);
  }
  return r;
}

}  // namespace furnihost::ism_synth
