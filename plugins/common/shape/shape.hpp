// Point-cloud measurements shared by plugins (proposals, recognisers). Units: metres; clouds
// in the scan's working frame (z up). Shapes: N points; per-point outputs have N entries.
#pragma once
#include <Eigen/Core>
#include <array>
#include <memory>
#include <string>
#include <optional>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::shape {

// k nearest neighbours over a fixed cloud (a nanoflann k-d tree; the cloud is referenced, not
// copied, and must outlive the index).
class KnnIndex {
 public:
  explicit KnnIndex(const Points& points);
  ~KnnIndex();
  KnnIndex(const KnnIndex&) = delete;
  KnnIndex& operator=(const KnnIndex&) = delete;
  // The k nearest points to q (q itself included when it is in the cloud), nearest first.
  void Query(const Eigen::Vector3f& q, int k, std::vector<uint32_t>& index, std::vector<float>& dist2) const;
  const Points& Cloud() const { return points_; }
  // Every point index once, in the tree's leaf order (points close in space close in the
  // list): queries issued in this order reuse the tree's memory.
  std::vector<uint32_t> LeafOrder() const;

 private:
  struct Impl;
  const Points& points_;
  std::unique_ptr<Impl> impl_;
};

// Per point: the unit normal of the plane fitted (PCA) to its k nearest neighbours (sign
// arbitrary), and the distance to its nearest and to its 4th-nearest other point (the local
// point spacing; 0 for duplicates). Parallel (TBB), deterministic.
struct LocalShape {
  Points normals;
  std::vector<float> nn;   // nearest other point [m]
  std::vector<float> nn4;  // 4th nearest other point [m]
};
LocalShape EstimateLocalShape(const KnnIndex& index, int k = 16);
// The same from the neighbours the pipeline found with the working frame (ScanNeighbours; the
// distances recomputed in this frame), without a search of its own. Only when CanUse.
bool CanUse(const ScanNeighbours* neighbours, const Points& points, int k);
LocalShape EstimateLocalShape(const Points& points, const ScanNeighbours& neighbours, int k = 16);

// Per point: the unit normal (sign arbitrary; +z where undefined) of the plane fitted (PCA) to
// the points of its voxel (edge `voxel` [m], anchored at the origin) and the 26 voxels around it:
// a normal at a fixed metric scale of ~1.5 voxels, for scans whose noise swamps k-nearest-
// neighbour normals (a raw depth camera at a few metres). O(N), parallel, deterministic.
// Not the ground's EstimateVoxelNormals (a plane through the occupied voxels' centroids, each
// voxel one vote): a noisy wall is a slab two or three voxels thick, whose sparse fringe voxels
// then count as much as its dense middle; here every point counts once (the test room of
// Clusters.WallsOfANoisySensorAreFoundByBlockNormals: 97 % of the walls found, 92 % by centroids).
Points BlockNormals(const Points& points, float voxel);

// Median of `nn` over every `stride`-th point, duplicates (0) left out: the scan's point
// spacing [m] (ScanNet's 50k-point rooms: 1.4-3.3 cm). 0 when there is nothing to measure.
float MedianSpacing(const std::vector<float>& nn, size_t stride = 10);

// The oriented footprint of points on the floor plane: length >= width [m], yaw [rad] of the
// length's direction, centre; extents between the 1st and 99th percentiles along the axes of
// the minimum-area rectangle over the convex hull (rotating calipers), so stray points do not
// set the size. Fewer than 5 points: their axis-aligned extents.
// The rectangle along the frame's axes is kept unless another is smaller by more than
// `axis_margin` of its area: in a scan's canonical frame the axes are the walls' directions,
// which most furniture follows, and of near-equal rectangles (an L-shaped sofa, a ragged
// outline) which one is smallest is decided by a few points.
struct Footprint {
  float length = 0.f, width = 0.f, yaw = 0.f;
  Eigen::Vector2f center = Eigen::Vector2f::Zero();
};
Footprint OrientedFootprint(const std::vector<Eigen::Vector2f>& xy, float axis_margin = 0.1f);

// Top-view height profile: the points binned into `cell` x `cell` columns on the floor plane,
// each column's highest point taken as a share of `top` (its height above the ground / top,
// clamped to [0, 1)), the columns' shares histogrammed into kProfileBins bins and normalised.
// A chair puts its back in the top bins and its seat in the middle, a table nearly all in the
// top bin, a sofa two levels. `heights`: per point height above the ground.
constexpr int kProfileBins = 20;
using Profile = std::array<float, kProfileBins>;
Profile TopViewProfile(const std::vector<Eigen::Vector2f>& xy, const std::vector<float>& heights, float top,
                       float cell = 0.05f);
// 1-D earth mover's distance of two profiles on [0, 1] (bin width 1 / kProfileBins).
float ProfileDistance(const Profile& a, const Profile& b);

// Which of `points` (dense surface samples) a sensor at any of `eyes` sees: per eye, a
// spherical depth buffer of `pixel` radians; a sample is seen when it lies within `tolerance`
// [m] of its pixel's nearest depth.
std::vector<uint8_t> VisibleFrom(const Points& points, const Points& eyes, float pixel = 0.01f, float tolerance = 0.03f);

// Eye points around an object standing at the origin (its bounding-box bottom centre) of
// extents `size`: `n` azimuths at `distance` beyond the footprint's half-diagonal, `height`
// above the floor (a person's or robot's sensor).
Points EyesAround(const Eigen::Vector3f& size, float height = 1.4f, float distance = 1.5f, int n = 8);

// --- Recognisers of proposals (voters.catalog_shape, voters.esf_catalog) ---

// 3D IoU of two axis-aligned boxes (0 when they do not overlap).
float BoxIou(const Eigen::AlignedBox3f& a, const Eigen::AlignedBox3f& b);

// Non-maximum suppression of one class: `candidates` (indices into `proposals` and `score`) by
// descending score, ties in their given order; each is kept unless its box overlaps a kept one
// by an IoU above `max_iou`. With `whole_ratio` > 0, a box that holds >= 90 % of a kept box and is
// at least `whole_ratio` times its volume is not suppressed by it: the kept one may be a fragment
// of the object the larger one covers. Returns the kept indices, best first.
std::vector<size_t> SuppressOverlaps(std::vector<size_t> candidates, const std::vector<float>& score,
                                     const std::vector<Proposal>& proposals, float max_iou, float whole_ratio = 0.f);

// The hypothesis that proposal `p` (number `index` of scene `scene`, footprint `f`) is of class
// `cls` with `score`: the proposal's box (world frame through the scan's `pose`; upright poses
// keep it upright), accepted when score >= threshold (its "score" check), and the
// model `model_id` standing on the ground at the footprint's centre, its width along the
// footprint's length when the model is wider than deep (`model_wide`), turned further by `turn`
// [rad] (TurnToMatchTop).
Hypothesis ProposalHypothesis(const std::string& cls, float score, float threshold, const Proposal& p, int index,
                              int scene, const Footprint& f, const std::string& model_id, bool model_wide,
                              const Eigen::Isometry3f& pose, float turn = 0.f);

// The yaw at which a model stands on footprint `f` (working frame): its x axis along the
// footprint's length when `model_wide`, else across it; modulo a half turn.
float ModelYaw(const Footprint& f, bool model_wide);

// The centre of the points' top quarter (heights `h` above the ground of at least 3/4 of
// `height`, the proposal's): nullopt when fewer than 10 points stand there.
std::optional<Eigen::Vector2f> TopQuarterCentre(const std::vector<Eigen::Vector2f>& xy, const std::vector<float>& h,
                                                float height);

// The further turn [rad] of a model stood at ModelYaw that puts its high part where the points'
// high part (`top_centre`, TopQuarterCentre) is: `model_top` is where the model's top quarter
// stands in its frame over its x and y extents (`model_size_xy`). A half turn is always a
// candidate, quarter turns when the model's footprint is near square (its sides within 20 %: the
// footprint's length may be either). A back (a chair's, a sofa's) tells the model's way round;
// where either top quarter is central (a table, a cabinet), 0.
float TurnToMatchTop(const Footprint& f, bool model_wide, const Eigen::Vector2f& model_top,
                     const Eigen::Vector2f& model_size_xy, const Eigen::Vector2f& top_centre);

}  // namespace furnihost::shape
