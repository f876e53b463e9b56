#include "furnihost/host/ground_estimation.hpp"

#include "furnihost/geometry.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <deque>
#include <nlohmann/json.hpp>
#include <random>

namespace furnihost {

// ---- level and plane ----------------------------------------------------------------------

namespace {

using Points = std::vector<Eigen::Vector3f>;

// The finite points, at most ~200k (a stride sample is plenty for a histogram or a plane).
Points FloorSample(const Points& pts) {
  Points w;
  const size_t step = std::max<size_t>(1, pts.size() / 200000);
  w.reserve(pts.size() / step + 1);
  for (size_t i = 0; i < pts.size(); i += step)
    if (pts[i].allFinite() && pts[i].cwiseAbs().maxCoeff() < 1e7f) w.push_back(pts[i]);
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

float EstimateLevelZ(const Points& points) {
  const Points w = FloorSample(points);
  if (w.empty()) return 0.f;
  return DensestSlice(w, LowCut(w));
}

FloorPlane EstimatePlane(const Points& points) {
  FloorPlane level;
  const Points w = FloorSample(points);
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

// ---- height map ---------------------------------------------------------------------------

namespace {

constexpr float kSlice = 0.02f;       // height slice of a floor cell [m]
constexpr float kMaxRise = 0.7f;      // floor parts looked for above the lowest points (warps rise 0.4 m)
constexpr int kMaxCells = 1 << 20;    // grid size cap (the cell grows for huge scans)
constexpr float kNormalVoxel = 0.05f; // voxel of the coarse normals that tell horizontal surfaces

// The floor seed: the lowest extensive horizontal level. Over the horizontal points' heights
// (2 cm bins from the lowest points up), the first bin holding 15 % of the densest one, moved
// to the densest bin within 6 cm above it. Not the densest level itself: in a bedroom view the
// bed's top can hold more points than the floor around it.
float LowestLevel(const std::vector<float>& z, float lo) {
  std::vector<int> hist(size_t(kMaxRise / kSlice) + 6, 0);
  for (float v : z) {
    const int b = int((v - lo) / kSlice);
    if (b >= 0 && b < int(hist.size())) ++hist[size_t(b)];
  }
  const int top = *std::max_element(hist.begin(), hist.end());
  size_t b = 0;
  while (b < hist.size() && hist[b] < 0.15 * top) ++b;
  size_t best = b;
  for (size_t k = b; k < std::min(hist.size(), b + 4); ++k)
    if (hist[k] > hist[best]) best = k;
  return lo + (float(best) + 0.5f) * kSlice;
}

// The height map of `w` (finite points); nullopt when too little floor is seen.
std::optional<GroundModel> HeightMap(const Points& w, const GroundOptions& o, const RangeFor& pfor) {
  // Horizontal surfaces (coarse voxel normals within 25 deg of vertical) near the bottom of the
  // scan: the floor candidates. Walls and furniture sides do not count, so a cell's floor is
  // not pulled up by the wall standing in it.
  const VoxelNormals vn = EstimateVoxelNormals(w, kNormalVoxel, pfor);
  std::vector<float> all_z;
  all_z.reserve(w.size());
  for (const auto& p : w) all_z.push_back(p.z());
  const size_t k1 = all_z.size() / 100;
  std::nth_element(all_z.begin(), all_z.begin() + k1, all_z.end());
  const float z1 = all_z[k1];
  std::vector<uint32_t> cand;
  std::vector<float> cand_z;
  for (size_t i = 0; i < w.size(); ++i) {
    const int v = vn.voxel_of[i];
    if (std::abs(vn.normals[size_t(v)].z()) <= 0.9f || w[i].z() > z1 + kMaxRise || w[i].z() < z1 - 0.1f) continue;
    cand.push_back(uint32_t(i));
    cand_z.push_back(w[i].z());
  }
  if (cand.size() < 10) return std::nullopt;
  const float z0 = LowestLevel(cand_z, z1 - 0.1f);

  Eigen::Vector2f lo(INFINITY, INFINITY), hi(-INFINITY, -INFINITY);
  for (const auto& p : w) {
    lo = lo.cwiseMin(p.head<2>());
    hi = hi.cwiseMax(p.head<2>());
  }
  float cell = o.cell_m;
  while (double((hi.x() - lo.x()) / cell + 2) * double((hi.y() - lo.y()) / cell + 2) > kMaxCells) cell *= 2.f;
  // Cells on the lattice of multiples of `cell` (not from the scan's corner): the scan's
  // canonical frame then lays them the same way on it whichever quarter turn it came in.
  lo = (lo / cell).array().floor().matrix() * cell;
  const Eigen::Vector2f ext = hi - lo;
  const int W = int(ext.x() / cell) + 1, H = int(ext.y() / cell) + 1;
  const size_t cells = size_t(W) * size_t(H);
  // Candidates bucketed by cell (counting sort); each cell's floor is the 20th percentile of
  // its candidates' heights (at least 3): low noise and a few points under the floor do not
  // set it, a seat above part of the cell does not either.
  std::vector<uint32_t> start(cells + 1, 0);
  std::vector<uint32_t> cell_of(cand.size());
  for (size_t k = 0; k < cand.size(); ++k) {
    const Eigen::Vector3f& p = w[cand[k]];
    const int ix = std::min(W - 1, int((p.x() - lo.x()) / cell));
    const int iy = std::min(H - 1, int((p.y() - lo.y()) / cell));
    cell_of[k] = uint32_t(size_t(iy) * size_t(W) + size_t(ix));
    ++start[cell_of[k] + 1];
  }
  for (size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
  std::vector<float> z(cand.size());
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t k = 0; k < cand.size(); ++k) z[fill[cell_of[k]]++] = cand_z[k];
  }
  std::vector<float> h(cells, NAN);
  for (size_t c = 0; c < cells; ++c) {
    const size_t b = start[c], e = start[c + 1];
    if (e - b < 3) continue;
    const auto at = z.begin() + long(b) + long(0.2 * double(e - b - 1));
    std::nth_element(z.begin() + long(b), at, z.begin() + long(e));
    h[c] = *at;
  }
  // Flood fill from the cells at the seed level, across steps of at most o.step_m (diagonal
  // steps 1.5 x): follows a warped floor, stops at seats, table tops and beds.
  std::vector<uint8_t> acc(cells, 0);
  std::deque<uint32_t> queue;
  for (size_t c = 0; c < cells; ++c)
    if (std::abs(h[c] - z0) < 0.05f) {
      acc[c] = 1;
      queue.push_back(uint32_t(c));
    }
  const float step = o.step_m * cell / 0.15f;
  while (!queue.empty()) {
    const uint32_t c = queue.front();
    queue.pop_front();
    const int cx = int(c % uint32_t(W)), cy = int(c / uint32_t(W));
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = cx + dx, ny = cy + dy;
        if ((!dx && !dy) || nx < 0 || ny < 0 || nx >= W || ny >= H) continue;
        const size_t n = size_t(ny) * size_t(W) + size_t(nx);
        if (acc[n] || !std::isfinite(h[n])) continue;
        if (!(std::abs(h[n] - h[c]) < step * (dx && dy ? 1.5f : 1.f))) continue;
        acc[n] = 1;
        queue.push_back(uint32_t(n));
      }
  }
  size_t seen = 0;
  for (uint8_t a : acc) seen += a;
  const float area = float(seen) * cell * cell;
  if (area < o.min_area_m2 || seen < 4) return std::nullopt;
  GroundModel g;
  g.kind = GroundKind::HeightMap;
  g.source = "estimated";
  g.origin = lo;
  g.cell = cell;
  g.width = W;
  g.height = H;
  g.observed = acc;
  g.observed_area_m2 = area;
  g.heights.assign(cells, NAN);
  // Least-squares plane of the observed cells (reported, and the fallback of HeightAt).
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  for (size_t c = 0; c < cells; ++c) {
    if (!acc[c]) continue;
    g.heights[c] = h[c];
    const Eigen::Vector3d r(lo.x() + (double(c % W) + 0.5) * cell, lo.y() + (double(c / W) + 0.5) * cell, 1.0);
    ata += r * r.transpose();
    atb += r * double(h[c]);
  }
  const Eigen::Vector3d x = ata.ldlt().solve(atb);
  g.plane = x.allFinite() ? FloorPlane{float(x[0]), float(x[1]), float(x[2])} : FloorPlane{0.f, 0.f, z0};
  // Hidden cells take the mean of their filled neighbours, in rings outwards from the seen
  // floor (breadth first), so each cell is written once.
  std::vector<uint8_t> known = acc;
  queue.clear();
  for (size_t c = 0; c < cells; ++c)
    if (known[c]) queue.push_back(uint32_t(c));
  std::vector<uint32_t> ring;
  while (!queue.empty()) {
    ring.clear();
    for (uint32_t c : queue) {
      const int cx = int(c % uint32_t(W)), cy = int(c / uint32_t(W));
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = cx + dx, ny = cy + dy;
          if (nx < 0 || ny < 0 || nx >= W || ny >= H) continue;
          const size_t n = size_t(ny) * size_t(W) + size_t(nx);
          if (known[n]) continue;
          known[n] = 2;  // queued for this ring
          ring.push_back(uint32_t(n));
        }
    }
    for (uint32_t n : ring) {
      const int cx = int(n % uint32_t(W)), cy = int(n / uint32_t(W));
      double s = 0;
      int k = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = cx + dx, ny = cy + dy;
          if (nx < 0 || ny < 0 || nx >= W || ny >= H) continue;
          const size_t m = size_t(ny) * size_t(W) + size_t(nx);
          if (known[m] == 1) {
            s += g.heights[m];
            ++k;
          }
        }
      g.heights[n] = k ? float(s / k) : g.plane.HeightAt(lo.x() + (cx + 0.5f) * cell, lo.y() + (cy + 0.5f) * cell);
    }
    for (uint32_t n : ring) known[n] = 1;
    queue.assign(ring.begin(), ring.end());
  }
  // The rings extrapolate from the nearest seen cell; relaxing the hidden cells towards the
  // mean of their four neighbours (the seen ones held fixed) makes the fill follow a slope or a
  // bend across a hidden patch (a sofa's footprint) instead of stepping in its middle. Sweeps
  // are bounded: the result is a smooth surface near the seen floor either way.
  std::vector<uint32_t> hidden;
  for (size_t c = 0; c < cells; ++c)
    if (!acc[c]) hidden.push_back(uint32_t(c));
  // Jacobi sweeps (each reads the previous sweep's heights; sums in double, exact for four
  // floats): the same result whatever order the cells are stored in, so a scan turned by a
  // quarter gets the same ground.
  std::vector<float> next(hidden.size());
  for (int sweep = 0; sweep < 400 && !hidden.empty(); ++sweep) {
    float change = 0.f;
    for (size_t i = 0; i < hidden.size(); ++i) {
      const uint32_t c = hidden[i];
      const int cx = int(c % uint32_t(W)), cy = int(c / uint32_t(W));
      double sum = 0.0;
      int k = 0;
      if (cx > 0) sum += g.heights[c - 1], ++k;
      if (cx + 1 < W) sum += g.heights[c + 1], ++k;
      if (cy > 0) sum += g.heights[c - size_t(W)], ++k;
      if (cy + 1 < H) sum += g.heights[c + size_t(W)], ++k;
      next[i] = k ? float(sum / k) : g.heights[c];
      change = std::max(change, std::abs(next[i] - g.heights[c]));
    }
    for (size_t i = 0; i < hidden.size(); ++i) g.heights[hidden[i]] = next[i];
    if (change < 1e-4f) break;
  }
  return g;
}

}  // namespace

GroundModel EstimateGround(const Points& points, const GroundOptions& o) {
  return EstimateGround(points, o, SerialRange);
}

GroundModel EstimateGround(const Points& points, const GroundOptions& o, const RangeFor& pfor) {
  if (o.kind == "fixed") return GroundModel::Level(o.z_m, "fixed");
  Points w;
  w.reserve(points.size());
  for (const auto& p : points)
    if (p.allFinite() && p.cwiseAbs().maxCoeff() < 1e7f) w.push_back(p);
  if (w.empty()) return GroundModel::Level(0.f, "estimated");
  if (o.kind == "level") return GroundModel::Level(EstimateLevelZ(w), "estimated");
  if (o.kind == "plane") return GroundModel::Tilted(EstimatePlane(w), "estimated");
  // Dense scans map an even stride sample of at most kMapPoints points: a 15 cm cell of a
  // 1M-point laser room still holds hundreds of floor points, and the map's coarse normals,
  // percentile heights and extent do not need the rest. Scans up to kMapPoints (ScanNet's and
  // SUN RGB-D's 50k, the synthetic benchmarks' 50-125k) use every point.
  constexpr size_t kMapPoints = 300000;
  if (w.size() > kMapPoints) {
    const size_t stride = (w.size() + kMapPoints - 1) / kMapPoints;
    size_t k = 0;
    for (size_t i = 0; i < w.size(); i += stride) w[k++] = w[i];
    w.resize(k);
  }
  if (auto hm = HeightMap(w, o, pfor)) return *hm;
  // Too little floor for a map (a close-up view): a plane, which falls back to level itself.
  return GroundModel::Tilted(EstimatePlane(w), "estimated");
}

}  // namespace furnihost
