// proposals.clusters, private to the plugin: its options, the types its steps share and the
// proposer, whose steps live one concern per file:
//   clusters.cpp     the parameters and ProposeAll, the steps in order
//   spacing.cpp      the points proposed on: distinct, thinned to thin_spacing_m; their spacing
//   walls.cpp        the ceiling cap, the vertical planes (Hough) and the wall removal rules
//   components.cpp   Euclidean clusters at several radii
//   split.cpp        support splits, work tops and cuts of long clusters
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include "furnihost/hash.hpp"
#include "furnihost/plugin.hpp"
#include "shape/shape.hpp"

namespace furnihost::clusters {

// The "segs" rule's shortest wall segment [m].
constexpr float kSegsLength = 0.6f;
// Median nearest-neighbour over median 4th-nearest-neighbour distance of points strewn at random
// (Poisson) over a surface: sqrt(ln 2) / sqrt(3.67) = 0.435, rounded up; the lowest spacing the
// proposer takes per 4th-neighbour distance.
constexpr float kSpacingPerNn4 = 0.45f;
// The "all" rule's walls: a plane's inliers more than this apart along its line [m] are separate
// stretches, each a wall only if large enough itself. A doorway leaves its lintel; two rooms of a
// space on one line are metres apart; furniture on a wall's line a metre past the room's corner
// keeps its back (docs/experiments/2026-12-05-wall-stretches.md).
constexpr float kWallRunGap = 1.0f;
// thin_spacing_m measures a large scan's spacing on every point of random cells of kSpacingCell
// [m] holding about kSpacingSample of them: small cells, so that they come from all over the
// scan (2 m cells: 7 % off on a test room), large enough that few points lose their nearest
// neighbours across a cell's faces.
constexpr size_t kSpacingSample = 100000;
constexpr double kSpacingCell = 0.5;

struct ClustersOptions {
  std::vector<double> radii{2.0, 2.5, 3.5};  // clustering radii [x spacing]
  int min_points = 40;
  int max_points = 0;             // denser scans are proposed on a random subset of this many points (0 = all)
  float thin_spacing = 0.f;       // denser scans are proposed on a random subset this sparse [m] (0 = all points)
  float floor_cut = 0.04f;        // points this close to the ground are floor [m]
  float floor_flat_cut = 0.08f;   // horizontal points this close are floor too [m]
  float max_height = 2.6f;        // nothing above this is furniture [m] (capped under a ceiling)
  float split_length = 1.1f;      // clusters longer than this are also split [m]
  float split_flatness = 0.05f;   // a cut needs this height step in the top-view profile [m]
  float extend_gap = 0.10f;       // proposals floating this far above the ground get extended [m]
  float ground_snap = 0.15f;      // bottoms this close to the ground are put on it [m]
  float leak_shell = 0.10f;       // shell around a box for the surround measure [m]
  std::string adaptive = "auto";  // radius per local spacing: "auto" (with a sensor origin), "on", "off"
  int neighbours = 16;            // for normals and local spacing
  bool top_variants = true;       // work-top variants of clusters with more above a table-height level
  float top_min = 0.55f, top_max = 0.86f;  // heights a work top may have [m] (desks 0.72-0.8, counters 0.9)
  float top_cover = 0.4f;         // share of the cluster's top-view cells the work top occupies
  float top_above = 0.05f;        // share of the cluster's points more than 8 cm over it
  bool low_top_variants = false;  // low-top variants of clusters whose top-view cells mostly end at one low level
  float low_top_min = 0.35f, low_top_max = 0.9f;  // heights a low top may have [m] (nightstands, dressers)
  float low_top_cover = 0.25f;    // share of the cluster's top-view cells whose top lies at the low top
  float low_top_above = 0.05f, low_top_above_max = 0.4f;  // least and most share of its cells topping out 15 cm over it
  bool support_splits = false;    // clusters holding a support surface: also its parts without it
  float support_min = 0.35f, support_max = 1.1f;  // heights a support surface may have [m]
  float support_area = 0.22f;     // least top-view area of a support surface [m2]
  bool split_ridges = true;       // also cut in two at the strongest ridge or valley of the profile
  float fronts_length = 0.f;      // "fronts" rule: wall segments are at least this long (0 = no such rule) [m]
  std::string wall_normals = "points";  // normals the walls are found by: "points" (k-NN), "blocks", "auto", "both"
  float wall_voxel = 0.05f;       // "blocks": voxel edge [m]; each point takes its 3x3x3 voxel block's plane
  // "both": the rules whose clusters the blocks' walls give (the recogniser may use only some).
  std::vector<std::string> blocks_rules = {"all", "segs", "fronts"};

};

// Each parameter declared once; its default is ClustersOptions{}'s (clusters.cpp).
const ParamBinding<ClustersOptions>& Binding();

// A vertical plane found by the Hough transform: unit normal nv and direction d on the floor
// plane, offset r (nv . p = r), extents of its inliers along d and in height.
struct VPlane {
  Eigen::Vector2f nv, d;
  float r = 0;
  float a0 = 0, a1 = 0, h0 = 0, h1 = 0;
  std::vector<uint32_t> inliers;
};

// Boxes over a subset of the points, for counting what lies in an axis-aligned box: points
// bucketed by 25 cm floor cells.
class BoxIndex {
 public:
  BoxIndex(const Points& pts, const std::vector<uint32_t>& subset, float cell = 0.25f) : pts_(pts), cell_(cell) {
    if (subset.empty()) return;
    lo_ = pts[subset[0]].head<2>();
    Eigen::Vector2f hi = lo_;
    for (uint32_t i : subset) lo_ = lo_.cwiseMin(pts[i].head<2>()), hi = hi.cwiseMax(pts[i].head<2>());
    w_ = int((hi.x() - lo_.x()) / cell) + 1;
    h_ = int((hi.y() - lo_.y()) / cell) + 1;
    start_.assign(size_t(w_) * h_ + 1, 0);
    for (uint32_t i : subset) ++start_[Cell(pts[i]) + 1];
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    items_.resize(subset.size());
    std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
    for (uint32_t i : subset) items_[fill[Cell(pts[i])]++] = i;
  }
  template <class F>
  void ForEachIn(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, F&& f) const {
    if (items_.empty()) return;
    const int x0 = std::max(0, int(std::floor((lo.x() - lo_.x()) / cell_)));
    const int y0 = std::max(0, int(std::floor((lo.y() - lo_.y()) / cell_)));
    const int x1 = std::min(w_ - 1, int(std::floor((hi.x() - lo_.x()) / cell_)));
    const int y1 = std::min(h_ - 1, int(std::floor((hi.y() - lo_.y()) / cell_)));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const size_t c = size_t(y) * w_ + x;
        for (uint32_t k = start_[c]; k < start_[c + 1]; ++k) {
          const Eigen::Vector3f& p = pts_[items_[k]];
          if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all()) f(items_[k]);
        }
      }
  }

 private:
  size_t Cell(const Eigen::Vector3f& p) const {
    const int x = std::clamp(int((p.x() - lo_.x()) / cell_), 0, w_ - 1), y = std::clamp(int((p.y() - lo_.y()) / cell_), 0, h_ - 1);
    return size_t(y) * w_ + x;
  }
  const Points& pts_;
  float cell_;
  Eigen::Vector2f lo_ = Eigen::Vector2f::Zero();
  int w_ = 0, h_ = 0;
  std::vector<uint32_t> start_, items_;
};

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t Find(uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void Join(uint32_t a, uint32_t b) {
    a = Find(a), b = Find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  }
};

class ClusterProposer : public Proposer {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit ClusterProposer(const nlohmann::json& p) : o_(Binding().Parse(p)) {}
  // Each point's k nearest neighbours besides itself, when the host finds them with the frame.
  StageNeeds Needs() const override { return {o_.neighbours + 1}; }

  Proposals Propose(const Scan& scan, const Segmentation*, const RunContext& ctx) override;

 private:
  // spacing.cpp: the points' spacing on a random sample of cells.
  static std::vector<uint32_t> CellSample(const Points& points, const std::vector<uint32_t>& chosen, uint64_t seed);

  // The key that orders a scan's points for its random subsets: a seeded hash of the index.
  static uint64_t SubsetKey(uint64_t seed, uint32_t i) { return SplitMix64(seed ^ SplitMix64(uint64_t(i) + 0x70726f70ull)); }

  static float SampleSpacing(const Points& points);

  // clusters.cpp: the proposals on every point of `scan` (too_dense: see its definition).
  Proposals ProposeAll(const Scan& scan, float* too_dense = nullptr) const;

  // split.cpp: alternative proposals of one cluster.
  static int BusiestLevel(const std::vector<std::pair<uint64_t, int>>& level, int nb, size_t* cells);

  std::vector<std::vector<int>> SupportSplit(const Points& P, const std::vector<float>& hz, const shape::LocalShape& ls,
                                             float sp, const std::vector<int>& idx, double radius, bool adaptive) const;

  std::vector<int> LowTop(const Points& P, const std::vector<float>& hz, float sp, const std::vector<int>& idx) const;
  std::vector<int> WorkTop(const Points& P, const std::vector<float>& hz, const shape::LocalShape& ls, float sp,
                           const std::vector<int>& idx) const;

  // A radius as the proposals' rule names print it ("2.5").
  static std::string Fixed1(double v) {
    char b[16];
    std::snprintf(b, sizeof b, "%.1f", v);
    return b;
  }

  // walls.cpp: the ceiling cap, the vertical planes and the wall removal rules.
  float CeilingCap(const shape::LocalShape& ls, const std::vector<float>& hz, const std::vector<float>& area) const;

  std::vector<VPlane> VerticalPlanes(const Points& P, const Points& normals, const std::vector<float>& hz,
                                     float) const;

  // The q-quantile of v (nearest rank; 0 when v is empty).
  static float Quantile(std::vector<float> v, double q) {
    if (v.empty()) return 0.f;
    const size_t k = std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[k];
  }

  static std::array<float, 4> StretchExtent(const std::vector<std::pair<float, uint32_t>>& along,
                                            const std::vector<float>& hz, size_t b, size_t e);

  std::vector<uint8_t> WallsAll(const Points& P, const std::vector<float>& hz, const std::vector<VPlane>& planes,
                                float sp) const;

  std::vector<uint8_t> WallSegments(const Points& P, const std::vector<float>& hz, const std::vector<VPlane>& planes,
                                    float min_length) const;

  // components.cpp: Euclidean clusters at several radii.
  std::vector<std::vector<std::vector<int>>> Cluster(const Points& P, const std::vector<uint32_t>& keep,
                                                     const std::vector<float>& nn4, float sp,
                                                     const std::vector<double>& radii, bool adaptive) const;

  // split.cpp: cuts of long clusters.
  static float ProfileStep(const std::vector<float>& prof, int b, size_t* sides);

  int RidgeCentre(const std::vector<float>& prof, int b0, int b1) const;

  std::vector<std::pair<std::vector<int>, int>> SplitLong(const Points& P, const std::vector<float>& hz,
                                                          const std::vector<int>& idx) const;

  ClustersOptions o_;
};

}  // namespace furnihost::clusters
