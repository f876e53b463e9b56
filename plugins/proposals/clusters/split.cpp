// proposals.clusters: alternative proposals of one cluster: support splits, work tops, cuts of long clusters.
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

namespace {
// The top-view cell of edge `cell` holding p, as one key.
uint64_t TopViewCell(const Eigen::Vector3f& p, float cell) {
  return (uint64_t(uint32_t(int32_t(std::floor(p.x() / cell)))) << 32) | uint32_t(int32_t(std::floor(p.y() / cell)));
}
}  // namespace

// Of (top-view cell, height bin) pairs sorted by cell (`nb` bins), the window of two adjacent
// bins that the most cells reach, each cell counted once per window; its lower bin (-1 when no
// cell reaches any), and in *cells how many cells reach it.
int ClusterProposer::BusiestLevel(const std::vector<std::pair<uint64_t, int>>& level, int nb, size_t* cells) {
  std::vector<size_t> occupied(size_t(nb), 0);
  for (size_t a = 0; a < level.size();) {
    int last = -1;
    size_t e = a;
    for (; e < level.size() && level[e].first == level[a].first; ++e)
      for (int w : {level[e].second - 1, level[e].second})
        if (w > last && w >= 0 && w + 1 < nb) ++occupied[size_t(w)], last = w;
    a = e;
  }
  *cells = 0;
  int k = -1;
  for (int b = 0; b + 1 < nb; ++b)
    if (occupied[size_t(b)] > *cells) *cells = occupied[size_t(b)], k = b;
  return k;
}

// Support splits of cluster `idx` (clustered at `radius` spacings): nothing, or first the
// support surface with the remains too small to be objects (min_points), then each part of
// real size that remains when the surface is taken out. The support surface is the 4 cm
// level between support_min_m and support_max_m above the ground whose upward-facing points
// (|n_z| > 0.9) occupy the most top-view cells (as WorkTop's), of support_area_m2 or more;
// its points are those within 4 cm of the level in its cells, whatever their normals (the
// top's rounded edges). Only when some part of real size remains.
std::vector<std::vector<int>> ClusterProposer::SupportSplit(const Points& P, const std::vector<float>& hz, const shape::LocalShape& ls,
                                           float sp, const std::vector<int>& idx, double radius, bool adaptive) const {
  constexpr float bin = 0.02f;
  const int nb = int(std::ceil((o_.support_max - o_.support_min) / bin));
  if (nb < 2 || idx.size() < size_t(2 * o_.min_points)) return {};
  const float cell = std::max(0.05f, 2.5f * sp);
  auto key = [&](const Eigen::Vector3f& p) { return TopViewCell(p, cell); };
  std::vector<std::pair<uint64_t, int>> level;
  for (int i : idx) {
    const float h = hz[size_t(i)];
    if (!(std::abs(ls.normals[size_t(i)].z()) > 0.9f) || !(h >= o_.support_min) || !(h < o_.support_max)) continue;
    level.emplace_back(key(P[size_t(i)]), std::min(nb - 1, int((h - o_.support_min) / bin)));
  }
  std::sort(level.begin(), level.end());
  size_t best = 0;
  const int k = BusiestLevel(level, nb, &best);
  if (k < 0 || double(best) * cell * cell < o_.support_area) return {};
  const float lo = o_.support_min + float(k) * bin, hi = lo + 2.f * bin;
  std::unordered_set<uint64_t> top_cells;
  for (const auto& [c, b] : level)
    if (b == k || b == k + 1) top_cells.insert(c);
  std::vector<int> surface;
  std::vector<uint32_t> rest;
  for (int i : idx) {
    const float h = hz[size_t(i)];
    if (h >= lo - 0.02f && h <= hi + 0.02f && top_cells.count(key(P[size_t(i)]))) surface.push_back(i);
    else rest.push_back(uint32_t(i));
  }
  const auto parts = Cluster(P, rest, ls.nn4, sp, {radius}, adaptive).front();
  if (parts.empty()) return {};
  std::vector<std::vector<int>> out;
  out.push_back(surface);
  std::vector<uint8_t> in_part(P.size(), 0);
  for (const auto& part : parts)
    for (int i : part) in_part[size_t(i)] = 1;
  for (uint32_t i : rest)
    if (!in_part[i]) out.front().push_back(int(i));
  std::sort(out.front().begin(), out.front().end());
  for (const auto& part : parts) out.push_back(part);
  spdlog::trace("support: {} pts, level {:.2f} m, {} cells, {} surface points, {} parts", idx.size(), lo, best,
                surface.size(), parts.size());
  return out;
}

// The points of cluster `idx` at or below its work top, or nothing. The work top is the 4 cm
// level between work_top_min_m and work_top_max_m above the ground whose upward-facing points
// (|n_z| > 0.9) occupy the most top-view cells (2.5 spacings, >= 5 cm: a count of cells, not of
// points, so the scan's density does not matter); it must occupy work_top_cover of the cells
// the whole cluster occupies (a desk or table top, not a shelf or an armrest), and at least
// work_top_above of the cluster's points must lie more than 8 cm over it (else it is the top).
std::vector<int> ClusterProposer::WorkTop(const Points& P, const std::vector<float>& hz, const shape::LocalShape& ls, float sp,
                         const std::vector<int>& idx) const {
  constexpr float bin = 0.02f;
  const int nb = int(std::ceil((o_.top_max - o_.top_min) / bin));
  if (nb < 2 || idx.size() < size_t(o_.min_points)) return {};
  const float cell = std::max(0.05f, 2.5f * sp);
  auto key = [&](const Eigen::Vector3f& p) { return TopViewCell(p, cell); };
  std::vector<uint64_t> all;
  std::vector<std::pair<uint64_t, int>> level;  // (cell, bin) of the upward-facing points in range
  all.reserve(idx.size());
  for (int i : idx) {
    const Eigen::Vector3f& p = P[size_t(i)];
    all.push_back(key(p));
    const float h = hz[size_t(i)];
    if (!(std::abs(ls.normals[size_t(i)].z()) > 0.9f) || !(h >= o_.top_min) || !(h < o_.top_max)) continue;
    level.emplace_back(key(p), std::min(nb - 1, int((h - o_.top_min) / bin)));
  }
  std::sort(all.begin(), all.end());
  const size_t cells = size_t(std::unique(all.begin(), all.end()) - all.begin());
  std::sort(level.begin(), level.end());
  size_t best = 0;
  const int k = BusiestLevel(level, nb, &best);
  if (k < 0 || double(best) < o_.top_cover * double(cells)) {
    spdlog::trace("worktop: {} pts {} cells, busiest level {:.2f} m {} cells: under work_top_cover", idx.size(), cells,
                  k < 0 ? 0.f : o_.top_min + float(k + 2) * bin, best);
    return {};
  }
  const float level_top = o_.top_min + float(k + 2) * bin;  // the window's upper edge
  std::vector<int> out;
  size_t above = 0;
  for (int i : idx) {
    const float h = hz[size_t(i)];
    if (h <= level_top + 0.02f) out.push_back(i);
    else if (h > level_top + 0.08f) ++above;
  }
  spdlog::trace("worktop: {} pts {} cells, level {:.2f} m {} cells, {} above", idx.size(), cells, level_top, best, above);
  if (double(above) < o_.top_above * double(idx.size()) || out.size() < size_t(o_.min_points)) return {};
  return out;
}

// The points of cluster `idx` at or under its low top, or nothing. Each top-view cell (2.5
// spacings, >= 5 cm) has a top, its highest point above the ground; the low top is the 4 cm level
// between low_top_min_m and low_top_max_m that the most cell tops lie in. It must hold
// low_top_cover of the cluster's cells, and low_top_above of them (at least one), but no more than
// low_top_above_max, must top out more than 15 cm over it: a cabinet's top with a lamp or a vase on
// it, seen from above, not a tall object with a shelf. The cells'
// highest points, not normals, find the level: a raw depth camera's noise tilts the normals of a
// small top at a few metres.
std::vector<int> ClusterProposer::LowTop(const Points& P, const std::vector<float>& hz, float sp,
                                         const std::vector<int>& idx) const {
  constexpr float bin = 0.02f;
  const int nb = int(std::ceil((o_.low_top_max - o_.low_top_min) / bin));
  if (nb < 2 || idx.size() < size_t(o_.min_points)) return {};
  const float cell = std::max(0.05f, 2.5f * sp);
  std::unordered_map<uint64_t, float> top;  // cell -> its highest point above the ground
  for (int i : idx) {
    auto [it, fresh] = top.try_emplace(TopViewCell(P[size_t(i)], cell), hz[size_t(i)]);
    if (!fresh) it->second = std::max(it->second, hz[size_t(i)]);
  }
  // Each cell's top in its height bin: the busiest window of two bins is the low top.
  std::vector<std::pair<uint64_t, int>> level;
  for (const auto& [c, h] : top)
    if (h >= o_.low_top_min && h < o_.low_top_max) level.emplace_back(c, std::min(nb - 1, int((h - o_.low_top_min) / bin)));
  std::sort(level.begin(), level.end());
  size_t best = 0;
  const int k = BusiestLevel(level, nb, &best);
  if (k < 0) return {};
  const float level_top = o_.low_top_min + float(k + 2) * bin;  // the level's upper edge
  size_t above = 0;
  for (const auto& [key, h] : top) above += h > level_top + 0.15f;
  spdlog::trace("lowtop: {} pts {} cells, level {:.2f} m {} cells, {} cells above", idx.size(), top.size(), level_top,
                best, above);
  if (double(best) < o_.low_top_cover * double(top.size()) || above == 0 ||
      double(above) > o_.low_top_above_max * double(top.size()) || double(above) < o_.low_top_above * double(top.size())) return {};
  std::vector<int> out;
  for (int i : idx)
    if (hz[size_t(i)] <= level_top + 0.02f) out.push_back(i);
  if (out.size() < size_t(o_.min_points)) return {};
  return out;
}

// Cuts of a cluster longer than split_length along its footprint's length: 2 parts (and 3
// past 1.7 x split_length), each cut at the sparsest 5 cm slice within a third of a part of
// the nominal cut, kept only where the top-view height profile there steps by split_flatness
// from the profile 20-25 cm to either side. Returns (part, k) pairs.
// How far slice b of a top-view profile stands above (> 0) or below its sides: the median of
// the finite slices 4 and 5 away on either side (how many in *sides; 0 when there is none).
float ClusterProposer::ProfileStep(const std::vector<float>& prof, int b, size_t* sides) {
  const int nb = int(prof.size());
  std::vector<float> side;
  for (int x : {b - 5, b - 4, b + 4, b + 5})
    if (x >= 0 && x < nb && std::isfinite(prof[size_t(x)])) side.push_back(prof[size_t(x)]);
  *sides = side.size();
  return side.empty() ? 0.f : prof[size_t(b)] - Quantile(side, 0.5);
}

// The centre slice of the strongest run of slices in [b0, b1) whose profile stands above (a
// ridge) or below (a valley) the median of its sides (4-5 slices away) by split_flatness or
// more; strength = the run's summed difference. -1 when there is none.
int ClusterProposer::RidgeCentre(const std::vector<float>& prof, int b0, int b1) const {
  const int nb = int(prof.size());
  std::vector<float> d(size_t(nb), 0.f);
  for (int b = b0; b < b1; ++b) {
    if (!std::isfinite(prof[size_t(b)])) continue;
    size_t sides = 0;
    const float v = ProfileStep(prof, b, &sides);
    if (sides >= 2 && std::abs(v) >= o_.split_flatness) d[size_t(b)] = v;
  }
  int best = -1;
  float strength = 0.f;
  for (int b = b0; b < b1;) {
    if (d[size_t(b)] == 0.f) {
      ++b;
      continue;
    }
    int e = b;
    float sum = 0.f;
    while (e < b1 && d[size_t(e)] != 0.f && (d[size_t(e)] > 0.f) == (d[size_t(b)] > 0.f)) sum += std::abs(d[size_t(e)]), ++e;
    if (sum > strength) strength = sum, best = (b + e - 1) / 2;
    b = e;
  }
  return best;
}

std::vector<std::pair<std::vector<int>, int>> ClusterProposer::SplitLong(const Points& P, const std::vector<float>& hz,
                                                        const std::vector<int>& idx) const {
  std::vector<std::pair<std::vector<int>, int>> out;
  if (idx.size() < 60) return out;
  std::vector<Eigen::Vector2f> xy(idx.size());
  for (size_t k = 0; k < idx.size(); ++k) xy[k] = P[idx[k]].head<2>();
  const shape::Footprint f = shape::OrientedFootprint(xy);
  if (f.length < o_.split_length) return out;
  const Eigen::Vector2f ax(std::cos(f.yaw), std::sin(f.yaw)), ay(-std::sin(f.yaw), std::cos(f.yaw));
  std::vector<float> u(idx.size()), v(idx.size());
  float vmin = INFINITY;
  for (size_t k = 0; k < idx.size(); ++k) {
    u[k] = (xy[k] - f.center).dot(ax);
    v[k] = (xy[k] - f.center).dot(ay);
    vmin = std::min(vmin, v[k]);
  }
  const float u0 = Quantile(u, 0.01), u1 = Quantile(u, 0.99);
  // Slices on the lattice of multiples of 5 cm about the footprint's centre, the outer 1 %
  // clamped into the end slices at both ends: the same slices when the footprint's axis
  // comes out the other way (a turned scan).
  constexpr float bin = 0.05f;
  const int B0 = int(std::floor(u0 / bin)), nb = std::max(1, int(std::floor(u1 / bin)) - B0 + 1);
  const int V0 = int(std::floor(vmin / bin));
  std::vector<int> iu(idx.size()), iv(idx.size());
  int vmax_bin = 0;
  for (size_t k = 0; k < idx.size(); ++k) {
    iu[k] = std::clamp(int(std::floor(u[k] / bin)) - B0, 0, nb - 1);
    iv[k] = int(std::floor(v[k] / bin)) - V0;
    vmax_bin = std::max(vmax_bin, iv[k]);
  }
  // Points per slice, each shared linearly between the two nearest slice centres: a point
  // moved by a rounding error moves the counts by as little, so the sparsest slice does not
  // jump 5 cm when the scan comes in another frame.
  std::vector<double> count(nb, 0.0);
  for (size_t k = 0; k < idx.size(); ++k) {
    const double t = std::clamp(double(u[k]) / bin - 0.5 - B0, 0.0, double(nb - 1));
    const int b = std::min(int(t), nb - 1);
    const double f = t - b;
    count[b] += 1.0 - f;
    if (b + 1 < nb) count[b + 1] += f;
  }
  // Per 5 cm slice: the median of its columns' top heights (above the cluster's ground).
  std::vector<float> g;
  for (int i : idx) g.push_back(P[i].z() - hz[i]);
  std::nth_element(g.begin(), g.begin() + g.size() / 2, g.end());
  const float g0 = g[g.size() / 2];
  std::unordered_map<int64_t, float> top;
  for (size_t k = 0; k < idx.size(); ++k) {
    const int64_t key = int64_t(iu[k]) * (vmax_bin + 1) + iv[k];
    const float h = P[idx[k]].z() - g0;
    auto [it, fresh] = top.try_emplace(key, h);
    if (!fresh) it->second = std::max(it->second, h);
  }
  std::vector<std::vector<float>> slice(nb);
  for (const auto& [key, h] : top) slice[size_t(key / (vmax_bin + 1))].push_back(h);
  std::vector<float> prof(nb, NAN);
  for (int b = 0; b < nb; ++b)
    if (!slice[b].empty()) prof[b] = Quantile(slice[b], 0.5);
  std::vector<int> ks = {2};
  if (f.length >= 1.7f * o_.split_length) ks.push_back(3);
  auto mid = [&](int b) { return (float(b + B0) + 0.5f) * bin; };
  // A cut is kept only where the top-view profile steps (a gap, valley or ridge).
  auto steps = [&](float c) {
    const int b = int(std::floor(c / bin)) - B0;
    if (b < 0 || b >= nb || !std::isfinite(prof[b])) return true;
    size_t sides = 0;
    const float step = ProfileStep(prof, b, &sides);
    return sides == 0 || std::abs(step) >= o_.split_flatness;
  };
  auto emit = [&](const std::vector<float>& cuts, int k) {
    std::vector<float> edges = {-INFINITY};
    edges.insert(edges.end(), cuts.begin(), cuts.end());
    edges.push_back(INFINITY);
    for (size_t e = 0; e + 1 < edges.size(); ++e) {
      std::vector<int> part;
      for (size_t q = 0; q < idx.size(); ++q)
        if (u[q] >= edges[e] && u[q] < edges[e + 1]) part.push_back(idx[q]);
      if (part.size() >= 30) out.emplace_back(std::move(part), k);
    }
  };
  for (int k : ks) {
    // Per nominal cut (j / k of the length), the sparse slices within a third of a part of
    // it: the sparsest, and for a cut in two also the next sparse local minimum when it is
    // nearly as sparse (within 25 % + 2 points): of two near-equal gaps either may be the
    // one between the objects, and which is the sparser is decided by a few points.
    std::vector<std::vector<float>> options(size_t(k - 1));
    for (int j = 1; j < k; ++j) {
      const float c = u0 + (u1 - u0) * float(j) / float(k), w = (u1 - u0) / float(3 * k);
      const int b0 = std::max(int(std::floor((c - w) / bin)) - B0, 0);
      const int b1 = std::min(int(std::floor((c + w) / bin)) - B0 + 1, nb);
      if (b1 <= b0) {
        options[size_t(j - 1)].push_back(c);
        continue;
      }
      std::vector<int> minima;
      for (int b = b0; b < b1; ++b)
        if ((b == b0 || count[b] <= count[b - 1]) && (b + 1 == b1 || count[b] <= count[b + 1])) minima.push_back(b);
      // Sparsest first; of equally sparse ones the nearest to the nominal cut.
      std::sort(minima.begin(), minima.end(), [&](int a, int b) {
        if (count[a] != count[b]) return count[a] < count[b];
        return std::abs(mid(a) - c) < std::abs(mid(b) - c);
      });
      auto& opt = options[size_t(j - 1)];
      opt.push_back(mid(minima.front()));
      if (k == 2)
        for (size_t m = 1; m < minima.size(); ++m)
          if (count[minima[m]] <= 1.25 * count[minima.front()] + 2.0 && std::abs(minima[m] - minima.front()) >= 2) {
            opt.push_back(mid(minima[m]));
            break;
          }
      // For a cut in two of a cluster too short for three objects, also the centre of the
      // strongest ridge or valley of the profile in the window: where two armchairs meet,
      // their armrests make a dense ridge (vertical faces), so the sparsest slice lies in a
      // seat, whose flat profile refuses the cut.
      if (k == 2 && o_.split_ridges && f.length < 1.7f * o_.split_length) {
        const int r = RidgeCentre(prof, b0, b1);
        if (r >= 0 && std::none_of(opt.begin(), opt.end(), [&](float x) { return std::abs(x - mid(r)) < 1.5f * bin; }))
          opt.push_back(mid(r));
      }
    }
    if (k == 2) {
      for (float c : options[0])
        if (steps(c)) emit({c}, k);
    } else {
      std::vector<float> cuts;
      for (const auto& o : options) cuts.push_back(o.front());
      if (std::all_of(cuts.begin(), cuts.end(), steps)) emit(cuts, k);
    }
  }
  return out;
}

}  // namespace furnihost::clusters
