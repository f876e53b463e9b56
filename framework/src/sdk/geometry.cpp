#include "furnihost/geometry.hpp"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include "furnihost/hash.hpp"

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

// Voxel key -> slot, open addressing (linear probing) over a power-of-two table that doubles
// at half load: the normals' 27 neighbour lookups per voxel were most of the height map's
// time through std::unordered_map's node chains.
class FlatSlots {
 public:
  explicit FlatSlots(size_t expected) {
    size_t cap = 16;
    while (cap < 2 * expected) cap <<= 1;
    keys_.assign(cap, 0);
    vals_.assign(cap, -1);
  }
  // The slot of `key`, inserting `fresh_val` when absent; `fresh` tells which.
  int Insert(uint64_t key, int fresh_val, bool& fresh) {
    if (2 * (size_ + 1) > keys_.size()) Grow();
    size_t h = Home(key);
    while (vals_[h] >= 0) {
      if (keys_[h] == key) {
        fresh = false;
        return vals_[h];
      }
      h = (h + 1) & (keys_.size() - 1);
    }
    keys_[h] = key;
    vals_[h] = fresh_val;
    ++size_;
    fresh = true;
    return fresh_val;
  }
  // The slot of `key`, -1 when absent.
  int Find(uint64_t key) const {
    size_t h = Home(key);
    while (vals_[h] >= 0) {
      if (keys_[h] == key) return vals_[h];
      h = (h + 1) & (keys_.size() - 1);
    }
    return -1;
  }

 private:
  size_t Home(uint64_t key) const { return HashSlot(key, keys_.size() - 1); }
  void Grow() {
    std::vector<uint64_t> keys;
    std::vector<int> vals;
    keys.swap(keys_);
    vals.swap(vals_);
    keys_.assign(2 * keys.size(), 0);
    vals_.assign(2 * keys.size(), -1);
    size_ = 0;
    bool fresh;
    for (size_t i = 0; i < keys.size(); ++i)
      if (vals[i] >= 0) Insert(keys[i], vals[i], fresh);
  }
  std::vector<uint64_t> keys_;
  std::vector<int> vals_;
  size_t size_ = 0;
};

}  // namespace

Points VoxelDownsample(const Points& points, float voxel, std::vector<int>* kept) {
  if (!(voxel > 0.f)) {
    if (kept) {
      kept->resize(points.size());
      for (size_t i = 0; i < points.size(); ++i) (*kept)[i] = static_cast<int>(i);
    }
    return points;
  }
  // Voxel key -> slot in first-met order, the sums in plain arrays: the map holds small
  // integers only, and the accumulators stay contiguous.
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

void GroupMembers(const std::vector<uint32_t>& of, size_t groups, std::vector<uint32_t>& start,
                  std::vector<uint32_t>& members) {
  start.assign(groups + 1, 0);
  for (uint32_t u : of) ++start[u + 1];
  for (size_t u = 0; u < groups; ++u) start[u + 1] += start[u];
  members.resize(of.size());
  std::vector<uint32_t> fill(start.begin(), start.end() - 1);
  for (size_t i = 0; i < of.size(); ++i) members[fill[of[i]]++] = uint32_t(i);
}

Points GroupEqualPoints(const Points& points, std::vector<uint32_t>* of) {
  auto bits = [](float v) {
    v += 0.f;  // -0 -> +0
    uint32_t b;
    std::memcpy(&b, &v, 4);
    return b;
  };
  auto same = [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return bits(a.x()) == bits(b.x()) && bits(a.y()) == bits(b.y()) && bits(a.z()) == bits(b.z());
  };
  size_t cap = 16;
  while (cap < 2 * points.size()) cap <<= 1;
  std::vector<uint32_t> slot(cap, UINT32_MAX);  // distinct index held by each table slot
  Points distinct;
  if (of) of->resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    size_t k = HashSlot(SplitMix64((uint64_t(bits(p.x())) << 32) | bits(p.y())) ^ bits(p.z()), cap - 1);
    while (slot[k] != UINT32_MAX && !same(distinct[slot[k]], p)) k = (k + 1) & (cap - 1);
    if (slot[k] == UINT32_MAX) {
      slot[k] = uint32_t(distinct.size());
      distinct.push_back(p);
    }
    if (of) (*of)[i] = slot[k];
  }
  return distinct;
}

VoxelNormals EstimateVoxelNormals(const Points& points, float voxel) {
  return EstimateVoxelNormals(points, voxel, SerialRange);
}

VoxelNormals EstimateVoxelNormals(const Points& points, float voxel, const RangeFor& pfor) {
  VoxelNormals out;
  FlatSlots slot(points.size() / 4 + 16);
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count;
  out.voxel_of.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    bool fresh;
    const int v = slot.Insert(VoxelKey(points[i], voxel), int(sum.size()), fresh);
    if (fresh) {
      sum.emplace_back(Eigen::Vector3d::Zero());
      count.push_back(0);
    }
    sum[v] += points[i].cast<double>();
    ++count[v];
    out.voxel_of[i] = v;
  }
  const size_t n = sum.size();
  out.centroids.resize(n);
  for (size_t v = 0; v < n; ++v) out.centroids[v] = (sum[v] / count[v]).cast<float>();
  out.normals.assign(n, Eigen::Vector3f::UnitZ());
  out.flat.assign(n, 0);
  // Each voxel's fit reads the centroids and writes its own entries only.
  pfor(0, n, [&](size_t first, size_t last) {
  for (size_t v = first; v < last; ++v) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    int k = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int u = slot.Find(VoxelKey(out.centroids[v], voxel, dx, dy, dz));
          if (u < 0) continue;
          const Eigen::Vector3d p = out.centroids[size_t(u)].cast<double>();
          mean += p;
          cov += p * p.transpose();
          ++k;
        }
    if (k < 5) continue;
    mean /= k;
    cov = cov / k - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(cov);  // closed form (the iterative solver was ~40 % of this function)
    const Eigen::Vector3d ev = es.eigenvalues();
    const Eigen::Vector3d nrm = es.eigenvectors().col(0);
    if (!nrm.allFinite()) continue;
    out.normals[v] = nrm.cast<float>();
    out.flat[v] = ev[0] < 0.05 * ev[1];
  }
  });
  return out;
}

void JitterPoints(Points& points, float sigma, uint64_t seed, const Eigen::Matrix3f& axes) {
  if (!(sigma > 0.f)) return;
  const uint64_t base = SplitMix64(seed ^ 0x6a6974746572ull);  // "jitter"
  for (size_t i = 0; i < points.size(); ++i) {
    Eigen::Vector3f& p = points[i];
    if (!p.allFinite() || (p.x() == 0.f && p.y() == 0.f && p.z() == 0.f)) continue;
    uint64_t h = SplitMix64(base ^ SplitMix64(uint64_t(i)));
    double g[4];
    for (int k = 0; k < 4; k += 2) {
      const double u1 = UnitOpen(h = SplitMix64(h)), u2 = UnitOpen(h = SplitMix64(h));
      const double r = std::sqrt(-2.0 * std::log(u1)), a = 2.0 * M_PI * u2;
      g[k] = r * std::cos(a), g[k + 1] = r * std::sin(a);
    }
    p += sigma * (axes * Eigen::Vector3d(g[0], g[1], g[2]).cast<float>());
  }
}

Eigen::Isometry3f UprightPose(float x, float y, float z, float yaw) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3f(x, y, z);
  return t;
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

namespace {
float Cross2(const Eigen::Vector2f& o, const Eigen::Vector2f& a, const Eigen::Vector2f& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}
}  // namespace

namespace {
// Andrew's monotone chain over p (sorted and deduplicated here).
std::vector<Eigen::Vector2f> MonotoneChain(std::vector<Eigen::Vector2f> p) {
  std::sort(p.begin(), p.end(), [](const auto& a, const auto& b) { return a.x() != b.x() ? a.x() < b.x() : a.y() < b.y(); });
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() < 3) return p;
  std::vector<Eigen::Vector2f> h(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && Cross2(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && Cross2(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k - 1);
  return h;
}
}  // namespace

std::vector<Eigen::Vector2f> ConvexHull2D(std::vector<Eigen::Vector2f> p) {
  // Akl-Toussaint: a point well inside the polygon of the extreme points in 8 directions is not
  // a hull vertex, so the sort (the cost) sees only the points near the outline. "Well inside":
  // by a margin far above float rounding, so the chain makes the same decisions as on all points.
  constexpr size_t kFilterFrom = 64;
  if (p.size() >= kFilterFrom) {
    constexpr int kDirs = 8;
    const double dx[kDirs] = {1, -1, 0, 0, 1, -1, 1, -1}, dy[kDirs] = {0, 0, 1, -1, 1, -1, -1, 1};
    size_t ext[kDirs] = {};
    double best[kDirs];
    std::fill(best, best + kDirs, -std::numeric_limits<double>::infinity());
    bool finite = true;
    for (size_t i = 0; i < p.size() && finite; ++i) {
      finite = p[i].allFinite();
      for (int d = 0; d < kDirs; ++d) {
        const double v = dx[d] * p[i].x() + dy[d] * p[i].y();
        if (v > best[d]) best[d] = v, ext[d] = i;
      }
    }
    if (finite) {
      std::vector<Eigen::Vector2f> corners;
      for (size_t e : ext) corners.push_back(p[e]);
      const std::vector<Eigen::Vector2f> poly = MonotoneChain(corners);  // counter-clockwise
      const double span = std::max(best[0] + best[1], best[2] + best[3]);
      const double margin = 1e-4 * span * span + 1e-12;
      if (poly.size() >= 3) {
        auto inside = [&](const Eigen::Vector2f& q) {
          for (size_t e = 0; e < poly.size(); ++e) {
            const Eigen::Vector2d a = poly[e].cast<double>(), b = poly[(e + 1) % poly.size()].cast<double>();
            const Eigen::Vector2d v = q.cast<double>();
            if ((b.x() - a.x()) * (v.y() - a.y()) - (b.y() - a.y()) * (v.x() - a.x()) <= margin) return false;
          }
          return true;
        };
        p.erase(std::remove_if(p.begin(), p.end(), inside), p.end());
      }
    }
  }
  return MonotoneChain(std::move(p));
}

}  // namespace furnihost
