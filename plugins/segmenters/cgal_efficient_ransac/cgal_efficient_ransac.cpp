// segmenters.cgal_efficient_ransac — CGAL 5.5 Efficient RANSAC (Schnabel et al. 2007) as a
// swappable alternative of segmenters.region_growing: planes (and optionally cylinders) are
// detected one after another, each shape keeping its largest connected component
// (`cluster_epsilon_m`); the points no shape explains are grouped by distance (`distance_m`,
// the paper's 5 cm) and groups of at least `min_points` become parts too, so legs and other
// small pieces are not lost. Smaller groups are counted in Segmentation::discarded_points.
//
// Normals as in segmenters.cgal_region_growing, same code (segmentation/cgal_normals.hpp: jet
// order 2 or PCA in a radius; NaN output where the radius holds fewer than 3 points);
// curvature is the surface variation lambda0 / (lambda0 + lambda1 + lambda2) in the same radius.
// Deterministic: CGAL draws from its thread-local default generator, which is reseeded from
// RunContext::seed before each detection.
// Frames: scan frame throughout; the points are shifted by their bounding-box centre.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Random.h>
#include <CGAL/Shape_detection/Efficient_RANSAC.h>
#include <CGAL/property_map.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"
#include "segmentation/cgal_normals.hpp"
#include "segmentation/copies.hpp"

namespace {

using furnihost::ParamSchema;
using furnihost::TbbFor;
using furnihost::VoxelIndex;
namespace cgal_common = furnihost::cgal_common;
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point3 = Kernel::Point_3;
using Vector3 = Kernel::Vector_3;
// Efficient RANSAC reorders its input: each point carries its local index along.
using Pni = std::tuple<Point3, Vector3, std::size_t>;
using PniVector = std::vector<Pni>;
using PointMap = CGAL::Nth_of_tuple_property_map<0, Pni>;
using NormalMap = CGAL::Nth_of_tuple_property_map<1, Pni>;
using Traits = CGAL::Shape_detection::Efficient_RANSAC_traits<Kernel, PniVector, PointMap, NormalMap>;
using Ransac = CGAL::Shape_detection::Efficient_RANSAC<Traits>;

struct CgalEfficientRansacOptions {
  std::string normals = "jet";        // "jet" | "pca"
  double normal_radius_m = 0.03;      // normal/curvature radius [m] (paper: 3 cm)
  std::string shapes = "planes_cylinders";  // "planes" | "planes_cylinders"
  double probability = 0.05;          // chance of missing the largest candidate shape
  int min_shape_points = 100;         // smallest shape RANSAC may accept
  double epsilon_m = 0.01;            // max point-to-shape distance [m]
  double cluster_epsilon_m = 0.03;    // max gap inside one shape [m] (>= sampling spacing)
  double angle_deg = 25.0;            // max angle between point normal and shape normal [deg]
  bool attach_leftovers = true;       // leftover points on an adjacent shape join it
  double distance_m = 0.05;           // grouping distance of the leftover points [m] (paper: 5 cm)
  int min_points = 10;                // smaller leftover groups are discarded (paper: 10)
};

// Each parameter declared once; its default is CgalEfficientRansacOptions{}'s. (The schema's
// ranges keep every radius and distance > 0.)
const furnihost::ParamBinding<CgalEfficientRansacOptions>& Binding() {
  using O = CgalEfficientRansacOptions;
  static const auto b =
      furnihost::ParamBinding<O>()
          .Enum("normals", &O::normals, {"jet", "pca"},
                "normal estimator: CGAL jet fitting (order 2, the paper's polynomial) or PCA")
          .Number("normal_radius_m", &O::normal_radius_m, 0.001, 10.0, "m",
                  "radius of the normal and curvature neighbourhood [m] (paper: 0.03)")
          .Enum("shapes", &O::shapes, {"planes", "planes_cylinders"}, "shape types RANSAC looks for")
          .Number("probability", &O::probability, 1e-6, 1.0, "1",
                  "probability of missing the largest candidate (lower = more thorough)")
          .Int("min_shape_points", &O::min_shape_points, 3, 1e9, "count", "smallest shape RANSAC accepts")
          .Number("epsilon_m", &O::epsilon_m, 1e-5, 1.0, "m", "max distance of a point to its shape")
          .Number("cluster_epsilon_m", &O::cluster_epsilon_m, 1e-5, 1.0, "m",
                  "max gap between neighbouring points of one shape")
          .Number("angle_deg", &O::angle_deg, 0.0, 90.0, "deg", "max angle between a point's normal and its shape's normal")
          .Bool("attach_leftovers", &O::attach_leftovers,
                "a leftover point within epsilon_m of a shape that has points within cluster_epsilon_m joins it")
          .Number("distance_m", &O::distance_m, 1e-4, 10.0, "m",
                  "points no shape explains are grouped at this distance [m] (paper: 0.05)")
          .Int("min_points", &O::min_points, 1, 1e9, "count", "leftover groups with fewer points are discarded (paper: 10)");
  return b;
}

class CgalEfficientRansac : public furnihost::DistinctPointsSegmenter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit CgalEfficientRansac(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  // Segment() (DistinctPointsSegmenter) passes the distinct positions: copies of a point would make
  // the library's k-d tree quadratic (see copies.hpp).

 private:
  furnihost::Segmentation SegmentDistinct(const furnihost::Scan& scan, const furnihost::RunContext& ctx) override {
    const size_t n = scan.points.size();
    furnihost::Segmentation seg = Unsegmented(n);
    const float nan = std::numeric_limits<float>::quiet_NaN();

    const cgal_common::LocalFrame frame = cgal_common::MakeLocalFrame(scan);
    const std::vector<int>& ids = frame.ids;  // local -> scan index
    const std::vector<Eigen::Vector3f>& local = frame.local;
    if (ids.size() < 6) {  // jet fitting needs 6 points
      seg.discarded_points = int(n);
      return seg;
    }
    const size_t m = ids.size();
    PniVector pts(m);
    for (size_t k = 0; k < m; ++k) {
      const Eigen::Vector3d& q = frame.points[k];
      pts[k] = Pni(Point3(q.x(), q.y(), q.z()), Vector3(0, 0, 1), k);
    }

    tbb::task_arena arena(ctx.threads > 0 ? ctx.threads : tbb::task_arena::automatic);
    std::vector<float> curvature(m, nan);
    std::vector<char> enough(m, 0);
    arena.execute([&] {
      cgal_common::EstimateNormals<PniVector, PointMap, NormalMap>(pts, o_.normals, o_.normal_radius_m, 0);
      cgal_common::SurfaceVariation(local, float(o_.normal_radius_m), curvature, enough);
    });

    for (auto& t : pts) {
      const std::size_t k = std::get<2>(t);
      const Vector3& raw = std::get<1>(t);
      Eigen::Vector3d v;
      // The sign test takes the float position (the plugin always did; only the side matters).
      if (!cgal_common::OrientedUnitNormal(raw.x(), raw.y(), raw.z(), local[k].cast<double>(), frame.eye, v)) {
        std::get<1>(t) = Vector3(0, 0, 1);  // keep CGAL's input valid; reported as NaN
        enough[k] = 0;
        continue;
      }
      std::get<1>(t) = Vector3(v.x(), v.y(), v.z());
      if (enough[k]) {
        seg.normals[ids[k]] = v.cast<float>();
        seg.curvature[ids[k]] = curvature[k];
      }
    }

    // Shapes.
    Ransac ransac;
    ransac.set_input(pts);
    ransac.add_shape_factory<CGAL::Shape_detection::Plane<Traits>>();
    if (o_.shapes == "planes_cylinders") ransac.add_shape_factory<CGAL::Shape_detection::Cylinder<Traits>>();
    Ransac::Parameters rp;
    rp.probability = o_.probability;
    rp.min_points = std::size_t(o_.min_shape_points);
    rp.epsilon = o_.epsilon_m;
    rp.cluster_epsilon = o_.cluster_epsilon_m;
    rp.normal_threshold = std::cos(o_.angle_deg * M_PI / 180.0);
    CGAL::get_default_random() = CGAL::Random(unsigned(ctx.seed ^ (ctx.seed >> 32)));
    ransac.detect(rp);

    // owner[k]: index of the shape holding local point k, -1 if none.
    std::vector<int> owner(m, -1);
    std::vector<const CGAL::Shape_detection::Shape_base<Traits>*> shape_list;
    int planes = 0, cylinders = 0;
    for (const auto& shape : ransac.shapes()) {
      for (std::size_t r : shape->indices_of_assigned_points())
        owner[std::get<2>(pts[r])] = int(shape_list.size());  // `r` indexes the reordered input
      if (dynamic_cast<const CGAL::Shape_detection::Plane<Traits>*>(shape.get())) ++planes; else ++cylinders;
      shape_list.push_back(shape.get());
    }

    // CGAL refuses points near a shape's border whose normal leans (box edges: ~45 deg),
    // which would leave a wire frame of leftovers around every planar part. A leftover that
    // lies within epsilon_m of a shape owning a point within cluster_epsilon_m joins the
    // nearest such shape. Rings: each pass sees only the previous passes' result, so the
    // outcome does not depend on the point order.
    if (o_.attach_leftovers && !shape_list.empty()) {
      VoxelIndex grid;
      grid.Build(local, float(o_.cluster_epsilon_m), VoxelIndex::Anchor::kWorld, TbbFor());
      const double eps2 = o_.epsilon_m * o_.epsilon_m;
      for (bool changed = true; changed;) {
        changed = false;
        std::vector<int> next = owner;
        for (int s = 0; s < int(m); ++s) {
          const size_t k = grid.order[s];
          if (owner[k] >= 0) continue;
          const Point3 pk(local[k].x(), local[k].y(), local[k].z());
          double best = eps2;
          cgal_common::ForEachInClosedBall(grid, local, s, float(o_.cluster_epsilon_m), [&](int t) {
            const int j = int(grid.order[t]);
            if (owner[j] < 0) return;
            const double d2 = CGAL::to_double(shape_list[owner[j]]->squared_distance(pk));
            if (d2 < best || (d2 == best && next[k] >= 0 && owner[j] < next[k])) {
              best = d2;
              next[k] = owner[j];
            }
          });
          changed |= next[k] >= 0;
        }
        owner.swap(next);
      }
    }

    std::vector<std::vector<int>> groups(shape_list.size());  // local indices
    std::vector<char> assigned(m, 0);
    for (size_t k = 0; k < m; ++k)
      if (owner[k] >= 0) {
        groups[owner[k]].push_back(int(k));
        assigned[k] = 1;
      }

    // Leftovers grouped by distance (breadth-first over the radius graph, index order).
    std::vector<Eigen::Vector3f> rest;
    std::vector<int> rest_ids;
    for (size_t k = 0; k < m; ++k)
      if (!assigned[k]) {
        rest.push_back(local[k]);
        rest_ids.push_back(int(k));
      }
    VoxelIndex rest_grid;
    rest_grid.Build(rest, float(o_.distance_m), VoxelIndex::Anchor::kWorld, TbbFor());
    const std::vector<uint32_t> rest_slot = rest_grid.SlotOfInput();
    std::vector<char> seen(rest.size(), 0);
    size_t small = 0;
    for (size_t s = 0; s < rest.size(); ++s) {
      if (seen[s]) continue;
      std::vector<int> comp{int(s)};
      seen[s] = 1;
      for (size_t h = 0; h < comp.size(); ++h)
        cgal_common::ForEachInClosedBall(rest_grid, rest, int(rest_slot[comp[h]]), float(o_.distance_m), [&](int t) {
          const int j = int(rest_grid.order[t]);
          if (!seen[j]) {
            seen[j] = 1;
            comp.push_back(j);
          }
        });
      if (int(comp.size()) < o_.min_points) {
        small += comp.size();
        continue;
      }
      std::vector<int> g;
      for (int j : comp) g.push_back(rest_ids[j]);
      std::sort(g.begin(), g.end());
      groups.push_back(std::move(g));
    }

    size_t total = 0;
    for (const auto& g : groups) {
      furnihost::Part part;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int k : g) {
        part.indices.push_back(ids[k]);
        sum += scan.points[ids[k]].cast<double>();
      }
      part.centroid = (sum / double(g.size())).cast<float>();
      total += g.size();
      seg.parts.push_back(std::move(part));
    }
    seg.discarded_points = int(n - total);
    spdlog::debug("cgal_efficient_ransac: {} points, {} planes, {} cylinders, {} leftover groups, {} in small groups",
                  n, planes, cylinders, groups.size() - size_t(planes + cylinders), small);
    return seg;
  }

  CgalEfficientRansacOptions o_;
};

}  // namespace

FURNIHOST_PLUGIN(CgalEfficientRansac, "segmenters.cgal_efficient_ransac", "1.0.0",
                 "CGAL 5.5 Efficient RANSAC planes (+ cylinders), leftovers grouped by distance")
