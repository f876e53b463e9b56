// fitters.ransac_upright: recognition by analysis by synthesis (FitSynthesis): catalog models
// posed, rendered as the camera would see them and compared with what it measured.
#include <octomap/OcTree.h>
#include <tbb/parallel_for.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <tuple>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"
#include "model_cloud.hpp"
#include "occupancy.hpp"
#include "shape/shape.hpp"
#include "pose_search.hpp"
#include "upright_ransac.hpp"
#include "view_synthesis.hpp"
#include "ransac_upright.hpp"

namespace furnihost::ransac_upright {

namespace {

// What the view prior compares of a set of points about a posed model: their extents along the
// model's two axes (2nd to 98th percentile), their top and bottom above the floor (98th and 2nd
// percentiles) and their top-view profile under the model's top.
struct ViewShape {
  float u = 0.f, v = 0.f, top = 0.f, bottom = 0.f;
  shape::Profile profile{};
};

float Spread(std::vector<float>* x, float* lo) {
  const size_t a = x->size() * 2 / 100, b = x->size() * 98 / 100;
  std::nth_element(x->begin(), x->begin() + long(a), x->end());
  *lo = (*x)[a];
  std::nth_element(x->begin(), x->begin() + long(b), x->end());
  return (*x)[b] - *lo;
}

// The shape of `points` (world frame) within `margin` of the box `bounds` (model frame) posed
// at `p`, leaving out those less than `low` above the floor; false with fewer than 10 points.
bool ShapeAbout(const Points& points, const Eigen::AlignedBox3f& bounds, const ModelPlacement& p, float floor_z,
                float low, float margin, ViewShape* out) {
  const float c = std::cos(p.yaw), s = std::sin(p.yaw);
  const Eigen::Vector3f lo = bounds.min().cwiseProduct(Eigen::Vector3f(p.sx, p.sy, p.sz));
  const Eigen::Vector3f hi = bounds.max().cwiseProduct(Eigen::Vector3f(p.sx, p.sy, p.sz));
  std::vector<float> us, vs, hs;
  std::vector<Eigen::Vector2f> xy;
  for (const auto& w : points) {
    const float dx = w.x() - p.x, dy = w.y() - p.y;
    const float u = c * dx + s * dy, v = -s * dx + c * dy, h = w.z() - floor_z;
    if (h < low || u < lo.x() - margin || u > hi.x() + margin || v < lo.y() - margin || v > hi.y() + margin ||
        h > hi.z() + margin)
      continue;
    us.push_back(u), vs.push_back(v), hs.push_back(h), xy.push_back(w.head<2>());
  }
  if (us.size() < 10) return false;
  out->profile = shape::TopViewProfile(xy, hs, std::max(hi.z(), 0.05f));
  float ignored;
  out->u = Spread(&us, &ignored);
  out->v = Spread(&vs, &ignored);
  out->top = Spread(&hs, &out->bottom) + out->bottom;
  return true;
}

}  // namespace

// The render clouds of `models` (same order): kept per stage object, and between runs in
// cloud_cache beside the sampled clouds (a few kilobytes each: loading them spares sampling
// or loading the dense clouds); the missing ones thinned from the sampled clouds.
std::vector<std::shared_ptr<const RenderCloud>> RansacUprightFitter::Renders(const std::vector<const CatalogModel*>& models) {
  std::vector<std::shared_ptr<const RenderCloud>> out(models.size());
  std::vector<uint64_t> keys(models.size());
  std::vector<size_t> missing;
  for (size_t i = 0; i < models.size(); ++i) {
    const uint64_t base = ModelCloud::CacheKey(*models[i], o_.sampling, Fnv1a(models[i]->id, kFnvOffsetTruncated));
    keys[i] = RenderCloud::CacheKey(base, o_.render_samples);
    std::lock_guard<std::mutex> lock(mu_);
    auto it = renders_.find(keys[i]);
    if (it != renders_.end()) out[i] = it->second;
    else missing.push_back(i);
  }
  auto path_of = [&](uint64_t key) {
    char name[32];
    std::snprintf(name, sizeof(name), "%016llx.fhrc", static_cast<unsigned long long>(key));
    return o_.cloud_cache + "/" + name;
  };
  std::vector<size_t> sample;
  for (size_t i : missing) {
    if (!o_.cloud_cache.empty())
      if (auto r = RenderCloud::Load(path_of(keys[i]), keys[i])) {
        out[i] = std::move(r);
        continue;
      }
    sample.push_back(i);
  }
  if (!sample.empty()) {
    std::vector<const CatalogModel*> ms;
    for (size_t i : sample) ms.push_back(models[i]);
    const std::vector<std::shared_ptr<const ModelCloud>> clouds = Clouds(ms);
    for (size_t k = 0; k < sample.size(); ++k) {
      const size_t i = sample[k];
      auto r = std::make_shared<const RenderCloud>(
          MakeRenderCloud(clouds[k]->Cloud(), clouds[k]->Bounds(), o_.render_samples));
      if (!o_.cloud_cache.empty()) {
        try {
          r->Save(path_of(keys[i]), keys[i]);
        } catch (const std::exception& e) {
          if (!cache_warned_.exchange(true))
            spdlog::warn("fitters.ransac_upright: render clouds not cached ({})", e.what());
        }
      }
      out[i] = std::move(r);
    }
  }
  std::lock_guard<std::mutex> lock(mu_);
  for (size_t i : missing) renders_.emplace(keys[i], out[i]);
  return out;
}

// Per scan point: 1 when it may belong to furniture (neither the proposer's wall or floor,
// nor within 5 cm of the ground).
std::vector<uint8_t> RansacUprightFitter::ObjectPoints(const SceneParts& sp) {
  const Scan& scan = *sp.scan;
  std::vector<uint8_t> obj(scan.points.size(), 1);
  const bool removed = sp.proposals && sp.proposals->removed.size() == scan.points.size();
  for (size_t i = 0; i < scan.points.size(); ++i) {
    if (removed && sp.proposals->removed[i]) obj[i] = 0;
    else if (scan.ground && scan.ground->Above(scan.points[i]) < 0.05f) obj[i] = 0;
  }
  return obj;
}

// The starting poses of `models` (the first `count`) for a detection: its footprint's centre
// and, when it differs, the position that puts the model's near face on the points' near face
// (a view sees an object's front); four yaws along the footprint's axes; the model stretched
// uniformly to the points' top, within its class's range.
std::vector<Start> RansacUprightFitter::Starts(const SynthesisInput& in, const std::vector<const CatalogModel*>& class_models,
                                 const std::vector<StretchRange>& ranges, size_t count, const Eigen::Vector3f& eye) {
  std::vector<Start> starts;
  const shape::Footprint& f = in.footprint;
  Eigen::Vector2f dir = f.center - eye.head<2>();
  dir = dir.norm() > 1e-3f ? Eigen::Vector2f(dir.normalized()) : Eigen::Vector2f(1.f, 0.f);
  float near = INFINITY;
  for (const auto& q : in.points) near = std::min(near, (q.head<2>() - f.center).dot(dir));
  for (size_t r = 0; r < count && r < in.models.size(); ++r) {
    const Eigen::Vector3f z = class_models[in.models[r]]->size;
    const bool wide = z.x() >= z.y();
    const StretchRange& sr = ranges[r];
    const float s0 = std::clamp(in.top / z.z(), sr.lo.z(), sr.hi.z());
    for (int q = 0; q < 4; ++q) {
      ModelPlacement p;
      p.yaw = f.yaw + (wide ? 0.f : float(M_PI / 2)) + float(q) * float(M_PI / 2);
      p.sx = p.sy = p.sz = s0;
      p.x = f.center.x(), p.y = f.center.y(), p.z = in.floor_z;
      starts.push_back({int(r), p});
      const float c = std::cos(p.yaw), s = std::sin(p.yaw);
      const float half = 0.5f * s0 * (std::abs(c * dir.x() + s * dir.y()) * z.x() + std::abs(-s * dir.x() + c * dir.y()) * z.y());
      const float shift = near + half;
      if (std::abs(shift) > 0.02f) {
        p.x = f.center.x() + dir.x() * shift, p.y = f.center.y() + dir.y() * shift;
        starts.push_back({int(r), p});
      }
    }
  }
  return starts;
}

std::vector<Detection> RansacUprightFitter::FitSynthesis(const std::vector<Detection>& input, const FitContext& ctx) {
  Stopwatch sw;
  // The views: every scan with a sensor origin.
  std::vector<std::unique_ptr<RangeImage>> images;
  std::vector<View> views;
  Eigen::Vector3f eye = Eigen::Vector3f::Zero();  // the first view's sensor, world frame
  for (const SceneParts& sp : ctx.scenes) {
    if (!sp.scan || !sp.scan->origin) continue;
    images.push_back(std::make_unique<RangeImage>(sp.scan->points, ObjectPoints(sp), *sp.scan->origin, o_.view));
    if (views.empty()) eye = sp.scan->pose * *sp.scan->origin;
    views.push_back({images.back().get(), sp.scan->pose.inverse()});
  }
  const double ms_images = sw.Ms();
  const Scan* ground_scan = nullptr;
  for (const SceneParts& sp : ctx.scenes)
    if (sp.scan && !ground_scan) ground_scan = sp.scan;
  // The level of the joint choice: pixels about select_pixel_deg wide.
  int sel = 0;
  {
    const float want = o_.select_pixel_deg * float(M_PI / 180.0);
    float best = INFINITY;
    for (int l = 0; l < images.front()->Levels(); ++l) {
      const float d = std::abs(std::log(images.front()->PixelRad(l) / want));
      if (d < best) best = d, sel = l;
    }
  }
  // Models per detected class, their stretch ranges (the class's catalog sizes, widened).
  std::map<std::string, std::vector<const CatalogModel*>> by_class;
  for (const CatalogModel* m : ctx.catalog)
    if (m) by_class[Mapped(m->cls)].push_back(m);
  std::set<std::string> wanted;
  for (const auto& d : input) wanted.insert(d.cls);
  std::vector<const CatalogModel*> needed;
  for (const auto& [cls, ms] : by_class)
    if (wanted.count(cls)) needed.insert(needed.end(), ms.begin(), ms.end());
  const std::vector<std::shared_ptr<const RenderCloud>> renders = Renders(needed);
  std::map<const CatalogModel*, std::shared_ptr<const RenderCloud>> render_of;
  for (size_t i = 0; i < needed.size(); ++i) render_of[needed[i]] = renders[i];
  std::map<const CatalogModel*, StretchRange> range_of;
  for (const auto& [cls, ms] : by_class) {
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = Eigen::Vector3f::Zero();  // length, width, height
    for (const CatalogModel* m : ms) {
      const Eigen::Vector3f lwh(std::max(m->size.x(), m->size.y()), std::min(m->size.x(), m->size.y()), m->size.z());
      lo = lo.cwiseMin(lwh), hi = hi.cwiseMax(lwh);
    }
    const float a = 1.f - o_.stretch_margin, b = 1.f + o_.stretch_margin;
    for (const CatalogModel* m : ms) {
      const Eigen::Vector3f z = m->size;
      const bool wide = z.x() >= z.y();
      StretchRange sr;
      sr.lo = a * Eigen::Vector3f((wide ? lo.x() : lo.y()) / z.x(), (wide ? lo.y() : lo.x()) / z.y(), lo.z() / z.z());
      sr.hi = b * Eigen::Vector3f((wide ? hi.x() : hi.y()) / z.x(), (wide ? hi.y() : hi.x()) / z.y(), hi.z() / z.z());
      range_of[m] = sr;
    }
  }
  // The detections of classes with models, and their points.
  std::vector<size_t> cand;
  for (size_t d = 0; d < input.size(); ++d)
    if (by_class.count(input[d].cls)) cand.push_back(d);
  std::vector<SynthesisInput> in(cand.size());
  for (size_t k = 0; k < cand.size(); ++k) {
    const Detection& det = input[cand[k]];
    std::vector<Eigen::AlignedBox3f> boxes;
    for (const CatalogModel* m : by_class.at(det.cls)) boxes.push_back(render_of.at(m)->bounds);
    in[k].floor_z = ground_scan ? ground_scan->GroundZ(det.center.x(), det.center.y()) : 0.f;
    int dropped = 0;
    in[k].points = Gather(det, ctx, &boxes, in[k].floor_z, &dropped, nullptr).points;
  }
  auto ranges_of = [&](const Detection& det, const SynthesisInput& x) {
    std::vector<StretchRange> r;
    for (size_t m : x.models) r.push_back(range_of.at(by_class.at(det.cls)[m]));
    return r;
  };
  auto renders_of = [&](const Detection& det, const SynthesisInput& x) {
    std::vector<const RenderCloud*> r;
    for (size_t m : x.models) r.push_back(render_of.at(by_class.at(det.cls)[m]).get());
    return r;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  // Screening: each detection's closest model at its starts.
  std::vector<double> screen(cand.size(), -1e300);
  tbb::parallel_for(size_t(0), cand.size(), [&](size_t k) {
    const Detection& det = input[cand[k]];
    SynthesisInput& x = in[k];
    if (x.points.size() < 5) return;
    std::vector<Eigen::Vector2f> xy(x.points.size());
    std::vector<float> hz(x.points.size());
    for (size_t i = 0; i < x.points.size(); ++i) xy[i] = x.points[i].head<2>(), hz[i] = x.points[i].z() - x.floor_z;
    x.footprint = shape::OrientedFootprint(xy);
    const size_t q = hz.size() * 98 / 100;
    std::nth_element(hz.begin(), hz.begin() + long(q), hz.end());
    x.top = std::max(hz[q], 0.05f);
    // The class's models: the recogniser's first, then the closest in size.
    const std::vector<const CatalogModel*>& ms = by_class.at(det.cls);
    std::vector<std::pair<float, size_t>> rank;
    for (size_t m = 0; m < ms.size(); ++m) {
      const Eigen::Vector3f& z = ms[m]->size;
      const float e = ms[m]->id == det.model ? -1.f
                                             : std::abs(std::log(std::max(x.footprint.length, 0.05f) / std::max(z.x(), z.y()))) +
                                                   std::abs(std::log(std::max(x.footprint.width, 0.05f) / std::min(z.x(), z.y()))) +
                                                   std::abs(std::log(x.top / z.z()));
      rank.emplace_back(e, m);
    }
    std::stable_sort(rank.begin(), rank.end());
    for (size_t r = 0; r < rank.size() && r < size_t(o_.models_per_detection); ++r) x.models.push_back(rank[r].second);
    SearchOptions once = o_.search;
    once.keep_starts = 1;
    once.max_evaluations = 0;
    const SearchResult r = SearchPose(renders_of(det, x), ranges_of(det, x),
                                      Starts(x, ms, ranges_of(det, x), 1, eye), views, o_.compare, once,
                                      &scratch.local());
    if (r.model < 0) return;
    // How much of its own surface the start explains, and how little of the model's the
    // sensor saw through, weighed by the prior.
    std::vector<uint64_t> own;
    std::vector<float> own_area;
    PointPixels(x.points, views, sel, o_.compare, &own, &own_area);
    double total = 0.0;
    for (float a : own_area) total += a;
    const Comparison& c = r.comparison;
    if (!(total > 0.0) || !(c.seen_object > 0.0)) return;
    screen[k] = std::pow(std::max(double(det.score), double(o_.prior_floor)), double(o_.shape_exponent)) *
                std::min(1.0, c.seen_object / total) * c.seen_object / (c.seen_object + c.free);
  });
  // Per scene and class, the max_candidates that screened best.
  std::vector<size_t> order;  // into cand
  for (size_t k = 0; k < cand.size(); ++k)
    if (screen[k] > 0.0) order.push_back(k);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return screen[a] > screen[b]; });
  {
    std::map<std::pair<int, std::string>, int> per_scene;
    std::vector<size_t> kept;
    for (size_t k : order) {
      const Detection& det = input[cand[k]];
      const int scene = det.proposal >= 0 ? det.proposal_scene : (det.support.empty() ? 0 : det.support.front().scene);
      if (per_scene[{scene, det.cls}]++ < o_.max_candidates) kept.push_back(k);
    }
    order.swap(kept);
  }
  const double ms_screen = sw.Ms();
  struct Fitted {
    SearchResult r;
    const CatalogModel* model = nullptr;
    ExplainedPixels pixels;
    double explained_share = 0.0, own_area = 0.0, explained_area = 0.0;
    float prior = 0.f;
    float view_prior = 1.f, view_size = 0.f, view_profile = 0.f;  // the view prior, its size and profile energies
    float compete = 1.f;  // the class competition's factor
  };
  std::vector<Fitted> fit(order.size());
  tbb::parallel_for(size_t(0), order.size(), [&](size_t j) {
    const size_t k = order[j];
    const Detection& det = input[cand[k]];
    const SynthesisInput& x = in[k];
    Scratch& sc = scratch.local();
    const std::vector<const CatalogModel*>& ms = by_class.at(det.cls);
    const std::vector<const RenderCloud*> renders = renders_of(det, x);
    Fitted& ft = fit[j];
    ft.r = SearchPose(renders, ranges_of(det, x), Starts(x, ms, ranges_of(det, x), x.models.size(), eye), views,
                      o_.compare, o_.search, &sc);
    if (ft.r.model < 0) return;
    ft.model = ms[x.models[size_t(ft.r.model)]];
    std::vector<uint64_t> keys;
    std::vector<float> areas;
    Points observable;
    ComparePose(*renders[size_t(ft.r.model)], ft.r.pose, views, o_.compare, &sc, &keys, &areas, sel,
                o_.view_prior_exponent > 0.f ? &observable : nullptr);
    std::vector<size_t> idx(keys.size());
    for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
    std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return keys[a] < keys[b]; });
    for (size_t i : idx) {
      if (!ft.pixels.keys.empty() && ft.pixels.keys.back() == keys[i]) {
        ft.pixels.areas.back() += areas[i];
      } else {
        ft.pixels.keys.push_back(keys[i]);
        ft.pixels.areas.push_back(areas[i]);
      }
    }
    std::vector<uint64_t> own;
    std::vector<float> own_area;
    PointPixels(x.points, views, sel, o_.compare, &own, &own_area);
    // The share of the detection's surface the model explains, the detection's surface being
    // its own points' pixels and those the model explains: a model that moved from a fragment
    // onto its whole object is judged on that object, one that leaves most of its own points
    // unexplained (a chair model on a table with a chair under it) loses.
    double own_total = 0.0, unexplained = 0.0, explained = 0.0;
    for (size_t i = 0; i < own.size(); ++i) {
      own_total += own_area[i];
      if (!std::binary_search(ft.pixels.keys.begin(), ft.pixels.keys.end(), own[i])) unexplained += own_area[i];
    }
    for (float a : ft.pixels.areas) explained += a;
    ft.own_area = own_total;
    ft.explained_area = explained;
    ft.explained_share = explained + unexplained > 0.0 ? explained / (explained + unexplained) : 0.0;
    const Comparison& c = ft.r.comparison;
    const double agree = c.seen_object + c.free > 0.0 ? c.seen_object / (c.seen_object + c.free) : 0.0;
    ft.prior = float(std::pow(std::max(double(det.score), double(o_.prior_floor)), double(o_.shape_exponent)));
    if (o_.view_prior_exponent > 0.f) {
      // The view prior: the detection's points about the fitted model against the part of the
      // model the sensor should see, both above the lowest height the proposals keep.
      ViewShape a, b;
      const Eigen::AlignedBox3f& bounds = renders[size_t(ft.r.model)]->bounds;
      ft.view_prior = o_.prior_floor;
      if (ShapeAbout(x.points, bounds, ft.r.pose, x.floor_z, 0.05f, 0.05f, &a) &&
          ShapeAbout(observable, bounds, ft.r.pose, x.floor_z, 0.05f, 0.05f, &b)) {
        auto ratio = [](float p, float q) {
          const float r = std::log(std::max(p, 0.05f) / std::max(q, 0.05f));
          return r * r;
        };
        const float ss = o_.view_prior_size, sb = o_.view_prior_bottom_m, sp = o_.view_prior_profile;
        ft.view_size = (ratio(a.u, b.u) + ratio(a.v, b.v) + ratio(a.top, b.top)) / (2 * ss * ss) +
                       (a.bottom - b.bottom) * (a.bottom - b.bottom) / (2 * sb * sb);
        const float emd = shape::ProfileDistance(a.profile, b.profile);
        ft.view_profile = emd * emd / (2 * sp * sp);
        ft.view_prior = std::max(std::exp(-(ft.view_size + ft.view_profile)), o_.prior_floor);
      }
      ft.prior *= std::pow(ft.view_prior, o_.view_prior_exponent);
    }
    const double visible = c.seen_object + c.seen_other + c.free + c.unknown;
    const double complete = visible > 0.0 ? c.seen_object / visible : 0.0;
    ft.pixels.score = ft.prior * std::pow(ft.explained_share, double(o_.explained_exponent)) *
                      std::pow(agree, double(o_.agreement_exponent)) *
                      std::pow(complete, double(o_.completeness_exponent)) *
                      (o_.evidence_m2 > 0.f ? 1.0 - std::exp(-c.seen_object / double(o_.evidence_m2)) : 1.0);
  });
  // The joint choice.
  std::vector<ExplainedPixels> chosen(order.size());
  for (size_t j = 0; j < order.size(); ++j) {
    chosen[j] = fit[j].pixels;
    if (fit[j].model) {
      const Eigen::AlignedBox3f& b = render_of.at(fit[j].model)->bounds;
      const ModelPlacement& p = fit[j].r.pose;
      chosen[j].box = OrientedBox{p.Apply(b.center()), b.sizes().cwiseProduct(Eigen::Vector3f(p.sx, p.sy, p.sz)), p.yaw}.Aabb();
    }
  }
  if (o_.class_compete_exponent > 0.f) {
    // Readings of one object by several classes (boxes overlapping by more than max_box_iou):
    // each weighed by how much of the view it explains against the best reading of another class
    // there (the pose search's objective: seen furniture surface less weighted free space), so
    // the class whose posed model explains the object wins (a sofa's model explains all of a
    // loveseat, an armchair's a part).
    std::vector<double> objective(order.size(), 0.0), factor(order.size(), 1.0);
    for (size_t j = 0; j < order.size(); ++j)
      if (fit[j].model) objective[j] = std::max(Objective(fit[j].r.comparison, o_.search), 0.0);
    for (size_t j = 0; j < order.size(); ++j) {
      if (!fit[j].model) continue;
      const std::string& cls = input[cand[order[j]]].cls;
      double best = objective[j];
      for (size_t i = 0; i < order.size(); ++i) {
        if (i == j || !fit[i].model || input[cand[order[i]]].cls == cls) continue;
        const Eigen::AlignedBox3f inter = chosen[i].box.intersection(chosen[j].box);
        if (inter.isEmpty()) continue;
        const float vi = inter.volume(), u = chosen[i].box.volume() + chosen[j].box.volume() - vi;
        if (u > 0.f && vi / u > o_.max_box_iou) best = std::max(best, objective[i]);
      }
      factor[j] = best > 0.0 ? std::pow(objective[j] / best, double(o_.class_compete_exponent)) : 1.0;
    }
    for (size_t j = 0; j < order.size(); ++j) chosen[j].score *= factor[j], fit[j].compete = float(factor[j]);
  }
  const std::vector<Choice> choice = ExplainAway(chosen, o_.min_new_share, o_.max_box_iou);
  std::vector<Detection> out;
  for (size_t j = 0; j < order.size(); ++j) {
    const Fitted& ft = fit[j];
    Detection det = input[cand[order[j]]];
    det.checks.clear();
    det.free_space_ratio.reset();
    det.coverage.reset();
    det.rms.reset();
    det.iterations = ft.r.evaluations;
    const float voter_score = det.score;
    if (!ft.model) continue;
    const Eigen::AlignedBox3f& bounds = render_of.at(ft.model)->bounds;
    ModelPlacement p = ft.r.pose;
    p.yaw = std::remainder(p.yaw, float(2 * M_PI));
    const Comparison& c = ft.r.comparison;
    det.model = ft.model->id;
    det.model_pose = p.Rigid();
    det.yaw = p.yaw;
    const Eigen::Vector3f size = bounds.sizes().cwiseProduct(Eigen::Vector3f(p.sx, p.sy, p.sz));
    det.center = p.Apply(bounds.center());
    det.box = OrientedBox{det.center, size, p.yaw};
    det.box_source = "model";
    det.coverage = float(ft.explained_share);
    const double seen = c.seen_object + c.seen_other;
    det.free_space_ratio = seen + c.free > 0.0 ? float(c.free / (seen + c.free)) : 0.f;
    det.score = float(chosen[j].score) * choice[j].share;
    det.evidence["recogniser_score"] = voter_score;
    det.evidence["syn_seen_m2"] = float(c.seen_object);
    det.evidence["syn_seen_other_m2"] = float(c.seen_other);
    det.evidence["syn_free_m2"] = float(c.free);
    det.evidence["syn_occluded_m2"] = float(c.occluded);
    det.evidence["syn_unknown_m2"] = float(c.unknown);
    det.evidence["syn_own_m2"] = float(ft.own_area);
    det.evidence["syn_explained_m2"] = float(ft.explained_area);
    det.evidence["syn_explained_share"] = float(ft.explained_share);
    det.evidence["syn_new_share"] = choice[j].share;
    det.evidence["syn_stretch_x"] = p.sx;
    det.evidence["syn_stretch_y"] = p.sy;
    det.evidence["syn_stretch_z"] = p.sz;
    if (o_.class_compete_exponent > 0.f) det.evidence["syn_compete"] = ft.compete;
    if (o_.view_prior_exponent > 0.f) {
      det.evidence["syn_view_prior"] = ft.view_prior;
      det.evidence["syn_view_e_size"] = ft.view_size;
      det.evidence["syn_view_e_profile"] = ft.view_profile;
    }
    const auto thr = o_.thresholds.find(det.cls);
    det.checks.push_back(Check::AtMost("free_space_ratio", *det.free_space_ratio, o_.max_free_space_ratio));
    det.checks.push_back(Check::AtLeast("score", det.score, thr == o_.thresholds.end() ? o_.default_threshold : thr->second));
    det.checks.push_back(Check::AtLeast("new_share", choice[j].share, o_.min_new_share));
    det.checks.push_back(Check::AtMost("box_iou_with_kept", choice[j].overlap, o_.max_box_iou));
    det.verified = std::all_of(det.checks.begin(), det.checks.end(), [](const Check& x) { return x.passed; });
    if (!choice[j].kept) det.notes.push_back("explained away by better-scored detections");
    out.push_back(std::move(det));
  }
  spdlog::debug("fitters.ransac_upright: synthesis: images {:.0f} ms, {} detections screened ({:.0f} ms), {} searched "
                "({:.0f} ms)", ms_images, cand.size(), ms_screen - ms_images, order.size(), sw.Ms() - ms_screen);
  return out;
}

}  // namespace furnihost::ransac_upright
