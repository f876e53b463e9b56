// Test and benchmark helper: box-built furniture meshes and a ray-cast range sensor, so that
// the fitter can be checked against known poses without any data file.
// World frame: metres, z up, floor at z = 0.
#pragma once
#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <random>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::synthetic {

// Appends an axis-aligned box with outward-wound faces; `component` is stored per triangle.
inline void AddBox(Mesh* m, std::vector<int>* comp, int component, const Eigen::Vector3f& lo,
                   const Eigen::Vector3f& hi) {
  const int b = static_cast<int>(m->vertices.size());
  for (int i = 0; i < 8; ++i)
    m->vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) {
    m->triangles.emplace_back(b + t[0], b + t[1], b + t[2]);
    if (comp) comp->push_back(component);
  }
}

struct Furniture {
  Mesh mesh;
  std::vector<int> component;  // per triangle: which box (seat, back, leg...)
};

// A chair: seat of w x d at height h, back of height back_h on the +y side, four legs.
inline Furniture Chair(float w, float d, float h, float back_h, float leg = 0.04f, float t = 0.04f) {
  Furniture f;
  const float x = w / 2, y = d / 2;
  AddBox(&f.mesh, &f.component, 0, {-x, -y, h - t}, {x, y, h});
  AddBox(&f.mesh, &f.component, 1, {-x, y - t, h}, {x, y, h + back_h});
  int c = 2;
  for (float sx : {-1.f, 1.f})
    for (float sy : {-1.f, 1.f}) {
      const Eigen::Vector3f a(sx > 0 ? x - leg : -x, sy > 0 ? y - leg : -y, 0.f);
      AddBox(&f.mesh, &f.component, c++, a, a + Eigen::Vector3f(leg, leg, h - t));
    }
  return f;
}

// A table: top of w x d x t at height h, four legs inset by `inset`.
inline Furniture Table(float w, float d, float h, float t = 0.04f, float leg = 0.06f, float inset = 0.05f) {
  Furniture f;
  AddBox(&f.mesh, &f.component, 0, {-w / 2, -d / 2, h - t}, {w / 2, d / 2, h});
  int c = 1;
  for (float sx : {-1.f, 1.f})
    for (float sy : {-1.f, 1.f}) {
      const Eigen::Vector3f a(sx > 0 ? w / 2 - inset - leg : -w / 2 + inset,
                              sy > 0 ? d / 2 - inset - leg : -d / 2 + inset, 0.f);
      AddBox(&f.mesh, &f.component, c++, a, a + Eigen::Vector3f(leg, leg, h - t));
    }
  return f;
}

inline Eigen::AlignedBox3f BoundsOf(const Mesh& mesh) {
  Eigen::AlignedBox3f b;
  b.setEmpty();
  for (const auto& v : mesh.vertices) b.extend(v);
  return b;
}

inline CatalogModel Model(const std::string& id, const std::string& cls, const Mesh& mesh) {
  CatalogModel m;
  m.id = id;
  m.cls = cls;
  m.mesh = mesh;
  const Eigen::AlignedBox3f b = BoundsOf(mesh);
  m.size = b.max() - b.min();
  return m;
}

// A scene to scan: triangle soup in the world frame with an object id per triangle
// (-1 = background such as floor and walls) and a component id per triangle.
struct World {
  Points v0, e1, e2;  // triangle = v0 + [e1 e2] barycentric
  std::vector<int> object, component;

  void Add(const Mesh& mesh, const Eigen::Isometry3f& pose, int obj, const std::vector<int>* comp = nullptr) {
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto& f = mesh.triangles[t];
      const Eigen::Vector3f a = pose * mesh.vertices[f[0]];
      v0.push_back(a);
      e1.push_back(pose * mesh.vertices[f[1]] - a);
      e2.push_back(pose * mesh.vertices[f[2]] - a);
      object.push_back(obj);
      component.push_back(comp ? (*comp)[t] : 0);
    }
  }
  // Floor z = 0 over [-r, r]² and, optionally, walls of height `wall_h` and a ceiling.
  void AddRoom(float r, float wall_h, bool ceiling = false) {
    Mesh m;
    AddBox(&m, nullptr, 0, {-r, -r, -0.02f}, {r, r, 0.f});
    if (wall_h > 0) {
      AddBox(&m, nullptr, 0, {-r, -r, 0}, {r, -r + 0.02f, wall_h});
      AddBox(&m, nullptr, 0, {-r, r - 0.02f, 0}, {r, r, wall_h});
      AddBox(&m, nullptr, 0, {-r, -r, 0}, {-r + 0.02f, r, wall_h});
      AddBox(&m, nullptr, 0, {r - 0.02f, -r, 0}, {r, r, wall_h});
      if (ceiling) AddBox(&m, nullptr, 0, {-r, -r, wall_h}, {r, r, wall_h + 0.02f});
    }
    Add(m, Eigen::Isometry3f::Identity(), -1);
  }

  // Nearest hit along o + s d (Möller-Trumbore); returns the triangle or -1.
  int Cast(const Eigen::Vector3f& o, const Eigen::Vector3f& d, float* dist) const {
    int best = -1;
    float tbest = std::numeric_limits<float>::infinity();
    for (size_t t = 0; t < v0.size(); ++t) {
      const Eigen::Vector3f p = d.cross(e2[t]);
      const float det = e1[t].dot(p);
      if (std::fabs(det) < 1e-12f) continue;
      const float inv = 1.f / det;
      const Eigen::Vector3f s = o - v0[t];
      const float u = s.dot(p) * inv;
      if (u < 0 || u > 1) continue;
      const Eigen::Vector3f q = s.cross(e1[t]);
      const float v = d.dot(q) * inv;
      if (v < 0 || u + v > 1) continue;
      const float tt = e2[t].dot(q) * inv;
      if (tt > 1e-4f && tt < tbest) {
        tbest = tt;
        best = static_cast<int>(t);
      }
    }
    *dist = tbest;
    return best;
  }
};

struct SimScan {
  Scan scan;                 // points in the scan frame (scan.pose maps them to the world)
  Points normals;            // per point, scan frame, facing the sensor
  std::vector<int> object;   // per point: object id of the hit triangle (-1 background)
  std::vector<int> component;
};

// Casts a grid of rays from `origin` (world) over azimuth [az0, az1] x elevation [el0, el1]
// (radians, about +z from +x / above the horizontal) and keeps the hits with Gaussian range
// noise `sigma` [m] and normals perturbed by about `normal_noise` [rad]. The result is
// expressed in a scan frame given by `pose` (scan -> world).
inline SimScan Simulate(const World& w, const Eigen::Vector3f& origin, float az0, float az1, int naz, float el0,
                        float el1, int nel, float sigma, float normal_noise, uint64_t seed,
                        const Eigen::Isometry3f& pose = Eigen::Isometry3f::Identity(), bool with_origin = true,
                        bool keep_background = true) {
  SimScan s;
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.f, 1.f);
  const Eigen::Isometry3f inv = pose.inverse();
  for (int i = 0; i < nel; ++i) {
    const float el = nel > 1 ? el0 + (el1 - el0) * i / (nel - 1) : el0;
    for (int j = 0; j < naz; ++j) {
      const float az = naz > 1 ? az0 + (az1 - az0) * j / (naz - 1) : az0;
      const Eigen::Vector3f d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      float t = 0.f;
      const int tri = w.Cast(origin, d, &t);
      if (tri < 0) continue;
      if (!keep_background && w.object[tri] < 0) continue;
      const Eigen::Vector3f p = origin + d * (t + sigma * g(rng));
      Eigen::Vector3f n = w.e1[tri].cross(w.e2[tri]).normalized();
      if (n.dot(d) > 0) n = -n;
      n = (n + normal_noise * Eigen::Vector3f(g(rng), g(rng), g(rng))).normalized();
      s.scan.points.push_back(inv * p);
      s.normals.push_back(inv.linear() * n);
      s.object.push_back(w.object[tri]);
      s.component.push_back(w.component[tri]);
    }
  }
  s.scan.pose = pose;
  if (with_origin) s.scan.origin = inv * origin;
  s.scan.source = "synthetic";
  return s;
}

// Rays covering the angular box of `centre` ± `radius` seen from `origin`.
inline SimScan SimulateObject(const World& w, const Eigen::Vector3f& origin, const Eigen::Vector3f& centre,
                              float radius, int rays_per_axis, float sigma, float normal_noise, uint64_t seed,
                              const Eigen::Isometry3f& pose = Eigen::Isometry3f::Identity(), bool with_origin = true) {
  const Eigen::Vector3f d = centre - origin;
  const float az = std::atan2(d.y(), d.x()), el = std::atan2(d.z(), d.head<2>().norm());
  const float half = std::atan2(radius, d.norm());
  return Simulate(w, origin, az - half, az + half, rays_per_axis, el - half, el + half, rays_per_axis, sigma,
                  normal_noise, seed, pose, with_origin, true);
}

// A segmentation with one part per (object, component) of the chosen object and one part for
// everything else; `parts_of_object` lists the object's part indices.
inline Segmentation PartsOf(const SimScan& s, int object, std::vector<int>* parts_of_object) {
  Segmentation seg;
  seg.normals = s.normals;
  seg.curvature.assign(s.scan.points.size(), 0.f);
  std::map<int, int> part_of_comp;
  Part rest;
  for (size_t i = 0; i < s.scan.points.size(); ++i) {
    if (s.object[i] != object) {
      rest.indices.push_back(static_cast<int>(i));
      continue;
    }
    auto it = part_of_comp.find(s.component[i]);
    if (it == part_of_comp.end()) {
      it = part_of_comp.emplace(s.component[i], static_cast<int>(seg.parts.size())).first;
      seg.parts.emplace_back();
      parts_of_object->push_back(it->second);
    }
    seg.parts[it->second].indices.push_back(static_cast<int>(i));
  }
  if (!rest.indices.empty()) seg.parts.push_back(rest);
  for (Part& p : seg.parts) {
    for (int i : p.indices) p.centroid += s.scan.points[i];
    p.centroid /= static_cast<float>(p.indices.size());
  }
  return seg;
}

}  // namespace furnihost::synthetic
