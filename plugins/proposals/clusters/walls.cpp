// proposals.clusters: the ceiling cap, the vertical planes (an iterative Hough transform) and the wall
// removal rules ("all", "segs").
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

// hmax, or 8 cm below a ceiling: a horizontal level above 1.9 m holding >= 1.5 m2 of points.
float ClusterProposer::CeilingCap(const shape::LocalShape& ls, const std::vector<float>& hz, const std::vector<float>& area) const {
  std::vector<double> a;
  for (size_t i = 0; i < hz.size(); ++i) {
    if (!(std::abs(ls.normals[i].z()) > 0.9f) || !(hz[i] > 1.9f) || hz[i] > 20.f) continue;
    const size_t b = size_t(hz[i] / 0.04f);
    if (a.size() <= b) a.resize(b + 1, 0.0);
    a[b] += area[i];
  }
  double best = 0;
  size_t k = 0;
  for (size_t b = 0; b < a.size(); ++b) {
    const double w = a[b] + (b + 1 < a.size() ? a[b + 1] : 0.0);
    if (w > best) best = w, k = b;
  }
  spdlog::debug("proposals.clusters: largest level above 1.9 m: {:.2f} m2 at {:.2f} m{}", best, float(k) * 0.04f,
                best < 1.5 ? "" : ": ceiling");
  if (best < 1.5) return o_.max_height;
  return std::min(o_.max_height, float(k) * 0.04f - 0.08f);
}

// Iterative (theta, rho) Hough over the vertical-normal points: 2 deg x 4 cm bins, 3x3
// smoothed; each peak's bin members give a line (PCA), its inliers (within 5 cm, normal
// within 25 deg) leave the pool. Up to 400 peaks (a space of several rooms has more walls
// than one room), planes of >= 100 inliers.
std::vector<VPlane> ClusterProposer::VerticalPlanes(const Points& P, const Points& normals, const std::vector<float>& hz,
                                   float) const {
  const size_t n = P.size();
  std::vector<uint8_t> vert(n), avail(n);
  for (size_t i = 0; i < n; ++i) vert[i] = avail[i] = std::abs(normals[i].z()) < 0.25f;
  std::vector<VPlane> planes;
  constexpr int TB = 90;
  const float kPi = float(M_PI);
  const float cos25 = std::cos(25.f * kPi / 180.f);
  std::vector<uint32_t> idx;
  std::vector<int> tb, rb;
  // rho about the cloud's centre on the floor plane, not the frame's origin: a room 100 m
  // from its origin (a shifted survey) bins like the same room at the origin.
  Eigen::AlignedBox2f extent;
  for (const auto& p : P) extent.extend(p.head<2>());
  Eigen::Vector2f c0 = Eigen::Vector2f::Zero();
  if (!P.empty()) c0 = extent.center();
  // A point's line coordinates depend on its own normal and position only: computed once.
  std::vector<float> rho_of(n, 0.f);
  std::vector<int> tb_of(n, 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      if (!vert[i]) continue;
      const Eigen::Vector3f& nn = normals[i];
      float th = std::atan2(nn.y(), nn.x());
      th = std::fmod(th + 2 * kPi, kPi);
      rho_of[i] = (P[i].x() - c0.x()) * std::cos(th) + (P[i].y() - c0.y()) * std::sin(th);
      tb_of[i] = std::min(TB - 1, int(th / kPi * TB));
    }
  });
  for (int it = 0; it < 400; ++it) {
    idx.clear();
    for (size_t i = 0; i < n; ++i)
      if (avail[i]) idx.push_back(uint32_t(i));
    if (idx.size() < 200) break;
    tb.resize(idx.size());
    rb.resize(idx.size());
    std::vector<float> rho(idx.size());
    float rmin = INFINITY, rmax = -INFINITY;
    for (size_t k = 0; k < idx.size(); ++k) {
      rho[k] = rho_of[idx[k]];
      tb[k] = tb_of[idx[k]];
      rmin = std::min(rmin, rho[k]);
      rmax = std::max(rmax, rho[k]);
    }
    // Bins on the lattice of multiples of 4 cm about c0, rho in [-K, K) bins: the line space
    // wraps like a Moebius strip (theta just below 180 deg is theta just above 0 with rho
    // negated), so a wall whose normal lies near the x axis is one peak across the wrap, as
    // it is when the scan comes turned by a quarter and its normal lies near the y axis.
    const int K = std::min(50000, int(std::ceil(std::max(std::abs(rmin), std::abs(rmax)) / 0.04f)) + 1);
    const int RB = 2 * K;
    std::vector<int> hist(size_t(TB) * RB, 0);
    for (size_t k = 0; k < idx.size(); ++k) {
      rb[k] = std::clamp(int(std::floor(rho[k] / 0.04f)) + K, 0, RB - 1);
      ++hist[size_t(tb[k]) * RB + rb[k]];
    }
    int best = -1, bt = 0, br = 0;
    for (int t = 0; t < TB; ++t)
      for (int r = 0; r < RB; ++r) {
        int s = 0;
        for (int dt = -1; dt <= 1; ++dt) {
          const int tt = t + dt;
          const bool wrap = tt < 0 || tt >= TB;
          for (int dr = -1; dr <= 1; ++dr) {
            const int rr = wrap ? RB - 1 - (r + dr) : r + dr;
            if (rr < 0 || rr >= RB) continue;
            s += hist[size_t((tt + TB) % TB) * RB + rr];
          }
        }
        if (s > best) best = s, bt = t, br = r;
      }
    if (best < 150) break;
    // The peak's members: within one bin in theta (across the wrap: rho negated) and rho.
    std::vector<uint32_t> members;
    for (size_t k = 0; k < idx.size(); ++k) {
      int dt = tb[k] - bt;
      bool wrap = false;
      if (dt > TB / 2) dt -= TB, wrap = true;
      else if (dt < -TB / 2) dt += TB, wrap = true;
      const int r = wrap ? RB - 1 - rb[k] : rb[k];
      if (std::abs(dt) <= 1 && std::abs(r - br) <= 1) members.push_back(idx[k]);
    }
    Eigen::Vector2d c = Eigen::Vector2d::Zero();
    for (uint32_t i : members) c += P[i].head<2>().cast<double>();
    c /= double(members.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (uint32_t i : members) {
      const Eigen::Vector2d d = P[i].head<2>().cast<double>() - c;
      cov += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
    VPlane pl;
    pl.d = es.eigenvectors().col(1).cast<float>();
    pl.nv = Eigen::Vector2f(-pl.d.y(), pl.d.x());
    pl.r = float(c.cast<float>().dot(pl.nv));
    for (size_t i = 0; i < n; ++i) {
      if (!vert[i]) continue;
      if (std::abs(P[i].head<2>().dot(pl.nv) - pl.r) < 0.05f &&
          std::abs(normals[i].head<2>().dot(pl.nv)) > cos25)
        pl.inliers.push_back(uint32_t(i));
    }
    for (uint32_t i : members) avail[i] = 0;
    if (pl.inliers.size() < 100) continue;
    for (uint32_t i : pl.inliers) avail[i] = 0;
    std::vector<float> al, hh;
    for (uint32_t i : pl.inliers) al.push_back(P[i].head<2>().dot(pl.d)), hh.push_back(hz[i]);
    pl.a0 = Quantile(al, 0.01), pl.a1 = Quantile(al, 0.99);
    pl.h0 = Quantile(hh, 0.02), pl.h1 = Quantile(hh, 0.98);
    planes.push_back(std::move(pl));
  }
  return planes;
}

// "all": every plane taller than 1 m and longer than 0.8 m, or with 1.5 m2 of inliers: the
// points within 6 cm of it along its length (+- 5 cm), at any height.
// A stretch [b, e) of a plane's inliers sorted along its line: its extents along it (1st and
// 99th percentiles) and in height (2nd and 98th).
std::array<float, 4> ClusterProposer::StretchExtent(const std::vector<std::pair<float, uint32_t>>& along,
                                          const std::vector<float>& hz, size_t b, size_t e) {
  std::vector<float> al(e - b), hh(e - b);
  for (size_t k = b; k < e; ++k) al[k - b] = along[k].first, hh[k - b] = hz[along[k].second];
  return {Quantile(al, 0.01), Quantile(al, 0.99), Quantile(hh, 0.02), Quantile(hh, 0.98)};
}

// A plane's inliers are taken in runs along its line, split where kWallRunGap holds none: the
// line of one room's wall crosses the other rooms of a larger space, where what lies on it is
// furniture.
std::vector<uint8_t> ClusterProposer::WallsAll(const Points& P, const std::vector<float>& hz, const std::vector<VPlane>& planes,
                              float sp) const {
  std::vector<uint8_t> wall(P.size(), 0);
  for (const VPlane& w : planes) {
    std::vector<std::pair<float, uint32_t>> along;
    along.reserve(w.inliers.size());
    for (uint32_t i : w.inliers) along.emplace_back(P[i].head<2>().dot(w.d), i);
    std::sort(along.begin(), along.end());
    std::vector<size_t> cuts{0};  // runs [cuts[r], cuts[r + 1])
    for (size_t k = 1; k < along.size(); ++k)
      if (along[k].first - along[k - 1].first > kWallRunGap) cuts.push_back(k);
    cuts.push_back(along.size());
    std::vector<std::pair<float, float>> spans;  // the wall stretches' extents along the line
    for (size_t r = 0; r + 1 < cuts.size(); ++r) {
      const size_t b = cuts[r], e = cuts[r + 1];
      const auto [a0, a1, h0, h1] = StretchExtent(along, hz, b, e);
      const bool big = (h1 - h0 > 1.0f && a1 - a0 > 0.8f) || float(e - b) * sp * sp > 1.5f;
      spdlog::debug("proposals.clusters: vertical plane n ({:.2f} {:.2f}) r {:.2f}: {:.2f} m long, {:.2f}-{:.2f} m high, "
                    "{} inliers{}", w.nv.x(), w.nv.y(), w.r, a1 - a0, h0, h1, e - b, big ? ": wall" : "");
      if (big) spans.emplace_back(a0 - 0.05f, a1 + 0.05f);
    }
    if (spans.empty()) continue;
    // One pass over the points per plane, whatever the number of its stretches.
    for (size_t i = 0; i < P.size(); ++i) {
      const Eigen::Vector2f q = P[i].head<2>();
      if (!(std::abs(q.dot(w.nv) - w.r) < 0.06f)) continue;
      const float a = q.dot(w.d);
      for (const auto& [lo, hi] : spans)
        if (a > lo && a < hi) {
          wall[i] = 1;
          break;
        }
    }
  }
  return wall;
}

// "segs": each plane's inliers rasterised in (along, height) cells of 10 cm, closed (3x3),
// split into 8-connected components; a component whose top is >= 1.5 m, >= 1.2 m tall and
// >= 0.6 m long is wall: the points within 6 cm of the plane inside its rectangle (+- 5 cm).
// A Hough "plane" also collects collinear points of several objects across a room; only
// connected stretches of wall size are walls.
std::vector<uint8_t> ClusterProposer::WallSegments(const Points& P, const std::vector<float>& hz, const std::vector<VPlane>& planes,
                                  float min_length) const {
  std::vector<uint8_t> wall(P.size(), 0);
  constexpr float cell = 0.10f;
  for (const VPlane& w : planes) {
    float alo = INFINITY, hlo = INFINITY, ahi = -INFINITY, hhi = -INFINITY;
    std::vector<float> al(w.inliers.size());
    for (size_t k = 0; k < w.inliers.size(); ++k) {
      al[k] = P[w.inliers[k]].head<2>().dot(w.d);
      alo = std::min(alo, al[k]), ahi = std::max(ahi, al[k]);
      hlo = std::min(hlo, hz[w.inliers[k]]), hhi = std::max(hhi, hz[w.inliers[k]]);
    }
    // On the lattice of multiples of the cell (a line's direction may come out either way).
    alo = std::floor(alo / cell) * cell;
    hlo = std::floor(hlo / cell) * cell;
    const int W = int((ahi - alo) / cell) + 3, H = int((hhi - hlo) / cell) + 3;
    if (W <= 0 || H <= 0 || size_t(W) * size_t(H) > 4000000) continue;
    std::vector<uint8_t> occ(size_t(W) * H, 0);
    std::vector<int> ci(w.inliers.size());
    for (size_t k = 0; k < w.inliers.size(); ++k) {
      const int ia = int((al[k] - alo) / cell) + 1, ih = int((hz[w.inliers[k]] - hlo) / cell) + 1;
      ci[k] = ih * W + ia;
      occ[size_t(ci[k])] = 1;
    }
    auto morph = [&](const std::vector<uint8_t>& in, bool dilate) {
      std::vector<uint8_t> o(in.size(), 0);
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          bool any = false, all = true;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int xx = x + dx, yy = y + dy;
              const bool v = xx >= 0 && yy >= 0 && xx < W && yy < H && in[size_t(yy) * W + xx];
              any |= v;
              all &= v;
            }
          o[size_t(y) * W + x] = dilate ? any : all;
        }
      return o;
    };
    std::vector<uint8_t> closed = morph(morph(occ, true), false);
    for (size_t c = 0; c < closed.size(); ++c) closed[c] |= occ[c];
    // 8-connected components of the closed raster.
    std::vector<int> label(closed.size(), -1);
    int labels = 0;
    std::vector<int> stack;
    for (size_t c0 = 0; c0 < closed.size(); ++c0) {
      if (!closed[c0] || label[c0] >= 0) continue;
      label[c0] = labels;
      stack.assign(1, int(c0));
      while (!stack.empty()) {
        const int c = stack.back();
        stack.pop_back();
        const int x = c % W, y = c / W;
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
            const size_t m = size_t(yy) * W + xx;
            if (closed[m] && label[m] < 0) label[m] = labels, stack.push_back(int(m));
          }
      }
      ++labels;
    }
    struct Seg {
      int n = 0, x0 = 1 << 30, x1 = -1, y0 = 1 << 30, y1 = -1;
    };
    std::vector<Seg> segs(labels);
    for (size_t k = 0; k < ci.size(); ++k) ++segs[label[size_t(ci[k])]].n;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const int l = label[size_t(y) * W + x];
        if (l < 0) continue;
        Seg& s = segs[l];
        s.x0 = std::min(s.x0, x), s.x1 = std::max(s.x1, x), s.y0 = std::min(s.y0, y), s.y1 = std::max(s.y1, y);
      }
    for (const Seg& s : segs) {
      if (s.n < 30) continue;
      const float a0 = alo + float(s.x0 - 1) * cell, a1 = alo + float(s.x1) * cell;
      const float h0 = hlo + float(s.y0 - 1) * cell, h1 = hlo + float(s.y1) * cell;
      if (h1 - h0 < 1.2f || h1 < 1.5f || a1 - a0 < min_length) continue;
      for (size_t i = 0; i < P.size(); ++i) {
        const Eigen::Vector2f q = P[i].head<2>();
        const float along = q.dot(w.d);
        if (std::abs(q.dot(w.nv) - w.r) < 0.06f && along > a0 - 0.05f && along < a1 + 0.05f && hz[i] > h0 - 0.05f &&
            hz[i] < h1 + 0.05f)
          wall[i] = 1;
      }
    }
  }
  return wall;
}

}  // namespace furnihost::clusters
