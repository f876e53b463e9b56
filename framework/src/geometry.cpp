#include "furnihost/geometry.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>
#include <unordered_map>
#include <unordered_set>

namespace furnihost {

namespace {

// Key of the cubic voxel of edge `voxel` holding p, shifted by (dx, dy, dz) voxels. 21 bits
// per axis: +-1e6 voxels around the origin; wraps beyond (still deterministic). v / voxel, not
// v * (1 / voxel): the correctly rounded quotient puts a point that lies on a voxel boundary
// (k * voxel) in voxel k, as floor(v / voxel) computed anywhere else does.
uint64_t VoxelKey(const Eigen::Vector3f& p, float voxel, int dx = 0, int dy = 0, int dz = 0) {
  auto q = [&](float v, int d) {
    return static_cast<uint64_t>((static_cast<int64_t>(std::floor(v / voxel)) + d) & 0x1FFFFF);
  };
  return q(p.x(), dx) | (q(p.y(), dy) << 21) | (q(p.z(), dz) << 42);
}

}  // namespace

Points VoxelDownsample(const Points& points, float voxel, std::vector<int>* kept) {
  if (!(voxel > 0.f)) {
    if (kept) {
      kept->resize(points.size());
      for (size_t i = 0; i < points.size(); ++i) (*kept)[i] = static_cast<int>(i);
    }
    return points;
  }
  // Voxel key -> slot in first-met order, the sums in plain arrays: ~1.5x faster than a map
  // holding the accumulators (400k points).
  std::unordered_map<uint64_t, int> slot;
  slot.reserve(points.size() / 2 + 16);
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count, first;
  for (size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    const uint64_t key = VoxelKey(p, voxel);
    auto [it, fresh] = slot.try_emplace(key, static_cast<int>(sum.size()));
    if (fresh) {
      sum.emplace_back(Eigen::Vector3d::Zero());
      count.push_back(0);
      first.push_back(static_cast<int>(i));
    }
    sum[it->second] += p.cast<double>();
    ++count[it->second];
  }
  Points out(sum.size());
  for (size_t s = 0; s < sum.size(); ++s) out[s] = (sum[s] / count[s]).cast<float>();
  if (kept) *kept = std::move(first);
  return out;
}

Eigen::Isometry3f UprightPose(float x, float y, float z, float yaw) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3f(x, y, z);
  return t;
}

namespace {

// World z of the finite points of the scans (each mapped by its pose), with x and y; at most
// ~200k per scan (a sample is plenty for a histogram or a plane).
Points FloorSample(const std::vector<const Scan*>& scans) {
  Points w;
  for (const Scan* sc : scans) {
    if (!sc) continue;
    const size_t n = sc->points.size();
    const size_t step = std::max<size_t>(1, n / 200000);
    for (size_t i = 0; i < n; i += step) {
      const Eigen::Vector3f p = sc->pose * sc->points[i];
      if (p.allFinite()) w.push_back(p);
    }
  }
  return w;
}

// Height below which 30 % of the sample lies.
float LowCut(const Points& w) {
  std::vector<float> z(w.size());
  for (size_t i = 0; i < w.size(); ++i) z[i] = w[i].z();
  const size_t cut = std::min(z.size() - 1, z.size() * 3 / 10);
  std::nth_element(z.begin(), z.begin() + cut, z.end());
  return z[cut];
}

// Mean height of the densest 2 cm z-slice among the points at or below `hi`.
float DensestSlice(const Points& w, float hi) {
  float lo = hi;
  for (const auto& p : w) lo = std::min(lo, p.z());
  const float bin = 0.02f;
  const int bins = std::min(100000, static_cast<int>((hi - lo) / bin) + 1);
  std::vector<int> count(bins, 0);
  std::vector<double> sum(bins, 0.0);
  for (const auto& p : w) {
    if (p.z() > hi) continue;
    const int b = std::clamp(static_cast<int>((p.z() - lo) / bin), 0, bins - 1);
    ++count[b];
    sum[b] += p.z();
  }
  const int best = static_cast<int>(std::max_element(count.begin(), count.end()) - count.begin());
  return static_cast<float>(sum[best] / std::max(1, count[best]));
}

}  // namespace

float EstimateFloorZ(const std::vector<const Scan*>& scans) {
  const Points w = FloorSample(scans);
  if (w.empty()) return 0.f;
  return DensestSlice(w, LowCut(w));
}

FloorPlane EstimateFloorPlane(const std::vector<const Scan*>& scans) {
  FloorPlane level;
  const Points w = FloorSample(scans);
  if (w.empty()) return level;
  const float hi = LowCut(w);
  level.c = DensestSlice(w, hi);
  // RANSAC over (a stride sample of) the lowest 30 %: the plane, tilted at most 10 degrees,
  // with the most points within 2 cm. The level plane through the densest slice competes too,
  // so a plane is only tilted when that explains more of the floor.
  const size_t n_low = static_cast<size_t>(std::count_if(w.begin(), w.end(), [&](const auto& p) { return p.z() <= hi; }));
  const size_t stride = std::max<size_t>(1, n_low / 4000);
  Points q;
  size_t k = 0;
  for (const auto& p : w)
    if (p.z() <= hi && k++ % stride == 0) q.push_back(p);
  const float band = 0.02f;
  const float min_nz = std::cos(10.f * 3.14159265f / 180.f);
  auto inliers = [&](const Eigen::Vector3f& n, float d) {
    int c = 0;
    for (const auto& p : q) c += std::abs(n.dot(p) - d) < band;
    return c;
  };
  Eigen::Vector3f best_n = Eigen::Vector3f::UnitZ();
  float best_d = level.c;
  int best = inliers(best_n, best_d);
  if (q.size() >= 3) {
    std::mt19937 rng(0x9e3779b9u);  // fixed: the floor of a scan does not depend on the run's seed
    for (int it = 0; it < 200; ++it) {
      const Eigen::Vector3f& a = q[rng() % q.size()];
      const Eigen::Vector3f& b = q[rng() % q.size()];
      const Eigen::Vector3f& c = q[rng() % q.size()];
      Eigen::Vector3f n = (b - a).cross(c - a);
      const float len = n.norm();
      if (!(len > 1e-6f)) continue;
      n /= len;
      if (n.z() < 0.f) n = -n;
      if (n.z() < min_nz) continue;
      const int k = inliers(n, n.dot(a));
      if (k > best) {
        best = k;
        best_n = n;
        best_d = n.dot(a);
      }
    }
  }
  // Least squares z = a x + b y + c over the points within the band, twice (the first pass
  // only saw the lowest 30 %; the second takes the whole sample, the high side of a tilt).
  FloorPlane plane{-best_n.x() / best_n.z(), -best_n.y() / best_n.z(), best_d / best_n.z()};
  for (int pass = 0; pass < 2; ++pass) {
    const Points& src = pass == 0 ? q : w;
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    int n = 0;
    const double cos_t = 1.0 / std::sqrt(1.0 + double(plane.a) * plane.a + double(plane.b) * plane.b);
    for (const auto& p : src) {
      if (std::abs(plane.Above(p)) * cos_t >= band) continue;
      const Eigen::Vector3d r(p.x(), p.y(), 1.0);
      ata += r * r.transpose();
      atb += r * double(p.z());
      ++n;
    }
    if (n < 3) break;
    const Eigen::Vector3d x = ata.ldlt().solve(atb);
    if (!x.allFinite() || std::hypot(x[0], x[1]) > std::tan(10.0 * 3.14159265358979 / 180.0)) break;
    plane = {static_cast<float>(x[0]), static_cast<float>(x[1]), static_cast<float>(x[2])};
  }
  return plane;
}

}  // namespace furnihost

#include <random>

namespace furnihost {

Points SampleSurface(const Mesh& mesh, float per_m2, uint64_t seed, Points* normals) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  Points out;
  if (normals) normals->clear();
  const int nv = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles) {
    if (t.minCoeff() < 0 || t.maxCoeff() >= nv) continue;
    const Eigen::Vector3f a = mesh.vertices[t[0]], b = mesh.vertices[t[1]], c = mesh.vertices[t[2]];
    const Eigen::Vector3f cr = (b - a).cross(c - a);
    const float area = 0.5f * cr.norm();
    if (!(area > 0.f)) continue;
    const float expected = area * per_m2;
    int n = static_cast<int>(expected);
    if (u(rng) < expected - n) ++n;
    for (int i = 0; i < n; ++i) {
      float r1 = u(rng), r2 = u(rng);
      if (r1 + r2 > 1.f) { r1 = 1.f - r1; r2 = 1.f - r2; }
      out.push_back(a + r1 * (b - a) + r2 * (c - a));
      if (normals) normals->push_back(cr.normalized());
    }
  }
  return out;
}

FloorPlane FloorByMode(const std::string& mode, const std::vector<const Scan*>& scans, float fixed_z) {
  if (mode == "fixed") return FloorPlane{0.f, 0.f, fixed_z};
  if (mode == "plane") return EstimateFloorPlane(scans);
  return FloorPlane{0.f, 0.f, EstimateFloorZ(scans)};
}

int YawSymmetry(const Mesh& mesh, float tolerance) {
  double area = 0.0;
  const int nv = static_cast<int>(mesh.vertices.size());
  for (const auto& t : mesh.triangles)
    if (t.minCoeff() >= 0 && t.maxCoeff() < nv)
      area += 0.5 * double((mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]).norm());
  if (!(area > 0.0) || !(tolerance > 0.f)) return 1;
  const Points pts = SampleSurface(mesh, static_cast<float>(6000.0 / area), 1);
  if (pts.empty()) return 1;
  std::unordered_set<uint64_t> occupied;
  for (const auto& p : pts) occupied.insert(VoxelKey(p, tolerance));
  auto maps_onto_itself = [&](float degrees) {
    const Eigen::Matrix3f r = Eigen::AngleAxisf(degrees * 3.14159265f / 180.f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
    size_t hit = 0;
    for (const auto& p : pts) {
      const Eigen::Vector3f q = r * p;
      bool near = false;
      for (int dz = -1; dz <= 1 && !near; ++dz)
        for (int dy = -1; dy <= 1 && !near; ++dy)
          for (int dx = -1; dx <= 1 && !near; ++dx) near = occupied.count(VoxelKey(q, tolerance, dx, dy, dz)) > 0;
      hit += near;
    }
    return double(hit) >= 0.95 * double(pts.size());
  };
  if (!maps_onto_itself(180.f)) return 1;
  if (!maps_onto_itself(90.f)) return 2;
  return maps_onto_itself(30.f) && maps_onto_itself(45.f) ? 0 : 4;
}

std::array<uint8_t, 3> ClassColor(const std::string& cls) {
  if (cls == "chair") return {40, 90, 220};
  if (cls == "table") return {220, 40, 40};
  if (cls == "cabinet") return {235, 200, 30};
  if (cls == "armchair") return {40, 180, 220};
  if (cls == "sofa") return {150, 60, 200};
  if (cls == "desk") return {230, 120, 30};
  uint32_t h = 2166136261u;
  for (char c : cls) h = (h ^ static_cast<uint8_t>(c)) * 16777619u;
  return {static_cast<uint8_t>(60 + h % 180), static_cast<uint8_t>(60 + (h >> 8) % 180),
          static_cast<uint8_t>(60 + (h >> 16) % 180)};
}

}  // namespace furnihost
