// Dense, noiseless point clouds of catalog models (paper Sect. VI-C: "we transform them to
// noiseless point clouds by filling the outer triangle faces with points") and the look-ups
// the upright RANSAC needs on them.
//
// Frame: the catalog model frame (metres, z up, bounding-box bottom centre at the origin).
#pragma once
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::ransac_upright {

struct SamplingOptions {
  double density_per_m2 = 10000.0;  // points per m² of outer face area before clamping
  int min_points = 5000;            // small models are sampled denser to reach this
  int max_points = 40000;           // large models are sampled sparser to stay below this
  float inlier_distance = 0.02f;    // [m] "covered" = nearest model point within this
  float min_horizontal_normal = 0.5f;  // |n_xy| above this: the normal fixes the yaw
  void Check() const;
};

// A kd-tree (nanoflann) over a point set that the caller keeps alive and unchanged.
class PointIndex {
 public:
  explicit PointIndex(const Points* points);
  ~PointIndex();
  PointIndex(const PointIndex&) = delete;
  PointIndex& operator=(const PointIndex&) = delete;
  bool AnyWithin(const Eigen::Vector3f& q, float radius) const;
  int Nearest(const Eigen::Vector3f& q, float* dist) const;  // -1 and +inf when empty

 private:
  struct Impl;  // nanoflann stays in the .cpp so that this header is light
  std::unique_ptr<Impl> impl_;
};

// "Is any point within `radius` of q" over a fixed point set, for one radius: a dense grid of
// cells a little larger than the radius, so the points within it lie in the 3 x 3 x 3 cells
// around q (9 runs of 3 consecutive cells, the query's own cell first, scanned until the first
// hit). The same answers as PointIndex::AnyWithin with that radius (the same float distance,
// strictly below radius^2); built in O(points + cells). A set whose box would need more than
// 2^24 cells is answered by a PointIndex instead.
class RadiusGrid {
 public:
  RadiusGrid(const Points* points, float radius);  // the caller keeps `points` alive
  ~RadiusGrid();
  RadiusGrid(const RadiusGrid&) = delete;
  RadiusGrid& operator=(const RadiusGrid&) = delete;
  bool AnyWithin(const Eigen::Vector3f& q) const;

 private:
  float radius_ = 0.f, r2_ = 0.f, inv_cell_ = 0.f;
  Eigen::Vector3f lo_ = Eigen::Vector3f::Zero();
  int dims_[3] = {0, 0, 0};
  std::vector<uint32_t> start_;  // points of cell c: [start_[c], start_[c + 1]) of x_, y_, z_
  std::vector<float> x_, y_, z_;
  std::unique_ptr<PointIndex> fallback_;
};

// Writes a cache file: `write` fills a temporary file beside `path` (named by process, thread and
// call), renamed onto `path` when complete, so a reader never sees half a file; StageError on an
// I/O error.
void WriteCacheFile(const std::string& path, const std::function<void(std::ostream&)>& write);

// One sampled model. All arrays have one entry per point.
class ModelCloud {
 public:
  ModelCloud(const CatalogModel& model, const SamplingOptions& options, uint64_t seed);
  ~ModelCloud();

  // Disk cache of a sampled model: the cloud, its normals and coverage grid (the kd-tree and
  // the height index are rebuilt on load, ~10 % of the sampling time). CacheKey hashes what
  // the sampling depends on (format, mesh, options, seed); Load returns null when the file is
  // missing, truncated, of another format or another key, so a bad cache only costs a
  // resampling. A loaded cloud equals the sampled one bit for bit (same fits).
  static uint64_t CacheKey(const CatalogModel& model, const SamplingOptions& options, uint64_t seed);
  void Save(const std::string& path, uint64_t key) const;  // temp file + rename; throws on I/O errors
  static std::unique_ptr<ModelCloud> Load(const std::string& path, uint64_t key, const std::string& id);
  ModelCloud(const ModelCloud&) = delete;
  ModelCloud& operator=(const ModelCloud&) = delete;

  const std::string& Id() const { return id_; }
  const Points& Cloud() const { return points_; }
  const Points& Normals() const { return normals_; }  // unit face normals, sign as the mesh winds
  const Eigen::AlignedBox3f& Bounds() const { return bounds_; }  // of the mesh
  double Area() const { return area_; }        // total face area [m²]
  double OuterArea() const { return outer_area_; }  // area seen from outside [m²] (sampled part)
  double Density() const { return density_; }  // points per m² actually used
  float Spacing() const { return spacing_; }   // mean point spacing 1/sqrt(density) [m]
  float InlierDistance() const { return inlier_; }

  // Candidate correspondences for a scene point at model-frame height z: indices of points
  // with |z_m - z| <= tol whose normal is informative (|n_xy| > min_horizontal_normal) or not.
  void HeightBand(float z, float tol, bool informative, std::vector<int>* out) const;

  // True when the nearest model point is within the inlier distance of q (model frame).
  // Exact (same answer as a kd-tree query); a precomputed cell grid answers most queries.
  bool Covered(const Eigen::Vector3f& q) const {
    const float fx = (q.x() - grid_min_.x()) * inv_cell_;
    const float fy = (q.y() - grid_min_.y()) * inv_cell_;
    const float fz = (q.z() - grid_min_.z()) * inv_cell_;
    if (!(fx >= 0.f && fy >= 0.f && fz >= 0.f)) return false;
    // Compared as floats: a coordinate beyond an int's range must not be converted.
    if (!(fx < float(dims_[0]) && fy < float(dims_[1]) && fz < float(dims_[2]))) return false;
    const int ix = static_cast<int>(fx), iy = static_cast<int>(fy), iz = static_cast<int>(fz);
    const int32_t b = blocks_[(size_t(iz >> 3) * bdims_[1] + (iy >> 3)) * bdims_[0] + (ix >> 3)];
    if (b < 0) return false;
    const unsigned idx = ((iz & 7) << 6) | ((iy & 7) << 3) | (ix & 7);
    const unsigned s = (cells_[size_t(b) * 128 + (idx >> 2)] >> ((idx & 3) * 2)) & 3u;
    if (s == kCovered) return true;
    if (s == kOutside) return false;
    return CoveredExact(q);
  }
  bool CoveredExact(const Eigen::Vector3f& q) const { return near_->AnyWithin(q); }
  // Covered() of 8 scene points turned into the model frame by an upright pose: q_l = (c dx +
  // s dy, -s dx + c dy, z[l]) with dx = x[l] - tx, dy = y[l] - ty (floats, as the RANSAC's
  // scoring computes them); bit l of the result is q_l's answer, Covered()'s. Where the CPU has
  // AVX2 (simd::UseAvx2) the grid is read by gathers, 8 lanes at a time, and only the ambiguous
  // lanes go to CoveredExact; elsewhere it calls Covered() 8 times.
  int CoveredUpright8(const float* x, const float* y, const float* z, float c, float s, float tx, float ty) const;
  int Nearest(const Eigen::Vector3f& q, float* dist) const { return kd_->Nearest(q, dist); }
  // Share of Covered() answers that needed the kd-tree; for benchmarks.
  double AmbiguousCellShare() const;
  size_t GridBytes() const { return cells_.size() + 4 * blocks_.size(); }

 private:
  static constexpr uint8_t kOutside = 0, kAmbiguous = 1, kCovered = 2;
  ModelCloud() = default;  // for Load
  void BuildIndices();     // height index and kd-tree over points_
  void BuildCoverageGrid();

  std::string id_;
  Points points_, normals_;
  Eigen::AlignedBox3f bounds_;
  double area_ = 0.0, outer_area_ = 0.0, density_ = 0.0;
  float spacing_ = 0.f, inlier_ = 0.f, min_h_ = 0.f;
  // Height index: point indices sorted by z, split into informative / not informative normals.
  std::vector<float> z_info_, z_flat_;
  std::vector<int> idx_info_, idx_flat_;
  // Coverage cells (a quarter of the inlier distance) over the bounds grown by the inlier
  // distance: kCovered = every position in the cell is within the inlier distance of a point,
  // kOutside = none is, else kAmbiguous (the kd-tree decides). Stored sparsely in blocks of
  // 8 x 8 x 8 cells of 2 bits (128 bytes): only blocks near the surface exist (blocks_ = -1
  // elsewhere), which keeps a model's grid around 1 MB, inside the L2 cache.
  Eigen::Vector3f grid_min_ = Eigen::Vector3f::Zero();
  float inv_cell_ = 1.f;
  int dims_[3] = {0, 0, 0}, bdims_[3] = {0, 0, 0};
  std::vector<int32_t> blocks_;
  std::vector<uint8_t> cells_;
  std::unique_ptr<PointIndex> kd_;    // nearest-point queries (ICP)
  std::unique_ptr<RadiusGrid> near_;  // CoveredExact: the grid's ambiguous cells, a third of
                                      // RANSAC's look-ups on dense scans (a cell scan, no tree walk)
};

}  // namespace furnihost::ransac_upright
