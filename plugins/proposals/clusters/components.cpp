// proposals.clusters: Euclidean clusters at several radii, one pass over the neighbourhoods.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <numeric>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/plugin.hpp"
#include "furnihost/voxel_index.hpp"
#include "shape/shape.hpp"
#include "clusters.hpp"

namespace furnihost::clusters {

// Connected components of `keep` with edges between points closer than m x spacing (or, for
// single views, m x the larger local spacing of the two), >= min_points each, in first-point
// order; one list per radius m of `radii`. The neighbourhoods are searched once, at the
// largest radius, and every pair joins the components of each radius it is within (a
// component's partition, hence its list, does not depend on the order the pairs come in).
std::vector<std::vector<std::vector<int>>> ClusterProposer::Cluster(const Points& P, const std::vector<uint32_t>& keep,
                                                   const std::vector<float>& nn4, float sp,
                                                   const std::vector<double>& radii, bool adaptive) const {
  const size_t R = radii.size();
  std::vector<std::vector<std::vector<int>>> out(R);
  if (keep.empty()) return out;
  // Exact duplicates are one point for the neighbourhood search (a (0, 0, 0) flood stays linear).
  std::unordered_map<uint64_t, uint32_t> first;
  std::vector<uint32_t> rep(keep.size());
  Points uniq;
  std::vector<float> lsp;
  first.reserve(keep.size());
  for (size_t k = 0; k < keep.size(); ++k) {
    const Eigen::Vector3f& p = P[keep[k]];
    uint32_t bits[3];
    std::memcpy(bits, p.data(), 12);
    const uint64_t h = (uint64_t(bits[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(bits[1]) * 0xC2B2AE3D27D4EB4Full) ^
                       (uint64_t(bits[2]) * 0x165667B19E3779F9ull);
    auto [it, fresh] = first.try_emplace(h, uint32_t(uniq.size()));
    if (fresh || uniq[it->second] != p) {
      if (!fresh) it->second = uint32_t(uniq.size());  // a hash clash: keep both
      uniq.push_back(p);
      lsp.push_back(nn4[keep[k]]);
    }
    rep[k] = it->second;
  }
  // Per radius: the search radius and the base edge length, as a search of its own would use.
  std::vector<float> ms(R), rmax(R), r2(R), base(R);
  const float q99 = adaptive ? Quantile(lsp, 0.99) : 0.f;
  float reach = 0.f;
  for (size_t a = 0; a < R; ++a) {
    const float m = float(radii[a]);
    ms[a] = m;
    rmax[a] = m * sp;
    if (adaptive) rmax[a] = std::max(rmax[a], m * q99);
    r2[a] = rmax[a] * rmax[a];
    base[a] = m * sp;
    reach = std::max(reach, rmax[a]);
  }
  std::vector<UnionFind> uf(R, UnionFind(uniq.size()));
  // A pair's edge limits grow with the radius m, so an edge at one radius is an edge at every
  // larger one and the components nest. Kept so at every step (each join is also made at the
  // larger radii), a pair already in one component at a radius is in one at every larger radius:
  // the radii are tried from the smallest m, and the first that joins the pair already ends it.
  // Nearly every pair of a dense surface ends there with two finds, not 2 x R.
  std::vector<size_t> by_m(R);
  std::iota(by_m.begin(), by_m.end(), size_t(0));
  std::stable_sort(by_m.begin(), by_m.end(), [&](size_t a, size_t b) { return ms[a] < ms[b]; });
  auto join = [&](uint32_t i, uint32_t j, float d2) {
    for (const size_t a : by_m) {
      if (!(d2 < r2[a])) continue;
      UnionFind& u = uf[a];
      const uint32_t ri = u.Find(i), rj = u.Find(j);
      if (ri == rj) return;
      const float lim = adaptive ? std::max(base[a], ms[a] * std::max(lsp[i], lsp[j])) : base[a];
      if (d2 < lim * lim) u.parent[std::max(ri, rj)] = std::min(ri, rj);
    }
  };
  // Every pair once: the later slots of a point's own cell and the cells after it (cells are
  // numbered in key order). Joins in any order give the same components (a root is always its
  // component's smallest index), and half the distances of visiting all 27 cells from both ends.
  if (!adaptive) {
    VoxelIndex index;
    index.Build(uniq, reach);
    const float reach2 = reach * reach;
    for (int c = 0; c < index.NumCells(); ++c) {
      for (int s = index.cell_start[c]; s < index.cell_start[c + 1]; ++s) {
        const uint32_t i = index.order[size_t(s)];
        const float px = index.x[size_t(s)], py = index.y[size_t(s)], pz = index.z[size_t(s)];
        for (int k = index.nb_start[c]; k < index.nb_start[c + 1]; ++k) {
          const int nc = index.nb[size_t(k)];
          if (nc < c) continue;
          for (int t = nc == c ? s + 1 : index.cell_start[nc]; t < index.cell_start[nc + 1]; ++t) {
            const float dx = index.x[size_t(t)] - px, dy = index.y[size_t(t)] - py, dz = index.z[size_t(t)] - pz;
            const float d2 = dx * dx + dy * dy + dz * dz;
            if (d2 < reach2) join(i, index.order[size_t(t)], d2);
          }
        }
      }
    }
  } else {
    // Single views: the edge of a pair grows with the sparser point's local spacing, from a few
    // millimetres near the camera to centimetres far away. Each pair is searched from its
    // sparser point (the later index of equal ones), within the reach that point's own spacing
    // gives: the points go into bands of spacing (up to the median, then doubling), and a band's
    // points look for partners among the points of its band and the denser ones, in cells of
    // the band's reach. A dense surface's points then test the few neighbours their short edges
    // can reach, not every point within the sparsest points' reach.
    std::vector<float> bound{std::max(Quantile(lsp, 0.1), 1e-6f)};
    const float top = *std::max_element(lsp.begin(), lsp.end());
    while (bound.back() < top && bound.size() < 60) bound.push_back(bound.back() * 1.41421356f);
    std::vector<uint8_t> band(uniq.size());
    for (size_t i = 0; i < uniq.size(); ++i)
      band[i] = uint8_t(std::lower_bound(bound.begin(), bound.end(), lsp[i]) - bound.begin());
    // Beyond the last bound (a spacing that is not a number): the whole reach.
    bound.push_back(INFINITY);
    Points members;
    std::vector<uint32_t> id;
    for (size_t b = 0; b < bound.size(); ++b) {
      float band_reach = 0.f;
      for (size_t a = 0; a < R; ++a)
        band_reach = std::max(band_reach, std::min(rmax[a], std::max(base[a], ms[a] * bound[b])));
      if (!(band_reach > 0.f)) continue;
      members.clear(), id.clear();
      bool any = false;
      for (size_t i = 0; i < uniq.size(); ++i)
        if (band[i] <= b) {
          members.push_back(uniq[i]), id.push_back(uint32_t(i));
          any = any || band[i] == b;
        }
      if (!any) continue;
      VoxelIndex index;
      index.Build(members, band_reach);
      const float reach2 = band_reach * band_reach;
      for (int c = 0; c < index.NumCells(); ++c)
        for (int s = index.cell_start[c]; s < index.cell_start[c + 1]; ++s) {
          const uint32_t i = id[index.order[size_t(s)]];
          if (band[i] != b) continue;
          const float li = lsp[i];
          const float px = index.x[size_t(s)], py = index.y[size_t(s)], pz = index.z[size_t(s)];
          for (int k = index.nb_start[c]; k < index.nb_start[c + 1]; ++k) {
            const int nc = index.nb[size_t(k)];
            for (int t = index.cell_start[nc]; t < index.cell_start[nc + 1]; ++t) {
              const uint32_t j = id[index.order[size_t(t)]];
              if (!(lsp[j] < li || (lsp[j] == li && j < i))) continue;  // searched from j
              const float dx = index.x[size_t(t)] - px, dy = index.y[size_t(t)] - py, dz = index.z[size_t(t)] - pz;
              const float d2 = dx * dx + dy * dy + dz * dz;
              if (d2 < reach2) join(i, j, d2);
            }
          }
        }
    }
  }
  for (size_t a = 0; a < R; ++a) {
    std::unordered_map<uint32_t, size_t> slot;
    std::vector<std::vector<int>> groups;
    for (size_t k = 0; k < keep.size(); ++k) {
      const uint32_t root = uf[a].Find(rep[k]);
      auto [it, fresh] = slot.try_emplace(root, groups.size());
      if (fresh) groups.emplace_back();
      groups[it->second].push_back(int(keep[k]));
    }
    for (auto& g : groups)
      if (int(g.size()) >= o_.min_points) out[a].push_back(std::move(g));
  }
  return out;
}

}  // namespace furnihost::clusters
