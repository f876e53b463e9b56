#include "upright_ransac.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <random>

#include "simd/left_pack.hpp"

namespace furnihost::ransac_upright {

namespace {
constexpr float kPi = 3.14159265358979f;

float WrapAngle(float a) {
  a = std::fmod(a + kPi, 2.f * kPi);
  if (a < 0) a += 2.f * kPi;
  return a - kPi;
}

struct Pose2 {
  float yaw = 0.f, tx = 0.f, ty = 0.f;
};

// One candidate transformation and what scoring it gave.
struct Hyp {
  Pose2 pose;
  int score = -1;    // exact covered count on the subset, -1 when abandoned
  int partial = 0;   // covered count when abandoned
};

// Scores `h` on the subset; abandons it as soon as it cannot reach max(floor, best - slack),
// `best` being the highest score of the batch so far (shared, only grows). Every candidate whose
// final score is within `slack` of the batch maximum is never abandoned, so the candidates kept
// (score >= max(floor, maximum - slack)) do not depend on thread timing. `ev` holds the subset
// points within the model's height range (also as coordinate arrays x, y, z, padded to a
// multiple of 8); `E` counts the whole subset, the others are misses. With `blocks` the points
// are looked up 8 at a time (ModelCloud::CoveredUpright8) and counted block by block; a block
// that would exceed the allowed misses is recounted point by point, so the candidate is abandoned
// at the same point with the same partial count as one point at a time (the allowed misses are
// re-read every 64 points, at the end of a block).
void Score(const ModelCloud& model, const std::vector<Eigen::Vector3f>& ev, const float* x, const float* y,
           const float* z, bool blocks, int E, int floor, int slack, Hyp* h, std::atomic<int>* best) {
  const int n = static_cast<int>(ev.size());
  const float c = std::cos(h->pose.yaw), s = std::sin(h->pose.yaw);
  auto allowed_misses = [&] { return E - std::max(floor, best->load(std::memory_order_relaxed) - slack); };
  int allowed = allowed_misses();
  int hits = 0, misses = E - n;
  if (misses > allowed) {
    h->score = -1;
    h->partial = 0;
    return;
  }
  int k = 0;
  if (blocks)
    for (; k + 8 <= n; k += 8) {
      const int hit = model.CoveredUpright8(x + k, y + k, z + k, c, s, h->pose.tx, h->pose.ty);
      const int block_hits = __builtin_popcount(unsigned(hit));
      if (misses + 8 - block_hits > allowed) {
        for (int l = 0; l < 8; ++l) {
          if (hit & (1 << l)) {
            ++hits;
          } else if (++misses > allowed) {
            h->score = -1;
            h->partial = hits;
            return;
          }
        }
      }
      hits += block_hits, misses += 8 - block_hits;
      if (((k + 7) & 63) == 63) allowed = std::min(allowed, allowed_misses());
    }
  for (; k < n; ++k) {
    const float dx = ev[k].x() - h->pose.tx, dy = ev[k].y() - h->pose.ty;
    if (model.Covered(Eigen::Vector3f(c * dx + s * dy, -s * dx + c * dy, ev[k].z()))) {
      ++hits;
    } else if (++misses > allowed) {
      h->score = -1;
      h->partial = hits;
      return;
    }
    if ((k & 63) == 63) allowed = std::min(allowed, allowed_misses());
  }
  h->score = hits;
  int b = best->load(std::memory_order_relaxed);
  while (hits > b && !best->compare_exchange_weak(b, hits, std::memory_order_relaxed)) {
  }
}

}  // namespace

namespace detail {
ScoreResult ScorePose(const ModelCloud& model, const std::vector<Eigen::Vector3f>& ev, int E, int floor, int slack,
                      float yaw, float tx, float ty, int best, bool blocks) {
  std::vector<float> x(ev.size()), y(ev.size()), z(ev.size());
  for (size_t k = 0; k < ev.size(); ++k) x[k] = ev[k].x(), y[k] = ev[k].y(), z[k] = ev[k].z();
  Hyp h;
  h.pose = {yaw, tx, ty};
  std::atomic<int> b(best);
  Score(model, ev, x.data(), y.data(), z.data(), blocks, E, floor, slack, &h, &b);
  return {h.score, h.partial};
}
}  // namespace detail

void RansacOptions::Check() const {
  auto in01 = [](float v) { return v > 0.f && v <= 1.f; };
  if (!(height_tolerance > 0)) throw StageError("height_tolerance_m must be > 0");
  if (!in01(correspondence_fraction)) throw StageError("correspondence_fraction must be in (0, 1]");
  if (!in01(score_fraction)) throw StageError("score_fraction must be in (0, 1]");
  if (!(p_success > 0 && p_success < 1)) throw StageError("p_success must be in (0, 1)");
  if (max_iterations < 1 || min_iterations < 0 || min_iterations > max_iterations)
    throw StageError("iterations: need 0 <= min_iterations <= max_iterations, max_iterations >= 1");
  if (max_correspondences < 0) throw StageError("max_correspondences must be >= 0");
  if (!(max_shift >= 0.f)) throw StageError("max_shift_m must be >= 0");
}

double RequiredIterations(double p_success, double p_good) {
  if (p_good <= 0.0) return std::numeric_limits<double>::infinity();
  if (p_good >= 1.0) return 0.0;
  return std::log(1.0 - p_success) / std::log(1.0 - p_good);
}

Eigen::Isometry3f UprightIsometry(float x, float y, float z, float yaw) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3f(x, y, z);
  return t;
}

// Optional upright ICP from `pose`, then the final figures of model `m` (index `win`) there.
static void Finish(const ScenePoints& scene, const ModelCloud& m, int win, const RansacOptions& o, Pose2 pose, FitResult* out) {
  const int n = static_cast<int>(scene.points.size());

  // Optional upright ICP: nearest model point per scene point. "point": closed-form 2D rigid
  // update of the point-to-point distances; "plane": linearised least squares of the distances
  // along the model's horizontal normals (points on near-horizontal faces carry no x, y, yaw
  // information and are left out), which slides along walls of the model instead of pulling
  // each scene point onto its nearest model sample.
  // ICP and the final figures use every `stride`-th scene point: all of them unless there are
  // more than 4 x max_score_points (dense scans), then an even subset of about that many.
  const size_t fig_cap = o.max_score_points > 0 ? 4 * static_cast<size_t>(o.max_score_points) : 0;
  const size_t stride = fig_cap > 0 && size_t(n) > fig_cap ? (size_t(n) + fig_cap - 1) / fig_cap : 1;
  for (int r = 0; r < o.refine_iterations; ++r) {
    const Eigen::Isometry3f Tw = UprightIsometry(pose.tx, pose.ty, o.floor_z, pose.yaw);
    const Eigen::Isometry3f Ti = Tw.inverse();
    std::vector<Eigen::Vector2f> a, b, nrm;
    for (size_t q = 0; q < scene.points.size(); q += stride) {
      const Eigen::Vector3f& p = scene.points[q];
      float d = 0.f;
      const int j = m.Nearest(Ti * p, &d);
      if (j < 0 || d > 2.f * m.InlierDistance()) continue;
      if (o.refine_plane) {
        const Eigen::Vector2f n = (Tw.linear() * m.Normals()[j]).head<2>();
        if (n.norm() < 0.5f) continue;
        nrm.push_back(n.normalized());
      }
      a.push_back((Tw * m.Cloud()[j]).head<2>());
      b.push_back(p.head<2>());
    }
    if (a.size() < 3) break;
    Eigen::Vector2f ca = Eigen::Vector2f::Zero(), cb = Eigen::Vector2f::Zero();
    for (size_t q = 0; q < a.size(); ++q) {
      ca += a[q];
      cb += b[q];
    }
    ca /= float(a.size());
    cb /= float(a.size());
    float dth = 0.f;
    Eigen::Vector2f t = Eigen::Vector2f::Zero();
    if (o.refine_plane) {
      // Model moved by a rotation dth about ca then t: a' ~ a + dth perp(a - ca) + t.
      Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      for (size_t q = 0; q < a.size(); ++q) {
        const Eigen::Vector2f u = a[q] - ca;
        const Eigen::Vector3d J(double(-u.y() * nrm[q].x() + u.x() * nrm[q].y()), nrm[q].x(), nrm[q].y());
        const double res = double((a[q] - b[q]).dot(nrm[q]));
        A += J * J.transpose();
        g += J * res;
      }
      A.diagonal().array() += 1e-6 * (A.trace() + 1e-12);
      const Eigen::Vector3d x = A.ldlt().solve(-g);
      if (!x.allFinite()) break;
      dth = static_cast<float>(x(0));
      t = ca - Eigen::Rotation2Df(dth) * ca + Eigen::Vector2f(float(x(1)), float(x(2)));
    } else {
      double sxy = 0, sdot = 0;
      for (size_t q = 0; q < a.size(); ++q) {
        const Eigen::Vector2f u = a[q] - ca, v = b[q] - cb;
        sxy += u.x() * v.y() - u.y() * v.x();
        sdot += u.x() * v.x() + u.y() * v.y();
      }
      dth = static_cast<float>(std::atan2(sxy, sdot));
      t = cb - Eigen::Rotation2Df(dth) * ca;
    }
    const Eigen::Rotation2Df R(dth);
    const Eigen::Vector2f nt = R * Eigen::Vector2f(pose.tx, pose.ty) + t;
    pose = {WrapAngle(pose.yaw + dth), nt.x(), nt.y()};
    if (std::fabs(dth) < 1e-5f && (t - (ca - R * ca)).norm() < 1e-5f) break;
  }

  // Final figures on all scene points.
  out->model = win;
  out->x = pose.tx;
  out->y = pose.ty;
  out->yaw = pose.yaw;
  out->pose = UprightIsometry(pose.tx, pose.ty, o.floor_z, pose.yaw);
  const Eigen::Isometry3f Ti = out->pose.inverse();
  double se = 0.0;
  int tested = 0;
  for (size_t q = 0; q < scene.points.size(); q += stride, ++tested) {
    float d = 0.f;
    m.Nearest(Ti * scene.points[q], &d);
    if (d <= m.InlierDistance()) {
      ++out->covered;
      se += double(d) * d;
    }
  }
  out->total = tested;
  out->coverage = float(out->covered) / float(tested);
  out->rms = out->covered > 0 ? static_cast<float>(std::sqrt(se / out->covered)) : -1.f;
}

FitResult FitUpright(const ScenePoints& scene, const std::vector<const ModelCloud*>& models,
                     const RansacOptions& o, uint64_t seed) {
  o.Check();
  FitResult out;
  out.trials.resize(models.size());
  const int n = static_cast<int>(scene.points.size());
  out.total = n;
  if (n == 0 || models.empty()) return out;
  const bool have_normals = scene.normals.size() == scene.points.size();
  std::mt19937_64 rng(seed);

  // Scoring subset: a fixed random share of the scene points, heights relative to the floor.
  std::vector<int> perm(n);
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), rng);
  // At most max_score_points: the coverage is a share, and a few thousand points estimate it
  // as well as the ~10^5 part points of an object in a dense laser scan (cost per candidate
  // bounded whatever the density; at room-scan densities, ~1-2 K part points, it never binds).
  int E = std::clamp(static_cast<int>(std::lround(o.score_fraction * n)), 1, n);
  if (o.max_score_points > 0) E = std::min(E, o.max_score_points);
  std::vector<Eigen::Vector3f> ev(E);
  for (int k = 0; k < E; ++k) {
    const Eigen::Vector3f& p = scene.points[perm[k]];
    ev[k] = {p.x(), p.y(), p.z() - o.floor_z};
  }
  // Candidates that cannot cover min_coverage would be rejected anyway: abandon them early.
  const int prune = std::max(1, static_cast<int>(std::ceil(o.min_coverage * E)));
  const int slack = static_cast<int>(std::floor(o.model_tie_tolerance * E));

  int global_best = -1;
  std::vector<int> model_best(models.size(), -1);
  std::vector<Pose2> model_pose(models.size());
  // Per model, the poses whose coverage is within the tie tolerance of its best: a partial
  // view (a table top, a seat) is often covered as well by shifted or turned poses, which the
  // explained model surface tells apart (below).
  constexpr size_t kMaxTied = 8;
  std::vector<std::vector<Hyp>> model_tied(models.size());
  int partial_best = -1, partial_model = -1;
  Pose2 partial_pose;

  std::uniform_int_distribution<int> pick(0, n - 1);
  std::uniform_real_distribution<float> random_yaw(-kPi, kPi);
  std::vector<int> cands;
  std::vector<Hyp> hyps;
  const bool blocks = simd::UseAvx2();  // 8 look-ups at a time pay only with AVX2's gathers
  for (size_t mi = 0; mi < models.size(); ++mi) {
    const ModelCloud& model = *models[mi];
    // Subset points above or below the model (by more than the inlier distance) are misses
    // whatever x, y and yaw: counted once, never looked up.
    std::vector<Eigen::Vector3f> ev_in;
    ev_in.reserve(ev.size());
    for (const Eigen::Vector3f& q : ev)
      if (q.z() >= model.Bounds().min().z() - model.InlierDistance() &&
          q.z() <= model.Bounds().max().z() + model.InlierDistance())
        ev_in.push_back(q);
    // The same as coordinate arrays for the lookups 8 at a time.
    std::vector<float> ex(ev_in.size()), ey(ev_in.size()), ez(ev_in.size());
    for (size_t k = 0; k < ev_in.size(); ++k) ex[k] = ev_in[k].x(), ey[k] = ev_in[k].y(), ez[k] = ev_in[k].z();
    int own = -1;
    auto base = [&] { return std::max(prune, global_best - slack); };
    double T = RequiredIterations(o.p_success, double(base()) / E);
    int it = 0;
    // The floor applies once some model has shown a plausible pose (then a high bound makes
    // each abandoned candidate cheap); until then, a model that does not reach min_coverage
    // within the eq. 7 count for p_good = min_coverage is given up (non-matching models).
    while (it < o.max_iterations && (it < T || (global_best >= 0 && it < o.min_iterations))) {
      ++it;
      const int i = pick(rng);
      const Eigen::Vector3f& p = scene.points[i];
      const Eigen::Vector3f ns = have_normals ? scene.normals[i] : Eigen::Vector3f::Constant(NAN);
      const float z = p.z() - o.floor_z;
      const bool known = ns.allFinite();
      const bool informative = known && std::hypot(ns.x(), ns.y()) > o.min_horizontal_normal;

      // Candidate correspondences: model points at a similar height (and normal tilt).
      cands.clear();
      if (informative) {
        model.HeightBand(z, o.height_tolerance, true, &cands);
        const float nz = std::fabs(ns.z());
        cands.erase(std::remove_if(cands.begin(), cands.end(),
                                   [&](int j) {
                                     return std::fabs(std::fabs(model.Normals()[j].z()) - nz) >
                                            o.normal_z_tolerance;
                                   }),
                    cands.end());
      } else {
        model.HeightBand(z, o.height_tolerance, false, &cands);
        if (!known) model.HeightBand(z, o.height_tolerance, true, &cands);
      }
      if (cands.empty()) continue;
      int k = static_cast<int>(std::ceil(o.correspondence_fraction * cands.size()));
      if (o.max_correspondences > 0) k = std::min(k, o.max_correspondences);
      for (int a = 0; a < k; ++a) {  // partial Fisher-Yates: a random subset of size k
        std::uniform_int_distribution<int> d(a, static_cast<int>(cands.size()) - 1);
        std::swap(cands[a], cands[d(rng)]);
      }
      hyps.clear();
      const float as = std::atan2(ns.y(), ns.x());
      for (int a = 0; a < k; ++a) {
        const Eigen::Vector3f& m = model.Cloud()[cands[a]];
        auto add = [&](float yaw) {
          const float c = std::cos(yaw), s = std::sin(yaw);
          Hyp h;
          h.pose = {WrapAngle(yaw), p.x() - (c * m.x() - s * m.y()), p.y() - (s * m.x() + c * m.y())};
          // The model origin is its bounding-box bottom centre: (tx, ty) is the fitted centre.
          if (o.max_shift > 0.f && std::hypot(h.pose.tx - o.prior_xy.x(), h.pose.ty - o.prior_xy.y()) > o.max_shift)
            return;
          hyps.push_back(h);
        };
        if (informative) {
          const Eigen::Vector3f& nm = model.Normals()[cands[a]];
          const float yaw = as - std::atan2(nm.y(), nm.x());
          add(yaw);
          if (o.normal_sign_ambiguous) add(yaw + kPi);
        } else {
          add(random_yaw(rng));  // near-vertical normal: the paper's random rotation
        }
      }

      const int floor = base();
      std::atomic<int> best(own);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, hyps.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t h = r.begin(); h < r.end(); ++h)
          Score(model, ev_in, ex.data(), ey.data(), ez.data(), blocks, E, floor, slack, &hyps[h], &best);
      });
      int best_h = -1;
      for (size_t h = 0; h < hyps.size(); ++h)
        if (hyps[h].score >= floor && (best_h < 0 || hyps[h].score > hyps[best_h].score)) best_h = int(h);
      if (best_h >= 0) {
        if (hyps[best_h].score > own) {
          own = hyps[best_h].score;
          model_best[mi] = own;
          model_pose[mi] = hyps[best_h].pose;
          global_best = std::max(global_best, own);
          T = RequiredIterations(o.p_success, double(std::max(own, base())) / E);
        }
        // Near ties, in candidate order (deterministic); near-duplicate poses are skipped.
        const int keep_from = std::max(floor, own - slack);
        std::vector<Hyp>& tied = model_tied[mi];
        tied.erase(std::remove_if(tied.begin(), tied.end(), [&](const Hyp& t) { return t.score < keep_from; }),
                   tied.end());
        for (const Hyp& h : hyps) {
          if (h.score < keep_from) continue;
          const bool dup = std::any_of(tied.begin(), tied.end(), [&](const Hyp& t) {
            return std::hypot(t.pose.tx - h.pose.tx, t.pose.ty - h.pose.ty) < 0.01f &&
                   std::fabs(WrapAngle(t.pose.yaw - h.pose.yaw)) < 0.02f;
          });
          if (!dup) tied.push_back(h);
        }
        std::stable_sort(tied.begin(), tied.end(), [](const Hyp& a, const Hyp& b) { return a.score > b.score; });
        if (tied.size() > kMaxTied) tied.resize(kMaxTied);
      } else if (global_best < 0) {
        // Nothing reached min_coverage yet: remember the most promising abandoned candidate so
        // that a rejected detection still reports a pose and its (low) coverage.
        for (const Hyp& h : hyps)
          if (h.partial > partial_best) {
            partial_best = h.partial;
            partial_model = static_cast<int>(mi);
            partial_pose = h.pose;
          }
      }
    }
    out.trials[mi].samples = it;
    out.trials[mi].subset_coverage = model_best[mi] >= 0 ? float(model_best[mi]) / E : -1.f;
    out.iterations += it;
  }

  // Share of a model's points within the inlier distance of a scene point (ranks tied poses
  // and tied models); scene = the context points when given (the scan around the hypothesis:
  // a partial support, e.g. a seat without its backrest, cannot tell a chair from its turn by
  // 180°, the scan can). At most ~4000 model points are tested: a share, not a count.
  std::unique_ptr<PointIndex> scene_index;
  auto explained_share = [&](int mi, const Pose2& ps) {
    if (!scene_index) scene_index = std::make_unique<PointIndex>(scene.context.empty() ? &scene.points : &scene.context);
    const ModelCloud& m = *models[mi];
    const Eigen::Isometry3f T = UprightIsometry(ps.tx, ps.ty, o.floor_z, ps.yaw);
    const size_t stride = std::max<size_t>(1, m.Cloud().size() / 4000);
    int cnt = 0, tested = 0;
    for (size_t q = 0; q < m.Cloud().size(); q += stride, ++tested)
      cnt += scene_index->AnyWithin(T * m.Cloud()[q], m.InlierDistance());
    return tested ? double(cnt) / double(tested) : 0.0;
  };
  // Each model's pose: the best-covering one, unless a near-tied pose explains a clearly larger
  // share of the model (kShareMargin: between good poses the share differs by sampling noise,
  // between a right and a shifted pose of a partial view by much more).
  constexpr double kShareMargin = 0.01;
  std::vector<double> model_share(models.size(), -1.0);
  for (size_t mi = 0; mi < models.size(); ++mi) {
    if (model_best[mi] < 0 || model_best[mi] < global_best - slack || model_tied[mi].size() < 2) continue;
    model_share[mi] = explained_share(static_cast<int>(mi), model_pose[mi]);
    for (const Hyp& h : model_tied[mi]) {
      const double share = explained_share(static_cast<int>(mi), h.pose);
      if (share > model_share[mi] + kShareMargin) {
        model_share[mi] = share;
        model_pose[mi] = h.pose;
      }
    }
  }

  int win = -1;
  Pose2 pose;
  if (global_best >= 0) {
    // The best model explains the most model points: among the models whose coverage is within
    // the tie tolerance of the best, the largest share of the model's (outer) points near scene
    // points wins. A share, not a count: a bigger model that also covers the scene points (a
    // dresser over a drawer's front) explains as many points but a smaller share of itself.
    std::vector<int> tied;
    for (size_t mi = 0; mi < models.size(); ++mi)
      if (model_best[mi] >= 0 && model_best[mi] >= global_best - slack) tied.push_back(static_cast<int>(mi));
    double best_share = -1.0;
    for (int mi : tied) {
      if (tied.size() == 1) {  // nothing to break: skip the model-to-scene queries
        win = mi;
        break;
      }
      const double share = model_share[mi] >= 0 ? model_share[mi] : explained_share(mi, model_pose[mi]);
      if (win < 0 || share > best_share || (share == best_share && model_best[mi] > model_best[win])) {
        win = mi;
        best_share = share;
      }
    }
    out.explained_share = best_share;
    out.reached_bound = true;
    pose = model_pose[win];
  } else if (partial_model >= 0) {
    win = partial_model;
    pose = partial_pose;
  } else {
    return out;
  }
  for (const Hyp& h : model_tied[win])
    if (out.reached_bound && (h.pose.tx != pose.tx || h.pose.ty != pose.ty || h.pose.yaw != pose.yaw))
      out.alternatives.emplace_back(h.pose.tx, h.pose.ty, h.pose.yaw);
  Finish(scene, *models[win], win, o, pose, &out);
  return out;
}

FitResult FinishAt(const ScenePoints& scene, const ModelCloud& model, int index, const RansacOptions& options,
                   float x, float y, float yaw) {
  FitResult out;
  out.total = static_cast<int>(scene.points.size());
  out.reached_bound = true;
  Pose2 pose;
  pose.tx = x;
  pose.ty = y;
  pose.yaw = yaw;
  Finish(scene, model, index, options, pose, &out);
  return out;
}



}  // namespace furnihost::ransac_upright
