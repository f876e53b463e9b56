// segmenters.cgal_region_growing — CGAL 5.5 Shape_detection region growing of planes on a
// point set, as a swappable alternative of segmenters.region_growing.
//
// Coded against the CGAL 5.5 API (Region_growing<InputRange, NeighborQuery, RegionType,
// SeedMap> with index-based queries); CGAL 5.6 replaced it with item-based queries.
//
// Normals (shared with segmenters.cgal_efficient_ransac, segmentation/cgal_normals.hpp):
// CGAL::jet_estimate_normals (2nd-order jet = the paper's bivariate polynomial
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
#include <CGAL/property_map.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"
#include "segmentation/cgal_normals.hpp"
#include "segmentation/copies.hpp"

namespace {

using furnihost::ParamSchema;
namespace cgal_common = furnihost::cgal_common;
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
};

// Each parameter declared once; its default is CgalRegionGrowingOptions{}'s. (The schema's
// ranges keep the radii > 0 and angle_deg in [0, 90], which CGAL's |cos| test needs.)
const furnihost::ParamBinding<CgalRegionGrowingOptions>& Binding() {
  using O = CgalRegionGrowingOptions;
  static const auto b =
      furnihost::ParamBinding<O>()
          .Enum("normals", &O::normals, {"jet", "pca"},
                "normal estimator: CGAL jet fitting (order 2, the paper's polynomial) or PCA")
          .Number("normal_radius_m", &O::normal_radius_m, 0.001, 10.0, "m",
                  "radius of the normal and curvature neighbourhood [m] (paper: 0.03)")
          .Int("normal_max_neighbours", &O::normal_max_neighbours, 0, 100000, "count",
               "cap on the points of a normal neighbourhood (0 = no cap)")
          .Enum("neighbourhood", &O::neighbourhood, {"radius", "knn"},
                "growing neighbourhood: all points within distance_m, or the `neighbours` nearest")
          .Number("distance_m", &O::distance_m, 0.001, 10.0, "m", "growing radius [m] (paper: 0.05)")
          .Int("neighbours", &O::neighbours, 1, 10000, "count", "k of the knn growing neighbourhood")
          .Number("max_plane_distance_m", &O::max_plane_distance_m, 0.0, 10.0, "m",
                  "max distance of a member to the region's fitted plane")
          .Number("angle_deg", &O::angle_deg, 0.0, 90.0, "deg",
                  "max angle between a member's normal and the region's plane normal [deg] (paper: 40)")
          .Int("min_points", &O::min_points, 1, 1e9, "count", "regions with fewer points are dropped (paper: 10)")
          .Enum("seed_order", &O::seed_order, {"curvature", "plane_fit"},
                "seeds by lowest curvature (paper) or by CGAL's local plane-fit quality");
  return b;
}

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

class CgalRegionGrowing : public furnihost::DistinctPointsSegmenter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit CgalRegionGrowing(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  // Segment() (DistinctPointsSegmenter) passes the distinct positions: copies of a point would make
  // the library's k-d tree quadratic (see copies.hpp).

 private:
  furnihost::Segmentation SegmentDistinct(const furnihost::Scan& scan, const furnihost::RunContext& ctx) override {
    const size_t n = scan.points.size();
    furnihost::Segmentation seg = Unsegmented(n);
    const float nan = std::numeric_limits<float>::quiet_NaN();

    // Finite points only, shifted to their bounding-box centre.
    const cgal_common::LocalFrame frame = cgal_common::MakeLocalFrame(scan);
    const std::vector<int>& ids = frame.ids;  // local -> scan index
    // Jet fitting needs 6 points; fewer cannot make a part of a plane anyway.
    if (ids.size() < 6) {
      seg.discarded_points = int(n);
      return seg;
    }
    const size_t m = ids.size();
    PwnVector pwn(m);
    for (size_t k = 0; k < m; ++k) pwn[k].first = Point3(frame.points[k].x(), frame.points[k].y(), frame.points[k].z());

    tbb::task_arena arena(ctx.threads > 0 ? ctx.threads : tbb::task_arena::automatic);
    std::vector<float> curvature(m, nan);
    std::vector<char> enough(m, 0);
    arena.execute([&] {
      cgal_common::EstimateNormals<PwnVector, PointMap, NormalMap>(pwn, o_.normals, o_.normal_radius_m,
                                                                   unsigned(o_.normal_max_neighbours));
      cgal_common::SurfaceVariation(frame.local, float(o_.normal_radius_m), curvature, enough);
    });

    for (size_t k = 0; k < m; ++k) {
      Eigen::Vector3d v;
      const Vector3& raw = pwn[k].second;
      if (!cgal_common::OrientedUnitNormal(raw.x(), raw.y(), raw.z(), frame.points[k], frame.eye, v)) {
        // A degenerate neighbourhood: give CGAL a valid unit vector, report NaN.
        pwn[k].second = Vector3(0, 0, 1);
        enough[k] = 0;
        continue;
      }
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

  CgalRegionGrowingOptions o_;
};

}  // namespace

FURNIHOST_PLUGIN(CgalRegionGrowing, "segmenters.cgal_region_growing", "1.0.0",
                 "CGAL 5.5 Shape_detection region growing of planes, jet or PCA normals")
