// segmenters.pcl_region_growing — PCL's RegionGrowing as a swappable alternative (and the
// speed/quality peer) of segmenters.region_growing.
//
// Differences from the paper's segmenter, all PCL's own behaviour:
//  * neighbourhoods of the growing step are the k nearest neighbours (`neighbours`), not a
//    radius: in sparse or unevenly sampled data a k-NN region can jump across gaps wider
//    than the paper's 5 cm, and in dense data it stops at a few millimetres;
//  * parts below `min_points` are dropped (no distance-based regrouping); they are counted
//    in Segmentation::discarded_points;
//  * curvature is PCL's surface variation lambda0 / (lambda0 + lambda1 + lambda2) of the
//    neighbourhood covariance (normals "omp") or of MLS's local plane fit (normals "mls").
//
// Frames: everything stays in the scan frame. The cloud is shifted by its bounding-box
// centre (in double) before it reaches PCL, whose covariance accumulation is single
// precision: scans in map coordinates (hundreds of metres away) would lose the normals.
#include <pcl/features/normal_3d_omp.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/region_growing.h>
#include <pcl/surface/mls.h>

#include <cmath>
#include <limits>
#include <thread>

#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"
#include "segmentation/copies.hpp"

namespace {

using furnihost::ParamSchema;

struct PclRegionGrowingOptions {
  std::string normals = "omp";       // "omp" (PCA, NormalEstimationOMP) | "mls" (order-2 MLS)
  double normal_radius_m = 0.03;     // radius of the normal neighbourhood [m] (paper: 3 cm)
  double angle_deg = 40.0;           // smoothness threshold [deg] (paper: 40)
  std::string compare_to = "seed";   // "seed" (paper) | "neighbour" (PCL's default smooth mode)
  double curvature_threshold = 1.0;  // a member continues the growth only below this; 1 = off
  int min_points = 10;               // smaller regions are dropped (paper: 10)
  int max_points = 0;                // larger regions are dropped; 0 = no limit
  int neighbours = 30;               // k of the k-NN growing neighbourhood
};

// Each parameter declared once; its default is PclRegionGrowingOptions{}'s.
const furnihost::ParamBinding<PclRegionGrowingOptions>& Binding() {
  using O = PclRegionGrowingOptions;
  static const auto b =
      furnihost::ParamBinding<O>()
          .Enum("normals", &O::normals, {"omp", "mls"},
                "normal estimator: PCA in a radius (NormalEstimationOMP) or MovingLeastSquares order 2")
          .Number("normal_radius_m", &O::normal_radius_m, 0.001, 10.0, "m",
                  "radius of the normal neighbourhood [m] (paper: 0.03)")
          .Number("angle_deg", &O::angle_deg, 0.0, 180.0, "deg",
                  "smoothness: max angle between normals [deg] (paper: 40)")
          .Enum("compare_to", &O::compare_to, {"seed", "neighbour"},
                "angle measured to the region's seed normal (paper) or to the growing point's (PCL default)")
          .Number("curvature_threshold", &O::curvature_threshold, 0.0, 1.0, "1",
                  "a member keeps growing the region only if its curvature is below this (1 = no test)")
          .Int("min_points", &O::min_points, 1, 1e9, "count", "regions with fewer points are dropped (paper: 10)")
          .Int("max_points", &O::max_points, 0, 2147483647.0, "count", "regions with more points are dropped; 0 = no limit")
          .Int("neighbours", &O::neighbours, 3, 10000, "count",
               "k of the k-NN neighbourhood of the growing step (PCL uses k-NN)")
          .Rule([](const O& o) {
            return o.max_points == 0 || o.max_points >= o.min_points
                       ? ""
                       : "max_points must be 0 (no limit) or >= min_points";
          });
  return b;
}

class PclRegionGrowing : public furnihost::DistinctPointsSegmenter {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit PclRegionGrowing(const nlohmann::json& p) : o_(Binding().Parse(p)) {}

  // Segment() (DistinctPointsSegmenter) passes the distinct positions: copies of a point would make
  // the library's k-d tree quadratic (see copies.hpp).

 private:
  furnihost::Segmentation SegmentDistinct(const furnihost::Scan& scan, const furnihost::RunContext& ctx) override {
    const size_t n = scan.points.size();
    furnihost::Segmentation seg = Unsegmented(n);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    if (n == 0) return seg;
    const unsigned threads = ctx.threads > 0 ? unsigned(ctx.threads)
                                             : std::max(1u, std::thread::hardware_concurrency());

    // Shift to the bounding-box centre (see the file comment).
    Eigen::AlignedBox3d box;
    for (const auto& q : scan.points)
      if (q.allFinite()) box.extend(q.cast<double>());
    const Eigen::Vector3d shift = box.isEmpty() ? Eigen::Vector3d::Zero().eval() : box.center().eval();
    pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
    cloud->resize(n);
    pcl::IndicesPtr finite(new pcl::Indices);
    finite->reserve(n);
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f q = (scan.points[i].cast<double>() - shift).cast<float>();
      (*cloud)[i].getVector3fMap() = q;
      if (q.allFinite()) finite->push_back(pcl::index_t(i));
    }
    cloud->is_dense = finite->size() == n;

    auto tree = std::make_shared<pcl::search::KdTree<pcl::PointXYZ>>();
    tree->setInputCloud(cloud, finite);

    // normals[i] belongs to input point i; NaN where PCL gives none.
    pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
    normals->resize(n);
    for (auto& nm : *normals) {
      nm.getNormalVector3fMap().setConstant(nan);
      nm.curvature = nan;
    }
    if (o_.normals == "omp") {
      pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(threads);
      ne.setInputCloud(cloud);
      ne.setIndices(finite);
      ne.setSearchMethod(tree);
      ne.setRadiusSearch(o_.normal_radius_m);
      pcl::PointCloud<pcl::Normal> out;
      ne.compute(out);  // one output per index
      for (size_t k = 0; k < finite->size(); ++k) (*normals)[(*finite)[k]] = out[k];
    } else {
      pcl::MovingLeastSquares<pcl::PointXYZ, pcl::PointNormal> mls;
      mls.setInputCloud(cloud);
      mls.setIndices(finite);
      mls.setSearchMethod(tree);
      mls.setSearchRadius(o_.normal_radius_m);
      mls.setPolynomialOrder(2);
      mls.setComputeNormals(true);
      mls.setNumberOfThreads(threads);
      pcl::PointCloud<pcl::PointNormal> out;
      mls.process(out);
      // Without upsampling each output point names the input point it was projected from.
      const auto corr = mls.getCorrespondingIndices();
      if (!corr || corr->indices.size() != out.size())
        throw furnihost::StageError("MovingLeastSquares returned no input correspondence", false);
      for (size_t k = 0; k < out.size(); ++k) {
        auto& nm = (*normals)[corr->indices[k]];
        nm.getNormalVector3fMap() = out[k].getNormalVector3fMap();
        nm.curvature = out[k].curvature;
      }
    }

    // Orient towards the sensor when it is known, else towards the scan frame's origin (PCL's
    // convention, the same in every alternative segmenter). The growing ignores the sign.
    const Eigen::Vector3d sensor =
        scan.origin ? Eigen::Vector3d(scan.origin->cast<double>()) : Eigen::Vector3d(Eigen::Vector3d::Zero());
    const Eigen::Vector3f eye = (sensor - shift).cast<float>();
    pcl::IndicesPtr usable(new pcl::Indices);
    usable->reserve(finite->size());
    for (pcl::index_t i : *finite) {
      auto& nm = (*normals)[i];
      Eigen::Vector3f v = nm.getNormalVector3fMap();
      if (!v.allFinite() || !std::isfinite(nm.curvature) || v.squaredNorm() < 1e-12f) continue;
      v.normalize();
      if (v.dot(eye - (*cloud)[i].getVector3fMap()) < 0) v = -v;
      nm.getNormalVector3fMap() = v;
      seg.normals[i] = v;
      seg.curvature[i] = nm.curvature;
      usable->push_back(i);
    }

    std::vector<pcl::PointIndices> clusters;
    if (!usable->empty()) {
      pcl::RegionGrowing<pcl::PointXYZ, pcl::Normal> rg;
      rg.setInputCloud(cloud);
      rg.setIndices(usable);
      rg.setInputNormals(normals);
      rg.setSearchMethod(tree);
      rg.setNumberOfNeighbours(unsigned(o_.neighbours));
      rg.setSmoothnessThreshold(float(o_.angle_deg * M_PI / 180.0));
      rg.setSmoothModeFlag(o_.compare_to == "neighbour");
      rg.setCurvatureTestFlag(o_.curvature_threshold < 1.0);
      rg.setCurvatureThreshold(float(o_.curvature_threshold));
      rg.setResidualTestFlag(false);
      rg.setMinClusterSize(pcl::uindex_t(o_.min_points));
      rg.setMaxClusterSize(o_.max_points > 0 ? pcl::uindex_t(o_.max_points)
                                             : std::numeric_limits<pcl::uindex_t>::max());
      rg.extract(clusters);
    }

    size_t assigned = 0;
    seg.parts.reserve(clusters.size());
    for (const auto& c : clusters) {
      furnihost::Part part;
      part.indices.assign(c.indices.begin(), c.indices.end());
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int i : part.indices) sum += scan.points[i].cast<double>();
      part.centroid = (sum / double(part.indices.size())).cast<float>();
      assigned += part.indices.size();
      seg.parts.push_back(std::move(part));
    }
    seg.discarded_points = int(n - assigned);
    spdlog::debug("pcl_region_growing: {} points, {} with normals, {} parts, {} unassigned", n,
                  usable->size(), seg.parts.size(), seg.discarded_points);
    return seg;
  }

  PclRegionGrowingOptions o_;
};

}  // namespace

FURNIHOST_PLUGIN(PclRegionGrowing, "segmenters.pcl_region_growing", "1.0.0",
                 "PCL RegionGrowing (k-NN) with NormalEstimationOMP or MovingLeastSquares normals")
