#include "parts/part_features.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <tuple>
#include <utility>

#include "furnihost/hash.hpp"
#include "furnihost/voxel_index.hpp"
#include "parallel/tbb_for.hpp"
#include "simd/left_pack.hpp"

namespace furnihost::parts {

namespace {

float SafeDiv(double a, double b) { return b < 1e-12 ? 0.f : float(a / b); }

// Monotonic in the angle of (a, b) over [0, 2 pi), in [0, 4): sorting by it sorts by angle
// without atan2.
float PseudoAngle(float a, float b) {
  const float s = std::fabs(a) + std::fabs(b);
  const float t = b / s;
  if (a >= 0) return b >= 0 ? t : 4.f + t;  // quadrants 1 and 4
  return 2.f - t;                            // quadrants 2 and 3
}

struct Dir {
  float key, a, b;
};

// True when the counter-clockwise angle from p to q exceeds the threshold whose cosine is
// cos_t (threshold < 180 deg): when it is reflex (cross < 0, or cross == 0 with opposite
// directions) or cos(angle) < cos_t, compared without square roots.
inline bool WideGap(float pa, float pb, float qa, float qb, float cos_t) {
  const float cross = pa * qb - pb * qa;
  const float dot = pa * qa + pb * qb;
  if (cross < 0 || (cross == 0 && dot < 0)) return true;
  const float l2 = (pa * pa + pb * pb) * (qa * qa + qb * qb);
  const float c2 = cos_t * cos_t;
  return cos_t >= 0 ? (dot < 0 || dot * dot < c2 * l2) : (dot < 0 && dot * dot > c2 * l2);
}

// For thresholds >= 90 deg: a gap wider than 90 deg contains a whole empty sector (the 45 deg
// sectors of simd::Octant; sector k is pseudo-angle keys [k / 2, (k + 1) / 2)), so only the
// gaps around the empty sectors need checking: the gap around sector k runs from the last
// direction before it to the first one after it. No sort.
bool GapAtEmptySectors(const float* a, const float* b, int m, unsigned sectors, float cos_t,
                       std::vector<float>& key) {
  if (m < 2) return true;
  key.resize(m);
  for (int j = 0; j < m; ++j) key[j] = PseudoAngle(a[j], b[j]);
  for (int k = 0; k < 8; ++k) {
    if (sectors & (1u << k)) continue;
    const float end = 0.5f * float(k + 1);
    int first = 0, last = 0;
    float tmin = 5.f, tmax = -1.f;
    for (int j = 0; j < m; ++j) {
      float t = key[j] - end;  // angle after the sector's end, in [0, 4)
      if (t < 0) t += 4.f;
      if (t < tmin) tmin = t, first = j;
      if (t > tmax) tmax = t, last = j;
    }
    if (tmax <= tmin) return true;  // one direction only: a 360 deg gap
    if (WideGap(a[last], b[last], a[first], b[first], cos_t)) return true;
  }
  return false;
}

// True when the largest angular gap between consecutive directions (sorted by angle) exceeds
// the threshold. Fewer than 2 directions: true.
bool HasGap(std::vector<Dir>& dirs, float cos_t) {
  if (dirs.size() < 2) return true;
  std::sort(dirs.begin(), dirs.end(), [](const Dir& l, const Dir& r) { return l.key < r.key; });
  if (dirs.back().key <= dirs.front().key) return true;  // one direction only: a 360 deg gap
  const size_t m = dirs.size();
  for (size_t i = 0; i < m; ++i) {
    const Dir& p = dirs[i];
    const Dir& q = dirs[(i + 1) % m];
    if (WideGap(p.a, p.b, q.a, q.b, cos_t)) return true;
  }
  return false;
}

// Feature 1 over the part's points (local frame, by part-local index).
// Thresholds >= 90 deg (the default) go through the sectors (GapAtEmptySectors), smaller ones
// sort the directions.
float BoundaryRatio(const Points& q, const Points& normals, const Eigen::Vector3f& fallback,
                    const PartFeatureOptions& o) {
  const float r = float(o.boundary_radius_m);
  const float r2 = r * r;
  const float cos_t = float(std::cos(o.boundary_angle_deg * M_PI / 180.0));
  const bool wide = o.boundary_angle_deg >= 90.0;
  const size_t max_tests = o.boundary_tests_per_cell > 0 ? size_t(o.boundary_tests_per_cell) : SIZE_MAX;
  VoxelIndex grid;
  grid.Build(q, r, VoxelIndex::Anchor::kBoundingBox, TbbFor());
  // Normals in slot order, gathered in one pass: read inside the loop below they would be a
  // cache miss per point (parts come in input order, slots in spatial order).
  Points slot_normal(q.size());
  for (size_t s = 0; s < q.size(); ++s) {
    Eigen::Vector3f n = normals[grid.order[s]];
    if (!n.allFinite() || n.squaredNorm() < 1e-12f) n = fallback;
    slot_normal[s] = n.normalized();
  }
  std::atomic<int> boundary{0};
  const bool avx2 = simd::UseAvx2();
  tbb::parallel_for(tbb::blocked_range<int>(0, grid.NumCells(), 32), [&](const tbb::blocked_range<int>& range) {
    std::vector<Dir> dirs;
    std::vector<float> pa, pb, keys;
    std::vector<int> slots, weights, run_b, run_e;
    int count = 0;
    for (int c = range.begin(); c != range.end(); ++c) {
      // The 27 cells' points read in place, as up to 9 runs of contiguous slots
      // (VoxelIndex::NeighbourSlotRuns): no copy, and a third of the loops.
      const int m = grid.NeighbourSlotRuns(c, run_b, run_e);
      // Copies of one point (with one normal) have one answer: test it once, weighted by its
      // copies, or N copies (a (0, 0, 0) flood) cost N tests of N neighbours each. Only cells
      // that could hold many copies are sorted; a small cell costs at most its size times its
      // neighbourhood. A cell of more than boundary_tests_per_cell distinct points (a scan much
      // denser than the boundary radius needs) tests an even sample of them, each standing for
      // the points up to the next, so the cost per point stops growing with the density (the
      // ratio is then an estimate; each test still sees every neighbour).
      const int cell_n = grid.cell_start[c + 1] - grid.cell_start[c];
      slots.resize(size_t(cell_n));
      std::iota(slots.begin(), slots.end(), grid.cell_start[c]);
      auto key = [&](int t) {
        const Eigen::Vector3f& n = slot_normal[t];
        return std::make_tuple(grid.x[t], grid.y[t], grid.z[t], n.x(), n.y(), n.z());
      };
      weights.assign(size_t(cell_n), 1);
      if (cell_n > 32 || size_t(cell_n) > max_tests) {
        std::sort(slots.begin(), slots.end(),
                  [&](int a, int b) { return std::make_pair(key(a), a) < std::make_pair(key(b), b); });
        size_t u = 0;  // distinct points to the front, weighted by their copies
        for (size_t t = 0; t < slots.size(); ++t)
          if (t > 0 && key(slots[t]) == key(slots[u - 1]))
            ++weights[u - 1];
          else
            slots[u] = slots[t], weights[u++] = 1;
        slots.resize(u), weights.resize(u);
        if (u > max_tests) {
          const size_t stride = (u + max_tests - 1) / max_tests;
          size_t k = 0;
          for (size_t t = 0; t < u; t += stride) {
            int w = 0;
            for (size_t j = t; j < std::min(u, t + stride); ++j) w += weights[j];
            slots[k] = slots[t], weights[k++] = w;
          }
          slots.resize(k), weights.resize(k);
        }
      }
      bool last = false;  // the answer of the last slot tested
      for (size_t t = 0; t < slots.size(); ++t) {
        const int s = slots[t];
        const int w = weights[t];
        const Eigen::Vector3f& n = slot_normal[s];
        // Any tangent basis: the gap test is rotation invariant in the plane.
        const Eigen::Vector3f u =
            (std::fabs(n.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY()).cross(n).normalized();
        const Eigen::Vector3f v = n.cross(u);
        const float px = grid.x[s], py = grid.y[s], pz = grid.z[s];
        const float min_len2 = 1e-10f * r2;
        // Projections of the neighbours on the tangent plane, compacted without branches:
        // within r, and not the point itself nor straight above it.
        if (pa.size() < size_t(m) + simd::kAppendSlack) pa.resize(size_t(m) + simd::kAppendSlack), pb.resize(pa.size());
        int cnt = 0;
        const float *gx = grid.x.data(), *gy = grid.y.data(), *gz = grid.z.data();
        const float ua[3] = {u.x(), u.y(), u.z()}, va[3] = {v.x(), v.y(), v.z()};
        auto project = [&](int j_begin, int j_end) {
          cnt = simd::AppendTangentWithin(avx2, gx, gy, gz, j_begin, j_end, px, py, pz, ua, va, r2, min_len2, pa.data(),
                                          pb.data(), cnt);
        };
        if (wide) {
          // Neighbours in all eight 45 deg sectors leave no gap above 90 deg whatever the
          // others: an inner point stops there, long before the end of a dense neighbourhood.
          // Otherwise every neighbour is projected, as without the chunks.
          constexpr int kChunk = 64;
          unsigned sectors = 0;
          for (size_t k = 0; k < run_b.size() && sectors != 0xffu; ++k)
            for (int j0 = run_b[k]; j0 < run_e[k] && sectors != 0xffu; j0 += kChunk) {
              const int first = cnt;
              project(j0, std::min(run_e[k], j0 + kChunk));
              sectors |= simd::SectorBits(avx2, pa.data(), pb.data(), first, cnt);
            }
          last = sectors != 0xffu && GapAtEmptySectors(pa.data(), pb.data(), cnt, sectors, cos_t, keys);
        } else {
          for (size_t k = 0; k < run_b.size(); ++k) project(run_b[k], run_e[k]);
          dirs.clear();
          for (int j = 0; j < cnt; ++j) dirs.push_back({PseudoAngle(pa[j], pb[j]), pa[j], pb[j]});
          last = HasGap(dirs, cos_t);
        }
        count += last ? w : 0;
      }
    }
    boundary += count;
  });
  return q.empty() ? 0.f : float(boundary.load()) / float(q.size());
}

// Feature 3: occupied voxels (anchored at the part's minimum corner) times voxel^3.
double VoxelVolume(const Points& q, double voxel) {
  if (q.empty()) return 0;
  Eigen::Vector3f lo = q[0];
  for (const auto& p : q) lo = lo.cwiseMin(p);
  std::vector<uint64_t> keys(q.size());
  const double inv = 1.0 / voxel;
  for (size_t i = 0; i < q.size(); ++i) {
    uint64_t k = 0;
    for (int a = 0; a < 3; ++a) k = (k << 21) | std::min<uint64_t>((1u << 21) - 1, uint64_t(double(q[i][a] - lo[a]) * inv));
    keys[i] = k;
  }
  // Distinct keys counted in an open-addressing table of at least twice as many slots (keys
  // are below 2^63, so all ones marks an empty slot): linear where a sort was n log n.
  int bits = 4;
  while ((size_t(1) << bits) < 2 * keys.size()) ++bits;
  const size_t slots = size_t(1) << bits;
  std::vector<uint64_t> table(slots, ~uint64_t(0));
  size_t occupied = 0;
  for (const uint64_t k : keys) {
    size_t h = HashSlot(k, slots - 1);
    while (table[h] != ~uint64_t(0) && table[h] != k) h = (h + 1) & (slots - 1);
    if (table[h] == ~uint64_t(0)) table[h] = k, ++occupied;
  }
  return double(occupied) * voxel * voxel * voxel;
}

void PartRow(const Scan& scan, const Segmentation& seg, const Part& part, const PartFeatureOptions& o,
             float* out) {
  std::fill(out, out + kPaper24Columns, 0.f);
  const size_t n = part.indices.size();
  if (n == 0) return;
  const bool have_normals = seg.normals.size() == scan.points.size();
  const bool have_curv = seg.curvature.size() == scan.points.size();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int i : part.indices) {
    if (i < 0 || size_t(i) >= scan.points.size())
      throw StageError("part indexes point " + std::to_string(i) + " of a scan of " +
                       std::to_string(scan.points.size()));
    c += scan.points[i].cast<double>();
  }
  c /= double(n);
  // Local frame centred on the part: features of a scan in map coordinates stay exact.
  Points q(n), normals(n);
  double curv_sum = 0;
  size_t curv_n = 0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t k = 0; k < n; ++k) {
    const int i = part.indices[k];
    const Eigen::Vector3d d = scan.points[i].cast<double>() - c;
    q[k] = d.cast<float>();
    cov += d * d.transpose();
    normals[k] = have_normals ? seg.normals[i] : Eigen::Vector3f::Constant(NAN);
    if (have_curv && std::isfinite(seg.curvature[i])) {
      curv_sum += seg.curvature[i];
      ++curv_n;
    }
  }
  cov /= double(n);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const Eigen::Vector3d e = es.eigenvalues().cwiseMax(0.0);  // ascending: e1 <= e2 <= e3
  Eigen::Matrix3d a = es.eigenvectors();
  const double sum = e.sum();

  double var[3] = {0, 0, 0}, lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  for (const auto& p : q) {
    const Eigen::Vector3d pd = p.cast<double>();
    for (int j = 0; j < 3; ++j) {
      const double t = pd.dot(a.col(j));
      var[j] += t * t;
      lo[j] = std::min(lo[j], t);
      hi[j] = std::max(hi[j], t);
    }
  }
  double far[3], near[3], extent[3];
  for (int j = 0; j < 3; ++j) {
    var[j] /= double(n);
    far[j] = std::max(hi[j], -lo[j]);
    near[j] = std::min(hi[j], -lo[j]);
    extent[j] = hi[j] - lo[j];
  }
  const double voxel_volume = VoxelVolume(q, o.voxel_m);
  double obb = 1;
  for (int j = 0; j < 3; ++j) obb *= std::max(extent[j], o.voxel_m);
  const Eigen::Vector3f fallback = a.col(0).cast<float>();

  out[0] = BoundaryRatio(q, normals, fallback, o);                             // 1
  out[1] = curv_n > 0 ? float(curv_sum / double(curv_n)) : SafeDiv(e[0], sum);  // 2
  out[2] = float(voxel_volume);                                                 // 3
  out[3] = SafeDiv(e[0], e[1]);                                                 // 4
  out[4] = SafeDiv(e[1], e[2]);
  out[5] = SafeDiv(e[0], e[2]);
  out[6] = SafeDiv(e[0], sum);
  out[7] = SafeDiv(e[1], sum);
  out[8] = SafeDiv(e[2], sum);
  for (int j = 0; j < 3; ++j) out[9 + j] = float(var[j]);  // 5
  const auto tilt = [](const Eigen::Vector3d& v) {
    return float(std::acos(std::min(1.0, std::fabs(v.z()) / std::max(1e-300, v.norm()))) * 180.0 / M_PI);
  };
  out[12] = tilt(a.col(0));  // 6
  out[13] = tilt(a.col(2));
  for (int j = 0; j < 3; ++j) {  // 7
    out[14 + 2 * j] = float(far[j]);
    out[15 + 2 * j] = float(near[j]);
  }
  for (int j = 0; j < 3; ++j) out[20 + j] = SafeDiv(var[j], extent[j]);  // 8
  out[23] = SafeDiv(voxel_volume, obb);                                   // 9
}

FeatureMatrix Compute(const Scan& scan, const Segmentation& seg, const PartFeatureOptions& o,
                      const std::vector<int>* columns) {
  o.Check();
  const int parts = int(seg.parts.size());
  Eigen::Matrix<float, Eigen::Dynamic, kPaper24Columns, Eigen::RowMajor> all(parts, kPaper24Columns);
  // Grain 1: part sizes differ by orders of magnitude (a floor vs a leg); big parts also
  // parallelise their boundary test inside.
  tbb::parallel_for(tbb::blocked_range<int>(0, parts, 1), [&](const tbb::blocked_range<int>& r) {
    for (int p = r.begin(); p != r.end(); ++p) PartRow(scan, seg, seg.parts[p], o, all.row(p).data());
  });
  FeatureMatrix f;
  if (!columns) {
    f.values = all;
    f.names = Paper24Names();
    return f;
  }
  f.values.resize(parts, Eigen::Index(columns->size()));
  for (size_t j = 0; j < columns->size(); ++j) {
    f.values.col(Eigen::Index(j)) = all.col((*columns)[j]);
    f.names.push_back(Paper24Names()[(*columns)[j]]);
  }
  return f;
}

}  // namespace

void PartFeatureOptions::Check() const {
  if (!(voxel_m > 0)) throw StageError("voxel_m must be > 0");
  if (!(boundary_radius_m > 0)) throw StageError("boundary_radius_m must be > 0");
  if (!(boundary_angle_deg > 0 && boundary_angle_deg < 180))
    throw StageError("boundary_angle_deg must be in (0, 180)");
  if (boundary_tests_per_cell < 0) throw StageError("boundary_tests_per_cell must be >= 0 (0: every point)");
}

const std::vector<std::string>& Paper24Names() {
  static const std::vector<std::string> names = {
      "boundary_ratio",  "mean_curvature",   "voxel_volume_m3",  "ratio_e1_e2",      "ratio_e2_e3",
      "ratio_e1_e3",     "ratio_e1_sum",     "ratio_e2_sum",     "ratio_e3_sum",     "var_a1_m2",
      "var_a2_m2",       "var_a3_m2",        "tilt_a1_deg",      "tilt_a3_deg",      "extent_a1_far_m",
      "extent_a1_near_m", "extent_a2_far_m", "extent_a2_near_m", "extent_a3_far_m",  "extent_a3_near_m",
      "var_extent_a1_m", "var_extent_a2_m",  "var_extent_a3_m",  "occupancy"};
  return names;
}

const std::vector<int>& ReducedColumns() {
  static const std::vector<int> cols = {0, 1, 2, 9, 10, 11, 12, 13, 23};
  return cols;
}

FeatureMatrix ComputePaper24(const Scan& scan, const Segmentation& seg, const PartFeatureOptions& o) {
  return Compute(scan, seg, o, nullptr);
}

FeatureMatrix ComputeReduced(const Scan& scan, const Segmentation& seg, const PartFeatureOptions& o) {
  return Compute(scan, seg, o, &ReducedColumns());
}

}  // namespace furnihost::parts
