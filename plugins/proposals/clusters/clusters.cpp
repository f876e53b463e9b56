// proposals.clusters — object proposals for real scans: the points that may be furniture
// (above the ground, walls and ceiling removed) clustered at several radii scaled to the
// scan's point spacing, long clusters split where two objects meet, clusters floating above
// the ground extended down to the supports under them.
//
// Why each step (measured on the ScanNet dev rooms; figures in docs/experiments/):
// - Radii in units of the scan's median point spacing: ScanNet's 50k-point rooms range from
//   1.4 to 3.3 cm spacing; a fixed 5 cm radius shatters the sparse ones.
// - Walls: every large vertical plane ("all" rule: > 1 m tall and > 0.8 m long, or > 1.5 m2;
//   each stretch of its inliers along its line, split where 1 m holds none, on its own: one
//   room's wall line runs on through the others of a larger space) is removed for chairs,
//   tables and sofas, which otherwise merge with the wall they touch;
//   classes made of large vertical faces (cabinets, wardrobes: their catalog models are mostly
//   taller than 1.2 m) use the "segs" rule, which removes only connected plane segments of wall
//   size (top >= 1.5 m, >= 1.2 m tall, >= 0.6 m long) so a low cabinet's front survives. An
//   optional third rule, "fronts" (fronts_length_m, off by default), also needs a segment to be
//   longer than a cabinet or wardrobe unit, so a tall cabinet's front survives too (the "segs"
//   rule takes 2.3 m wardrobes for walls). On the dev rooms, cabinets scored on "fronts" of
//   1.3 m: in-sample cabinet AP25 0.064 -> 0.102-0.116, but held out (leave one space out)
//   0.085 -> 0.085 and paper-rule AP 0.220 -> 0.176: not shipped in scannet.json.
//   The walls are found by a Hough transform over the points' normals: by default their k
//   nearest neighbours' planes; wall_normals "blocks" takes each point's 3x3x3 block of voxels
//   instead, for a raw depth camera whose range noise reaches the point spacing on far walls
//   (synthetic views at a raw Kinect's noise: 12 -> 45 walls found in 10 views, sofa AP25 0.25 ->
//   0.75; rgbd_view.json uses it). wall_normals "both" makes a second set of removals from the
//   blocks' walls, whose proposals carry the rule names "all_blocks", "segs_blocks" (and
//   "fronts_blocks"), so a recogniser can score each class on the walls that suit it (ScanNet dev,
//   held out, the blocks' walls suit cabinets; scannet.json scores its cabinets on them,
//   docs/configs.md).
// - Splits: two armchairs side by side or a chair against a table end form one cluster longer
//   than any catalog chair; it is cut at the sparsest slice near the middle, but only where the
//   top-view height profile has a gap, valley or ridge (not across a flat seat or table top),
//   and (in two, clusters too short for three) at the centre of the profile's strongest ridge or
//   valley near the middle: two armchairs meet at their armrests, a ridge of dense vertical
//   faces, so their sparsest slices lie in the flat seats (on the dev rooms chair AP25 0.536 ->
//   0.611 in-sample, held out 0.469 -> 0.517).
// - Extend down: thin legs and floor contacts are often missing in reconstructions, and the
//   objects' boxes include them.
// - The spacing the radii scale with is not taken from duplicates or twins: exact duplicates are
//   proposed on once, and the spacing is at least 0.45 x the median 4th-neighbour distance
//   (what points strewn at random give; 0.48-0.55 on the dev rooms, which it leaves alone). Each
//   point twice made every dev room propose nothing (AP 0); a second pass 2 mm off did too.
//   `thin_spacing_m` proposes a scan denser than that on a seeded random subset about that far
//   apart (scannet.json: 1.3 cm, just under its densest dev room): a density, not a count, so a
//   space several ScanNet rooms large at their density keeps every point, where a cap on the
//   point count would thin it below any room the settings were chosen on
//   (docs/experiments/2026-12-05-jitter-and-large-spaces.md).
//
// Frames: the scan's working frame (z up); heights above Scan::ground. Points are referenced
// by index into Scan::points.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <numeric>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/plugin.hpp"
#include "furnihost/voxel_index.hpp"
#include "shape/shape.hpp"

namespace furnihost {
namespace {

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

// Each parameter declared once; its default is ClustersOptions{}'s.
const ParamBinding<ClustersOptions>& Binding() {
  using O = ClustersOptions;
  static const auto b =
      ParamBinding<O>()
          .NumberList("radii", &O::radii, 0.5, 20, "1",
                      "Euclidean clustering radii in units of the scan's median point spacing; every radius gives "
                      "its own proposals (a small radius separates touching objects, a large one joins sparse ones)")
          .Int("min_points", &O::min_points, 3, 1e7, "count", "clusters with fewer points are dropped")
          .Int("max_points", &O::max_points, 0, 1e9, "count",
               "a scan with more points is proposed on a random subset of this many (seeded; the proposals hold "
               "only those points): the radii scale with the point spacing, so a scan denser than the ones the "
               "settings were chosen on (ScanNet's 50k-point rooms), or one holding each surface twice (two "
               "passes, duplicated vertices), breaks into fragments; 0 = all points")
          .Number("thin_spacing_m", &O::thin_spacing, 0, 1, "m",
                  "a scan whose point spacing (measured on its distinct points in random 0.5 m cells holding about 100k) "
                  "is below this is proposed on a random subset with about this spacing (seeded; the proposals hold "
                  "only those points): a density, unlike max_points, so a large space scanned as densely as the "
                  "rooms the settings were chosen on keeps all its points; 0 = all points")
          .Number("floor_cut_m", &O::floor_cut, 0, 1, "m", "points less than this above the ground are floor")
          .Number("floor_flat_cut_m", &O::floor_flat_cut, 0, 1, "m",
                  "horizontal points (|n_z| > 0.9) less than this above the ground are floor")
          .Number("max_height_m", &O::max_height, 0.5, 20, "m",
                  "points higher above the ground are not furniture [m]; lowered to 8 cm under a ceiling when one is seen")
          .Number("split_length_m", &O::split_length, 0.2, 20, "m",
                  "clusters whose footprint is longer (longer than any catalog chair) are also cut in 2 (and 3 past 1.7x)")
          .Number("split_flatness_m", &O::split_flatness, 0, 1, "m",
                  "a cut is kept only where the top-view height profile steps by this much (a gap, valley or ridge)")
          .Number("extend_gap_m", &O::extend_gap, 0, 2, "m",
                  "proposals whose bottom is this far above the ground get a variant down to the points under them")
          .Number("ground_snap_m", &O::ground_snap, 0, 1, "m",
                  "a bottom this close to the ground is put on it (floor contacts are not scanned)")
          .Number("surround_shell_m", &O::leak_shell, 0.01, 1, "m",
                  "shell around each box whose occupied area, relative to the box's, is the proposal's surround measure")
          .Enum("adaptive_radius", &O::adaptive, {"auto", "on", "off"},
                "scale the radius by each point's local spacing (single views thin out with range): 'auto' = when the "
                "scan has a sensor origin")
          .Int("neighbours", &O::neighbours, 4, 64, "count", "neighbours of the normal and local-spacing estimates")
          .Bool("work_top_variants", &O::top_variants,
                "a cluster holding a large horizontal level at table height with more over it (a desk under monitors) "
                "also gives the level and what is under it as a proposal")
          .Number("work_top_min_m", &O::top_min, 0, 5, "m", "lowest height of a work top (above chair seats)")
          .Number("work_top_max_m", &O::top_max, 0, 5, "m", "highest height of a work top")
          .Number("work_top_cover", &O::top_cover, 0, 1, "1",
                  "top-view cells the work top's upward-facing points occupy, as a share of those the whole cluster occupies")
          .Number("work_top_above", &O::top_above, 0, 1, "1",
                  "share of the cluster's points that must lie more than 8 cm over the work top")
          .Bool("support_splits", &O::support_splits,
                "a cluster holding a large upward-facing level between support_min_m and support_max_m (a table or "
                "desk top) also gives, as alternatives, each part of real size that remains when the level is taken "
                "out (a chair pushed under the table or standing against it, a monitor on it) and the level with the "
                "remains too small to be objects (its legs): what stands under a table top is not the table")
          .Number("support_min_m", &O::support_min, 0, 5, "m", "lowest height of a support surface")
          .Number("support_max_m", &O::support_max, 0, 5, "m", "highest height of a support surface")
          .Number("support_area_m2", &O::support_area, 0.01, 100, "m2",
                  "least top-view area of a support surface (a chair seat is about 0.2 m2)")
          .Bool("split_ridges", &O::split_ridges,
                "a long cluster (shorter than 1.7 x split_length_m) is also cut in two at the centre of the strongest "
                "ridge or valley of its top-view height profile near the middle (two armchairs meet at their armrests)")
          .Number("fronts_length_m", &O::fronts_length, 0, 20, "m",
                  "a third wall removal, 'fronts': as 'segs', but a wall segment must also be this long, so the fronts "
                  "of tall cabinets and wardrobes up to this width survive (0 = no such rule)")
          .Enum("wall_normals", &O::wall_normals, {"points", "blocks", "auto", "both"},
                "normals the vertical planes (walls) are found by: 'points' = each point's k nearest neighbours; "
                "'blocks' = the plane of its 3x3x3 block of wall_voxel_m voxels (a raw depth camera's noise at a "
                "few metres swamps k-NN normals, and the walls go unfound); 'auto' = blocks when the scan has a "
                "sensor origin; 'both' = the points' walls, and a second set of removals from the blocks' walls whose "
                "proposals' rules are named all_blocks, segs_blocks (fronts_blocks): a recogniser picks per class")
          .Number("wall_voxel_m", &O::wall_voxel, 0.005, 1, "m", "wall_normals 'blocks' and 'both': voxel edge")
          .StringList("blocks_rules", &O::blocks_rules,
                      "wall_normals 'both': the removals of the blocks' walls that give proposals, of 'all', 'segs', "
                      "'fronts' (the last only with fronts_length_m); list only those a recogniser's source names: "
                      "each costs a clustering and its proposals' scoring")
          .Rule([](const O& o) {
            for (const auto& r : o.blocks_rules)
              if (r != "all" && r != "segs" && r != "fronts")
                return "blocks_rules: '" + r + "' is not a removal rule (all, segs, fronts)";
            return std::string();
          })
          .Rule([](const O& o) { return o.radii.empty() ? "radii: give at least one clustering radius" : ""; })
          .Rule([](const O& o) {
            return o.top_max > o.top_min + 0.05f ? "" : "work_top_max_m: must exceed work_top_min_m by more than 5 cm";
          })
          .Rule([](const O& o) {
            return o.fronts_length == 0.f || o.fronts_length > kSegsLength
                       ? ""
                       : "fronts_length_m: 0 (no 'fronts' rule) or longer than the 'segs' rule's 0.6 m";
          });
  return b;
}

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

  Proposals Propose(const Scan& scan, const Segmentation*, const RunContext& ctx) override {
    const size_t n = scan.points.size();
    // The points proposed on: each distinct point once (a duplicate adds no surface, and the
    // spacing the radii scale with would shrink), then, past max_points, a random subset of them.
    std::vector<uint32_t> of;
    const size_t groups = GroupEqualPoints(scan.points, &of).size();
    std::vector<uint32_t> chosen;  // the first point of each distinct position (they come in that order)
    chosen.reserve(groups);
    for (size_t i = 0; i < n; ++i)
      if (of[i] == chosen.size()) chosen.push_back(uint32_t(i));
    const size_t distinct = chosen.size();
    // A random subset is the points whose seeded hashes of their index are the smallest (O(n); the
    // same for the same scan and seed; a smaller subset is part of a larger one).
    std::vector<std::pair<uint64_t, uint32_t>> key;
    auto smallest = [&](size_t m) {
      if (key.empty()) {
        key.resize(chosen.size());
        for (size_t k = 0; k < chosen.size(); ++k) key[k] = {SubsetKey(ctx.seed, chosen[k]), chosen[k]};
      }
      std::nth_element(key.begin(), key.begin() + long(m), key.end());
    };
    size_t m = distinct;
    // A scan with nothing to leave out (no copies, no more points than max_points, at most
    // kSpacingSample) is measured by the proposals' own spacing: one pass unless it is too dense.
    float measured = 0.f;
    if (o_.thin_spacing > 0.f && distinct == n && n <= kSpacingSample &&
        (o_.max_points <= 0 || n <= size_t(o_.max_points))) {
      Proposals out = ProposeAll(scan, &measured);
      if (measured == 0.f) return out;
    }
    if (o_.thin_spacing > 0.f && distinct >= 10) {
      // The spacing of a random subset of m points, measured on the subset's points in a random
      // choice of 0.5 m cells that hold about kSpacingSample points of the scan (all of them when
      // there are no more); m searched for where it reaches thin_spacing. No formula gives it:
      // the spacing of a random share k of a sample grows as 1/sqrt(k) for points strewn at
      // random, slower for a mesh's regular vertices, faster for clumped passes.
      const std::vector<uint32_t> cells = CellSample(scan.points, chosen, ctx.seed);
      std::vector<uint64_t> cell_key(cells.size());
      for (size_t k = 0; k < cells.size(); ++k) cell_key[k] = SubsetKey(ctx.seed, chosen[cells[k]]);
      auto spacing_of = [&](size_t count) {
        uint64_t below = ~0ull;  // the subset: the keys below the count-th smallest
        if (count < distinct) {
          smallest(count);
          below = key[count].first;
        }
        Points pts;
        for (size_t k = 0; k < cells.size(); ++k)
          if (count == distinct || cell_key[k] < below) pts.push_back(scan.points[chosen[cells[k]]]);
        return SampleSpacing(pts);
      };
      const float sp_all = measured > 0.f ? measured : spacing_of(distinct);
      float sp = sp_all;
      if (sp_all > 0.f && sp_all < o_.thin_spacing) {
        // The largest subset found at or above thin_spacing: bracketed by quarters, then 6
        // geometric bisections (about 2 % of the count).
        size_t hi = distinct, lo = distinct;
        float sp_lo = sp_all;
        while (lo > 10 && sp_lo < o_.thin_spacing) {
          hi = lo;
          lo = std::max<size_t>(10, lo / 4);
          sp_lo = spacing_of(lo);
        }
        for (int it = 0; it < 6 && hi > lo + 1; ++it) {
          const size_t mid = std::clamp<size_t>(size_t(std::sqrt(double(lo) * double(hi))), lo + 1, hi - 1);
          const float s_mid = spacing_of(mid);
          if (s_mid >= o_.thin_spacing) lo = mid, sp_lo = s_mid;
          else hi = mid;
        }
        m = lo;
        sp = sp_lo;
      }
      spdlog::debug("proposals.clusters: {} distinct points, spacing {:.4f} m (on {} of them in 0.5 m cells){}", distinct,
                    sp_all, cells.size(),
                    m < distinct ? fmt::format(": thinned to {} points, spacing {:.4f} m", m, sp) : std::string());
    }
    if (o_.max_points > 0) m = std::min(m, size_t(o_.max_points));
    if (m < chosen.size()) {
      smallest(m);
      chosen.resize(m);
      for (size_t k = 0; k < m; ++k) chosen[k] = key[k].second;
      std::sort(chosen.begin(), chosen.end());
    }
    if (chosen.size() == n) return ProposeAll(scan);
    Scan sub;  // what the proposals need of the scan; its own neighbours (the pipeline's are of all points)
    sub.source = scan.source;
    sub.origin = scan.origin;
    sub.pose = scan.pose;
    sub.frame = scan.frame;
    sub.ground = scan.ground;
    sub.points.reserve(chosen.size());
    for (uint32_t i : chosen) sub.points.push_back(scan.points[i]);
    spdlog::debug("proposals.clusters: {} points, {} distinct, proposing on {}", n, distinct, m);
    Proposals out = ProposeAll(sub);
    for (auto& q : out.items)
      for (int& i : q.indices) i = int(chosen[size_t(i)]);
    std::vector<uint8_t> removed(n, 0);  // the points left out: not reported
    if (out.removed.size() == chosen.size())
      for (size_t k = 0; k < chosen.size(); ++k) removed[chosen[k]] = out.removed[k];
    if (n >= 10) out.removed = std::move(removed);
    return out;
  }

 private:
  // The positions in `chosen` of the points that lie in a seeded random choice of kSpacingCell cells
  // holding at least kSpacingSample of them together (every position when there are no more).
  static std::vector<uint32_t> CellSample(const Points& points, const std::vector<uint32_t>& chosen, uint64_t seed) {
    std::vector<uint32_t> out;
    if (chosen.size() <= kSpacingSample) {
      out.resize(chosen.size());
      std::iota(out.begin(), out.end(), 0u);
      return out;
    }
    // Each point's cell, hashed once: the key both counts and picks by.
    const uint64_t base = SplitMix64(seed ^ 0x63656c6cull);  // "cell"
    std::vector<uint64_t> cell_of(chosen.size());
    std::unordered_map<uint64_t, size_t> count;
    for (size_t k = 0; k < chosen.size(); ++k) {
      const Eigen::Vector3f& p = points[chosen[k]];
      uint64_t h = base;
      for (int a = 0; a < 3; ++a) h = SplitMix64(h ^ uint64_t(int64_t(std::floor(double(p[a]) / kSpacingCell))));
      cell_of[k] = h;
      ++count[h];
    }
    std::vector<std::pair<uint64_t, size_t>> cells(count.begin(), count.end());
    std::sort(cells.begin(), cells.end());  // by the cells' hashes: a random order
    std::unordered_set<uint64_t> take;
    size_t total = 0;
    for (const auto& [h, c] : cells) {
      if (total >= kSpacingSample) break;
      take.insert(h);
      total += c;
    }
    out.reserve(total);
    for (size_t k = 0; k < chosen.size(); ++k)
      if (take.count(cell_of[k])) out.push_back(uint32_t(k));
    return out;
  }

  // The key that orders a scan's points for its random subsets: a seeded hash of the index.
  static uint64_t SubsetKey(uint64_t seed, uint32_t i) { return SplitMix64(seed ^ SplitMix64(uint64_t(i) + 0x70726f70ull)); }

  // The spacing of `points` as ProposeAll measures it (the nearest other point, at least 0.45 x
  // the 4th nearest; medians over every 10th point).
  static float SampleSpacing(const Points& points) {
    if (points.size() < 10) return 0.f;
    shape::KnnIndex index(points);
    const size_t q = (points.size() + 9) / 10;
    std::vector<float> nn(q), nn4(q);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, q, 256), [&](const tbb::blocked_range<size_t>& r) {
      std::vector<uint32_t> idx;
      std::vector<float> d2;
      for (size_t k = r.begin(); k != r.end(); ++k) {
        index.Query(points[k * 10], 5, idx, d2);
        // Copies of the query point (distance 0) are not its neighbours: distinct points here.
        nn[k] = d2.size() > 1 ? std::sqrt(d2[1]) : 0.f;
        nn4[k] = d2.size() > 4 ? std::sqrt(d2[4]) : 0.f;
      }
    });
    return std::max(shape::MedianSpacing(nn, 1), kSpacingPerNn4 * shape::MedianSpacing(nn4, 1));
  }

  // With `too_dense`: a scan whose spacing is below thin_spacing_m is not proposed on; its
  // spacing goes to *too_dense (left alone otherwise).
  Proposals ProposeAll(const Scan& scan, float* too_dense = nullptr) const {
    Proposals out;
    const size_t n = scan.points.size();
    if (n < 10) return out;
    // Working copy: finite points only (the readers drop the others; stay safe).
    const Points& P = scan.points;
    // The blocks' normals (when asked for) need only the points: computed beside the k-d tree,
    // whose build is serial.
    const bool both = o_.wall_normals == "both";
    const bool blocks = o_.wall_normals == "blocks" || (o_.wall_normals == "auto" && scan.origin.has_value());
    // The points' k nearest neighbours: those the pipeline found with the working frame when it
    // has them (the same up to rounding; no second search), else a k-d tree's.
    Points block_normals;
    shape::LocalShape ls;
    if (shape::CanUse(scan.neighbours.get(), P, o_.neighbours)) {
      tbb::parallel_invoke([&] { ls = shape::EstimateLocalShape(P, *scan.neighbours, o_.neighbours); },
                           [&] { if (blocks || both) block_normals = shape::BlockNormals(P, o_.wall_voxel); });
    } else {
      std::unique_ptr<shape::KnnIndex> knn_ptr;
      tbb::parallel_invoke([&] { knn_ptr = std::make_unique<shape::KnnIndex>(P); },
                           [&] { if (blocks || both) block_normals = shape::BlockNormals(P, o_.wall_voxel); });
      ls = shape::EstimateLocalShape(*knn_ptr, o_.neighbours);
    }
    // The points' spacing: the median distance to the nearest other point, but not below what the
    // 4th nearest gives for points strewn at random over the surfaces (0.45 x its median; 0.48-0.55
    // on the ScanNet dev rooms, so their spacing is the nearest neighbours'). Duplicates, twin
    // layers of two passes and clumps shorten the nearest distance without covering the surfaces
    // more densely; taken at face value they shrink every radius and break objects into fragments.
    const float sp = std::max({shape::MedianSpacing(ls.nn), kSpacingPerNn4 * shape::MedianSpacing(ls.nn4), 1e-3f});
    out.spacing = sp;
    if (too_dense && sp < o_.thin_spacing) {
      *too_dense = sp;
      return out;
    }
    std::vector<float> hz(n);
    for (size_t i = 0; i < n; ++i) hz[i] = scan.ground ? scan.ground->Above(P[i]) : P[i].z();
    std::vector<float> area(n);  // the surface each point stands for
    for (size_t i = 0; i < n; ++i) area[i] = std::pow(std::max(ls.nn[i], 0.5f * sp), 2.f);

    const float hmax = CeilingCap(ls, hz, area);
    // The walls' normals: the points' own (k nearest neighbours), or at a fixed metric scale
    // where a raw sensor's noise swamps those (single views: "auto"). With "both", a second set
    // of removals from the blocks' walls gives its own proposals, their rules suffixed "_blocks".
    const bool fronts = o_.fronts_length > kSegsLength;
    // One wall set: the removals ("all", "segs" and, with fronts_length_m > 0, "fronts") of one
    // set of vertical planes, and the points each keeps.
    struct WallSet {
      std::vector<uint8_t> all;
      std::vector<uint32_t> keep[3];
    };
    auto keep_of = [&](const std::vector<uint8_t>& wall) {
      std::vector<uint32_t> keep;
      for (size_t i = 0; i < n; ++i) {
        if (wall[i] || !(hz[i] > o_.floor_cut) || !(hz[i] < hmax)) continue;
        if (std::abs(ls.normals[i].z()) > 0.9f && hz[i] < o_.floor_flat_cut) continue;
        keep.push_back(uint32_t(i));
      }
      return keep;
    };
    auto wall_set = [&](const Points& normals) {
      WallSet w;
      const std::vector<VPlane> planes = VerticalPlanes(P, normals, hz, sp);
      w.all = WallsAll(P, hz, planes, sp);
      w.keep[0] = keep_of(w.all);
      w.keep[1] = keep_of(WallSegments(P, hz, planes, kSegsLength));
      if (fronts) w.keep[2] = keep_of(WallSegments(P, hz, planes, o_.fronts_length));
      return w;
    };
    std::vector<WallSet> sets(both ? 2 : 1);
    tbb::parallel_for(0, int(sets.size()), [&](int k) {
      sets[size_t(k)] = wall_set(k == 1 || (blocks && !both) ? block_normals : ls.normals);
    });
    out.removed.assign(n, 0);
    for (size_t i = 0; i < n; ++i) out.removed[i] = sets[0].all[i] ? 1 : hz[i] <= o_.floor_cut ? 2 : 0;

    const bool adaptive = o_.adaptive == "on" || (o_.adaptive == "auto" && scan.origin.has_value());
    struct Raw {
      std::vector<int> idx;
      std::string rule, how;
      int parent = -1;
      int set = 0;
      double radius = 0.0;  // the clustering radius [x spacing]
    };
    std::vector<Raw> raw;
    // The rules' clusterings are independent: one task each.
    const char* const rules[3] = {"all", "segs", "fronts"};
    const int nrules = fronts ? 3 : 2;
    const int ntasks = nrules * int(sets.size());
    std::vector<std::vector<std::vector<std::vector<int>>>> per_radius(static_cast<size_t>(ntasks));
    auto wanted = [&](int k) {
      return k < nrules || std::find(o_.blocks_rules.begin(), o_.blocks_rules.end(), rules[k % nrules]) !=
                               o_.blocks_rules.end();
    };
    tbb::parallel_for(0, ntasks, [&](int k) {
      if (!wanted(k)) return;
      per_radius[size_t(k)] = Cluster(P, sets[size_t(k / nrules)].keep[k % nrules], ls.nn4, sp, o_.radii, adaptive);
    });
    for (int k = 0; k < ntasks; ++k) {
      if (!wanted(k)) continue;
      const std::string rule = std::string(rules[k % nrules]) + (k >= nrules ? "_blocks" : "");
      for (size_t mi = 0; mi < o_.radii.size(); ++mi)
        for (auto& c : per_radius[size_t(k)][mi]) {
          Raw r;
          r.idx = std::move(c);
          r.rule = rule;
          r.how = rule + "/r" + Fixed1(o_.radii[mi]);
          r.set = k / nrules;
          r.radius = o_.radii[mi];
          raw.push_back(std::move(r));
        }
    }
    const size_t clusters = raw.size();
    for (size_t i = 0; i < clusters; ++i) raw[i].parent = int(i);
    // Support splits: the parts of a cluster without its support surface, and the surface with
    // its legs.
    if (o_.support_splits) {
      const size_t upto = raw.size();
      // A cluster that repeats an earlier one (another rule or radius found the same points)
      // gives the same splits: it is split once.
      std::vector<size_t> first(upto);
      {
        std::unordered_map<uint64_t, std::vector<size_t>> seen;
        for (size_t i = 0; i < upto; ++i) {
          first[i] = i;
          auto& list = seen[Fnv1a(raw[i].idx.data(), raw[i].idx.size() * sizeof(int))];
          for (size_t j : list)
            if (raw[j].idx == raw[i].idx && raw[j].radius == raw[i].radius) {
              first[i] = j;
              break;
            }
          if (first[i] == i) list.push_back(i);
        }
      }
      std::vector<std::vector<std::vector<int>>> sup(upto);
      // Only the clusters of the walls' "all" removal (those chairs and tables are scored on):
      // the "segs" removal keeps low cabinet fronts, which stand on no table top.
      tbb::parallel_for(size_t(0), upto, [&](size_t i) {
        if (first[i] == i && (raw[i].rule == "all" || raw[i].rule == "all_blocks"))
          sup[i] = SupportSplit(P, hz, ls, sp, raw[i].idx, raw[i].radius, adaptive);
      });
      for (size_t i = 0; i < upto; ++i)
        if (first[i] != i) sup[i] = sup[first[i]];
      for (size_t i = 0; i < upto; ++i)
        for (size_t k = 0; k < sup[i].size(); ++k) {
          Raw r;
          r.idx = std::move(sup[i][k]);
          r.rule = raw[i].rule;
          r.how = raw[i].how + (k == 0 ? "+support" : "+under" + std::to_string(k));
          r.parent = raw[i].parent;
          r.set = raw[i].set;
          r.radius = raw[i].radius;
          raw.push_back(std::move(r));
        }
    }
    // The clusters' cuts are independent: found in parallel, appended in cluster order.
    const size_t to_split = clusters;
    std::vector<std::vector<std::pair<std::vector<int>, int>>> parts(to_split);
    tbb::parallel_for(size_t(0), to_split, [&](size_t i) { parts[i] = SplitLong(P, hz, raw[i].idx); });
    for (size_t i = 0; i < to_split; ++i)
      for (auto& part : parts[i]) {
        Raw r;
        r.idx = std::move(part.first);
        r.rule = raw[i].rule;
        r.how = raw[i].how + "+split" + std::to_string(part.second);
        r.parent = raw[i].parent;
        r.set = raw[i].set;
        r.radius = raw[i].radius;
        raw.push_back(std::move(r));
      }
    // Work-top variants: a cluster holding a large horizontal level at table height with more
    // above it (a desk under monitors, shelves or lamps) also gives the level and what is under it.
    if (o_.top_variants) {
      const size_t upto = raw.size();
      std::vector<std::vector<int>> tops(upto);
      tbb::parallel_for(size_t(0), upto, [&](size_t i) { tops[i] = WorkTop(P, hz, ls, sp, raw[i].idx); });
      for (size_t i = 0; i < upto; ++i)
        if (!tops[i].empty()) {
          Raw r;
          r.idx = std::move(tops[i]);
          r.rule = raw[i].rule;
          r.how = raw[i].how + "+top";
          r.parent = raw[i].parent;
          r.set = raw[i].set;
          raw.push_back(std::move(r));
        }
    }
    // Boxes, then the extend-down variants of every proposal (clusters, splits and work tops).
    // Each wall set's own indexes: the columns under a proposal and its surround.
    std::vector<BoxIndex> column_index, leak_index;
    for (const WallSet& w : sets) column_index.emplace_back(P, w.keep[1]), leak_index.emplace_back(P, w.keep[0]);
    auto make = [&](const Raw& r) {
      Proposal p;
      p.indices = r.idx;
      for (int i : r.idx) p.box.extend(P[i]);
      std::vector<float> g;
      for (int i : r.idx) g.push_back(P[i].z() - hz[i]);
      std::nth_element(g.begin(), g.begin() + g.size() / 2, g.end());
      p.ground_z = g.empty() ? 0.f : g[g.size() / 2];
      p.group = r.parent;
      p.how = r.how;
      p.source = r.rule;
      return p;
    };
    // Each proposal and its variant are made on their own (in parallel), appended in order.
    const size_t base = raw.size();
    out.items.resize(base);
    std::vector<std::optional<Proposal>> extended(base);
    std::vector<int> set_of(base);
    for (size_t i = 0; i < base; ++i) set_of[i] = raw[i].set;
    tbb::parallel_for(size_t(0), base, [&](size_t i) {
      out.items[i] = make(raw[i]);
      const Proposal& p = out.items[i];
      if (p.box.min().z() - p.ground_z < o_.extend_gap) return;
      const Eigen::Vector3f lo(p.box.min().x(), p.box.min().y(), p.ground_z + 0.02f);
      const Eigen::Vector3f hi(p.box.max().x(), p.box.max().y(), p.box.min().z());
      std::vector<int> col;
      column_index[size_t(raw[i].set)].ForEachIn(lo, hi, [&](uint32_t k) { col.push_back(int(k)); });
      if (col.size() < 5) return;
      float zlo = INFINITY;
      for (int k : col) zlo = std::min(zlo, P[k].z());
      if (zlo - p.ground_z < o_.ground_snap) zlo = p.ground_z;
      Proposal e = p;
      e.indices.insert(e.indices.end(), col.begin(), col.end());
      e.box.min().z() = zlo;
      e.how += "+ext";
      extended[i] = std::move(e);
    });
    for (size_t i = 0; i < base; ++i)
      if (extended[i]) out.items.push_back(std::move(*extended[i])), set_of.push_back(raw[i].set);
    if (spdlog::should_log(spdlog::level::trace))
      for (const auto& p : out.items)
        spdlog::trace("proposals.clusters: {} {} points, box ({:.3f} {:.3f} {:.3f})-({:.3f} {:.3f} {:.3f})", p.how, p.indices.size(),
                      p.box.min().x(), p.box.min().y(), p.box.min().z(), p.box.max().x(), p.box.max().y(), p.box.max().z());
    // Surround: the occupied area in a shell around the box relative to the area inside. A
    // proposal cut out of a larger structure (a wall's leftovers, half a bed) has a high one.
    tbb::parallel_for(size_t(0), out.items.size(), [&](size_t k) {
      Proposal& p = out.items[k];
      const BoxIndex& leak = leak_index[size_t(set_of[k])];
      const Eigen::Vector3f s(o_.leak_shell, o_.leak_shell, 0.f);
      double inside = 0, outer = 0;
      leak.ForEachIn(p.box.min(), p.box.max(), [&](uint32_t i) { inside += area[i]; });
      leak.ForEachIn(p.box.min() - s, p.box.max() + s + Eigen::Vector3f(0, 0, o_.leak_shell),
                           [&](uint32_t i) { outer += area[i]; });
      p.surround = float((outer - inside) / std::max(inside, 1e-6));
    });
    return out;
  }

 private:
  // Of (top-view cell, height bin) pairs sorted by cell (`nb` bins), the window of two adjacent
  // bins that the most cells reach, each cell counted once per window; its lower bin (-1 when no
  // cell reaches any), and in *cells how many cells reach it.
  static int BusiestLevel(const std::vector<std::pair<uint64_t, int>>& level, int nb, size_t* cells) {
    std::vector<size_t> occupied(size_t(nb), 0);
    for (size_t a = 0; a < level.size();) {
      int last = -1;
      size_t e = a;
      for (; e < level.size() && level[e].first == level[a].first; ++e)
        for (int w : {level[e].second - 1, level[e].second})
          if (w > last && w >= 0 && w + 1 < nb) ++occupied[size_t(w)], last = w;
      a = e;
    }
    *cells = 0;
    int k = -1;
    for (int b = 0; b + 1 < nb; ++b)
      if (occupied[size_t(b)] > *cells) *cells = occupied[size_t(b)], k = b;
    return k;
  }

  // Support splits of cluster `idx` (clustered at `radius` spacings): nothing, or first the
  // support surface with the remains too small to be objects (min_points), then each part of
  // real size that remains when the surface is taken out. The support surface is the 4 cm
  // level between support_min_m and support_max_m above the ground whose upward-facing points
  // (|n_z| > 0.9) occupy the most top-view cells (as WorkTop's), of support_area_m2 or more;
  // its points are those within 4 cm of the level in its cells, whatever their normals (the
  // top's rounded edges). Only when some part of real size remains.
  std::vector<std::vector<int>> SupportSplit(const Points& P, const std::vector<float>& hz, const shape::LocalShape& ls,
                                             float sp, const std::vector<int>& idx, double radius, bool adaptive) const {
    constexpr float bin = 0.02f;
    const int nb = int(std::ceil((o_.support_max - o_.support_min) / bin));
    if (nb < 2 || idx.size() < size_t(2 * o_.min_points)) return {};
    const float cell = std::max(0.05f, 2.5f * sp);
    auto key = [&](const Eigen::Vector3f& p) {
      return (uint64_t(uint32_t(int32_t(std::floor(p.x() / cell)))) << 32) | uint32_t(int32_t(std::floor(p.y() / cell)));
    };
    std::vector<std::pair<uint64_t, int>> level;
    for (int i : idx) {
      const float h = hz[size_t(i)];
      if (!(std::abs(ls.normals[size_t(i)].z()) > 0.9f) || !(h >= o_.support_min) || !(h < o_.support_max)) continue;
      level.emplace_back(key(P[size_t(i)]), std::min(nb - 1, int((h - o_.support_min) / bin)));
    }
    std::sort(level.begin(), level.end());
    size_t best = 0;
    const int k = BusiestLevel(level, nb, &best);
    if (k < 0 || double(best) * cell * cell < o_.support_area) return {};
    const float lo = o_.support_min + float(k) * bin, hi = lo + 2.f * bin;
    std::unordered_set<uint64_t> top_cells;
    for (const auto& [c, b] : level)
      if (b == k || b == k + 1) top_cells.insert(c);
    std::vector<int> surface;
    std::vector<uint32_t> rest;
    for (int i : idx) {
      const float h = hz[size_t(i)];
      if (h >= lo - 0.02f && h <= hi + 0.02f && top_cells.count(key(P[size_t(i)]))) surface.push_back(i);
      else rest.push_back(uint32_t(i));
    }
    const auto parts = Cluster(P, rest, ls.nn4, sp, {radius}, adaptive).front();
    if (parts.empty()) return {};
    std::vector<std::vector<int>> out;
    out.push_back(surface);
    std::vector<uint8_t> in_part(P.size(), 0);
    for (const auto& part : parts)
      for (int i : part) in_part[size_t(i)] = 1;
    for (uint32_t i : rest)
      if (!in_part[i]) out.front().push_back(int(i));
    std::sort(out.front().begin(), out.front().end());
    for (const auto& part : parts) out.push_back(part);
    spdlog::trace("support: {} pts, level {:.2f} m, {} cells, {} surface points, {} parts", idx.size(), lo, best,
                  surface.size(), parts.size());
    return out;
  }

  // The points of cluster `idx` at or below its work top, or nothing. The work top is the 4 cm
  // level between work_top_min_m and work_top_max_m above the ground whose upward-facing points
  // (|n_z| > 0.9) occupy the most top-view cells (2.5 spacings, >= 5 cm: a count of cells, not of
  // points, so the scan's density does not matter); it must occupy work_top_cover of the cells
  // the whole cluster occupies (a desk or table top, not a shelf or an armrest), and at least
  // work_top_above of the cluster's points must lie more than 8 cm over it (else it is the top).
  std::vector<int> WorkTop(const Points& P, const std::vector<float>& hz, const shape::LocalShape& ls, float sp,
                           const std::vector<int>& idx) const {
    constexpr float bin = 0.02f;
    const int nb = int(std::ceil((o_.top_max - o_.top_min) / bin));
    if (nb < 2 || idx.size() < size_t(o_.min_points)) return {};
    const float cell = std::max(0.05f, 2.5f * sp);
    auto key = [&](const Eigen::Vector3f& p) {
      return (uint64_t(uint32_t(int32_t(std::floor(p.x() / cell)))) << 32) | uint32_t(int32_t(std::floor(p.y() / cell)));
    };
    std::vector<uint64_t> all;
    std::vector<std::pair<uint64_t, int>> level;  // (cell, bin) of the upward-facing points in range
    all.reserve(idx.size());
    for (int i : idx) {
      const Eigen::Vector3f& p = P[size_t(i)];
      all.push_back(key(p));
      const float h = hz[size_t(i)];
      if (!(std::abs(ls.normals[size_t(i)].z()) > 0.9f) || !(h >= o_.top_min) || !(h < o_.top_max)) continue;
      level.emplace_back(key(p), std::min(nb - 1, int((h - o_.top_min) / bin)));
    }
    std::sort(all.begin(), all.end());
    const size_t cells = size_t(std::unique(all.begin(), all.end()) - all.begin());
    std::sort(level.begin(), level.end());
    size_t best = 0;
    const int k = BusiestLevel(level, nb, &best);
    if (k < 0 || double(best) < o_.top_cover * double(cells)) return {};
    const float level_top = o_.top_min + float(k + 2) * bin;  // the window's upper edge
    std::vector<int> out;
    size_t above = 0;
    for (int i : idx) {
      const float h = hz[size_t(i)];
      if (h <= level_top + 0.02f) out.push_back(i);
      else if (h > level_top + 0.08f) ++above;
    }
    spdlog::trace("worktop: {} pts {} cells, level {:.2f} m {} cells, {} above", idx.size(), cells, level_top, best, above);
    if (double(above) < o_.top_above * double(idx.size()) || out.size() < size_t(o_.min_points)) return {};
    return out;
  }

  static std::string Fixed1(double v) {
    char b[16];
    std::snprintf(b, sizeof b, "%.1f", v);
    return b;
  }

  // hmax, or 8 cm below a ceiling: a horizontal level above 1.9 m holding >= 1.5 m2 of points.
  float CeilingCap(const shape::LocalShape& ls, const std::vector<float>& hz, const std::vector<float>& area) const {
    std::vector<double> a;
    for (size_t i = 0; i < hz.size(); ++i) {
      if (!(std::abs(ls.normals[i].z()) > 0.9f) || !(hz[i] > 1.9f) || hz[i] > 20.f) continue;
      const size_t b = size_t(hz[i] / 0.04f);
      if (a.size() <= b) a.resize(b + 1, 0.0);
      a[b] += area[i];
    }
    double best = 0;
    size_t k = 0;
    for (size_t b = 0; b < a.size(); ++b) {
      const double w = a[b] + (b + 1 < a.size() ? a[b + 1] : 0.0);
      if (w > best) best = w, k = b;
    }
    spdlog::debug("proposals.clusters: largest level above 1.9 m: {:.2f} m2 at {:.2f} m{}", best, float(k) * 0.04f,
                  best < 1.5 ? "" : ": ceiling");
    if (best < 1.5) return o_.max_height;
    return std::min(o_.max_height, float(k) * 0.04f - 0.08f);
  }

  // Iterative (theta, rho) Hough over the vertical-normal points: 2 deg x 4 cm bins, 3x3
  // smoothed; each peak's bin members give a line (PCA), its inliers (within 5 cm, normal
  // within 25 deg) leave the pool. Up to 400 peaks (a space of several rooms has more walls
  // than one room), planes of >= 100 inliers.
  std::vector<VPlane> VerticalPlanes(const Points& P, const Points& normals, const std::vector<float>& hz,
                                     float) const {
    const size_t n = P.size();
    std::vector<uint8_t> vert(n), avail(n);
    for (size_t i = 0; i < n; ++i) vert[i] = avail[i] = std::abs(normals[i].z()) < 0.25f;
    std::vector<VPlane> planes;
    constexpr int TB = 90;
    const float kPi = float(M_PI);
    const float cos25 = std::cos(25.f * kPi / 180.f);
    std::vector<uint32_t> idx;
    std::vector<int> tb, rb;
    // rho about the cloud's centre on the floor plane, not the frame's origin: a room 100 m
    // from its origin (a shifted survey) bins like the same room at the origin.
    Eigen::AlignedBox2f extent;
    for (const auto& p : P) extent.extend(p.head<2>());
    Eigen::Vector2f c0 = Eigen::Vector2f::Zero();
    if (!P.empty()) c0 = extent.center();
    // A point's line coordinates depend on its own normal and position only: computed once.
    std::vector<float> rho_of(n, 0.f);
    std::vector<int> tb_of(n, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        if (!vert[i]) continue;
        const Eigen::Vector3f& nn = normals[i];
        float th = std::atan2(nn.y(), nn.x());
        th = std::fmod(th + 2 * kPi, kPi);
        rho_of[i] = (P[i].x() - c0.x()) * std::cos(th) + (P[i].y() - c0.y()) * std::sin(th);
        tb_of[i] = std::min(TB - 1, int(th / kPi * TB));
      }
    });
    for (int it = 0; it < 400; ++it) {
      idx.clear();
      for (size_t i = 0; i < n; ++i)
        if (avail[i]) idx.push_back(uint32_t(i));
      if (idx.size() < 200) break;
      tb.resize(idx.size());
      rb.resize(idx.size());
      std::vector<float> rho(idx.size());
      float rmin = INFINITY, rmax = -INFINITY;
      for (size_t k = 0; k < idx.size(); ++k) {
        rho[k] = rho_of[idx[k]];
        tb[k] = tb_of[idx[k]];
        rmin = std::min(rmin, rho[k]);
        rmax = std::max(rmax, rho[k]);
      }
      // Bins on the lattice of multiples of 4 cm about c0, rho in [-K, K) bins: the line space
      // wraps like a Moebius strip (theta just below 180 deg is theta just above 0 with rho
      // negated), so a wall whose normal lies near the x axis is one peak across the wrap, as
      // it is when the scan comes turned by a quarter and its normal lies near the y axis.
      const int K = std::min(50000, int(std::ceil(std::max(std::abs(rmin), std::abs(rmax)) / 0.04f)) + 1);
      const int RB = 2 * K;
      std::vector<int> hist(size_t(TB) * RB, 0);
      for (size_t k = 0; k < idx.size(); ++k) {
        rb[k] = std::clamp(int(std::floor(rho[k] / 0.04f)) + K, 0, RB - 1);
        ++hist[size_t(tb[k]) * RB + rb[k]];
      }
      int best = -1, bt = 0, br = 0;
      for (int t = 0; t < TB; ++t)
        for (int r = 0; r < RB; ++r) {
          int s = 0;
          for (int dt = -1; dt <= 1; ++dt) {
            const int tt = t + dt;
            const bool wrap = tt < 0 || tt >= TB;
            for (int dr = -1; dr <= 1; ++dr) {
              const int rr = wrap ? RB - 1 - (r + dr) : r + dr;
              if (rr < 0 || rr >= RB) continue;
              s += hist[size_t((tt + TB) % TB) * RB + rr];
            }
          }
          if (s > best) best = s, bt = t, br = r;
        }
      if (best < 150) break;
      // The peak's members: within one bin in theta (across the wrap: rho negated) and rho.
      std::vector<uint32_t> members;
      for (size_t k = 0; k < idx.size(); ++k) {
        int dt = tb[k] - bt;
        bool wrap = false;
        if (dt > TB / 2) dt -= TB, wrap = true;
        else if (dt < -TB / 2) dt += TB, wrap = true;
        const int r = wrap ? RB - 1 - rb[k] : rb[k];
        if (std::abs(dt) <= 1 && std::abs(r - br) <= 1) members.push_back(idx[k]);
      }
      Eigen::Vector2d c = Eigen::Vector2d::Zero();
      for (uint32_t i : members) c += P[i].head<2>().cast<double>();
      c /= double(members.size());
      Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
      for (uint32_t i : members) {
        const Eigen::Vector2d d = P[i].head<2>().cast<double>() - c;
        cov += d * d.transpose();
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
      VPlane pl;
      pl.d = es.eigenvectors().col(1).cast<float>();
      pl.nv = Eigen::Vector2f(-pl.d.y(), pl.d.x());
      pl.r = float(c.cast<float>().dot(pl.nv));
      for (size_t i = 0; i < n; ++i) {
        if (!vert[i]) continue;
        if (std::abs(P[i].head<2>().dot(pl.nv) - pl.r) < 0.05f &&
            std::abs(normals[i].head<2>().dot(pl.nv)) > cos25)
          pl.inliers.push_back(uint32_t(i));
      }
      for (uint32_t i : members) avail[i] = 0;
      if (pl.inliers.size() < 100) continue;
      for (uint32_t i : pl.inliers) avail[i] = 0;
      std::vector<float> al, hh;
      for (uint32_t i : pl.inliers) al.push_back(P[i].head<2>().dot(pl.d)), hh.push_back(hz[i]);
      pl.a0 = Quantile(al, 0.01), pl.a1 = Quantile(al, 0.99);
      pl.h0 = Quantile(hh, 0.02), pl.h1 = Quantile(hh, 0.98);
      planes.push_back(std::move(pl));
    }
    return planes;
  }

  static float Quantile(std::vector<float> v, double q) {
    if (v.empty()) return 0.f;
    const size_t k = std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5));
    std::nth_element(v.begin(), v.begin() + k, v.end());
    return v[k];
  }

  // "all": every plane taller than 1 m and longer than 0.8 m, or with 1.5 m2 of inliers: the
  // points within 6 cm of it along its length (+- 5 cm), at any height.
  // A stretch [b, e) of a plane's inliers sorted along its line: its extents along it (1st and
  // 99th percentiles) and in height (2nd and 98th).
  static std::array<float, 4> StretchExtent(const std::vector<std::pair<float, uint32_t>>& along,
                                            const std::vector<float>& hz, size_t b, size_t e) {
    std::vector<float> al(e - b), hh(e - b);
    for (size_t k = b; k < e; ++k) al[k - b] = along[k].first, hh[k - b] = hz[along[k].second];
    return {Quantile(al, 0.01), Quantile(al, 0.99), Quantile(hh, 0.02), Quantile(hh, 0.98)};
  }

  // A plane's inliers are taken in runs along its line, split where kWallRunGap holds none: the
  // line of one room's wall crosses the other rooms of a larger space, where what lies on it is
  // furniture.
  std::vector<uint8_t> WallsAll(const Points& P, const std::vector<float>& hz, const std::vector<VPlane>& planes,
                                float sp) const {
    std::vector<uint8_t> wall(P.size(), 0);
    for (const VPlane& w : planes) {
      std::vector<std::pair<float, uint32_t>> along;
      along.reserve(w.inliers.size());
      for (uint32_t i : w.inliers) along.emplace_back(P[i].head<2>().dot(w.d), i);
      std::sort(along.begin(), along.end());
      std::vector<size_t> cuts{0};  // runs [cuts[r], cuts[r + 1])
      for (size_t k = 1; k < along.size(); ++k)
        if (along[k].first - along[k - 1].first > kWallRunGap) cuts.push_back(k);
      cuts.push_back(along.size());
      std::vector<std::pair<float, float>> spans;  // the wall stretches' extents along the line
      for (size_t r = 0; r + 1 < cuts.size(); ++r) {
        const size_t b = cuts[r], e = cuts[r + 1];
        const auto [a0, a1, h0, h1] = StretchExtent(along, hz, b, e);
        const bool big = (h1 - h0 > 1.0f && a1 - a0 > 0.8f) || float(e - b) * sp * sp > 1.5f;
        spdlog::debug("proposals.clusters: vertical plane n ({:.2f} {:.2f}) r {:.2f}: {:.2f} m long, {:.2f}-{:.2f} m high, "
                      "{} inliers{}", w.nv.x(), w.nv.y(), w.r, a1 - a0, h0, h1, e - b, big ? ": wall" : "");
        if (big) spans.emplace_back(a0 - 0.05f, a1 + 0.05f);
      }
      if (spans.empty()) continue;
      // One pass over the points per plane, whatever the number of its stretches.
      for (size_t i = 0; i < P.size(); ++i) {
        const Eigen::Vector2f q = P[i].head<2>();
        if (!(std::abs(q.dot(w.nv) - w.r) < 0.06f)) continue;
        const float a = q.dot(w.d);
        for (const auto& [lo, hi] : spans)
          if (a > lo && a < hi) {
            wall[i] = 1;
            break;
          }
      }
    }
    return wall;
  }

  // "segs": each plane's inliers rasterised in (along, height) cells of 10 cm, closed (3x3),
  // split into 8-connected components; a component whose top is >= 1.5 m, >= 1.2 m tall and
  // >= 0.6 m long is wall: the points within 6 cm of the plane inside its rectangle (+- 5 cm).
  // A Hough "plane" also collects collinear points of several objects across a room; only
  // connected stretches of wall size are walls.
  std::vector<uint8_t> WallSegments(const Points& P, const std::vector<float>& hz, const std::vector<VPlane>& planes,
                                    float min_length) const {
    std::vector<uint8_t> wall(P.size(), 0);
    constexpr float cell = 0.10f;
    for (const VPlane& w : planes) {
      float alo = INFINITY, hlo = INFINITY, ahi = -INFINITY, hhi = -INFINITY;
      std::vector<float> al(w.inliers.size());
      for (size_t k = 0; k < w.inliers.size(); ++k) {
        al[k] = P[w.inliers[k]].head<2>().dot(w.d);
        alo = std::min(alo, al[k]), ahi = std::max(ahi, al[k]);
        hlo = std::min(hlo, hz[w.inliers[k]]), hhi = std::max(hhi, hz[w.inliers[k]]);
      }
      // On the lattice of multiples of the cell (a line's direction may come out either way).
      alo = std::floor(alo / cell) * cell;
      hlo = std::floor(hlo / cell) * cell;
      const int W = int((ahi - alo) / cell) + 3, H = int((hhi - hlo) / cell) + 3;
      if (W <= 0 || H <= 0 || size_t(W) * size_t(H) > 4000000) continue;
      std::vector<uint8_t> occ(size_t(W) * H, 0);
      std::vector<int> ci(w.inliers.size());
      for (size_t k = 0; k < w.inliers.size(); ++k) {
        const int ia = int((al[k] - alo) / cell) + 1, ih = int((hz[w.inliers[k]] - hlo) / cell) + 1;
        ci[k] = ih * W + ia;
        occ[size_t(ci[k])] = 1;
      }
      auto morph = [&](const std::vector<uint8_t>& in, bool dilate) {
        std::vector<uint8_t> o(in.size(), 0);
        for (int y = 0; y < H; ++y)
          for (int x = 0; x < W; ++x) {
            bool any = false, all = true;
            for (int dy = -1; dy <= 1; ++dy)
              for (int dx = -1; dx <= 1; ++dx) {
                const int xx = x + dx, yy = y + dy;
                const bool v = xx >= 0 && yy >= 0 && xx < W && yy < H && in[size_t(yy) * W + xx];
                any |= v;
                all &= v;
              }
            o[size_t(y) * W + x] = dilate ? any : all;
          }
        return o;
      };
      std::vector<uint8_t> closed = morph(morph(occ, true), false);
      for (size_t c = 0; c < closed.size(); ++c) closed[c] |= occ[c];
      // 8-connected components of the closed raster.
      std::vector<int> label(closed.size(), -1);
      int labels = 0;
      std::vector<int> stack;
      for (size_t c0 = 0; c0 < closed.size(); ++c0) {
        if (!closed[c0] || label[c0] >= 0) continue;
        label[c0] = labels;
        stack.assign(1, int(c0));
        while (!stack.empty()) {
          const int c = stack.back();
          stack.pop_back();
          const int x = c % W, y = c / W;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int xx = x + dx, yy = y + dy;
              if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
              const size_t m = size_t(yy) * W + xx;
              if (closed[m] && label[m] < 0) label[m] = labels, stack.push_back(int(m));
            }
        }
        ++labels;
      }
      struct Seg {
        int n = 0, x0 = 1 << 30, x1 = -1, y0 = 1 << 30, y1 = -1;
      };
      std::vector<Seg> segs(labels);
      for (size_t k = 0; k < ci.size(); ++k) ++segs[label[size_t(ci[k])]].n;
      for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
          const int l = label[size_t(y) * W + x];
          if (l < 0) continue;
          Seg& s = segs[l];
          s.x0 = std::min(s.x0, x), s.x1 = std::max(s.x1, x), s.y0 = std::min(s.y0, y), s.y1 = std::max(s.y1, y);
        }
      for (const Seg& s : segs) {
        if (s.n < 30) continue;
        const float a0 = alo + float(s.x0 - 1) * cell, a1 = alo + float(s.x1) * cell;
        const float h0 = hlo + float(s.y0 - 1) * cell, h1 = hlo + float(s.y1) * cell;
        if (h1 - h0 < 1.2f || h1 < 1.5f || a1 - a0 < min_length) continue;
        for (size_t i = 0; i < P.size(); ++i) {
          const Eigen::Vector2f q = P[i].head<2>();
          const float along = q.dot(w.d);
          if (std::abs(q.dot(w.nv) - w.r) < 0.06f && along > a0 - 0.05f && along < a1 + 0.05f && hz[i] > h0 - 0.05f &&
              hz[i] < h1 + 0.05f)
            wall[i] = 1;
        }
      }
    }
    return wall;
  }

  // Connected components of `keep` with edges between points closer than m x spacing (or, for
  // single views, m x the larger local spacing of the two), >= min_points each, in first-point
  // order; one list per radius m of `radii`. The neighbourhoods are searched once, at the
  // largest radius, and every pair joins the components of each radius it is within (a
  // component's partition, hence its list, does not depend on the order the pairs come in).
  std::vector<std::vector<std::vector<int>>> Cluster(const Points& P, const std::vector<uint32_t>& keep,
                                                     const std::vector<float>& nn4, float sp,
                                                     const std::vector<double>& radii, bool adaptive) const {
    const size_t R = radii.size();
    std::vector<std::vector<std::vector<int>>> out(R);
    if (keep.empty()) return out;
    // Exact duplicates are one point for the neighbourhood search (a (0, 0, 0) flood stays linear).
    std::unordered_map<uint64_t, uint32_t> first;
    std::vector<uint32_t> rep(keep.size());
    Points uniq;
    std::vector<float> lsp;
    first.reserve(keep.size());
    for (size_t k = 0; k < keep.size(); ++k) {
      const Eigen::Vector3f& p = P[keep[k]];
      uint32_t bits[3];
      std::memcpy(bits, p.data(), 12);
      const uint64_t h = (uint64_t(bits[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(bits[1]) * 0xC2B2AE3D27D4EB4Full) ^
                         (uint64_t(bits[2]) * 0x165667B19E3779F9ull);
      auto [it, fresh] = first.try_emplace(h, uint32_t(uniq.size()));
      if (fresh || uniq[it->second] != p) {
        if (!fresh) it->second = uint32_t(uniq.size());  // a hash clash: keep both
        uniq.push_back(p);
        lsp.push_back(nn4[keep[k]]);
      }
      rep[k] = it->second;
    }
    // Per radius: the search radius and the base edge length, as a search of its own would use.
    std::vector<float> ms(R), rmax(R), r2(R), base(R);
    const float q99 = adaptive ? Quantile(lsp, 0.99) : 0.f;
    float reach = 0.f;
    for (size_t a = 0; a < R; ++a) {
      const float m = float(radii[a]);
      ms[a] = m;
      rmax[a] = m * sp;
      if (adaptive) rmax[a] = std::max(rmax[a], m * q99);
      r2[a] = rmax[a] * rmax[a];
      base[a] = m * sp;
      reach = std::max(reach, rmax[a]);
    }
    std::vector<UnionFind> uf(R, UnionFind(uniq.size()));
    auto join = [&](uint32_t i, uint32_t j, float d2) {
      for (size_t a = 0; a < R; ++a) {
        if (!(d2 < r2[a])) continue;
        const float lim = adaptive ? std::max(base[a], ms[a] * std::max(lsp[i], lsp[j])) : base[a];
        if (d2 < lim * lim) uf[a].Join(i, j);
      }
    };
    // Single views: the edge of a pair grows with the sparser point's local spacing, so the
    // search reach is set by the sparsest points (the 99th percentile), while nearly every pair
    // of the dense majority is far shorter. Two searches find the same pairs: every pair within
    // the reach of points no sparser than the 90th percentile, then every pair within the full
    // reach that has a sparser point, searched from that point.
    float near_reach = reach;
    float sparse_from = INFINITY;
    if (adaptive) {
      sparse_from = Quantile(lsp, 0.9);
      near_reach = 0.f;
      for (size_t a = 0; a < R; ++a) near_reach = std::max(near_reach, std::min(rmax[a], std::max(base[a], ms[a] * sparse_from)));
      if (!(near_reach < reach)) near_reach = reach, sparse_from = INFINITY;
    }
    // Every pair once: the later slots of a point's own cell and the cells after it (cells are
    // numbered in key order). Joins in any order give the same components (a root is always its
    // component's smallest index), and half the distances of visiting all 27 cells from both ends.
    {
      VoxelIndex index;
      index.Build(uniq, near_reach);
      const float reach2 = near_reach * near_reach;
      for (int c = 0; c < index.NumCells(); ++c) {
        for (int s = index.cell_start[c]; s < index.cell_start[c + 1]; ++s) {
          const uint32_t i = index.order[size_t(s)];
          const float px = index.x[size_t(s)], py = index.y[size_t(s)], pz = index.z[size_t(s)];
          for (int k = index.nb_start[c]; k < index.nb_start[c + 1]; ++k) {
            const int nc = index.nb[size_t(k)];
            if (nc < c) continue;
            for (int t = nc == c ? s + 1 : index.cell_start[nc]; t < index.cell_start[nc + 1]; ++t) {
              const float dx = index.x[size_t(t)] - px, dy = index.y[size_t(t)] - py, dz = index.z[size_t(t)] - pz;
              const float d2 = dx * dx + dy * dy + dz * dz;
              if (d2 < reach2) join(i, index.order[size_t(t)], d2);
            }
          }
        }
      }
    }
    if (sparse_from < INFINITY) {
      VoxelIndex index;
      index.Build(uniq, reach);
      const float reach2 = reach * reach;
      for (int c = 0; c < index.NumCells(); ++c)
        for (int s = index.cell_start[c]; s < index.cell_start[c + 1]; ++s) {
          const uint32_t i = index.order[size_t(s)];
          if (!(lsp[i] > sparse_from)) continue;
          const float px = index.x[size_t(s)], py = index.y[size_t(s)], pz = index.z[size_t(s)];
          for (int k = index.nb_start[c]; k < index.nb_start[c + 1]; ++k) {
            const int nc = index.nb[size_t(k)];
            for (int t = index.cell_start[nc]; t < index.cell_start[nc + 1]; ++t) {
              if (t == s) continue;
              const float dx = index.x[size_t(t)] - px, dy = index.y[size_t(t)] - py, dz = index.z[size_t(t)] - pz;
              const float d2 = dx * dx + dy * dy + dz * dz;
              if (d2 < reach2) join(i, index.order[size_t(t)], d2);
            }
          }
        }
    }
    for (size_t a = 0; a < R; ++a) {
      std::unordered_map<uint32_t, size_t> slot;
      std::vector<std::vector<int>> groups;
      for (size_t k = 0; k < keep.size(); ++k) {
        const uint32_t root = uf[a].Find(rep[k]);
        auto [it, fresh] = slot.try_emplace(root, groups.size());
        if (fresh) groups.emplace_back();
        groups[it->second].push_back(int(keep[k]));
      }
      for (auto& g : groups)
        if (int(g.size()) >= o_.min_points) out[a].push_back(std::move(g));
    }
    return out;
  }

  // Cuts of a cluster longer than split_length along its footprint's length: 2 parts (and 3
  // past 1.7 x split_length), each cut at the sparsest 5 cm slice within a third of a part of
  // the nominal cut, kept only where the top-view height profile there steps by split_flatness
  // from the profile 20-25 cm to either side. Returns (part, k) pairs.
  // How far slice b of a top-view profile stands above (> 0) or below its sides: the median of
  // the finite slices 4 and 5 away on either side (how many in *sides; 0 when there is none).
  static float ProfileStep(const std::vector<float>& prof, int b, size_t* sides) {
    const int nb = int(prof.size());
    std::vector<float> side;
    for (int x : {b - 5, b - 4, b + 4, b + 5})
      if (x >= 0 && x < nb && std::isfinite(prof[size_t(x)])) side.push_back(prof[size_t(x)]);
    *sides = side.size();
    return side.empty() ? 0.f : prof[size_t(b)] - Quantile(side, 0.5);
  }

  // The centre slice of the strongest run of slices in [b0, b1) whose profile stands above (a
  // ridge) or below (a valley) the median of its sides (4-5 slices away) by split_flatness or
  // more; strength = the run's summed difference. -1 when there is none.
  int RidgeCentre(const std::vector<float>& prof, int b0, int b1) const {
    const int nb = int(prof.size());
    std::vector<float> d(size_t(nb), 0.f);
    for (int b = b0; b < b1; ++b) {
      if (!std::isfinite(prof[size_t(b)])) continue;
      size_t sides = 0;
      const float v = ProfileStep(prof, b, &sides);
      if (sides >= 2 && std::abs(v) >= o_.split_flatness) d[size_t(b)] = v;
    }
    int best = -1;
    float strength = 0.f;
    for (int b = b0; b < b1;) {
      if (d[size_t(b)] == 0.f) {
        ++b;
        continue;
      }
      int e = b;
      float sum = 0.f;
      while (e < b1 && d[size_t(e)] != 0.f && (d[size_t(e)] > 0.f) == (d[size_t(b)] > 0.f)) sum += std::abs(d[size_t(e)]), ++e;
      if (sum > strength) strength = sum, best = (b + e - 1) / 2;
      b = e;
    }
    return best;
  }

  std::vector<std::pair<std::vector<int>, int>> SplitLong(const Points& P, const std::vector<float>& hz,
                                                          const std::vector<int>& idx) const {
    std::vector<std::pair<std::vector<int>, int>> out;
    if (idx.size() < 60) return out;
    std::vector<Eigen::Vector2f> xy(idx.size());
    for (size_t k = 0; k < idx.size(); ++k) xy[k] = P[idx[k]].head<2>();
    const shape::Footprint f = shape::OrientedFootprint(xy);
    if (f.length < o_.split_length) return out;
    const Eigen::Vector2f ax(std::cos(f.yaw), std::sin(f.yaw)), ay(-std::sin(f.yaw), std::cos(f.yaw));
    std::vector<float> u(idx.size()), v(idx.size());
    float vmin = INFINITY;
    for (size_t k = 0; k < idx.size(); ++k) {
      u[k] = (xy[k] - f.center).dot(ax);
      v[k] = (xy[k] - f.center).dot(ay);
      vmin = std::min(vmin, v[k]);
    }
    const float u0 = Quantile(u, 0.01), u1 = Quantile(u, 0.99);
    // Slices on the lattice of multiples of 5 cm about the footprint's centre, the outer 1 %
    // clamped into the end slices at both ends: the same slices when the footprint's axis
    // comes out the other way (a turned scan).
    constexpr float bin = 0.05f;
    const int B0 = int(std::floor(u0 / bin)), nb = std::max(1, int(std::floor(u1 / bin)) - B0 + 1);
    const int V0 = int(std::floor(vmin / bin));
    std::vector<int> iu(idx.size()), iv(idx.size());
    int vmax_bin = 0;
    for (size_t k = 0; k < idx.size(); ++k) {
      iu[k] = std::clamp(int(std::floor(u[k] / bin)) - B0, 0, nb - 1);
      iv[k] = int(std::floor(v[k] / bin)) - V0;
      vmax_bin = std::max(vmax_bin, iv[k]);
    }
    // Points per slice, each shared linearly between the two nearest slice centres: a point
    // moved by a rounding error moves the counts by as little, so the sparsest slice does not
    // jump 5 cm when the scan comes in another frame.
    std::vector<double> count(nb, 0.0);
    for (size_t k = 0; k < idx.size(); ++k) {
      const double t = std::clamp(double(u[k]) / bin - 0.5 - B0, 0.0, double(nb - 1));
      const int b = std::min(int(t), nb - 1);
      const double f = t - b;
      count[b] += 1.0 - f;
      if (b + 1 < nb) count[b + 1] += f;
    }
    // Per 5 cm slice: the median of its columns' top heights (above the cluster's ground).
    std::vector<float> g;
    for (int i : idx) g.push_back(P[i].z() - hz[i]);
    std::nth_element(g.begin(), g.begin() + g.size() / 2, g.end());
    const float g0 = g[g.size() / 2];
    std::unordered_map<int64_t, float> top;
    for (size_t k = 0; k < idx.size(); ++k) {
      const int64_t key = int64_t(iu[k]) * (vmax_bin + 1) + iv[k];
      const float h = P[idx[k]].z() - g0;
      auto [it, fresh] = top.try_emplace(key, h);
      if (!fresh) it->second = std::max(it->second, h);
    }
    std::vector<std::vector<float>> slice(nb);
    for (const auto& [key, h] : top) slice[size_t(key / (vmax_bin + 1))].push_back(h);
    std::vector<float> prof(nb, NAN);
    for (int b = 0; b < nb; ++b)
      if (!slice[b].empty()) prof[b] = Quantile(slice[b], 0.5);
    std::vector<int> ks = {2};
    if (f.length >= 1.7f * o_.split_length) ks.push_back(3);
    auto mid = [&](int b) { return (float(b + B0) + 0.5f) * bin; };
    // A cut is kept only where the top-view profile steps (a gap, valley or ridge).
    auto steps = [&](float c) {
      const int b = int(std::floor(c / bin)) - B0;
      if (b < 0 || b >= nb || !std::isfinite(prof[b])) return true;
      size_t sides = 0;
      const float step = ProfileStep(prof, b, &sides);
      return sides == 0 || std::abs(step) >= o_.split_flatness;
    };
    auto emit = [&](const std::vector<float>& cuts, int k) {
      std::vector<float> edges = {-INFINITY};
      edges.insert(edges.end(), cuts.begin(), cuts.end());
      edges.push_back(INFINITY);
      for (size_t e = 0; e + 1 < edges.size(); ++e) {
        std::vector<int> part;
        for (size_t q = 0; q < idx.size(); ++q)
          if (u[q] >= edges[e] && u[q] < edges[e + 1]) part.push_back(idx[q]);
        if (part.size() >= 30) out.emplace_back(std::move(part), k);
      }
    };
    for (int k : ks) {
      // Per nominal cut (j / k of the length), the sparse slices within a third of a part of
      // it: the sparsest, and for a cut in two also the next sparse local minimum when it is
      // nearly as sparse (within 25 % + 2 points): of two near-equal gaps either may be the
      // one between the objects, and which is the sparser is decided by a few points.
      std::vector<std::vector<float>> options(size_t(k - 1));
      for (int j = 1; j < k; ++j) {
        const float c = u0 + (u1 - u0) * float(j) / float(k), w = (u1 - u0) / float(3 * k);
        const int b0 = std::max(int(std::floor((c - w) / bin)) - B0, 0);
        const int b1 = std::min(int(std::floor((c + w) / bin)) - B0 + 1, nb);
        if (b1 <= b0) {
          options[size_t(j - 1)].push_back(c);
          continue;
        }
        std::vector<int> minima;
        for (int b = b0; b < b1; ++b)
          if ((b == b0 || count[b] <= count[b - 1]) && (b + 1 == b1 || count[b] <= count[b + 1])) minima.push_back(b);
        // Sparsest first; of equally sparse ones the nearest to the nominal cut.
        std::sort(minima.begin(), minima.end(), [&](int a, int b) {
          if (count[a] != count[b]) return count[a] < count[b];
          return std::abs(mid(a) - c) < std::abs(mid(b) - c);
        });
        auto& opt = options[size_t(j - 1)];
        opt.push_back(mid(minima.front()));
        if (k == 2)
          for (size_t m = 1; m < minima.size(); ++m)
            if (count[minima[m]] <= 1.25 * count[minima.front()] + 2.0 && std::abs(minima[m] - minima.front()) >= 2) {
              opt.push_back(mid(minima[m]));
              break;
            }
        // For a cut in two of a cluster too short for three objects, also the centre of the
        // strongest ridge or valley of the profile in the window: where two armchairs meet,
        // their armrests make a dense ridge (vertical faces), so the sparsest slice lies in a
        // seat, whose flat profile refuses the cut.
        if (k == 2 && o_.split_ridges && f.length < 1.7f * o_.split_length) {
          const int r = RidgeCentre(prof, b0, b1);
          if (r >= 0 && std::none_of(opt.begin(), opt.end(), [&](float x) { return std::abs(x - mid(r)) < 1.5f * bin; }))
            opt.push_back(mid(r));
        }
      }
      if (k == 2) {
        for (float c : options[0])
          if (steps(c)) emit({c}, k);
      } else {
        std::vector<float> cuts;
        for (const auto& o : options) cuts.push_back(o.front());
        if (std::all_of(cuts.begin(), cuts.end(), steps)) emit(cuts, k);
      }
    }
    return out;
  }

  ClustersOptions o_;
};

}  // namespace
}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::ClusterProposer, "proposals.clusters", "1.7.0",
                 "object proposals: ground, walls and ceiling removed, Euclidean clusters at radii scaled to the scan's "
                 "point spacing, long clusters split, floating ones extended to the ground")
