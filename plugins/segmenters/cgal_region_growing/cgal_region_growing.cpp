// segmenters.cgal_region_growing — CGAL 5.5 Shape_detection region growing of planes on a
// point set, as a swappable alternative of segmenters.region_growing.
//
// Coded against the CGAL 5.5 API (Region_growing<InputRange, NeighborQuery, RegionType,
// SeedMap> with index-based queries); CGAL 5.6 replaced it with item-based queries.
//
// Normals: CGAL::jet_estimate_normals (2nd-order jet = the paper's bivariate polynomial
// fitted over the tangent plane, unweighted) or pca_estimate_normals, in a radius. Where the
// radius holds fewer than 3 points the output normal/curvature is NaN like PCL's (CGAL
// itself falls back to the nearest neighbours and still uses the point for growing).
// Curvature: surface variation lambda0 / (lambda0 + lambda1 + lambda2) of the radius
// neighbourhood, as in the paper.
// Growing: a point joins a region if it is a neighbour (`neighbourhood`: radius `distance_m`
// or the `neighbours` nearest) of a member, lies within `max_plane_distance_m` of the
// region's least-squares plane and its normal is within `angle_deg` of the plane's normal
// — planar parts only; curved surfaces split into facets. Regions below `min_points` are
// dropped (no regrouping) and counted in Segmentation::discarded_points.
// Frames: scan frame throughout; the points are shifted by their bounding-box centre so
// map-coordinate scans keep their precision.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing.h>
#include <CGAL/Shape_detection/Region_growing/Region_growing_on_point_set.h>
#include <CGAL/jet_estimate_normals.h>
#include <CGAL/pca_estimate_normals.h>
#include <CGAL/property_map.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"

namespace {

using furnihost::ParamSchema;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point3 = Kernel::Point_3;
using Vector3 = Kernel::Vector_3;
using Pwn = std::pair<Point3, Vector3>;
using PwnVector = std::vector<Pwn>;
using PointMap = CGAL::First_of_pair_property_map<Pwn>;
using NormalMap = CGAL::Second_of_pair_property_map<Pwn>;

struct CgalRegionGrowingOptions {
  std::string normals = "jet";           // "jet" | "pca"
  double normal_radius_m = 0.03;         // normal/curvature neighbourhood radius [m] (paper: 3 cm)
  int normal_max_neighbours = 0;         // cap on the normal neighbourhood (0 = none)
  std::string neighbourhood = "radius";  // "radius" (Sphere_neighbor_query) | "knn" (K_neighbor_query)
  double distance_m = 0.05;              // growing radius [m] (paper: 5 cm)
  int neighbours = 12;                   // k of the "knn" neighbourhood
  double max_plane_distance_m = 0.02;    // max distance of a member to the region's plane [m]
  double angle_deg = 40.0;               // max angle between normal and region plane [deg]
  int min_points = 10;                   // smaller regions are dropped (paper: 10)
  std::string seed_order = "curvature";  // "curvature" (paper: flattest first) | "plane_fit" (CGAL)

  void Check() const {
    if (!(normal_radius_m > 0) || !(distance_m > 0))
      throw furnihost::StageError("normal_radius_m and distance_m must be > 0");
    if (angle_deg < 0 || angle_deg > 90)
      throw furnihost::StageError("angle_deg must be in [0, 90] (CGAL compares |cos|)");
  }
};

// Radius neighbourhoods on a hashed voxel grid (cell = radius): curvature needs the same
// radius as the normals and a grid is much cheaper to build than another kd-tree.
class VoxelGrid {
 public:
  VoxelGrid(const std::vector<Eigen::Vector3f>& pts, float cell) : pts_(pts), inv_(1.f / cell) {
    order_.resize(pts.size());
    std::iota(order_.begin(), order_.end(), 0);
    std::vector<uint64_t> keys(pts.size());
    for (size_t i = 0; i < pts.size(); ++i) keys[i] = Key(Cell(pts[i]));
    std::sort(order_.begin(), order_.end(), [&](int a, int b) {
      return keys[a] != keys[b] ? keys[a] < keys[b] : a < b;
    });
    cells_.reserve(pts.size() / 4 + 1);
    for (size_t b = 0; b < order_.size();) {
      size_t e = b;
      while (e < order_.size() && keys[order_[e]] == keys[order_[b]]) ++e;
      cells_.emplace(keys[order_[b]], std::make_pair(uint32_t(b), uint32_t(e)));
      b = e;
    }
  }
  // Calls f(j) for every point j within `r` (<= cell) of q.
  template <class F>
  void Radius(const Eigen::Vector3f& q, float r, F&& f) const {
    const Eigen::Vector3i c = Cell(q);
    const float r2 = r * r;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          auto it = cells_.find(Key(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == cells_.end()) continue;
          for (uint32_t k = it->second.first; k < it->second.second; ++k)
            if ((pts_[order_[k]] - q).squaredNorm() <= r2) f(order_[k]);
        }
  }

 private:
  Eigen::Vector3i Cell(const Eigen::Vector3f& p) const {
    return (p * inv_).array().floor().cast<int>();
  }
  static uint64_t Key(const Eigen::Vector3i& c) {
    auto u = [](int v) { return uint64_t(uint32_t(v + (1 << 20)) & 0x1fffff); };
    return u(c.x()) | (u(c.y()) << 21) | (u(c.z()) << 42);
  }
  const std::vector<Eigen::Vector3f>& pts_;
  float inv_;
  std::vector<int> order_;
  std::unordered_map<uint64_t, std::pair<uint32_t, uint32_t>> cells_;
};

template <class Query>
std::vector<std::vector<std::size_t>> Grow(const PwnVector& pwn, Query& query,
                                           const CgalRegionGrowingOptions& o,
                                           const std::vector<float>& curvature) {
  namespace SD = CGAL::Shape_detection;
  using Region = SD::Point_set::Least_squares_plane_fit_region<Kernel, PwnVector, PointMap, NormalMap>;
  using Sorting = SD::Point_set::Least_squares_plane_fit_sorting<Kernel, PwnVector, Query, PointMap>;
  using SeedMap = typename Sorting::Seed_map;
  Region region(pwn, o.max_plane_distance_m, o.angle_deg, std::size_t(o.min_points));
  std::vector<std::size_t> order(pwn.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::vector<std::vector<std::size_t>> regions;
  auto run = [&](SeedMap seeds) {
    SD::Region_growing<PwnVector, Query, Region, SeedMap> rg(pwn, query, region, seeds);
    rg.detect(std::back_inserter(regions));
  };
  if (o.seed_order == "plane_fit") {
    Sorting sorting(pwn, query);
    sorting.sort();
    run(sorting.seed_map());
  } else {
    // Flattest first; NaN curvature (isolated points) last; ties by index (deterministic).
    auto key = [&](std::size_t i) {
      return std::isfinite(curvature[i]) ? curvature[i] : std::numeric_limits<float>::infinity();
    };
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return key(a) < key(b); });
    run(SeedMap(order));
  }
  return regions;
}

class CgalRegionGrowing : public furnihost::Segmenter {
 public:
  static ParamSchema Schema() {
    ParamSchema s;
    s.Enum("normals", "jet", {"jet", "pca"},
           "normal estimator: CGAL jet fitting (order 2, the paper's polynomial) or PCA");
    s.Number("normal_radius_m", 0.03, 0.001, 10.0, "radius of the normal and curvature neighbourhood [m] (paper: 0.03)");
    s.Int("normal_max_neighbours", 0, 0, 100000, "cap on the points of a normal neighbourhood (0 = no cap)");
    s.Enum("neighbourhood", "radius", {"radius", "knn"},
           "growing neighbourhood: all points within distance_m, or the `neighbours` nearest");
    s.Number("distance_m", 0.05, 0.001, 10.0, "growing radius [m] (paper: 0.05)");
    s.Int("neighbours", 12, 1, 10000, "k of the knn growing neighbourhood");
    s.Number("max_plane_distance_m", 0.02, 0.0, 10.0, "max distance of a member to the region's fitted plane [m]");
    s.Number("angle_deg", 40.0, 0.0, 90.0, "max angle between a member's normal and the region's plane normal [deg] (paper: 40)");
    s.Int("min_points", 10, 1, 1e9, "regions with fewer points are dropped (paper: 10)");
    s.Enum("seed_order", "curvature", {"curvature", "plane_fit"},
           "seeds by lowest curvature (paper) or by CGAL's local plane-fit quality");
    return s;
  }

  explicit CgalRegionGrowing(const nlohmann::json& p) {
    o_.normals = p.at("normals").get<std::string>();
    o_.normal_radius_m = p.at("normal_radius_m").get<double>();
    o_.normal_max_neighbours = p.at("normal_max_neighbours").get<int>();
    o_.neighbourhood = p.at("neighbourhood").get<std::string>();
    o_.distance_m = p.at("distance_m").get<double>();
    o_.neighbours = p.at("neighbours").get<int>();
    o_.max_plane_distance_m = p.at("max_plane_distance_m").get<double>();
    o_.angle_deg = p.at("angle_deg").get<double>();
    o_.min_points = p.at("min_points").get<int>();
    o_.seed_order = p.at("seed_order").get<std::string>();
    o_.Check();
  }

  furnihost::Segmentation Segment(const furnihost::Scan& scan,
                                  const furnihost::RunContext& ctx) override {
    const size_t n = scan.points.size();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    furnihost::Segmentation seg;
    seg.normals.assign(n, Eigen::Vector3f::Constant(nan));
    seg.curvature.assign(n, nan);

    // Finite points only, shifted to their bounding-box centre.
    std::vector<int> ids;  // local -> scan index
    ids.reserve(n);
    Eigen::AlignedBox3d box;
    for (size_t i = 0; i < n; ++i)
      if (scan.points[i].allFinite()) {
        ids.push_back(int(i));
        box.extend(scan.points[i].cast<double>());
      }
    // Jet fitting needs 6 points; fewer cannot make a part of a plane anyway.
    if (ids.size() < 6) {
      seg.discarded_points = int(n);
      return seg;
    }
    const Eigen::Vector3d shift = box.center();
    const size_t m = ids.size();
    std::vector<Eigen::Vector3f> local(m);
    PwnVector pwn(m);
    for (size_t k = 0; k < m; ++k) {
      const Eigen::Vector3d q = scan.points[ids[k]].cast<double>() - shift;
      local[k] = q.cast<float>();
      pwn[k].first = Point3(q.x(), q.y(), q.z());
    }

    tbb::task_arena arena(ctx.threads > 0 ? ctx.threads : tbb::task_arena::automatic);
    std::vector<float> curvature(m, nan);
    std::vector<char> enough(m, 0);
    arena.execute([&] {
      const auto np = CGAL::parameters::point_map(PointMap()).normal_map(NormalMap())
                          .neighbor_radius(o_.normal_radius_m);
      const unsigned cap = unsigned(o_.normal_max_neighbours);
      if (o_.normals == "jet")
        CGAL::jet_estimate_normals<CGAL::Parallel_if_available_tag>(pwn, cap, np.degree_fitting(2));
      else
        CGAL::pca_estimate_normals<CGAL::Parallel_if_available_tag>(pwn, cap, np);

      const VoxelGrid grid(local, float(o_.normal_radius_m));
      tbb::parallel_for(tbb::blocked_range<size_t>(0, m, 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
          // Centred two-pass covariance (the neighbourhood is small, the scan may not be).
          Eigen::Vector3d mean = Eigen::Vector3d::Zero();
          int cnt = 0;
          grid.Radius(local[k], float(o_.normal_radius_m), [&](int j) {
            mean += local[j].cast<double>();
            ++cnt;
          });
          if (cnt < 3) continue;
          mean /= cnt;
          Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
          grid.Radius(local[k], float(o_.normal_radius_m), [&](int j) {
            const Eigen::Vector3d d = local[j].cast<double>() - mean;
            cov.noalias() += d * d.transpose();
          });
          const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov, Eigen::EigenvaluesOnly).eigenvalues();
          const double tr = ev.sum();
          curvature[k] = tr > 0 ? float(std::max(0.0, ev[0]) / tr) : 0.f;
          enough[k] = 1;
        }
      });
    });

    // Towards the sensor when known, else towards the scan frame's origin (as PCL does).
    const Eigen::Vector3d eye =
        (scan.origin ? Eigen::Vector3d(scan.origin->cast<double>()) : Eigen::Vector3d(Eigen::Vector3d::Zero())) -
        shift;
    for (size_t k = 0; k < m; ++k) {
      Eigen::Vector3d v(pwn[k].second.x(), pwn[k].second.y(), pwn[k].second.z());
      const double len = v.norm();
      if (!(len > 0) || !v.allFinite()) {
        // A degenerate neighbourhood: give CGAL a valid unit vector, report NaN.
        pwn[k].second = Vector3(0, 0, 1);
        enough[k] = 0;
        continue;
      }
      v /= len;
      const Eigen::Vector3d p(pwn[k].first.x(), pwn[k].first.y(), pwn[k].first.z());
      if (v.dot(eye - p) < 0) v = -v;
      pwn[k].second = Vector3(v.x(), v.y(), v.z());
      if (enough[k]) {
        seg.normals[ids[k]] = v.cast<float>();
        seg.curvature[ids[k]] = curvature[k];
      }
    }

    std::vector<std::vector<std::size_t>> regions;
    if (o_.neighbourhood == "radius") {
      CGAL::Shape_detection::Point_set::Sphere_neighbor_query<Kernel, PwnVector, PointMap> q(pwn, o_.distance_m);
      regions = Grow(pwn, q, o_, curvature);
    } else {
      CGAL::Shape_detection::Point_set::K_neighbor_query<Kernel, PwnVector, PointMap> q(pwn, std::size_t(o_.neighbours));
      regions = Grow(pwn, q, o_, curvature);
    }

    size_t assigned = 0;
    for (const auto& r : regions) {
      furnihost::Part part;
      part.indices.reserve(r.size());
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (std::size_t k : r) {
        part.indices.push_back(ids[k]);
        sum += scan.points[ids[k]].cast<double>();
      }
      part.centroid = (sum / double(r.size())).cast<float>();
      assigned += r.size();
      seg.parts.push_back(std::move(part));
    }
    seg.discarded_points = int(n - assigned);
    spdlog::debug("cgal_region_growing: {} points, {} parts, {} unassigned", n, seg.parts.size(),
                  seg.discarded_points);
    return seg;
  }

 private:
  CgalRegionGrowingOptions o_;
};

}  // namespace

FURNIHOST_PLUGIN(CgalRegionGrowing, "segmenters.cgal_region_growing", "1.0.0",
                 "CGAL 5.5 Shape_detection region growing of planes, jet or PCA normals")
