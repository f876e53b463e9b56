#include "model_cloud.hpp"

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"

#include <nanoflann.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <thread>

#include <unistd.h>

namespace furnihost::ransac_upright {

void SamplingOptions::Check() const {
  if (!(density_per_m2 > 0)) throw StageError("model_density_per_m2 must be > 0");
  if (min_points < 1 || max_points < min_points)
    throw StageError("model point limits: need 1 <= min_model_points <= max_model_points");
  if (!(inlier_distance > 0)) throw StageError("inlier_distance_m must be > 0");
}

namespace {

// nanoflann reads the points where they are (no copy).
struct PointsAdaptor {
  const Points* pts;
  size_t kdtree_get_point_count() const { return pts->size(); }
  float kdtree_get_pt(size_t i, size_t d) const { return (*pts)[i][static_cast<int>(d)]; }
  template <class B>
  bool kdtree_get_bbox(B&) const { return false; }
};

// Result set that stops the search at the first point within the radius: a yes/no query.
struct AnyWithinSet {
  float radius_sq;
  bool found = false;
  explicit AnyWithinSet(float r2) : radius_sq(r2) {}
  bool full() const { return true; }
  float worstDist() const { return radius_sq; }
  bool addPoint(float, uint32_t) {
    found = true;
    return false;
  }
};

using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointsAdaptor>,
                                                 PointsAdaptor, 3, uint32_t>;

// Indices of the points seen from outside: orthographic point z-buffers from 12 azimuths at
// elevations -20°, 0°, 30°, 60° and from straight above (furniture is never seen from below
// the floor). A point is seen when it lies within one pixel of the front-most depth of its
// pixel in some view; pixels are 2.5 point spacings wide so the front surface has no holes.
std::vector<int> OuterPoints(const Points& pts, float spacing) {
  std::vector<char> seen(pts.size(), 0);
  std::vector<Eigen::Vector3f> dirs;  // towards the viewer
  for (float el : {-20.f, 0.f, 30.f, 60.f})
    for (int a = 0; a < 12; ++a) {
      const float az = a * 30.f * 3.14159265f / 180.f, e = el * 3.14159265f / 180.f;
      dirs.emplace_back(std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e));
    }
  dirs.emplace_back(0.f, 0.f, 1.f);
  const float pix = 2.5f * spacing;
  std::vector<float> top;
  std::vector<int> cell(pts.size());
  for (const Eigen::Vector3f& d : dirs) {
    const Eigen::Vector3f u = d.unitOrthogonal(), v = d.cross(u);
    float u0 = std::numeric_limits<float>::infinity(), v0 = u0, u1 = -u0, v1 = -u0;
    for (const auto& p : pts) {
      u0 = std::min(u0, p.dot(u));
      u1 = std::max(u1, p.dot(u));
      v0 = std::min(v0, p.dot(v));
      v1 = std::max(v1, p.dot(v));
    }
    const int w = static_cast<int>((u1 - u0) / pix) + 1, h = static_cast<int>((v1 - v0) / pix) + 1;
    top.assign(size_t(w) * h, -std::numeric_limits<float>::infinity());
    for (size_t i = 0; i < pts.size(); ++i) {
      const int x = std::min(w - 1, static_cast<int>((pts[i].dot(u) - u0) / pix));
      const int y = std::min(h - 1, static_cast<int>((pts[i].dot(v) - v0) / pix));
      cell[i] = y * w + x;
      top[cell[i]] = std::max(top[cell[i]], pts[i].dot(d));
    }
    for (size_t i = 0; i < pts.size(); ++i)
      if (pts[i].dot(d) >= top[cell[i]] - pix) seen[i] = 1;
  }
  std::vector<int> out;
  for (size_t i = 0; i < pts.size(); ++i)
    if (seen[i]) out.push_back(static_cast<int>(i));
  return out;
}

}  // namespace

struct PointIndex::Impl {
  PointsAdaptor adaptor;
  Tree tree;
  // nanoflann 1.4's constructor builds the tree (a second buildIndex() built it again).
  explicit Impl(const Points* p) : adaptor{p}, tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {}
};

PointIndex::PointIndex(const Points* points) : impl_(std::make_unique<Impl>(points)) {}
PointIndex::~PointIndex() = default;

bool PointIndex::AnyWithin(const Eigen::Vector3f& q, float radius) const {
  if (impl_->adaptor.pts->empty()) return false;
  AnyWithinSet rs(radius * radius);
  impl_->tree.findNeighbors(rs, q.data(), nanoflann::SearchParams());
  return rs.found;
}

int PointIndex::Nearest(const Eigen::Vector3f& q, float* dist) const {
  if (impl_->adaptor.pts->empty()) {
    if (dist) *dist = std::numeric_limits<float>::infinity();
    return -1;
  }
  uint32_t idx = 0;
  float d2 = std::numeric_limits<float>::infinity();
  nanoflann::KNNResultSet<float, uint32_t> rs(1);
  rs.init(&idx, &d2);
  impl_->tree.findNeighbors(rs, q.data(), nanoflann::SearchParams());
  if (dist) *dist = std::sqrt(d2);
  return static_cast<int>(idx);
}

RadiusGrid::RadiusGrid(const Points* points, float radius) : radius_(radius), r2_(radius * radius) {
  const Points& pts = *points;
  if (pts.empty()) return;
  Eigen::AlignedBox3f box;
  for (const auto& p : pts) box.extend(p);
  // 1 % wider than the radius: rounding in the cell coordinates never puts a point within the
  // radius two cells away.
  const float cell = 1.01f * radius;
  inv_cell_ = 1.f / cell;
  lo_ = box.min();
  double cells = 1.0;
  for (int a = 0; a < 3; ++a) {
    dims_[a] = int(std::min(double(1 << 24), std::floor(double(box.max()[a] - lo_[a]) * inv_cell_) + 1.0));
    cells *= dims_[a];
  }
  if (!(radius > 0.f) || !box.sizes().allFinite() || cells > double(1 << 24)) {
    fallback_ = std::make_unique<PointIndex>(points);
    return;
  }
  auto cell_of = [&](const Eigen::Vector3f& p) {
    int i[3];
    for (int a = 0; a < 3; ++a) i[a] = std::clamp(int((p[a] - lo_[a]) * inv_cell_), 0, dims_[a] - 1);
    return (size_t(i[2]) * dims_[1] + i[1]) * dims_[0] + i[0];
  };
  start_.assign(size_t(cells) + 1, 0);
  std::vector<uint32_t> key(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) ++start_[(key[i] = uint32_t(cell_of(pts[i]))) + 1];
  for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
  x_.resize(pts.size()), y_.resize(pts.size()), z_.resize(pts.size());
  std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
  for (size_t i = 0; i < pts.size(); ++i) {
    const uint32_t s = fill[key[i]]++;
    x_[s] = pts[i].x(), y_[s] = pts[i].y(), z_[s] = pts[i].z();
  }
}

RadiusGrid::~RadiusGrid() = default;

bool RadiusGrid::AnyWithin(const Eigen::Vector3f& q) const {
  if (fallback_) return fallback_->AnyWithin(q, radius_);
  if (x_.empty()) return false;
  // The same distance as nanoflann's L2_Simple_Adaptor (x, y, z summed in that order) and the
  // same strict comparison, so the answers are PointIndex's bit for bit.
  auto scan = [&](uint32_t b, uint32_t e) {
    for (uint32_t s = b; s < e; ++s) {
      const float dx = q.x() - x_[s], dy = q.y() - y_[s], dz = q.z() - z_[s];
      if (dx * dx + dy * dy + dz * dz < r2_) return true;
    }
    return false;
  };
  int own[3], lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    const float f = (q[a] - lo_[a]) * inv_cell_;
    // A query a whole cell (> the radius) outside the box has no point within the radius.
    if (!(f > -1.f && f < float(dims_[a]) + 1.f)) return false;
    own[a] = int(std::floor(f));
    lo[a] = std::max(own[a] - 1, 0);
    hi[a] = std::min(own[a] + 1, dims_[a] - 1);
  }
  const bool inside = own[0] >= 0 && own[0] < dims_[0] && own[1] >= 0 && own[1] < dims_[1] && own[2] >= 0 &&
                      own[2] < dims_[2];
  auto at = [&](int x, int y, int z) { return (size_t(z) * dims_[1] + y) * dims_[0] + x; };
  if (inside) {  // on a surface the hit is almost always in the query's own cell
    const size_t c = at(own[0], own[1], own[2]);
    if (scan(start_[c], start_[c + 1])) return true;
  }
  for (int z = lo[2]; z <= hi[2]; ++z)
    for (int y = lo[1]; y <= hi[1]; ++y) {
      const size_t row = at(0, y, z);
      if (inside && z == own[2] && y == own[1]) {  // the query's row, without its own cell
        if (scan(start_[row + lo[0]], start_[row + own[0]]) || scan(start_[row + own[0] + 1], start_[row + hi[0] + 1]))
          return true;
      } else if (scan(start_[row + lo[0]], start_[row + hi[0] + 1])) {
        return true;
      }
    }
  return false;
}

ModelCloud::ModelCloud(const CatalogModel& model, const SamplingOptions& o, uint64_t seed)
    : id_(model.id), inlier_(o.inlier_distance), min_h_(o.min_horizontal_normal) {
  const Mesh& mesh = model.mesh;
  const int nv = static_cast<int>(mesh.vertices.size());
  // Total area of the valid faces (the same faces SampleSurface samples).
  area_ = 0.0;
  for (const Eigen::Vector3i& f : mesh.triangles)
    if (f.minCoeff() >= 0 && f.maxCoeff() < nv) {
      const double a = 0.5 * static_cast<double>(
                                 (mesh.vertices[f[1]] - mesh.vertices[f[0]]).cross(mesh.vertices[f[2]] - mesh.vertices[f[0]]).norm());
      if (std::isfinite(a)) area_ += a;
    }
  if (!(area_ > 0.0)) throw StageError("catalog model " + model.id + " has no faces with area");
  // Dense pass over all faces (up to 4x the final budget), then only the outer surface is kept
  // (paper: "filling the outer triangle faces with points"), then a uniform subset within the
  // budget. Faces inside closed furniture (drawer interiors, doubled walls) never face a sensor.
  const double wanted = area_ * o.density_per_m2;
  const double n = std::clamp(wanted, double(o.min_points), 4.0 * o.max_points);
  const double dense_spacing = std::sqrt(area_ / n);
  Points nrm;
  const Points pts = SampleSurface(mesh, static_cast<float>(n / area_), seed, &nrm);
  if (pts.empty()) throw StageError("catalog model " + model.id + ": surface sampling gave no points");
  std::mt19937_64 rng(SplitMix64(seed));  // a second stream for the budget subset, apart from SampleSurface's
  std::vector<int> keep = OuterPoints(pts, static_cast<float>(dense_spacing));
  if (keep.empty()) {  // degenerate (e.g. a single flat face seen edge-on): keep everything
    keep.resize(pts.size());
    std::iota(keep.begin(), keep.end(), 0);
  }
  outer_area_ = area_ * double(keep.size()) / double(pts.size());
  const size_t budget = static_cast<size_t>(
      std::clamp(outer_area_ * o.density_per_m2, double(o.min_points), double(o.max_points)));
  if (keep.size() > budget) {
    for (size_t a = 0; a < budget; ++a) {
      std::uniform_int_distribution<size_t> d(a, keep.size() - 1);
      std::swap(keep[a], keep[d(rng)]);
    }
    keep.resize(budget);
    std::sort(keep.begin(), keep.end());
  }
  points_.reserve(keep.size());
  normals_.reserve(keep.size());
  for (int i : keep) {
    points_.push_back(pts[i]);
    normals_.push_back(nrm[i]);
  }
  density_ = double(points_.size()) / outer_area_;
  spacing_ = static_cast<float>(1.0 / std::sqrt(density_));
  // Bounds of the referenced vertices (Mesh::Bounds is not exported by the core library).
  bounds_.setEmpty();
  for (const Eigen::Vector3i& f : mesh.triangles)
    if (f.minCoeff() >= 0 && f.maxCoeff() < nv)
      for (int c = 0; c < 3; ++c) bounds_.extend(mesh.vertices[f[c]]);

  BuildIndices();
  BuildCoverageGrid();
}

void ModelCloud::BuildIndices() {
  // Height index.
  std::vector<int> order(points_.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return points_[a].z() < points_[b].z(); });
  for (int i : order) {
    const Eigen::Vector3f& nn = normals_[i];
    const bool info = std::hypot(nn.x(), nn.y()) > min_h_;
    (info ? z_info_ : z_flat_).push_back(points_[i].z());
    (info ? idx_info_ : idx_flat_).push_back(i);
  }

  kd_ = std::make_unique<PointIndex>(&points_);
  near_ = std::make_unique<RadiusGrid>(&points_, inlier_);
}

ModelCloud::~ModelCloud() = default;

namespace {

constexpr char kCacheMagic[8] = {'F', 'H', 'M', 'C', 'L', 'D', '0', '1'};

template <class T>
void Put(std::ostream& out, const T& v) {
  out.write(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <class T>
void PutVec(std::ostream& out, const std::vector<T>& v) {
  Put(out, static_cast<uint64_t>(v.size()));
  out.write(reinterpret_cast<const char*>(v.data()), static_cast<std::streamsize>(v.size() * sizeof(T)));
}
template <class T>
bool Get(std::istream& in, T* v) {
  return static_cast<bool>(in.read(reinterpret_cast<char*>(v), sizeof(T)));
}
// Refuses counts beyond what is left of the file (a corrupt count must not allocate gigabytes).
template <class T>
bool GetVec(std::istream& in, uint64_t left, std::vector<T>* v) {
  uint64_t n = 0;
  if (!Get(in, &n) || n > left / sizeof(T)) return false;
  v->resize(n);
  return static_cast<bool>(in.read(reinterpret_cast<char*>(v->data()), static_cast<std::streamsize>(n * sizeof(T))));
}

}  // namespace

uint64_t ModelCloud::CacheKey(const CatalogModel& model, const SamplingOptions& o, uint64_t seed) {
  uint64_t h = Fnv1a(kCacheMagic, sizeof(kCacheMagic), kFnvOffsetTruncated);
  h = Fnv1a(model.id, h);
  const double opts[5] = {o.density_per_m2, double(o.min_points), double(o.max_points), double(o.inlier_distance),
                          double(o.min_horizontal_normal)};
  h = Fnv1a(opts, sizeof(opts), h);
  h = Fnv1a(&seed, sizeof(seed), h);
  // Eigen's 3-vectors are packed (12 bytes each), so the arrays hash as one run of bytes.
  static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float) && sizeof(Eigen::Vector3i) == 3 * sizeof(int));
  h = Fnv1a(model.mesh.vertices.data(), model.mesh.vertices.size() * sizeof(Eigen::Vector3f), h);
  h = Fnv1a(model.mesh.triangles.data(), model.mesh.triangles.size() * sizeof(Eigen::Vector3i), h);
  return h;
}

void WriteCacheFile(const std::string& path, const std::function<void(std::ostream&)>& write) {
  namespace fs = std::filesystem;
  static std::atomic<uint64_t> calls{0};
  std::ostringstream tag;
  tag << ".tmp." << ::getpid() << "." << std::hash<std::thread::id>()(std::this_thread::get_id()) << "." << calls++;
  const fs::path tmp = path + tag.str();
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw StageError("cannot write " + tmp.string());
    write(out);
    out.close();
    if (!out) {
      std::error_code ec;
      fs::remove(tmp, ec);
      throw StageError("cannot write " + tmp.string());
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw StageError("cannot rename " + tmp.string() + " to " + path);
  }
}

void ModelCloud::Save(const std::string& path, uint64_t key) const {
  WriteCacheFile(path, [&](std::ostream& out) {
    out.write(kCacheMagic, sizeof(kCacheMagic));
    Put(out, key);
    PutVec(out, points_);
    PutVec(out, normals_);
    Put(out, bounds_.min());
    Put(out, bounds_.max());
    Put(out, area_);
    Put(out, outer_area_);
    Put(out, density_);
    Put(out, spacing_);
    Put(out, inlier_);
    Put(out, min_h_);
    Put(out, grid_min_);
    Put(out, inv_cell_);
    for (int d = 0; d < 3; ++d) Put(out, dims_[d]);
    for (int d = 0; d < 3; ++d) Put(out, bdims_[d]);
    PutVec(out, blocks_);
    PutVec(out, cells_);
    out.write(kCacheMagic, sizeof(kCacheMagic));
  });
}

std::unique_ptr<ModelCloud> ModelCloud::Load(const std::string& path, uint64_t key, const std::string& id) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec) return nullptr;
  std::ifstream in(path, std::ios::binary);
  if (!in) return nullptr;
  char magic[sizeof(kCacheMagic)];
  uint64_t got = 0;
  if (!in.read(magic, sizeof(magic)) || std::memcmp(magic, kCacheMagic, sizeof(magic)) != 0 || !Get(in, &got) ||
      got != key)
    return nullptr;
  std::unique_ptr<ModelCloud> m(new ModelCloud());
  m->id_ = id;
  Eigen::Vector3f lo, hi;
  bool ok = GetVec(in, size, &m->points_) && GetVec(in, size, &m->normals_) && Get(in, &lo) && Get(in, &hi) &&
            Get(in, &m->area_) && Get(in, &m->outer_area_) && Get(in, &m->density_) && Get(in, &m->spacing_) &&
            Get(in, &m->inlier_) && Get(in, &m->min_h_) && Get(in, &m->grid_min_) && Get(in, &m->inv_cell_);
  for (int d = 0; ok && d < 3; ++d) ok = Get(in, &m->dims_[d]);
  for (int d = 0; ok && d < 3; ++d) ok = Get(in, &m->bdims_[d]);
  ok = ok && GetVec(in, size, &m->blocks_) && GetVec(in, size, &m->cells_);
  ok = ok && in.read(magic, sizeof(magic)) && std::memcmp(magic, kCacheMagic, sizeof(magic)) == 0;
  // Consistency, so that Covered() can never index out of its arrays.
  ok = ok && !m->points_.empty() && m->normals_.size() == m->points_.size() && m->cells_.size() % 128 == 0;
  ok = ok && std::isfinite(m->inv_cell_) && m->inv_cell_ > 0.f && m->grid_min_.allFinite() && m->inlier_ > 0.f &&
       std::isfinite(m->inlier_) && lo.allFinite() && hi.allFinite();
  for (size_t i = 0; ok && i < m->points_.size(); ++i) ok = m->points_[i].allFinite() && m->normals_[i].allFinite();
  for (int d = 0; ok && d < 3; ++d) ok = m->dims_[d] > 0 && m->bdims_[d] == (m->dims_[d] + 7) / 8;
  ok = ok && m->blocks_.size() == size_t(m->bdims_[0]) * m->bdims_[1] * m->bdims_[2];
  const int32_t nblocks = static_cast<int32_t>(m->cells_.size() / 128);
  for (size_t i = 0; ok && i < m->blocks_.size(); ++i) ok = m->blocks_[i] < nblocks;
  if (!ok) return nullptr;
  m->bounds_ = Eigen::AlignedBox3f(lo, hi);
  m->BuildIndices();
  return m;
}

void ModelCloud::HeightBand(float z, float tol, bool informative, std::vector<int>* out) const {
  const std::vector<float>& zs = informative ? z_info_ : z_flat_;
  const std::vector<int>& idx = informative ? idx_info_ : idx_flat_;
  auto lo = std::lower_bound(zs.begin(), zs.end(), z - tol);
  auto hi = std::upper_bound(lo, zs.end(), z + tol);
  out->insert(out->end(), idx.begin() + (lo - zs.begin()), idx.begin() + (hi - zs.begin()));
}

double ModelCloud::AmbiguousCellShare() const {
  size_t amb = 0, any = 0;
  for (uint8_t byte : cells_)
    for (int k = 0; k < 4; ++k) {
      const unsigned c = (byte >> (2 * k)) & 3u;
      amb += c == kAmbiguous;
      any += c != kOutside;
    }
  return any ? double(amb) / double(any) : 0.0;
}

void ModelCloud::BuildCoverageGrid() {
  // Thin cells keep the ambiguous shell (inlier ± half a cell diagonal) thin, so that few
  // queries reach the kd-tree; huge models get coarser cells (at most ~2^31 cells).
  float cell = inlier_ * 0.25f;
  const Eigen::Vector3f lo = bounds_.min() - Eigen::Vector3f::Constant(inlier_ + cell);
  const Eigen::Vector3f ext = bounds_.max() - bounds_.min() + Eigen::Vector3f::Constant(2 * (inlier_ + cell));
  while (double(ext.x() / cell + 1) * (ext.y() / cell + 1) * (ext.z() / cell + 1) > 2e9) cell *= 1.25f;
  grid_min_ = lo;
  inv_cell_ = 1.f / cell;
  for (int d = 0; d < 3; ++d) {
    dims_[d] = static_cast<int>(std::ceil(ext[d] / cell)) + 1;
    bdims_[d] = (dims_[d] + 7) / 8;
  }
  blocks_.assign(size_t(bdims_[0]) * bdims_[1] * bdims_[2], -1);
  cells_.clear();
  // Block of cell (x, y, z), allocated on first use (all cells kOutside).
  auto block = [&](int x, int y, int z) -> uint8_t* {
    int32_t& b = blocks_[(size_t(z >> 3) * bdims_[1] + (y >> 3)) * bdims_[0] + (x >> 3)];
    if (b < 0) {
      b = static_cast<int32_t>(cells_.size() / 128);
      cells_.resize(cells_.size() + 128, 0);
    }
    return &cells_[size_t(b) * 128];
  };
  const float half_diag = 0.5f * std::sqrt(3.f) * cell;
  // 10 µm of slack keeps float rounding from marking a cell covered that is not.
  const float d_in = inlier_ - half_diag - 1e-5f, d_out = inlier_ + half_diag + 1e-5f;
  const float d_in2 = d_in > 0 ? d_in * d_in : -1.f, d_out2 = d_out * d_out;
  // Per point: the cell box its d_out ball can reach, and x in cell-centre units.
  struct Reach {
    int a[3], b[3];
    float px;
  };
  const size_t n = points_.size();
  std::vector<Reach> reach(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = points_[i];
    const Eigen::Vector3f rel = (p - grid_min_) * inv_cell_;
    for (int d = 0; d < 3; ++d) {
      reach[i].a[d] = std::max(0, static_cast<int>(std::floor(rel[d] - d_out * inv_cell_ - 0.5f)));
      reach[i].b[d] = std::min(dims_[d] - 1, static_cast<int>(std::ceil(rel[d] + d_out * inv_cell_ - 0.5f)));
    }
    reach[i].px = (p.x() - grid_min_.x()) * inv_cell_ - 0.5f;
  }
  std::vector<int> by_start(n);
  std::iota(by_start.begin(), by_start.end(), 0);
  std::sort(by_start.begin(), by_start.end(), [&](int i, int j) { return reach[i].a[2] < reach[j].a[2]; });

  // One z-plane of cells at a time. Each point within reach adds, per row (y) of the plane,
  // the x-interval of cells within d_out of it (and the sub-interval within d_in) to the row's
  // difference arrays; then every cell of the plane is written once with the union's state
  // (covered if in any covered interval, else ambiguous if in any interval). The intervals are
  // those of a per-point loop over its ball (same arithmetic), only the writes are merged:
  // at 1 cm sampling ~75 points reach each cell.
  const int W = dims_[0], H = dims_[1];
  std::vector<int32_t> any_diff(size_t(W + 1) * H, 0), cov_diff(size_t(W + 1) * H, 0);
  std::vector<int> row_lo(H, std::numeric_limits<int>::max()), row_hi(H, -1), rows;
  std::vector<int> active;
  size_t next = 0;
  for (int z = 0; z < dims_[2]; ++z) {
    while (next < n && reach[by_start[next]].a[2] <= z) active.push_back(by_start[next++]);
    active.erase(std::remove_if(active.begin(), active.end(), [&](int i) { return reach[i].b[2] < z; }),
                 active.end());
    if (active.empty()) continue;
    const float cz = grid_min_.z() + (z + 0.5f) * cell;
    for (int i : active) {
      const Reach& r = reach[i];
      const Eigen::Vector3f& p = points_[i];
      const float dz = cz - p.z();
      for (int y = r.a[1]; y <= r.b[1]; ++y) {
        const float dy = grid_min_.y() + (y + 0.5f) * cell - p.y();
        const float dyz = dy * dy + dz * dz;
        if (dyz > d_out2) continue;
        const float ro = std::sqrt(d_out2 - dyz) * inv_cell_;
        const int x0 = std::max(r.a[0], static_cast<int>(std::ceil(r.px - ro)));
        const int x1 = std::min(r.b[0], static_cast<int>(std::floor(r.px + ro)));
        if (x0 > x1) continue;
        int32_t* any = &any_diff[size_t(y) * (W + 1)];
        ++any[x0];
        --any[x1 + 1];
        if (dyz <= d_in2) {
          const float ri = std::sqrt(d_in2 - dyz) * inv_cell_;
          const int i0 = std::max(x0, static_cast<int>(std::ceil(r.px - ri)));
          const int i1 = std::min(x1, static_cast<int>(std::floor(r.px + ri)));
          if (i0 <= i1) {
            int32_t* cov = &cov_diff[size_t(y) * (W + 1)];
            ++cov[i0];
            --cov[i1 + 1];
          }
        }
        if (row_hi[y] < 0) rows.push_back(y);
        row_lo[y] = std::min(row_lo[y], x0);
        row_hi[y] = std::max(row_hi[y], x1);
      }
    }
    for (int y : rows) {
      int32_t* any = &any_diff[size_t(y) * (W + 1)];
      int32_t* cov = &cov_diff[size_t(y) * (W + 1)];
      const unsigned yz = ((z & 7) << 6) | ((y & 7) << 3);
      int in_any = 0, in_cov = 0;
      uint8_t* blk = nullptr;
      int blk_x = -1;
      for (int x = row_lo[y]; x <= row_hi[y]; ++x) {
        in_any += any[x];
        in_cov += cov[x];
        any[x] = 0;
        cov[x] = 0;
        if (in_any <= 0) continue;
        if ((x >> 3) != blk_x) {
          blk = block(x, y, z);
          blk_x = x >> 3;
        }
        const unsigned state = in_cov > 0 ? kCovered : kAmbiguous;
        const unsigned idx = yz | (x & 7), sh = (idx & 3) * 2;
        uint8_t& byte = blk[idx >> 2];
        if (((byte >> sh) & 3u) < state) byte = static_cast<uint8_t>((byte & ~(3u << sh)) | (state << sh));
      }
      any[row_hi[y] + 1] = 0;
      cov[row_hi[y] + 1] = 0;
      row_lo[y] = std::numeric_limits<int>::max();
      row_hi[y] = -1;
    }
    rows.clear();
  }
}

}  // namespace furnihost::ransac_upright
