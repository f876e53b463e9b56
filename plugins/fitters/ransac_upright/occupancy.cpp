#include "occupancy.hpp"

#include <octomap/OcTree.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include "furnihost/log.hpp"

namespace furnihost::ransac_upright {

void OccupancyOptions::Check() const {
  if (!(resolution >= 0.005 && resolution <= 1.0))
    throw StageError("grid_resolution_m must be in [0.005, 1]");
  if (!(max_range >= 0.0)) throw StageError("grid_max_range_m must be >= 0");
}

namespace {

// Keys are OctoMap's 16-bit voxel indices per axis, packed as x | y << 16 | z << 32.
inline uint64_t Pack(const octomap::OcTreeKey& k) {
  return uint64_t(k[0]) | (uint64_t(k[1]) << 16) | (uint64_t(k[2]) << 32);
}
inline octomap::OcTreeKey Unpack(uint64_t p) {
  return octomap::OcTreeKey(p & 0xffff, (p >> 16) & 0xffff, (p >> 32) & 0xffff);
}
inline uint64_t Spread3(uint64_t v) {  // 16 bits -> every third of 48 bits
  v &= 0xffff;
  v = (v | (v << 16)) & 0xff0000ffull;
  v = (v | (v << 8)) & 0xf00f00f00full;
  v = (v | (v << 4)) & 0xc30c30c30c3ull;
  v = (v | (v << 2)) & 0x249249249249ull;
  return v;
}
// Morton order = depth-first octree order (child index = x bit + 2 y bit + 4 z bit per level).
inline uint64_t Morton(uint64_t p) {
  return Spread3(p) | (Spread3(p >> 16) << 1) | (Spread3(p >> 32) << 2);
}

// Dense bit set over a box of keys, or nothing when the box would be too large.
struct KeyBox {
  int lo[3] = {0, 0, 0}, n[3] = {0, 0, 0};
  size_t Bits() const { return size_t(n[0]) * n[1] * n[2]; }
  bool Holds(const octomap::OcTreeKey& k) const {
    for (int d = 0; d < 3; ++d)
      if (int(k[d]) < lo[d] || int(k[d]) >= lo[d] + n[d]) return false;
    return true;
  }
  size_t Index(const octomap::OcTreeKey& k) const {
    return (size_t(k[2] - lo[2]) * n[1] + (k[1] - lo[1])) * n[0] + (k[0] - lo[0]);
  }
};

// Amanatides-Woo walk through the voxels from `o` to the centre of voxel `end`, calling
// visit(key) for every voxel before `end` (the same voxels as OctoMap's computeRayKeys).
template <class Visit>
void TraceRay(const octomap::OcTree& tree, const octomap::point3d& o, const octomap::OcTreeKey& start,
              const octomap::OcTreeKey& end, Visit&& visit) {
  if (start == end) return;
  const octomap::point3d e = tree.keyToCoord(end);
  octomap::point3d dir = e - o;
  const double len = dir.norm();
  if (!(len > 0)) return;
  dir /= static_cast<float>(len);
  const double res = tree.getResolution();
  int step[3];
  double tmax[3], tdelta[3];
  octomap::OcTreeKey cur = start;
  for (int d = 0; d < 3; ++d) {
    step[d] = dir(d) > 0 ? 1 : (dir(d) < 0 ? -1 : 0);
    if (step[d] != 0) {
      const double border = tree.keyToCoord(cur[d]) + step[d] * 0.5 * res;
      tmax[d] = (border - o(d)) / dir(d);
      tdelta[d] = res / std::fabs(dir(d));
    } else {
      tmax[d] = tdelta[d] = std::numeric_limits<double>::infinity();
    }
  }
  const int max_steps = std::abs(int(end[0]) - int(start[0])) + std::abs(int(end[1]) - int(start[1])) +
                        std::abs(int(end[2]) - int(start[2])) + 3;
  for (int s = 0; s < max_steps; ++s) {
    visit(cur);
    int d = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
    if (tmax[d] > len) break;  // numerically at the end voxel
    cur[d] = static_cast<octomap::key_type>(cur[d] + step[d]);
    tmax[d] += tdelta[d];
    if (cur == end) break;
  }
}

// True when the voxel `k` and, for erosion 1, its six face neighbours are known free: a
// voxel crossed by a ray that passed a thin object's surface at a few centimetres is free
// although the object is there, so a single free voxel is weak evidence at 5 cm resolution.
bool FreeAround(const octomap::OcTree& grid, const octomap::OcTreeKey& k, int erosion) {
  auto free_at = [&](int dx, int dy, int dz) {
    const octomap::OcTreeKey q(static_cast<octomap::key_type>(k[0] + dx), static_cast<octomap::key_type>(k[1] + dy),
                               static_cast<octomap::key_type>(k[2] + dz));
    const octomap::OcTreeNode* node = grid.search(q);
    return node && !grid.isNodeOccupied(node);
  };
  if (!free_at(0, 0, 0)) return false;
  if (erosion <= 0) return true;
  return free_at(1, 0, 0) && free_at(-1, 0, 0) && free_at(0, 1, 0) && free_at(0, -1, 0) && free_at(0, 0, 1) &&
         free_at(0, 0, -1);
}

// OctoMap's binary tree stream (OccupancyOcTreeBase::writeBinaryNode): depth first, two bytes
// per inner node, two bits per child in child order: 10 free leaf, 01 occupied leaf, 11 inner,
// 00 unknown. Child c of a node holds the keys whose next Morton triple (x, y, z bits) is c, so
// Morton-sorted leaves are already in the stream's order. `leaves`: Morton << 1 | occupied,
// sorted, unique, at the finest level (16).
std::string EncodeOctree(const std::vector<uint64_t>& leaves) {
  constexpr int kDepth = 16;
  std::vector<uint32_t> free_before(leaves.size() + 1, 0);
  for (size_t i = 0; i < leaves.size(); ++i) free_before[i + 1] = free_before[i] + ((leaves[i] & 1) == 0);
  std::string out;
  out.reserve(leaves.size() / 2 + 64);
  // Node at `level` (0 = root) spanning leaves [a, b): writes its two bytes, then its inner children.
  auto encode = [&](auto&& self, size_t a, size_t b, int level) -> void {
    const int shift = 3 * (kDepth - 1 - level) + 1;  // +1: the occupied flag
    const uint64_t full = uint64_t(1) << (3 * (kDepth - 1 - level));  // leaves in a complete child
    size_t begin[8], end[8];
    uint8_t bytes[2] = {0, 0};
    bool inner[8] = {false};
    size_t s = a;
    for (int c = 0; c < 8; ++c) {
      size_t e = s;
      while (e < b && static_cast<int>((leaves[e] >> shift) & 7) == c) ++e;
      begin[c] = s;
      end[c] = e;
      s = e;
      const size_t n = e - begin[c];
      if (n == 0) continue;
      const size_t nfree = free_before[e] - free_before[begin[c]];
      int code;  // bit 0: "free" bit, bit 1: "occupied" bit, both: inner
      if (level + 1 == kDepth) code = nfree ? 1 : 2;
      else if (n == full && nfree == n) code = 1;
      else if (n == full && nfree == 0) code = 2;
      else code = 3;
      inner[c] = code == 3;
      bytes[c / 4] = static_cast<uint8_t>(bytes[c / 4] | (code << (2 * (c % 4))));
    }
    out.push_back(static_cast<char>(bytes[0]));
    out.push_back(static_cast<char>(bytes[1]));
    for (int c = 0; c < 8; ++c)
      if (inner[c]) self(self, begin[c], end[c], level + 1);
  };
  encode(encode, 0, leaves.size(), 0);
  return out;
}

}  // namespace

std::shared_ptr<const octomap::OcTree> BuildOccupancy(const Points& points, const Eigen::Vector3f& origin,
                                                      const OccupancyOptions& opt, OccupancyStats* stats) {
  opt.Check();
  Stopwatch sw;
  auto tree = std::make_shared<octomap::OcTree>(opt.resolution);
  const octomap::point3d o(origin.x(), origin.y(), origin.z());
  if (!origin.allFinite()) throw StageError("the sensor origin is not finite");
  // Rays are traced inside the points' box grown by kClipMargin only: a sensor origin outside it
  // (1.3 km from a room) starts each ray where it enters the box, so the grid and the rays cost
  // what the scan spans, not the origin's distance. An origin inside it (every scan seen from
  // within) traces whole rays, as OctoMap would.
  constexpr float kClipMargin = 2.f;
  Eigen::AlignedBox3f clip;
  for (const auto& p : points)
    if (p.allFinite()) clip.extend(p);
  if (clip.isEmpty()) clip.extend(origin);
  clip.min().array() -= kClipMargin;
  clip.max().array() += kClipMargin;
  const float range = float(32767.0 * opt.resolution);  // OctoMap's 16-bit keys reach this far
  clip.min() = clip.min().cwiseMax(-range);
  clip.max() = clip.max().cwiseMin(range);
  octomap::OcTreeKey okey;
  const bool clipped = !clip.contains(origin) || !tree->coordToKeyChecked(o, okey);
  // Where the ray from the origin to `e` enters the clip box, and its voxel; false when it
  // misses the box (a clear-only end short of it).
  auto ray_start = [&](const octomap::point3d& e, octomap::point3d& s, octomap::OcTreeKey& k) {
    if (!clipped) {
      s = o;
      k = okey;
      return true;
    }
    double t0 = 0.0, t1 = 1.0;
    for (int d = 0; d < 3; ++d) {
      const double from = o(d), dir = double(e(d)) - from;
      const double lo = clip.min()[d], hi = clip.max()[d];
      if (std::abs(dir) < 1e-12) {
        if (from < lo || from > hi) return false;
        continue;
      }
      double ta = (lo - from) / dir, tb = (hi - from) / dir;
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    }
    if (!(t0 <= t1)) return false;
    s = octomap::point3d(float(o(0) + t0 * (double(e(0)) - o(0))), float(o(1) + t0 * (double(e(1)) - o(1))),
                         float(o(2) + t0 * (double(e(2)) - o(2))));
    return tree->coordToKeyChecked(s, k);
  };

  // 1. Endpoint voxel of every point; points beyond max_range end at max_range and only clear.
  constexpr uint64_t kNone = ~uint64_t(0), kClearOnly = uint64_t(1) << 63;
  std::vector<uint64_t> ends(points.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const Eigen::Vector3f& p = points[i];
      ends[i] = kNone;
      if (!p.allFinite()) continue;
      octomap::point3d q(p.x(), p.y(), p.z());
      uint64_t flag = 0;
      if (opt.max_range > 0) {
        const octomap::point3d d = q - o;
        const double len = d.norm();
        if (len > opt.max_range) {
          q = o + d * static_cast<float>(opt.max_range / len);
          flag = kClearOnly;
        }
      }
      octomap::OcTreeKey k;
      if (tree->coordToKeyChecked(q, k)) ends[i] = Pack(k) | flag;
    }
  });
  tbb::parallel_sort(ends.begin(), ends.end());
  ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
  if (!ends.empty() && ends.back() == kNone) ends.pop_back();
  // A voxel that is both a hit and a clear-only end stays a hit (the hit sorts first).
  std::vector<uint64_t> occupied, clear_ends;
  for (uint64_t e : ends) {
    if (e & kClearOnly) clear_ends.push_back(e & ~kClearOnly);
    else occupied.push_back(e);
  }
  if (clipped)  // a clear-only end outside the clip box ends a ray that never reaches it
    clear_ends.erase(std::remove_if(clear_ends.begin(), clear_ends.end(),
                                    [&](uint64_t e) {
                                      const octomap::point3d c = tree->keyToCoord(Unpack(e));
                                      return !clip.contains(Eigen::Vector3f(c.x(), c.y(), c.z()));
                                    }),
                     clear_ends.end());
  if (stats) stats->ms_keys = sw.Ms();

  // 2. Trace one ray per distinct endpoint voxel into a dense bit set over the keys' box
  //    (per-thread copies OR-ed together: no atomics on the crowded voxels near the origin).
  KeyBox box;
  {
    int lo[3], hi[3];
    // Whole rays span the origin's voxel and the ends; clipped ones the clip box.
    octomap::OcTreeKey from = okey, to = okey;
    if (clipped &&
        (!tree->coordToKeyChecked(octomap::point3d(clip.min().x(), clip.min().y(), clip.min().z()), from) ||
         !tree->coordToKeyChecked(octomap::point3d(clip.max().x(), clip.max().y(), clip.max().z()), to)))
      throw StageError("the scan lies outside the occupancy grid's range");
    for (int d = 0; d < 3; ++d) lo[d] = std::min<int>(from[d], to[d]), hi[d] = std::max<int>(from[d], to[d]);
    for (const auto* list : {&occupied, &clear_ends})
      for (uint64_t e : *list) {
        const octomap::OcTreeKey k = Unpack(e);
        for (int d = 0; d < 3; ++d) {
          lo[d] = std::min<int>(lo[d], k[d]);
          hi[d] = std::max<int>(hi[d], k[d]);
        }
      }
    for (int d = 0; d < 3; ++d) {
      box.lo[d] = lo[d];
      box.n[d] = hi[d] - lo[d] + 1;
    }
  }
  std::vector<uint64_t> free_keys;
  const size_t nrays = occupied.size() + clear_ends.size();
  auto ray_end = [&](size_t i) { return Unpack(i < occupied.size() ? occupied[i] : clear_ends[i - occupied.size()]); };
  if (box.Bits() <= (size_t(1) << 31)) {  // up to 256 MB of bits per thread
    const size_t words = (box.Bits() + 63) / 64;
    tbb::enumerable_thread_specific<std::vector<uint64_t>> local([&] { return std::vector<uint64_t>(words, 0); });
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nrays, 256), [&](const tbb::blocked_range<size_t>& r) {
      std::vector<uint64_t>& bits = local.local();
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const octomap::OcTreeKey end = ray_end(i);
        octomap::point3d s;
        octomap::OcTreeKey start;
        if (!ray_start(tree->keyToCoord(end), s, start)) continue;
        TraceRay(*tree, s, start, end, [&](const octomap::OcTreeKey& k) {
          if (clipped && !box.Holds(k)) return;
          const size_t b = box.Index(k);
          bits[b >> 6] |= uint64_t(1) << (b & 63);
        });
        if (i >= occupied.size()) {
          const size_t b = box.Index(end);
          bits[b >> 6] |= uint64_t(1) << (b & 63);
        }
      }
    });
    std::vector<uint64_t> all(words, 0);
    for (auto& bits : local)
      tbb::parallel_for(size_t(0), words, [&](size_t w) { all[w] |= bits[w]; });
    for (uint64_t e : occupied) {
      const size_t b = box.Index(Unpack(e));
      all[b >> 6] &= ~(uint64_t(1) << (b & 63));
    }
    for (size_t w = 0; w < words; ++w) {
      for (uint64_t m = all[w]; m; m &= m - 1) {
        const size_t b = w * 64 + static_cast<size_t>(__builtin_ctzll(m));
        const int x = static_cast<int>(b % box.n[0]);
        const int y = static_cast<int>((b / box.n[0]) % box.n[1]);
        const int z = static_cast<int>(b / (size_t(box.n[0]) * box.n[1]));
        free_keys.push_back(Pack(octomap::OcTreeKey(x + box.lo[0], y + box.lo[1], z + box.lo[2])));
      }
    }
  } else {  // huge extents: collect keys per thread and deduplicate by sorting
    tbb::enumerable_thread_specific<std::vector<uint64_t>> local;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nrays, 256), [&](const tbb::blocked_range<size_t>& r) {
      std::vector<uint64_t>& v = local.local();
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const octomap::OcTreeKey end = ray_end(i);
        octomap::point3d s;
        octomap::OcTreeKey start;
        if (!ray_start(tree->keyToCoord(end), s, start)) continue;
        TraceRay(*tree, s, start, end, [&](const octomap::OcTreeKey& k) { v.push_back(Pack(k)); });
        if (i >= occupied.size()) v.push_back(Pack(end));
      }
      std::sort(v.begin(), v.end());
      v.erase(std::unique(v.begin(), v.end()), v.end());
    });
    for (auto& v : local) free_keys.insert(free_keys.end(), v.begin(), v.end());
    tbb::parallel_sort(free_keys.begin(), free_keys.end());
    free_keys.erase(std::unique(free_keys.begin(), free_keys.end()), free_keys.end());
    std::vector<uint64_t> kept;
    kept.reserve(free_keys.size());
    std::set_difference(free_keys.begin(), free_keys.end(), occupied.begin(), occupied.end(),
                        std::back_inserter(kept));
    free_keys.swap(kept);
  }
  if (stats) stats->ms_rays = sw.Ms() - stats->ms_keys;

  // 3. Hand the leaves to OctoMap as its own binary stream (readBinaryData): uniform, complete
  //    octants become single pruned nodes, so the interior of a room costs a few thousand
  //    nodes instead of a million updateNode() walks. Free leaves get OctoMap's clamped free
  //    log-odds, occupied ones the clamped occupied value; unknown space has no node.
  std::vector<uint64_t> leaves(free_keys.size() + occupied.size());  // Morton << 1 | occupied
  tbb::parallel_for(size_t(0), free_keys.size(), [&](size_t i) { leaves[i] = Morton(free_keys[i]) << 1; });
  tbb::parallel_for(size_t(0), occupied.size(),
                    [&](size_t i) { leaves[free_keys.size() + i] = (Morton(occupied[i]) << 1) | 1; });
  tbb::parallel_sort(leaves.begin(), leaves.end());
  if (!leaves.empty()) {
    std::string stream = EncodeOctree(leaves);
    std::istringstream in(stream);
    tree->readBinaryData(in);
  }
  if (stats) {
    stats->rays = nrays;
    stats->occupied = occupied.size();
    stats->free = free_keys.size();
    stats->ms_insert = sw.Ms() - stats->ms_keys - stats->ms_rays;
  }
  return tree;
}

FreeSpaceCount CountFreeSpace(const octomap::OcTree& grid, const Points& model_points,
                              const Eigen::Vector3f& origin, const FreeSpaceOptions& opt) {
  FreeSpaceCount out;
  if (model_points.empty()) return out;
  // Self-occlusion by a point z-buffer on a virtual image plane facing the model's centroid.
  Eigen::Vector3f c = Eigen::Vector3f::Zero();
  for (const auto& p : model_points) c += p;
  c /= static_cast<float>(model_points.size());
  Eigen::Vector3f axis = c - origin;
  const float dist = axis.norm();
  std::vector<char> visible(model_points.size(), 1);
  if (dist > 1e-4f) {
    axis /= dist;
    const Eigen::Vector3f u = axis.unitOrthogonal(), v = axis.cross(u);
    std::vector<Eigen::Vector3f> img(model_points.size());  // (x, y) on the plane, range
    float min_depth = std::numeric_limits<float>::infinity();
    Eigen::Vector2f lo = Eigen::Vector2f::Constant(std::numeric_limits<float>::infinity()), hi = -lo;
    for (size_t i = 0; i < model_points.size(); ++i) {
      const Eigen::Vector3f w = model_points[i] - origin;
      const float depth = w.dot(axis);
      if (depth <= 1e-3f) {  // behind the sensor: cannot be seen
        visible[i] = 0;
        continue;
      }
      img[i] = {w.dot(u) / depth, w.dot(v) / depth, w.norm()};
      min_depth = std::min(min_depth, depth);
      lo = lo.cwiseMin(img[i].head<2>());
      hi = hi.cwiseMax(img[i].head<2>());
    }
    if (std::isfinite(min_depth)) {
      // Pixels of ~2.5 point spacings at the nearest depth leave no holes in the front surface.
      float pix = 2.5f * opt.point_spacing / min_depth;
      const Eigen::Vector2f ext = hi - lo;
      while (ext.x() / pix > 1024.f || ext.y() / pix > 1024.f) pix *= 1.5f;
      const int w = static_cast<int>(ext.x() / pix) + 1, h = static_cast<int>(ext.y() / pix) + 1;
      std::vector<float> zbuf(size_t(w) * h, std::numeric_limits<float>::infinity());
      auto pixel = [&](const Eigen::Vector3f& q) {
        const int x = std::min(w - 1, static_cast<int>((q.x() - lo.x()) / pix));
        const int y = std::min(h - 1, static_cast<int>((q.y() - lo.y()) / pix));
        return size_t(y) * w + x;
      };
      for (size_t i = 0; i < model_points.size(); ++i)
        if (visible[i]) zbuf[pixel(img[i])] = std::min(zbuf[pixel(img[i])], img[i].z());
      for (size_t i = 0; i < model_points.size(); ++i)
        if (visible[i] && img[i].z() > zbuf[pixel(img[i])] + opt.visibility_margin) visible[i] = 0;
    }
  }
  for (size_t i = 0; i < model_points.size(); ++i) {
    if (!visible[i]) continue;
    ++out.visible;
    const Eigen::Vector3f w = model_points[i] - origin;
    const float r = w.norm();
    const Eigen::Vector3f q = r > 0 ? Eigen::Vector3f(model_points[i] + opt.free_margin / r * w) : model_points[i];
    octomap::OcTreeKey k;
    if (!grid.coordToKeyChecked(octomap::point3d(q.x(), q.y(), q.z()), k)) continue;
    if (FreeAround(grid, k, opt.erosion)) ++out.free;
  }
  return out;
}

}  // namespace furnihost::ransac_upright
