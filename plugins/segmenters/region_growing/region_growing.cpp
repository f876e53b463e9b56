// segmenters.region_growing — the paper's segmenter (Sect. III): normals from a 2nd-order
// height function (MLS, eq. 1) in a radius, region growing against the SEED's normal from
// seeds of increasing curvature, small parts regrouped by distance and the rest discarded.
// The algorithm lives in region_growing_core.{hpp,cpp}; this file only maps parameters.
#include <tbb/task_arena.h>

#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"
#include "region_growing_core.hpp"

namespace furnihost {

// Each parameter declared once; its default is rg::RegionGrowingOptions{}'s.
const ParamBinding<rg::RegionGrowingOptions>& Binding() {
  using O = rg::RegionGrowingOptions;
  static const auto b =
      ParamBinding<O>()
          .Number("normal_radius_m", &O::normal_radius_m, 0.001, 10.0, "m",
                  "radius of the neighbourhood of the height-function fit [m] (paper: 0.03)")
          .Number("distance_m", &O::distance_m, 0.001, 10.0, "m",
                  "a point joins a part if closer than this to one of its points [m] (paper: 0.05)")
          .Number("angle_deg", &O::angle_deg, 0.0, 180.0, "deg",
                  "max angle between a point's normal and the part's seed normal [deg] (paper: 40)")
          .Int("min_points", &O::min_points, 1, 1e9, "count",
               "parts with fewer points are regrouped by distance; still smaller ones are discarded (paper: 10)")
          .Int("min_fit_points", &O::min_fit_points, 3, 1e6, "count",
               "with fewer neighbours (the point included) the normal is the PCA normal, below 3 it is NaN")
          .Int("max_normal_points", &O::max_normal_points, 0, 1e6, "count",
               "where the normal ball would hold more than about this many points (its 3x3x3 cells of "
               "normal_radius_m hold more than 4x this), fit the normal to the point-weighted centroids of "
               "voxels of normal_radius_m / 4 (~50 in a planar ball), not to every point; 0 = always every point")
          .Bool("signed_normals", &O::signed_normals,
                "compare signed normals (needs a sensor origin); false treats n and -n as parallel")
          .Bool("growth_by_sub_cells", &O::growth_by_sub_cells,
                "dense scans (>= 2 points per cube of distance_m / 2) grow cube by cube, the same parts as point "
                "by point (false) in time about linear in the points")
          .Int("max_list_candidates", &O::max_list_candidates, 0, 1e6, "count",
               "sparse scans list each point's neighbours within distance_m before growing (the same parts, "
               "faster) while each point has at most this many candidates in its 27 cells on average; 0 = never");
  return b;
}

class RegionGrowingSegmenter : public Segmenter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }

  explicit RegionGrowingSegmenter(const nlohmann::json& p) : o_(Binding().Parse(p)) { o_.Check(); }

  Segmentation Segment(const Scan& scan, const RunContext& ctx) override {
    tbb::task_arena arena(ctx.threads > 0 ? ctx.threads : tbb::task_arena::automatic);
    rg::SegmentTimings t;
    Segmentation seg;
    arena.execute([&] { seg = rg::Segment(scan, o_, &t); });
    spdlog::debug("region_growing: {} points -> {} parts (normals {:.1f} ms, growing {:.1f} ms)",
                  scan.points.size(), seg.parts.size(), t.normals_ms, t.growing_ms);
    return seg;
  }

 private:
  rg::RegionGrowingOptions o_;
};

}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::RegionGrowingSegmenter, "segmenters.region_growing", "1.2.0",
                 "paper Sect. III: MLS normals, region growing against the seed normal, small parts regrouped")
