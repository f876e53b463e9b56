#include "shape/shape.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <nanoflann.hpp>
#include <unordered_map>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"

namespace furnihost::shape {

namespace {
struct Adaptor {
  const Points& pts;
  size_t kdtree_get_point_count() const { return pts.size(); }
  float kdtree_get_pt(size_t i, size_t d) const { return pts[i][int(d)]; }
  template <class B>
  bool kdtree_get_bbox(B&) const { return false; }
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Adaptor>, Adaptor, 3, uint32_t>;

// Groups equal points (GroupEqualPoints: linear time). Fills `start` / `members` and returns the
// distinct positions in order of first appearance; returns nothing (and leaves the others
// empty) when every point is distinct.
Points GroupDuplicates(const Points& p, std::vector<uint32_t>& start, std::vector<uint32_t>& members) {
  std::vector<uint32_t> which;  // distinct index of each point
  Points distinct = GroupEqualPoints(p, &which);
  if (distinct.size() == p.size()) return {};
  GroupMembers(which, distinct.size(), start, members);
  return distinct;
}

// The points at `positions` (nearest first, with their squared distances), each position's
// points in index order, until `want` points: what a query of a cloud with copies answers.
void ExpandPositions(const std::vector<uint32_t>& positions, const std::vector<float>& d2, const uint32_t* start,
                     const uint32_t* members, size_t want, std::vector<uint32_t>& index, std::vector<float>& dist2) {
  index.clear(), dist2.clear();
  for (size_t j = 0; j < positions.size() && index.size() < want; ++j)
    for (uint32_t m = start[positions[j]]; m < start[positions[j] + 1] && index.size() < want; ++m)
      index.push_back(members[m]), dist2.push_back(d2[j]);
}
}  // namespace

// A k-d tree leaf of identical points cannot split, so a cloud of N copies (a driver's
// (0, 0, 0) for every invalid return) put all N in one leaf that every query scanned: N^2.
// The tree is built over the distinct positions instead, each listing the points at it. A
// cloud without duplicates gets the tree it always had (same points, same order).
struct KnnIndex::Impl {
  std::vector<uint32_t> start;    // the points at distinct position u: members[start[u] .. start[u+1])
  std::vector<uint32_t> members;  // ascending point indices within a position
  Points distinct;                // empty when every point is distinct (the tree is over the cloud)
  Adaptor adaptor;
  Tree tree;
  explicit Impl(const Points& p)
      : distinct(GroupDuplicates(p, start, members)),
        adaptor{distinct.empty() ? p : distinct},
        tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16)) {}  // built by its constructor (nanoflann 1.4)
};

KnnIndex::KnnIndex(const Points& points) : points_(points), impl_(std::make_unique<Impl>(points)) {}
KnnIndex::~KnnIndex() = default;

void KnnIndex::Query(const Eigen::Vector3f& q, int k, std::vector<uint32_t>& index, std::vector<float>& dist2) const {
  const size_t want = std::min<size_t>(size_t(std::max(k, 1)), points_.size());
  const size_t positions = impl_->distinct.empty() ? points_.size() : impl_->distinct.size();
  // The k nearest points lie at the k nearest positions (fewer when some are shared).
  const size_t look = std::min(want, positions);
  index.resize(look);
  dist2.resize(look);
  if (look == 0) return;
  nanoflann::KNNResultSet<float, uint32_t> rs(look);
  rs.init(index.data(), dist2.data());
  impl_->tree.findNeighbors(rs, q.data(), nanoflann::SearchParams());
  index.resize(rs.size());
  dist2.resize(rs.size());
  if (impl_->distinct.empty()) return;
  std::vector<uint32_t> at;
  std::vector<float> d;
  ExpandPositions(index, dist2, impl_->start.data(), impl_->members.data(), want, at, d);
  index.swap(at);
  dist2.swap(d);
}

std::vector<uint32_t> KnnIndex::LeafOrder() const {
  const auto& leaves = impl_->tree.vAcc;
  if (impl_->distinct.empty()) return std::vector<uint32_t>(leaves.begin(), leaves.end());
  std::vector<uint32_t> order;
  order.reserve(points_.size());
  for (uint32_t u : leaves)
    order.insert(order.end(), impl_->members.begin() + impl_->start[u], impl_->members.begin() + impl_->start[u + 1]);
  return order;
}

Points BlockNormals(const Points& pts, float voxel) {
  const size_t n = pts.size();
  Points normals(n, Eigen::Vector3f::UnitZ());
  if (pts.empty() || !(voxel > 0.f)) return normals;
  auto key_of = [voxel](const Eigen::Vector3f& p) {
    const auto c = [voxel](float v) { return int64_t(std::floor(double(v) / double(voxel))) & 0x1FFFFF; };
    return (c(p.x()) << 42) | (c(p.y()) << 21) | c(p.z());
  };
  // The points by voxel (key, then index: each voxel's points in their own order), and each
  // occupied voxel's moments about its first point (far-off coordinates do not cancel in
  // float sums). A sort and a flat hash table: a node-based map cost 2/3 of this function.
  std::vector<std::pair<int64_t, uint32_t>> by_key(n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) by_key[i] = {key_of(pts[i]), uint32_t(i)};
  });
  std::sort(by_key.begin(), by_key.end());
  std::vector<uint32_t> start;  // cell c holds by_key[start[c], start[c + 1])
  for (size_t i = 0; i < n; ++i)
    if (i == 0 || by_key[i].first != by_key[i - 1].first) start.push_back(uint32_t(i));
  const size_t cells = start.size();
  start.push_back(uint32_t(n));
  struct Cell {
    Eigen::Vector3d ref = Eigen::Vector3d::Zero(), s = Eigen::Vector3d::Zero();
    Eigen::Matrix3d ss = Eigen::Matrix3d::Zero();
    double n = 0;
  };
  std::vector<Cell> cell(cells);
  std::vector<uint32_t> cell_of(n);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cells, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t c = r.begin(); c != r.end(); ++c) {
      Cell& v = cell[c];
      v.ref = pts[by_key[start[c]].second].cast<double>();
      for (uint32_t k = start[c]; k < start[c + 1]; ++k) {
        const uint32_t i = by_key[k].second;
        const Eigen::Vector3d d = pts[i].cast<double>() - v.ref;
        v.s += d;
        v.ss += d * d.transpose();
        v.n += 1;
        cell_of[i] = uint32_t(c);
      }
    }
  });
  // Key -> cell: open addressing, linear probing, at most half full.
  size_t cap = 16;
  while (cap < 2 * cells) cap <<= 1;
  std::vector<int64_t> slot_key(cap, -1);
  std::vector<uint32_t> slot_cell(cap, 0);
  auto home = [cap](int64_t k) { return HashSlot(uint64_t(k), cap - 1); };
  for (size_t c = 0; c < cells; ++c) {
    const int64_t k = by_key[start[c]].first;
    size_t h = home(k);
    while (slot_key[h] != -1) h = (h + 1) & (cap - 1);
    slot_key[h] = k, slot_cell[h] = uint32_t(c);
  }
  auto find = [&](int64_t k) -> int64_t {
    for (size_t h = home(k);; h = (h + 1) & (cap - 1)) {
      if (slot_key[h] == k) return slot_cell[h];
      if (slot_key[h] == -1) return -1;
    }
  };
  // Each voxel's normal from its 3 x 3 x 3 block (moments moved to the voxel's own reference).
  std::vector<Eigen::Vector3f> cell_normal(cells, Eigen::Vector3f::UnitZ());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cells, 256), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t c = r.begin(); c != r.end(); ++c) {
      const int64_t k = by_key[start[c]].first;
      const int64_t kx = (k >> 42) & 0x1FFFFF, ky = (k >> 21) & 0x1FFFFF, kz = k & 0x1FFFFF;
      const Eigen::Vector3d ref = cell[c].ref;
      Eigen::Vector3d s = Eigen::Vector3d::Zero();
      Eigen::Matrix3d ss = Eigen::Matrix3d::Zero();
      double m = 0;
      for (int64_t dx = -1; dx <= 1; ++dx)
        for (int64_t dy = -1; dy <= 1; ++dy)
          for (int64_t dz = -1; dz <= 1; ++dz) {
            const int64_t nk = (((kx + dx) & 0x1FFFFF) << 42) | (((ky + dy) & 0x1FFFFF) << 21) | ((kz + dz) & 0x1FFFFF);
            const int64_t f = find(nk);
            if (f < 0) continue;
            const Cell& o = cell[size_t(f)];
            const Eigen::Vector3d t = o.ref - ref;  // sums about o.ref -> about ref
            s += o.s + o.n * t;
            ss += o.ss + o.s * t.transpose() + t * o.s.transpose() + o.n * t * t.transpose();
            m += o.n;
          }
      if (m < 3) continue;
      const Eigen::Vector3d mean = s / m;
      const Eigen::Matrix3d cov = ss / m - mean * mean.transpose();
      const Eigen::Vector3d nv = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
      if (nv.allFinite()) cell_normal[c] = nv.cast<float>();
    }
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) normals[i] = cell_normal[cell_of[i]];
  });
  return normals;
}

namespace {
// One point's local shape from its neighbours (idx: points, nearest first, the point itself
// and its copies among them; d2: their squared distances).
void ShapeOf(const Points& pts, size_t i, const std::vector<uint32_t>& idx, const std::vector<float>& d2,
             std::vector<float>& others, LocalShape& out) {
  // Distances to other points: skip the query itself (and exact duplicates count as 0).
  others.clear();
  bool self = false;
  for (size_t j = 0; j < idx.size(); ++j) {
    if (!self && idx[j] == i) {
      self = true;
      continue;
    }
    others.push_back(std::sqrt(d2[j]));
  }
  if (!others.empty()) out.nn[i] = others.front();
  if (others.size() >= 4) out.nn4[i] = others[3];
  else if (!others.empty()) out.nn4[i] = others.back();
  if (idx.size() < 3) return;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (uint32_t j : idx) mean += pts[j].cast<double>();
  mean /= double(idx.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (uint32_t j : idx) {
    const Eigen::Vector3d d = pts[j].cast<double>() - mean;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
  es.computeDirect(cov);  // closed form: a third of the iterative solver's time
  const Eigen::Vector3d n = es.eigenvectors().col(0);
  if (n.allFinite()) out.normals[i] = n.cast<float>();
}

LocalShape EmptyShape(size_t n) {
  LocalShape out;
  out.normals.assign(n, Eigen::Vector3f::UnitZ());
  out.nn.assign(n, 0.f);
  out.nn4.assign(n, 0.f);
  return out;
}
}  // namespace

LocalShape EstimateLocalShape(const KnnIndex& index, int k) {
  const Points& pts = index.Cloud();
  LocalShape out = EmptyShape(pts.size());
  // Queries in the tree's leaf order (each point's result is its own): a scan's file order is
  // random for ScanNet's sampled vertices, and queries in it miss the cache on every level.
  const std::vector<uint32_t> order = index.LeafOrder();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, pts.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<uint32_t> idx;
    std::vector<float> d2, others;
    for (size_t t = r.begin(); t != r.end(); ++t) {
      const size_t i = order[t];
      index.Query(pts[i], k + 1, idx, d2);
      ShapeOf(pts, i, idx, d2, others, out);
    }
  });
  return out;
}

bool CanUse(const ScanNeighbours* nb, const Points& pts, int k) {
  return nb && nb->Describes(pts.size()) && k + 1 <= nb->k;
}

LocalShape EstimateLocalShape(const Points& pts, const ScanNeighbours& nb, int k) {
  LocalShape out = EmptyShape(pts.size());
  const size_t positions = nb.Positions();
  const size_t want = std::min<size_t>(size_t(std::max(k + 1, 1)), pts.size());
  const size_t look = std::min(want, positions);
  const size_t stride = size_t(nb.k);
  // Per position (its points share its neighbours), as KnnIndex::Query answers a query at it:
  // the nearest `look` positions by their distance in this frame, each position's points in
  // index order until `want` points.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, positions, 512), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<std::pair<float, uint32_t>> near;
    std::vector<uint32_t> pos, idx;
    std::vector<float> pos_d2, d2, others;
    for (size_t u = r.begin(); u != r.end(); ++u) {
      const Eigen::Vector3f& q = pts[nb.members[nb.start[u]]];
      near.clear();
      const size_t c = std::min<size_t>(nb.count[u], look);
      for (size_t j = 0; j < c; ++j) {
        const uint32_t v = nb.nearest[u * stride + j];
        const Eigen::Vector3f& p = pts[nb.members[nb.start[v]]];
        // As nanoflann's L2_Simple_Adaptor sums it.
        float s = 0.f;
        for (int d = 0; d < 3; ++d) {
          const float diff = q[d] - p[d];
          s += diff * diff;
        }
        near.emplace_back(s, v);
      }
      std::stable_sort(near.begin(), near.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      pos.clear(), pos_d2.clear();
      for (const auto& [s, v] : near) pos.push_back(v), pos_d2.push_back(s);
      ExpandPositions(pos, pos_d2, nb.start.data(), nb.members.data(), want, idx, d2);
      for (uint32_t m = nb.start[u]; m < nb.start[u + 1]; ++m) ShapeOf(pts, nb.members[m], idx, d2, others, out);
    }
  });
  return out;
}

float MedianSpacing(const std::vector<float>& nn, size_t stride) {
  std::vector<float> v;
  for (size_t i = 0; i < nn.size(); i += std::max<size_t>(stride, 1))
    if (nn[i] > 1e-6f && std::isfinite(nn[i])) v.push_back(nn[i]);
  if (v.empty()) return 0.f;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

namespace {
// The value at quantile q of v (v is reordered).
float Quantile(std::vector<float>& v, double q) {
  const size_t k = std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

// The m (<= kCap) smallest (PushLow) or largest (PushHigh) values pushed, sorted from the
// extreme inwards; Last() is then the m-th smallest (largest) value: the order statistic
// Quantile finds, whatever order the values come in.
class ExtremeBuffer {
 public:
  static constexpr size_t kCap = 16;
  explicit ExtremeBuffer(size_t m) : m_(m) {}
  void PushLow(float x) {
    if (size_ == m_ && !(x < v_[size_ - 1])) return;
    size_t i = size_ == m_ ? size_ - 1 : size_++;
    for (; i > 0 && x < v_[i - 1]; --i) v_[i] = v_[i - 1];
    v_[i] = x;
  }
  void PushHigh(float x) {
    if (size_ == m_ && !(x > v_[size_ - 1])) return;
    size_t i = size_ == m_ ? size_ - 1 : size_++;
    for (; i > 0 && x > v_[i - 1]; --i) v_[i] = v_[i - 1];
    v_[i] = x;
  }
  float Last() const { return v_[size_ - 1]; }

 private:
  size_t m_, size_ = 0;
  std::array<float, kCap> v_{};
};
}  // namespace

// Points the footprint's direction is chosen on (OrientedFootprint).
constexpr size_t kFootprintSample = 256;

Footprint OrientedFootprint(const std::vector<Eigen::Vector2f>& xy, float axis_margin) {
  Footprint f;
  if (xy.empty()) return f;
  if (xy.size() < 5) {
    Eigen::Vector2f lo = xy[0], hi = xy[0];
    for (const auto& p : xy) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    const Eigen::Vector2f e = hi - lo;
    f.center = 0.5f * (lo + hi);
    f.length = std::max(e.x(), e.y());
    f.width = std::min(e.x(), e.y());
    f.yaw = e.x() >= e.y() ? 0.f : float(M_PI / 2);
    return f;
  }
  // Candidate directions: the hull edges' angles folded into [0, 90 deg), deduplicated to 1 mrad.
  const std::vector<Eigen::Vector2f> h = ConvexHull2D(xy);
  std::vector<float> angles;
  for (size_t i = 0; i < h.size(); ++i) {
    const Eigen::Vector2f e = h[(i + 1) % h.size()] - h[i];
    float a = std::fmod(std::atan2(e.y(), e.x()), float(M_PI / 2));
    if (a < 0) a += float(M_PI / 2);
    angles.push_back(std::round(a * 1000.f) / 1000.f);
  }
  if (angles.empty()) angles.push_back(0.f);
  std::sort(angles.begin(), angles.end());
  angles.erase(std::unique(angles.begin(), angles.end()), angles.end());
  // The direction is chosen on a subsample of about kFootprintSample points (the trimmed extents
  // of a few hundred points rank the directions as all of them do), the extents then taken over
  // all. A point is in it when the hash of its 1 cm cell falls under a share that varies
  // smoothly with the count; the cell's hash is of its indices' magnitudes, unordered, so a
  // quarter turn or mirror of the frame about its origin keeps it (a canonical frame's axes
  // come out in any of those). The same points whatever order they come in, and when a point or
  // two join or leave the cluster (a radius's rounding in a turned scan), the others stay. Every
  // k-th point of the list instead shifted all later picks by one more point before them; of two
  // rectangles 5 % apart in area the subsample then took either (FramesOnRealScans.ScanNetRoom).
  std::vector<Eigen::Vector2f> sub;
  if (xy.size() <= kFootprintSample) {
    sub = xy;
  } else {
    const uint64_t under = uint64_t(double(kFootprintSample) / double(xy.size()) * 18446744073709551616.0);
    for (const auto& p : xy) {
      const int64_t cx = std::llabs(std::llround(p.x() * 100.f)), cy = std::llabs(std::llround(p.y() * 100.f));
      if (SplitMix64(uint64_t(std::min(cx, cy)) * 0x9E3779B97F4A7C15ull ^ uint64_t(std::max(cx, cy))) < under)
        sub.push_back(p);
    }
    if (sub.size() < 5) sub = xy;
  }
  auto extents = [](const std::vector<Eigen::Vector2f>& pts, float a, std::vector<float>& u, std::vector<float>& v) {
    const float c = std::cos(a), s = std::sin(a);
    const size_t n = pts.size();
    // The 1st and 99th percentiles are the k-th smallest and the k'-th largest values with k,
    // k' small for the subsample: one pass keeping the few extreme values of each side finds
    // the same order statistics as four nth_element calls, at a fraction of their cost (the
    // footprint's directions were ~60 % of proposals.clusters' and voters.catalog_shape's
    // footprint time on a ScanNet room).
    const size_t k_lo = std::min(n - 1, size_t(0.01 * double(n - 1) + 0.5));
    const size_t k_hi = std::min(n - 1, size_t(0.99 * double(n - 1) + 0.5));
    if (k_lo < ExtremeBuffer::kCap && n - 1 - k_hi < ExtremeBuffer::kCap) {
      ExtremeBuffer ulo(k_lo + 1), uhi(n - k_hi), vlo(k_lo + 1), vhi(n - k_hi);
      for (size_t i = 0; i < n; ++i) {
        const float ui = c * pts[i].x() + s * pts[i].y();
        const float vi = -s * pts[i].x() + c * pts[i].y();
        ulo.PushLow(ui), uhi.PushHigh(ui), vlo.PushLow(vi), vhi.PushHigh(vi);
      }
      return Eigen::Vector4f(ulo.Last(), uhi.Last(), vlo.Last(), vhi.Last());
    }
    u.resize(n);
    v.resize(n);
    for (size_t i = 0; i < n; ++i) {
      u[i] = c * pts[i].x() + s * pts[i].y();
      v[i] = -s * pts[i].x() + c * pts[i].y();
    }
    return Eigen::Vector4f(Quantile(u, 0.01), Quantile(u, 0.99), Quantile(v, 0.01), Quantile(v, 0.99));
  };
  double best = INFINITY;
  float best_a = 0.f;
  std::vector<float> u, v;
  for (float a : angles) {
    const Eigen::Vector4f e = extents(sub, a, u, v);
    const double area = double(e[1] - e[0]) * double(e[3] - e[2]);
    if (area < best) best = area, best_a = a;
  }
  {
    const Eigen::Vector4f e = extents(sub, 0.f, u, v);
    if (double(e[1] - e[0]) * double(e[3] - e[2]) * (1.0 - double(axis_margin)) <= best) best_a = 0.f;
  }
  const Eigen::Vector4f e = extents(xy, best_a, u, v);
  const float c = std::cos(best_a), s = std::sin(best_a);
  const float uc = 0.5f * (e[0] + e[1]), vc = 0.5f * (e[2] + e[3]);
  f.center = Eigen::Vector2f(uc * c - vc * s, uc * s + vc * c);
  if (e[1] - e[0] >= e[3] - e[2]) {
    f.length = e[1] - e[0], f.width = e[3] - e[2], f.yaw = best_a;
  } else {
    f.length = e[3] - e[2], f.width = e[1] - e[0], f.yaw = best_a + float(M_PI / 2);
  }
  return f;
}

Profile TopViewProfile(const std::vector<Eigen::Vector2f>& xy, const std::vector<float>& heights, float top, float cell) {
  Profile p{};
  if (xy.empty()) {
    p.fill(1.f / kProfileBins);
    return p;
  }
  // Columns on the lattice of multiples of `cell` (the scan's canonical frame lays it the same
  // way on an object whichever quarter turn the scan came in).
  std::unordered_map<uint64_t, float> column;
  column.reserve(xy.size());
  for (size_t i = 0; i < xy.size(); ++i) {
    const int64_t ix = int64_t(std::floor(xy[i].x() / cell)), iy = int64_t(std::floor(xy[i].y() / cell));
    const uint64_t key = (uint64_t(ix) << 32) ^ (uint64_t(iy) & 0xffffffffu);
    auto [it, fresh] = column.try_emplace(key, heights[i]);
    if (!fresh) it->second = std::max(it->second, heights[i]);
  }
  const float t = std::max(top, 1e-3f);
  for (const auto& [key, h] : column) {
    const float r = std::clamp(h / t, 0.f, 1.f - 1e-6f);
    p[size_t(r * kProfileBins)] += 1.f;
  }
  const float n = float(column.size());
  for (auto& v : p) v /= n;
  return p;
}

float ProfileDistance(const Profile& a, const Profile& b) {
  float ca = 0.f, cb = 0.f, d = 0.f;
  for (int i = 0; i < kProfileBins; ++i) {
    ca += a[i];
    cb += b[i];
    d += std::abs(ca - cb);
  }
  return d / kProfileBins;
}

std::vector<uint8_t> VisibleFrom(const Points& points, const Points& eyes, float pixel, float tolerance) {
  std::vector<uint8_t> seen(points.size(), 0);
  std::vector<float> r(points.size());
  std::vector<int64_t> key(points.size());
  for (const auto& e : eyes) {
    std::unordered_map<int64_t, float> nearest;
    nearest.reserve(points.size());
    for (size_t i = 0; i < points.size(); ++i) {
      const Eigen::Vector3f d = points[i] - e;
      r[i] = d.norm();
      if (!(r[i] > 0.f)) continue;
      const float az = std::atan2(d.y(), d.x()), el = std::asin(std::clamp(d.z() / r[i], -1.f, 1.f));
      key[i] = int64_t(std::floor(az / pixel)) * 100000 + int64_t(std::floor(el / pixel));
      auto [it, fresh] = nearest.try_emplace(key[i], r[i]);
      if (!fresh) it->second = std::min(it->second, r[i]);
    }
    for (size_t i = 0; i < points.size(); ++i)
      if (r[i] > 0.f && r[i] <= nearest[key[i]] + tolerance) seen[i] = 1;
  }
  return seen;
}

Points EyesAround(const Eigen::Vector3f& size, float height, float distance, int n) {
  Points eyes;
  const float R = distance + 0.5f * std::hypot(size.x(), size.y());
  for (int k = 0; k < n; ++k) {
    const float a = 2.f * float(M_PI) * float(k) / float(n);
    eyes.emplace_back(R * std::cos(a), R * std::sin(a), height);
  }
  return eyes;
}

float BoxIou(const Eigen::AlignedBox3f& a, const Eigen::AlignedBox3f& b) {
  const Eigen::AlignedBox3f i = a.intersection(b);
  if (i.isEmpty()) return 0.f;
  const float vi = i.volume(), u = a.volume() + b.volume() - vi;
  return u > 0 ? vi / u : 0.f;
}

std::vector<size_t> SuppressOverlaps(std::vector<size_t> candidates, const std::vector<float>& score,
                                     const std::vector<Proposal>& proposals, float max_iou, float whole_ratio) {
  std::stable_sort(candidates.begin(), candidates.end(), [&](size_t a, size_t b) { return score[a] > score[b]; });
  // Whether box a is a whole of which the kept box b may be a fragment.
  auto whole_of = [whole_ratio](const Eigen::AlignedBox3f& a, const Eigen::AlignedBox3f& b) {
    if (!(whole_ratio > 0.f)) return false;
    const Eigen::AlignedBox3f in = a.intersection(b);
    return !in.isEmpty() && in.volume() >= 0.9f * b.volume() && a.volume() >= whole_ratio * b.volume();
  };
  std::vector<size_t> kept;
  for (size_t i : candidates) {
    bool suppressed = false;
    for (size_t k : kept)
      if (BoxIou(proposals[i].box, proposals[k].box) > max_iou && !whole_of(proposals[i].box, proposals[k].box)) {
        suppressed = true;
        break;
      }
    if (!suppressed) kept.push_back(i);
  }
  return kept;
}

Hypothesis ProposalHypothesis(const std::string& cls, float score, float threshold, const Proposal& p, int index,
                              int scene, const Footprint& f, const std::string& model_id, bool model_wide,
                              const Eigen::Isometry3f& pose, float turn) {
  Hypothesis h;
  h.cls = cls;
  h.score = score;
  h.proposal = index;
  h.scene = scene;
  OrientedBox b;
  b.center = pose * p.box.center();
  b.size = p.box.sizes();
  b.yaw = std::atan2(pose.linear()(1, 0), pose.linear()(0, 0));
  h.box = b;
  h.center = b.center;
  h.checks.push_back(Check::AtLeast("score", score, threshold));
  h.accepted = h.checks.back().passed;
  h.model = model_id;
  const float yaw = ModelYaw(f, model_wide) + turn;
  Eigen::Isometry3f m = Eigen::Isometry3f::Identity();
  m.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  m.translation() = Eigen::Vector3f(f.center.x(), f.center.y(), p.ground_z);
  h.model_pose = pose * m;
  return h;
}

float ModelYaw(const Footprint& f, bool model_wide) { return f.yaw + (model_wide ? 0.f : float(M_PI / 2)); }

std::optional<Eigen::Vector2f> TopQuarterCentre(const std::vector<Eigen::Vector2f>& xy, const std::vector<float>& h,
                                                float height) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  size_t n = 0;
  for (size_t k = 0; k < xy.size() && k < h.size(); ++k)
    if (h[k] >= 0.75f * height) sum += xy[k].cast<double>(), ++n;
  if (n < 10) return std::nullopt;
  return (sum / double(n)).cast<float>();
}

float TurnToMatchTop(const Footprint& f, bool model_wide, const Eigen::Vector2f& model_top,
                     const Eigen::Vector2f& model_size_xy, const Eigen::Vector2f& top_centre) {
  // Offsets under 0.1 of the extent: no side stands out.
  constexpr float kCentral = 0.1f;
  if (model_top.norm() < kCentral || !(model_size_xy.minCoeff() > 0.f)) return 0.f;
  const Eigen::Vector2f mean = top_centre - f.center;
  const bool square = model_size_xy.maxCoeff() <= 1.2f * model_size_xy.minCoeff();
  float best_turn = 0.f, best = -INFINITY;
  for (int k = 0; k < 4; ++k) {
    if (k % 2 == 1 && !square) continue;
    const float turn = float(k) * float(M_PI / 2);
    const float yaw = ModelYaw(f, model_wide) + turn;
    // The points' top quarter in the model's frame as stood, over its extents.
    const Eigen::Vector2f local(std::cos(yaw) * mean.x() + std::sin(yaw) * mean.y(),
                                -std::sin(yaw) * mean.x() + std::cos(yaw) * mean.y());
    const Eigen::Vector2f seen = local.cwiseQuotient(model_size_xy);
    if (seen.norm() < kCentral) return 0.f;
    const float agree = seen.dot(model_top);
    if (agree > best) best = agree, best_turn = turn;
  }
  return best_turn;
}

}  // namespace furnihost::shape
