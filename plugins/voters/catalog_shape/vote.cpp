// voters.catalog_shape: every proposal scored against every class's catalog models by size and
// top-view profile, one hypothesis per proposal and plausible class, non-maximum suppressed (Vote).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <map>
#include <set>
#include <tuple>
#include <unordered_map>

#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/plugin.hpp"
#include "shape/shape.hpp"
#include "catalog_shape.hpp"

namespace furnihost::catalog_shape {

namespace {

float Pen(float d, float small, float big) {
  const float s = d < 0 ? small : big;
  return d * d / (2 * s * s);
}

// The extra energy of a model hung with its bottom B above the ground: below the lowest mount.
float Hung(float B, const ClassParams& cp) {
  const float d = std::max(cp.mount_bottom - B, 0.f) / cp.bottom;
  return 0.5f * d * d;
}

// Per proposal: the first proposal with exactly its points (in order), box, ground and surround
// (itself when none before it has them).
std::vector<size_t> SameAsEarlier(const std::vector<Proposal>& items) {
  std::vector<size_t> same(items.size());
  std::unordered_map<uint64_t, std::vector<size_t>> by_hash;
  for (size_t i = 0; i < items.size(); ++i) {
    const Proposal& p = items[i];
    const uint64_t h = Fnv1a(p.indices.data(), p.indices.size() * sizeof(int));
    same[i] = i;
    auto& list = by_hash[h];
    for (size_t j : list) {
      const Proposal& q = items[j];
      if (q.indices == p.indices && q.box.min() == p.box.min() && q.box.max() == p.box.max() &&
          q.ground_z == p.ground_z && q.surround == p.surround) {
        same[i] = j;
        break;
      }
    }
    if (same[i] == i) list.push_back(i);
  }
  return same;
}

// The floor cells of a scan that hold ground-level points (within 3 cm of the ground).
class FloorCells {
 public:
  FloorCells() = default;
  explicit FloorCells(const Scan& scan) {
    if (!scan.ground) return;
    for (const auto& p : scan.points)
      if (std::abs(scan.ground->Above(p)) < 0.03f) cells_.insert(Key(p.head<2>()));
  }
  // Share of the footprint's inner cells whose floor is seen.
  float SeenUnder(const shape::Footprint& f) const {
    int n = 0, seen = 0;
    ForEachInnerCell(f.center, f.length, f.width, f.yaw, [&](const Eigen::Vector2f& q) {
      ++n;
      seen += cells_.count(Key(q)) > 0;
    });
    return n ? float(seen) / float(n) : 0.f;
  }

 private:
  static uint64_t Key(const Eigen::Vector2f& q) {
    const int64_t x = int64_t(std::floor(q.x() / kFloorCell)), y = int64_t(std::floor(q.y() / kFloorCell));
    return (uint64_t(x) << 32) ^ (uint64_t(y) & 0xffffffffu);
  }
  std::set<uint64_t> cells_;
};

// Single views (a scan with a sensor origin): 1 for the points at the left or right end of what
// the sensor saw. A camera's image ends left and right; an object the edge cuts is seen in part,
// and its part may look like a smaller object (a sofa's end like an armchair). Each point's
// azimuth and elevation about the origin (azimuth from the points' mean horizontal heading); per
// 1 deg row of elevation holding 10 or more points, those within `band_deg` of the row's smallest
// or largest azimuth (a pitched camera's edges are curves in azimuth: the rows follow them). A
// row also ends where nothing was seen beyond an object (no return from a window, a dark surface,
// open space beyond the range): what lies beside that object is unknown too, so it counts as cut
// as well. Real views are ragged there (SUN RGB-D dev rows end 5-8 deg apart from one degree of
// elevation to the next). All 0 for a scan whose points surround the origin (a panoramic laser:
// 1 % or more of them behind it, or an azimuth span over 150 deg), and for a scan without an
// origin. Linear in the points.
std::vector<uint8_t> ViewEdges(const Scan& scan, float band_deg) {
  const size_t n = scan.points.size();
  std::vector<uint8_t> edge(n, 0);
  if (!scan.origin || !scan.origin->allFinite()) return edge;
  const Eigen::Vector3f o = *scan.origin;
  Eigen::Vector2d heading = Eigen::Vector2d::Zero();
  for (const auto& p : scan.points) {
    const Eigen::Vector2f d = (p - o).head<2>();
    const float len = d.norm();
    if (p.allFinite() && len > 1e-6f) heading += (d / len).cast<double>();
  }
  if (!(heading.norm() > 1e-9)) return edge;
  heading.normalize();
  const float hx = float(heading.x()), hy = float(heading.y());
  constexpr float kDeg = float(180.0 / M_PI);
  std::vector<float> az(n, NAN);
  std::vector<int> row(n, -1);
  size_t finite = 0, behind = 0;
  float lo = INFINITY, hi = -INFINITY;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f d = scan.points[i] - o;
    if (!d.allFinite() || d.squaredNorm() < 1e-12f) continue;
    ++finite;
    const float f = d.x() * hx + d.y() * hy, r = d.y() * hx - d.x() * hy;  // along the heading; to its left
    behind += f <= 0.f;
    az[i] = std::atan2(r, f) * kDeg;
    row[i] = std::clamp(int(std::floor(std::atan2(d.z(), std::hypot(f, r)) * kDeg)) + 90, 0, 179);
    lo = std::min(lo, az[i]), hi = std::max(hi, az[i]);
  }
  if (finite == 0 || double(behind) >= 0.01 * double(finite) || hi - lo > 150.f) return edge;
  std::array<float, 180> row_lo, row_hi;
  std::array<int, 180> count{};
  row_lo.fill(INFINITY), row_hi.fill(-INFINITY);
  for (size_t i = 0; i < n; ++i)
    if (row[i] >= 0) {
      const int b = row[i];
      ++count[size_t(b)];
      row_lo[size_t(b)] = std::min(row_lo[size_t(b)], az[i]), row_hi[size_t(b)] = std::max(row_hi[size_t(b)], az[i]);
    }
  for (size_t i = 0; i < n; ++i)
    if (row[i] >= 0 && count[size_t(row[i])] >= 10)
      edge[i] = az[i] - row_lo[size_t(row[i])] < band_deg || row_hi[size_t(row[i])] - az[i] < band_deg;
  spdlog::debug("catalog_shape: {} of {} points at the view's left or right edge (azimuth span {:.1f} deg)",
                std::count(edge.begin(), edge.end(), uint8_t(1)), n, hi - lo);
  return edge;
}

}  // namespace

VoteResult CatalogShapeVoter::Vote(const std::vector<SceneParts>& scenes, const RunContext&) {
  VoteResult out;
  out.classes = classes_;
  if (models_.empty()) throw StageError("voters.catalog_shape: no model loaded", false);
  for (size_t s = 0; s < scenes.size(); ++s) {
    const SceneParts& sc = scenes[s];
    if (!sc.proposals || !sc.scan) {
      if (s == 0 && !sc.proposals)
        throw InputError("voters.catalog_shape recognises proposals: give it a proposer as input (e.g. proposals.clusters)");
      continue;
    }
    const Scan& scan = *sc.scan;
    const auto& items = sc.proposals->items;
    const size_t n = items.size();
    const FloorCells floor = o_.floor_term ? FloorCells(scan) : FloorCells();
    const bool views = o_.view_profiles && scan.origin.has_value();
    // The view's edges, where a class uses them.
    bool edges_used = false;
    for (const auto& c : classes_) edges_used = edges_used || o_.Of(c).view_edge > 0.f;
    const std::vector<uint8_t> at_edge =
        edges_used && scan.origin ? ViewEdges(scan, o_.edge_band_deg) : std::vector<uint8_t>();
    const size_t C = classes_.size();
    std::vector<std::vector<float>> score(C, std::vector<float>(n, 0.f));
    std::vector<std::vector<int>> best_model(C, std::vector<int>(n, -1));
    std::vector<std::vector<std::map<std::string, float>>> evidence(C, std::vector<std::map<std::string, float>>(n));
    std::vector<shape::Footprint> foot(n);
    // Per class and proposal: the further turn of its best model that puts its back where the
    // points' is (shape::TurnToMatchTop).
    std::vector<std::vector<float>> turn(C, std::vector<float>(n, 0.f));
    // The models whose energy is computed, over the proposals and classes scored (a debug line).
    std::atomic<size_t> energies{0}, candidates{0};
    // Each proposal's footprint, profile and scores are its own: scored in parallel (in
    // order when tracing, so the trace reads as before).
    auto score_one = [&](size_t i) {
      const Proposal& p = items[i];
      if (p.indices.size() < 10) return;
      std::vector<Eigen::Vector2f> xy(p.indices.size());
      std::vector<float> h(p.indices.size());
      for (size_t k = 0; k < p.indices.size(); ++k) {
        const Eigen::Vector3f& q = scan.points[size_t(p.indices[k])];
        xy[k] = q.head<2>();
        h[k] = q.z() - p.ground_z;
      }
      foot[i] = shape::OrientedFootprint(xy);
      const float L = std::max(foot[i].length, 0.02f), W = std::max(foot[i].width, 0.02f);
      const float T = std::max(p.box.max().z() - p.ground_z, 0.02f), B = std::max(p.box.min().z() - p.ground_z, 0.f);
      const shape::Profile prof = shape::TopViewProfile(xy, h, T, o_.cell);
      const float seen = o_.floor_term ? floor.SeenUnder(foot[i]) : 0.f;
      const std::optional<Eigen::Vector2f> top = shape::TopQuarterCentre(xy, h, T);
      // Cut by the view's edge: 3 or more of its points there.
      int edge_points = 0;
      if (!at_edge.empty())
        for (int k : p.indices) edge_points += at_edge[size_t(k)];
      const float cut = edge_points >= 3 ? 1.f : 0.f;
      for (size_t c = 0; c < C; ++c) {
        const ClassParams& cp = o_.Of(classes_[c]);
        if (cp.max_top > 0.f && T > cp.max_top) continue;  // score 0: no hypothesis of the class here
        candidates.fetch_add(index_[c].size(), std::memory_order_relaxed);
        // Model md's energy and its terms: length, width, top, bottom, profile, floor.
        const float bottom = 0.5f * (B / cp.bottom) * (B / cp.bottom);
        const float hung_bottom = cp.wall_mount + Hung(B, cp);
        const float span = std::max(T - B, 0.02f);
        auto energy = [&](const Model& md, std::array<float, 6>& t) {
          energies.fetch_add(1, std::memory_order_relaxed);
          const float emd = shape::ProfileDistance(prof, md.profile);
          t = {Pen(std::log(L / md.length), cp.long_small, cp.long_big),
               Pen(std::log(W / md.width), cp.short_small, cp.short_big),
               Pen(std::log(T / md.height), cp.top_small, cp.top_big),
               bottom,
               emd * emd / (2 * cp.profile * cp.profile),
               o_.floor_term ? Pen(seen - md.open, cp.floor_under, cp.floor_over) : 0.f};
          // A single view: the profile of the model as the one eye around it that explains the
          // proposal's best, if closer than all eyes fused.
          if (views)
            for (const shape::Profile& v : md.views) {
              const float d = shape::ProfileDistance(prof, v);
              t[4] = std::min(t[4], d * d / (2 * cp.profile * cp.profile));
            }
          float E = t[0] + t[1] + t[2] + t[3] + t[4] + t[5];
          if (cp.wall_mount > 0.f) {
            // Hanging: the model spans the proposal's height extent; no bottom gap, floor or top-view
            // evidence (a sensor below a wall cabinet rarely sees its top).
            const std::array<float, 6> tl = {t[0], t[1], Pen(std::log(span / md.height), cp.top_small, cp.top_big),
                                             hung_bottom, 0.f, 0.f};
            const float El = tl[0] + tl[1] + tl[2] + tl[3] + tl[4] + tl[5];
            if (El < E) E = El, t = tl;
          }
          return E;
        };
        float best = INFINITY;
        std::array<float, 6> terms{};  // of the best model
        if (!o_.model_index) {
          for (size_t m = 0; m < models_.size(); ++m) {
            if (models_[m].cls != classes_[c]) continue;
            std::array<float, 6> t;
            const float E = energy(models_[m], t);
            if (E < best) best = E, best_model[c][i] = int(m), terms = t;
          }
        } else {
          // The candidates of the class's index. A model's energy is at least the sum of its
          // size, bottom and floor terms (the profile term is >= 0, and float sums of terms >= 0
          // never fall below a partial sum), so a model whose partial sum exceeds the best energy
          // found is skipped before its profile distances. A node of the tree is skipped when a
          // bound over its box exceeds it: the size, bottom and floor terms over the box, and the
          // profile term of the gaps between the proposal's ChunkSums and the box's. Ties go to
          // the earlier model, as in a scan of all models in order.
          const double lL = std::log(double(L)), lW = std::log(double(W)), lT = std::log(double(T)),
                       lS = std::log(double(span));
          const std::array<double, kProfileChunks> qP = ChunkSums(prof);
          double qS = 0;
          for (double v : qP) qS += v;
          // The box's bound is in double, the models' terms in float: each gap to the box shrinks
          // by 1e-5 (far above the float rounding of a log or a share, ~1e-6), the profile
          // distance by 1e-4 per unit of profile mass (above the float rounding of its sums), and
          // the sum by a relative 1e-5, so it never exceeds a model's energy.
          auto pen_box = [](double q, double lo, double hi, float small, float big) {
            constexpr double kSlack = 1e-5;
            const double d = q < lo ? std::min(q - lo + kSlack, 0.0) : q > hi ? std::max(q - hi - kSlack, 0.0) : 0.0;
            const double s = d < 0 ? double(small) : double(big);
            return d * d / (2 * s * s);
          };
          constexpr size_t K = SizeIndex::kDims;
          auto bound = [&](const SizeIndex::Box& b) {
            const double sides = pen_box(lL, b[0], b[K], cp.long_small, cp.long_big) +
                                 pen_box(lW, b[1], b[K + 1], cp.short_small, cp.short_big);
            double gap = 0, mass = 1.0 + qS;
            for (size_t k = 0; k < size_t(kProfileChunks); ++k)
              gap += std::max({b[4 + k] - qP[k], qP[k] - b[K + 4 + k], 0.0}), mass += b[K + 4 + k];
            const double emd = std::max(gap / shape::kProfileBins - 1e-4 * mass, 0.0);
            double height = pen_box(lT, b[2], b[K + 2], cp.top_small, cp.top_big) + double(bottom) +
                            emd * emd / (2 * double(cp.profile) * double(cp.profile)) +
                            (o_.floor_term ? pen_box(double(seen), b[3], b[K + 3], cp.floor_under, cp.floor_over) : 0.0);
            if (cp.wall_mount > 0.f)
              height = std::min(height, pen_box(lS, b[2], b[K + 2], cp.top_small, cp.top_big) + double(hung_bottom));
            return (sides + height) * (1.0 - 1e-5);
          };
          int chosen = -1;
          index_[c].Search(bound, [&] { return best; }, [&](size_t m) {
            const Model& md = models_[m];
            const float t01 = Pen(std::log(L / md.length), cp.long_small, cp.long_big) +
                              Pen(std::log(W / md.width), cp.short_small, cp.short_big);
            float partial = t01 + Pen(std::log(T / md.height), cp.top_small, cp.top_big) + bottom +
                            (o_.floor_term ? Pen(seen - md.open, cp.floor_under, cp.floor_over) : 0.f);
            if (cp.wall_mount > 0.f)
              partial = std::min(partial, t01 + Pen(std::log(span / md.height), cp.top_small, cp.top_big) + hung_bottom);
            if (partial > best) return;
            std::array<float, 6> t;
            const float E = energy(md, t);
            if (E < best || (E == best && chosen >= 0 && int(m) < chosen)) best = E, chosen = int(m), terms = t;
          });
          best_model[c][i] = chosen;
        }
        if (best_model[c][i] >= 0 && top) {
          const Model& md = models_[size_t(best_model[c][i])];
          const Eigen::Vector2f extent = md.wide ? Eigen::Vector2f(md.length, md.width) : Eigen::Vector2f(md.width, md.length);
          turn[c][i] = shape::TurnToMatchTop(foot[i], md.wide, md.top_offset, extent, *top);
        }
        score[c][i] = std::exp(-best - p.surround / cp.surround - cut * cp.view_edge);
        evidence[c][i] = {{"length_m", L},          {"width_m", W},         {"top_m", T},
                          {"bottom_m", B},          {"surround", p.surround}, {"floor_seen", seen},
                          {"points", float(p.indices.size())},
                          {"e_length", terms[0]},   {"e_width", terms[1]},  {"e_top", terms[2]},
                          {"e_bottom", terms[3]},   {"e_profile", terms[4]}, {"e_floor", terms[5]},
                          {"e_surround", p.surround / cp.surround}};
        if (!at_edge.empty() && cp.view_edge > 0.f) {
          evidence[c][i]["view_edge_points"] = float(edge_points);
          evidence[c][i]["e_view_edge"] = cut * cp.view_edge;
        }
        if (spdlog::should_log(spdlog::level::trace) && score[c][i] >= o_.min_score)
          spdlog::trace("catalog_shape: {} {} box ({:.2f} {:.2f} {:.2f})-({:.2f} {:.2f} {:.2f}) L {:.3f} W {:.3f} T {:.3f} "
                        "B {:.3f} surround {:.3f} floor seen {:.3f} -> {} {:.4f}",
                        p.how, classes_[c], p.box.min().x(), p.box.min().y(), p.box.min().z(), p.box.max().x(),
                        p.box.max().y(), p.box.max().z(), L, W, T, B, p.surround, seen,
                        models_[size_t(best_model[c][i])].id, score[c][i]);
      }
    };
    if (spdlog::should_log(spdlog::level::trace)) {
      for (size_t i = 0; i < n; ++i) score_one(i);
    } else {
      // A proposal of exactly the points, box, ground and surround of an earlier one (another
      // radius or rule that found the same cluster: half the proposals of some rooms) scores
      // as that one: scored once, copied. Its group, and so its competition, stays its own.
      const std::vector<size_t> same = SameAsEarlier(items);
      std::vector<size_t> first;
      for (size_t i = 0; i < n; ++i)
        if (same[i] == i) first.push_back(i);
      tbb::parallel_for(size_t(0), first.size(), [&](size_t k) { score_one(first[k]); });
      for (size_t i = 0; i < n; ++i) {
        const size_t j = same[i];
        if (j == i) continue;
        foot[i] = foot[j];
        for (size_t c = 0; c < C; ++c)
          score[c][i] = score[c][j], best_model[c][i] = best_model[c][j], evidence[c][i] = evidence[c][j],
          turn[c][i] = turn[c][j];
      }
    }
    spdlog::debug("catalog_shape: {} of {} model energies computed ({})", energies.load(), candidates.load(),
                  o_.model_index ? "size index" : "every model");
    // Class competition within each group (the variants of one cluster are one object).
    std::map<int, float> group_best;
    std::vector<float> best_of(n, 0.f);
    for (size_t i = 0; i < n; ++i) {
      for (size_t c = 0; c < C; ++c) best_of[i] = std::max(best_of[i], score[c][i]);
      float& g = group_best[items[i].group];
      g = std::max(g, best_of[i]);
    }
    for (size_t c = 0; c < C; ++c) {
      const float a = o_.Of(classes_[c]).compete;
      if (a > 0.f)
        for (size_t i = 0; i < n; ++i) {
          const float b = std::max(group_best[items[i].group], 1e-12f);
          evidence[c][i]["compete_factor"] = std::pow(score[c][i] / b, a);
          score[c][i] *= std::pow(score[c][i] / b, a);
        }
      const std::string& src = source_.at(classes_[c]);
      if (src != "any")
        for (size_t i = 0; i < n; ++i)
          if (!RuleListed(src, items[i].source)) score[c][i] = 0.f;
    }
    // Non-maximum suppression per class by box IoU, then the hypotheses.
    for (size_t c = 0; c < C; ++c) {
      std::vector<size_t> order;
      for (size_t i = 0; i < n; ++i)
        if (score[c][i] >= o_.min_score && best_model[c][i] >= 0) order.push_back(i);
      const auto thr = o_.thresholds.find(classes_[c]);
      const float t = thr == o_.thresholds.end() ? o_.default_threshold : thr->second;
      for (size_t i : shape::SuppressOverlaps(std::move(order), score[c], items, o_.nms_iou, o_.nms_whole)) {
        const Model& md = models_[size_t(best_model[c][i])];
        out.hypotheses.push_back(shape::ProposalHypothesis(classes_[c], score[c][i], t, items[i], int(i), int(s),
                                                           foot[i], md.id, md.wide, scan.pose, turn[c][i]));
        out.hypotheses.back().evidence = std::move(evidence[c][i]);
      }
    }
  }
  return out;
}

}  // namespace furnihost::catalog_shape
