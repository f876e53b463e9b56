#include "pose_search.hpp"

#include <algorithm>
#include <cmath>

namespace furnihost::ransac_upright {

void SearchOptions::Check() const {
  if (!(free_weight >= 0.f)) throw StageError("free_weight must be >= 0");
  if (!(max_shift >= 0.f)) throw StageError("max_shift_m must be >= 0");
  if (!(step_m > 0.f) || !(min_step_m > 0.f) || min_step_m > step_m)
    throw StageError("search steps: need 0 < min_step_m <= step_m");
  if (!(step_yaw >= 0.f) || !(step_scale >= 0.f)) throw StageError("search steps must be >= 0");
  if (keep_starts < 1 || max_evaluations < 1) throw StageError("keep_starts and max_evaluations must be >= 1");
}

double Objective(const Comparison& c, const SearchOptions& o) { return c.seen_object - o.free_weight * c.free; }

namespace {

ModelPlacement Clamp(ModelPlacement p, const StretchRange& r) {
  p.sx = std::clamp(p.sx, r.lo.x(), r.hi.x());
  p.sy = std::clamp(p.sy, r.lo.y(), r.hi.y());
  p.sz = std::clamp(p.sz, r.lo.z(), r.hi.z());
  return p;
}

}  // namespace

SearchResult SearchPose(const std::vector<const RenderCloud*>& models, const std::vector<StretchRange>& ranges,
                        const std::vector<Start>& starts, const std::vector<View>& views, const CompareOptions& compare,
                        const SearchOptions& o, Scratch* scratch) {
  SearchResult best;
  if (starts.empty()) return best;
  // Every start as given; the best keep_starts go on.
  struct Scored {
    double j;
    size_t k;
    ModelPlacement pose;
    Comparison c;
  };
  std::vector<Scored> scored;
  for (size_t k = 0; k < starts.size(); ++k) {
    const Start& s = starts[k];
    const ModelPlacement p = Clamp(s.pose, ranges[size_t(s.model)]);
    const Comparison c = ComparePose(*models[size_t(s.model)], p, views, compare, scratch);
    ++best.evaluations;
    scored.push_back({Objective(c, o), k, p, c});
  }
  std::stable_sort(scored.begin(), scored.end(), [](const Scored& a, const Scored& b) { return a.j > b.j; });
  const size_t keep = std::min(scored.size(), size_t(o.keep_starts));
  for (size_t r = 0; r < keep; ++r) {
    const Start& s = starts[scored[r].k];
    const RenderCloud& m = *models[size_t(s.model)];
    const StretchRange& range = ranges[size_t(s.model)];
    ModelPlacement cur = scored[r].pose;
    Comparison cur_c = scored[r].c;
    double cur_j = scored[r].j;
    float step = o.step_m, yaw_step = o.step_yaw, sc_step = o.step_scale;
    int evals = 0;
    const float x0 = cur.x, y0 = cur.y;
    while (step >= o.min_step_m - 1e-6f && evals < o.max_evaluations) {
      bool improved = false;
      // Moves: x, y, yaw, then the stretch along x, y (together and apart) and z.
      std::vector<ModelPlacement> moves;
      for (float sgn : {1.f, -1.f}) {
        ModelPlacement p = cur;
        p.x += sgn * step;
        moves.push_back(p);
        p = cur;
        p.y += sgn * step;
        moves.push_back(p);
        if (yaw_step > 0.f) {
          p = cur;
          p.yaw += sgn * yaw_step;
          moves.push_back(p);
        }
        if (sc_step > 0.f) {
          const float f = std::exp(sgn * sc_step);
          p = cur;
          p.sx *= f;
          p.sy *= f;
          moves.push_back(p);
          p = cur;
          p.sx *= f;
          moves.push_back(p);
          p = cur;
          p.sy *= f;
          moves.push_back(p);
          p = cur;
          p.sz *= f;
          moves.push_back(p);
        }
      }
      for (ModelPlacement p : moves) {
        if (evals >= o.max_evaluations) break;
        p = Clamp(p, range);
        if (std::hypot(p.x - x0, p.y - y0) > o.max_shift) continue;
        if (p.sx == cur.sx && p.sy == cur.sy && p.sz == cur.sz && p.x == cur.x && p.y == cur.y && p.yaw == cur.yaw)
          continue;
        const Comparison c = ComparePose(m, p, views, compare, scratch);
        ++evals;
        const double j = Objective(c, o);
        if (j > cur_j + 1e-9) {
          cur = p, cur_c = c, cur_j = j;
          improved = true;
        }
      }
      if (!improved) {
        step *= 0.5f;
        yaw_step *= 0.5f;
        sc_step *= 0.5f;
      }
    }
    best.evaluations += evals;
    if (cur_j > best.objective) {
      best.objective = cur_j;
      best.model = s.model;
      best.pose = cur;
      best.comparison = cur_c;
    }
  }
  return best;
}

}  // namespace furnihost::ransac_upright
