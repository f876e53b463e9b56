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
//   rule takes 2.3 m wardrobes for walls); held out (leave one space out) on the dev rooms it
//   does not help cabinets, so scannet.json does not use it.
//   The walls are found by a Hough transform over the points' normals: by default their k
//   nearest neighbours' planes; wall_normals "blocks" takes each point's 3x3x3 block of voxels
//   instead, for a raw depth camera whose range noise reaches the point spacing on far walls,
//   where k-NN normals leave most walls unfound (rgbd_view.json uses it). wall_normals "both"
//   makes a second set of removals from the blocks' walls, whose proposals carry the rule names
//   "all_blocks", "segs_blocks" (and "fronts_blocks"), so a recogniser can score each class on
//   the walls that suit it (ScanNet dev, held out, the blocks' walls suit cabinets; scannet.json
//   scores its cabinets on them, docs/configs.md).
// - Splits: two armchairs side by side or a chair against a table end form one cluster longer
//   than any catalog chair; it is cut at the sparsest slice near the middle, but only where the
//   top-view height profile has a gap, valley or ridge (not across a flat seat or table top),
//   and (in two, clusters too short for three) at the centre of the profile's strongest ridge or
//   valley near the middle: two armchairs meet at their armrests, a ridge of dense vertical
//   faces, so their sparsest slices lie in the flat seats.
// - Extend down: thin legs and floor contacts are often missing in reconstructions, and the
//   objects' boxes include them.
// - The spacing the radii scale with is not taken from duplicates or twins: exact duplicates are
//   proposed on once, and the spacing is at least 0.45 x the median 4th-neighbour distance
//   (what points strewn at random give; the dev rooms lie above it and keep their own): a
//   scan holding each point twice, or a second pass 2 mm off, would otherwise propose nothing.
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
#include "clusters.hpp"

namespace furnihost::clusters {

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
          .Bool("low_top_variants", &O::low_top_variants,
                "a cluster whose top-view cells mostly end at one level between low_top_min_m and low_top_max_m, "
                "a few reaching higher (a nightstand or dresser with a lamp on it), also gives what is at or under "
                "that level as a proposal of its own rule, the cluster's rule suffixed '_low' (e.g. all_low), so "
                "only the classes whose source names it are scored on it; found from the cells' highest points, "
                "not from normals (a raw depth camera's noise tilts the normals of a small top)")
          .Number("low_top_min_m", &O::low_top_min, 0, 5, "m", "lowest height of a low top")
          .Number("low_top_max_m", &O::low_top_max, 0, 5, "m", "highest height of a low top")
          .Number("low_top_cover", &O::low_top_cover, 0, 1, "1",
                  "top-view cells (2.5 spacings, >= 5 cm) whose highest point lies at the low top (a 4 cm level), "
                  "as a share of those the whole cluster occupies")
          .Number("low_top_above", &O::low_top_above, 0, 1, "1",
                  "share of the cluster's top-view cells whose highest point lies more than 15 cm over the low top "
                  "(what stands on it; at least one cell)")
          .Number("low_top_above_max", &O::low_top_above_max, 0, 1, "1",
                  "most share of the cluster's top-view cells over the low top (more: a tall object with a shelf, "
                  "not a low one with a lamp on it)")
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
          .Rule([](const O& o) {
            return o.low_top_max > o.low_top_min + 0.05f ? "" : "low_top_max_m: must exceed low_top_min_m by more than 5 cm";
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

// With `too_dense`: a scan whose spacing is below thin_spacing_m is not proposed on; its
// spacing goes to *too_dense (left alone otherwise).
Proposals ClusterProposer::ProposeAll(const Scan& scan, float* too_dense) const {
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
  // Low-top variants: a cluster whose cells mostly end at one low level with a few higher (a
  // nightstand under a lamp) also gives what is at or under the level, under a rule of its own.
  if (o_.low_top_variants) {
    const size_t upto = raw.size();
    std::vector<std::vector<int>> lows(upto);
    tbb::parallel_for(size_t(0), upto, [&](size_t i) { lows[i] = LowTop(P, hz, sp, raw[i].idx); });
    for (size_t i = 0; i < upto; ++i)
      if (!lows[i].empty()) {
        Raw r;
        r.idx = std::move(lows[i]);
        r.rule = raw[i].rule + "_low";
        r.how = raw[i].how + "+low";
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

}  // namespace furnihost::clusters

FURNIHOST_PLUGIN(furnihost::clusters::ClusterProposer, "proposals.clusters", "1.8.1",
                 "object proposals: ground, walls and ceiling removed, Euclidean clusters at radii scaled to the scan's "
                 "point spacing, long clusters split, floating ones extended to the ground")
