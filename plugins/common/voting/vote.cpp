// furnihost::voting: Hough voting of the scene parts' words for object centres on the floor plane,
// and the selection of hypotheses (smoothing, maxima, non-maximum suppression).
#include "voting/voting.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <set>

#include "furnihost/error.hpp"
#include "furnihost/geometry.hpp"

namespace furnihost::voting {

// ---- voting and selection ---------------------------------------------------------------

namespace {

struct PartRef {
  int scene, part;
  Eigen::Vector3f world;  // part centroid in the world frame
};

// All votes, grouped by class: class c owns [class_begin[c], class_begin[c + 1]).
struct VoteSet {
  std::vector<float> x, y, z, w;
  std::vector<int> part;  // index into the PartRef list
  std::vector<size_t> class_begin;
};

// Separable Gaussian (normalised kernel, truncated at 3 sigma) on a W x H row-major grid.
void GaussianSmooth(std::vector<float>& g, int W, int H, float sigma_cells) {
  if (!(sigma_cells > 0.f)) return;
  const int r = std::max(1, static_cast<int>(std::ceil(3.f * sigma_cells)));
  std::vector<float> k(2 * r + 1);
  float sum = 0.f;
  for (int i = -r; i <= r; ++i) sum += k[i + r] = std::exp(-0.5f * i * i / (sigma_cells * sigma_cells));
  for (float& v : k) v /= sum;
  std::vector<float> tmp(g.size(), 0.f);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float v = g[static_cast<size_t>(y) * W + x];
      if (v == 0.f) continue;
      for (int i = std::max(-r, -x); i <= std::min(r, W - 1 - x); ++i)
        tmp[static_cast<size_t>(y) * W + x + i] += v * k[i + r];
    }
  std::fill(g.begin(), g.end(), 0.f);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const float v = tmp[static_cast<size_t>(y) * W + x];
      if (v == 0.f) continue;
      for (int i = std::max(-r, -y); i <= std::min(r, H - 1 - y); ++i)
        g[static_cast<size_t>(y + i) * W + x] += v * k[i + r];
    }
}

// Running maximum over windows of 2r+1 samples of one line (van Herk / Gil-Werman: three
// comparisons per sample whatever r). Values are >= 0, so padding with 0 changes nothing.
void LineMax(const float* in, size_t stride, int n, int r, float* out, size_t out_stride,
             std::vector<float>& pre, std::vector<float>& suf) {
  const int w = 2 * r + 1;
  const int padded = ((n + 2 * r + w - 1) / w) * w;
  pre.assign(padded, 0.f);
  suf.assign(padded, 0.f);
  auto at = [&](int i) { return (i >= r && i < n + r) ? in[static_cast<size_t>(i - r) * stride] : 0.f; };
  for (int b = 0; b < padded; b += w) {
    pre[b] = at(b);
    for (int i = b + 1; i < b + w; ++i) pre[i] = std::max(pre[i - 1], at(i));
    suf[b + w - 1] = at(b + w - 1);
    for (int i = b + w - 2; i >= b; --i) suf[i] = std::max(suf[i + 1], at(i));
  }
  // Output x covers padded samples [x, x + 2r].
  for (int x = 0; x < n; ++x) out[static_cast<size_t>(x) * out_stride] = std::max(suf[x], pre[x + 2 * r]);
}

// Sliding maximum over a (2r+1) x (2r+1) square.
std::vector<float> MaxFilter(const std::vector<float>& g, int W, int H, int r) {
  std::vector<float> tmp(g.size()), out(g.size()), pre, suf;
  for (int y = 0; y < H; ++y)
    LineMax(&g[static_cast<size_t>(y) * W], 1, W, r, &tmp[static_cast<size_t>(y) * W], 1, pre, suf);
  for (int x = 0; x < W; ++x) LineMax(&tmp[x], W, H, r, &out[x], W, pre, suf);
  return out;
}

// Items bucketed by the cell of a W x H grid on the floor plane (counting sort, items of a
// cell in index order): a disc query visits the items of the cells its bounding square touches.
class FloorBuckets {
 public:
  FloorBuckets(Eigen::Vector2f origin, float cell, int W, int H) : origin_(origin), cell_(cell), W_(W), H_(H) {}

  int CellIndex(float x, float y) const {
    const int ix = std::clamp(static_cast<int>(std::floor((x - origin_.x()) / cell_)), 0, W_ - 1);
    const int iy = std::clamp(static_cast<int>(std::floor((y - origin_.y()) / cell_)), 0, H_ - 1);
    return iy * W_ + ix;
  }

  // Sorts items [0, n) by cell_of(i) (a CellIndex); item i is reported as i + offset.
  template <class CellOf>
  void Build(size_t n, size_t offset, CellOf&& cell_of) {
    start_.assign(static_cast<size_t>(W_) * H_ + 1, 0);
    std::vector<int> cell(n);
    for (size_t i = 0; i < n; ++i) ++start_[(cell[i] = cell_of(i)) + 1];
    std::partial_sum(start_.begin(), start_.end(), start_.begin());
    order_.resize(n);
    std::vector<int> next(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < n; ++i) order_[next[cell[i]]++] = static_cast<int>(i + offset);
  }

  // Calls f(i) for every item in the cells of the square of half side `radius` around (x, y);
  // the caller tests the distance.
  template <class F>
  void ForSquare(double x, double y, double radius, F&& f) const {
    const int x0 = std::max(0, static_cast<int>(std::floor((x - radius - origin_.x()) / cell_)));
    const int x1 = std::min(W_ - 1, static_cast<int>(std::floor((x + radius - origin_.x()) / cell_)));
    const int y0 = std::max(0, static_cast<int>(std::floor((y - radius - origin_.y()) / cell_)));
    const int y1 = std::min(H_ - 1, static_cast<int>(std::floor((y + radius - origin_.y()) / cell_)));
    for (int cy = y0; cy <= y1; ++cy)
      for (int cx = x0; cx <= x1; ++cx) {
        const int c = cy * W_ + cx;
        for (int k = start_[c]; k < start_[c + 1]; ++k) f(order_[k]);
      }
  }

 private:
  Eigen::Vector2f origin_;
  float cell_;
  int W_, H_;
  std::vector<int> start_, order_;
};

// The votes of one class bucketed by grid cell (for disc queries) and summed per cell.
class VoteBuckets {
 public:
  VoteBuckets(const VoteSet& votes, size_t begin, size_t end, Eigen::Vector2f origin, float cell,
              int W, int H)
      : v_(votes), b_(origin, cell, W, H) {
    raw.assign(static_cast<size_t>(W) * H, 0.f);
    b_.Build(end - begin, begin, [&](size_t k) {
      const size_t i = begin + k;
      const int c = b_.CellIndex(votes.x[i], votes.y[i]);
      raw[c] += votes.w[i];
      return c;
    });
  }

  // Calls f(i) for every vote i within `radius` of c (x, y).
  template <class F>
  void ForDisc(const Eigen::Vector2d& c, double radius, F&& f) const {
    const double r2 = radius * radius;
    b_.ForSquare(c.x(), c.y(), radius, [&](int i) {
      const double dx = v_.x[i] - c.x(), dy = v_.y[i] - c.y();
      if (dx * dx + dy * dy <= r2) f(i);
    });
  }

  std::vector<float> raw;  // summed vote weight per cell, row-major W x H

 private:
  const VoteSet& v_;
  FloorBuckets b_;
};

bool FootprintsOverlap(const Eigen::Vector3f& a, const Eigen::Vector3f& b, float size,
                       bool circle) {
  const float dx = a.x() - b.x(), dy = a.y() - b.y();
  if (circle) return dx * dx + dy * dy < size * size;
  return std::abs(dx) < size && std::abs(dy) < size;
}

struct Activation {
  int part;  // index into the PartRef list
  int word;
  float weight;  // p(A_i | f), times 1 / (1 + distance) with inverse_distance
};

// Scan points (world frame) bucketed on the floor plane for the column check; heights are
// taken above the floor.
class ColumnIndex {
 public:
  ColumnIndex(const std::vector<SceneParts>& scenes, float cell) {
    for (const auto& sc : scenes) {
      if (!sc.scan) continue;
      for (const auto& p : sc.scan->points) {
        const Eigen::Vector3f w = sc.scan->pose * p;
        if (!w.allFinite()) continue;
        pts_.emplace_back(w.x(), w.y(), sc.scan->ground ? sc.scan->ground->Above(p) : w.z());
      }
    }
    if (pts_.empty()) return;
    Eigen::Vector2f lo(std::numeric_limits<float>::max(), std::numeric_limits<float>::max());
    Eigen::Vector2f hi = -lo;
    for (const auto& p : pts_) {
      lo = lo.cwiseMin(p.head<2>());
      hi = hi.cwiseMax(p.head<2>());
    }
    // Cap the grid at ~4M cells: far outliers make the cells coarser, not the memory larger.
    cell = std::max(cell, std::max(hi.x() - lo.x(), hi.y() - lo.y()) / 2000.f);
    b_ = std::make_unique<FloorBuckets>(lo, cell, static_cast<int>((hi.x() - lo.x()) / cell) + 1,
                                        static_cast<int>((hi.y() - lo.y()) / cell) + 1);
    b_->Build(pts_.size(), 0, [&](size_t i) { return b_->CellIndex(pts_[i].x(), pts_[i].y()); });
  }

  // Points within `radius` of (x, y): counts of heights in (0.05, top] and above top.
  void Count(float x, float y, float radius, float top, int& object, int& above) const {
    object = above = 0;
    if (!b_) return;
    const float r2 = radius * radius;
    b_->ForSquare(x, y, radius, [&](int i) {
      const Eigen::Vector3f& p = pts_[i];
      const float dx = p.x() - x, dy = p.y() - y;
      if (dx * dx + dy * dy > r2) return;
      if (p.z() > top) ++above;
      else if (p.z() > 0.05f) ++object;
    });
  }

 private:
  std::vector<Eigen::Vector3f> pts_;
  std::unique_ptr<FloorBuckets> b_;
};

// Maxima search, scoring, thresholding and the footprint check for the votes [vb, ve) of
// one class; fills grid.values (grid geometry set by the caller); `keep` (if set) vets each
// hypothesis before the footprint check.
std::vector<Hypothesis> SelectClass(const VoteSet& votes, size_t vb, size_t ve,
                                    const std::vector<PartRef>& parts, const ClassModel& cm,
                                    const SelectionOptions& opt, VoteGrid& grid,
                                    const std::function<bool(const Hypothesis&)>& keep) {
  const int W = grid.width, H = grid.height;
  const Eigen::Vector2f origin = grid.origin;
  const float cell = grid.cell;
  const VoteBuckets buckets(votes, vb, ve, origin, cell, W, H);
  // Summed-area table of the raw weights: an upper bound of any window's score, so
  // candidates that cannot pass the threshold skip the exact disc sum.
  std::vector<double> sat(static_cast<size_t>(W + 1) * (H + 1), 0.0);
  for (int y = 0; y < H; ++y) {
    double row = 0.0;
    for (int x = 0; x < W; ++x) {
      row += buckets.raw[static_cast<size_t>(y) * W + x];
      sat[static_cast<size_t>(y + 1) * (W + 1) + x + 1] = row + sat[static_cast<size_t>(y) * (W + 1) + x + 1];
    }
  }
  auto box_sum = [&](int x0, int y0, int x1, int y1) {  // inclusive cell ranges, clamped
    x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, W - 1), y1 = std::min(y1, H - 1);
    if (x0 > x1 || y0 > y1) return 0.0;
    auto at = [&](int x, int y) { return sat[static_cast<size_t>(y) * (W + 1) + x]; };
    return at(x1 + 1, y1 + 1) - at(x0, y1 + 1) - at(x1 + 1, y0) + at(x0, y0);
  };

  grid.values = buckets.raw;
  GaussianSmooth(grid.values, W, H, opt.smoothing / cell);
  const float half = 0.5f * opt.window_scale * cm.width;  // search and score radius [m]
  const int r = std::max(1, static_cast<int>(std::floor(half / cell)));
  const std::vector<float> mx = MaxFilter(grid.values, W, H, r);
  std::vector<int> cand;
  for (int i = 0; i < W * H; ++i)
    if (grid.values[i] > 0.f && grid.values[i] >= mx[i]) cand.push_back(i);
  std::sort(cand.begin(), cand.end(), [&](int a, int b) {
    return grid.values[a] != grid.values[b] ? grid.values[a] > grid.values[b] : a < b;
  });

  const float threshold = opt.ThresholdFor(cm.name);
  std::vector<Hypothesis> hyps;
  std::vector<double> part_weight(parts.size(), 0.0);
  std::vector<int> touched;
  for (int ci : cand) {
    Eigen::Vector2d ctr(origin.x() + (ci % W + 0.5) * cell, origin.y() + (ci / W + 0.5) * cell);
    // Mean shift onto the raw votes: the grid quantises to a cell, the votes do not.
    for (int it = 0; it < 10 && opt.refine_radius > 0.f; ++it) {
      double sw = 0.0;
      Eigen::Vector2d sp = Eigen::Vector2d::Zero();
      buckets.ForDisc(ctr, opt.refine_radius, [&](int i) {
        sw += votes.w[i];
        sp += votes.w[i] * Eigen::Vector2d(votes.x[i], votes.y[i]);
      });
      if (!(sw > 0.0)) break;
      const Eigen::Vector2d next = sp / sw;
      const double shift = (next - ctr).norm();
      ctr = next;
      if (shift < 1e-5) break;
    }
    const int bx0 = static_cast<int>(std::floor((ctr.x() - half - origin.x()) / cell));
    const int by0 = static_cast<int>(std::floor((ctr.y() - half - origin.y()) / cell));
    const int bx1 = static_cast<int>(std::floor((ctr.x() + half - origin.x()) / cell));
    const int by1 = static_cast<int>(std::floor((ctr.y() + half - origin.y()) / cell));
    if (box_sum(bx0, by0, bx1, by1) < threshold) continue;
    double score = 0.0, zsum = 0.0;
    buckets.ForDisc(ctr, half, [&](int i) {
      score += votes.w[i];
      zsum += static_cast<double>(votes.w[i]) * votes.z[i];
      if (part_weight[votes.part[i]] == 0.0) touched.push_back(votes.part[i]);
      part_weight[votes.part[i]] += votes.w[i];
    });
    if (score >= threshold && score > 0.0) {
      Hypothesis h;
      h.cls = cm.name;
      h.center = Eigen::Vector3f(static_cast<float>(ctr.x()), static_cast<float>(ctr.y()),
                                 static_cast<float>(zsum / score));
      h.score = static_cast<float>(score);
      for (int gp : touched)
        h.support.push_back({parts[gp].scene, parts[gp].part, static_cast<float>(part_weight[gp])});
      std::sort(h.support.begin(), h.support.end(), [](const Support& a, const Support& b) {
        if (a.weight != b.weight) return a.weight > b.weight;
        return a.scene != b.scene ? a.scene < b.scene : a.part < b.part;
      });
      hyps.push_back(std::move(h));
    }
    for (int gp : touched) part_weight[gp] = 0.0;
    touched.clear();
  }

  std::sort(hyps.begin(), hyps.end(), [](const Hypothesis& a, const Hypothesis& b) {
    if (a.score != b.score) return a.score > b.score;
    if (a.center.x() != b.center.x()) return a.center.x() < b.center.x();
    return a.center.y() < b.center.y();
  });
  // Maxima that mean shift moved into one window are one maximum (window = search window);
  // then same-class footprints must not overlap (Sect. VI-B), the stronger one wins.
  const float fsize = opt.footprint_scale * cm.width;
  std::vector<Hypothesis> kept;
  for (auto& h : hyps) {
    if (keep && !keep(h)) continue;  // before the footprint check: a dropped one suppresses nothing
    bool drop = false;
    for (const auto& k : kept)
      drop = drop || FootprintsOverlap(h.center, k.center, half, false) ||
             FootprintsOverlap(h.center, k.center, fsize, opt.footprint == "circle");
    if (!drop) kept.push_back(std::move(h));
  }
  return kept;
}

}  // namespace

VoteResult VoteAndSelect(const Codebook& book, const WordIndex& index,
                         const std::vector<SceneParts>& scenes, const SelectionOptions& opt) {
  VoteResult res;
  const int C = static_cast<int>(book.classes.size());
  const int K = book.Words();
  for (const auto& c : book.classes) res.classes.push_back(c.name);
  std::vector<char> active(C, opt.classes.empty() ? 1 : 0);
  for (const auto& name : opt.classes) {
    const auto it = std::find(res.classes.begin(), res.classes.end(), name);
    if (it == res.classes.end()) {
      std::string known;
      for (const auto& c : res.classes) known += (known.empty() ? "" : ", ") + c;
      throw StageError("classes: the model has no class '" + name + "' (it knows: " + known + ")");
    }
    active[it - res.classes.begin()] = 1;
  }
  for (const auto& name : opt.column_clear_classes)
    if (std::find(res.classes.begin(), res.classes.end(), name) == res.classes.end())
      spdlog::warn("voter: column_clear_classes names '{}', a class the model does not have (ignored)", name);

  // ---- activation (eq. 4) ----
  std::vector<PartRef> parts;
  std::vector<Activation> acts;
  std::vector<float> scene_yaw(scenes.size(), 0.f);
  const int dim = book.Dim();
  const int act = std::max(1, opt.activations);
  const int vocabularies = index.Vocabularies();
  if (vocabularies != book.Vocabularies())
    throw StageError("voter: the word index has " + std::to_string(vocabularies) + " vocabularies, the codebook " +
                     std::to_string(book.Vocabularies()));
  std::vector<long> idx(act);
  std::vector<float> d2(act), q(dim);
  std::vector<double> wv(act);
  // The word search is bounded a hair above max_distance; the exact cut stays the check below.
  const float bound = opt.max_distance > 0.f ? opt.max_distance * opt.max_distance * 1.0001f : 0.f;
  size_t skipped = 0, out_of_range = 0;
  for (size_t s = 0; s < scenes.size(); ++s) {
    const SceneParts& sc = scenes[s];
    const std::string where = "scene " + std::to_string(s) + ": ";
    if (!sc.scan || !sc.segmentation || !sc.features)
      throw StageError(where + "missing scan, segmentation or features");
    const auto& F = sc.features->values;
    const auto& segs = sc.segmentation->parts;
    if (static_cast<size_t>(F.rows()) != segs.size())
      throw StageError(where + std::to_string(F.rows()) + " feature rows for " +
                       std::to_string(segs.size()) + " parts");
    if (F.rows() > 0 && F.cols() != dim)
      throw StageError(where + "features have " + std::to_string(F.cols()) +
                       " columns, the voter model was trained with " + std::to_string(dim));
    const Eigen::Isometry3f& pose = sc.scan->pose;
    scene_yaw[s] = std::atan2(pose.linear()(1, 0), pose.linear()(0, 0));
    for (Eigen::Index i = 0; i < F.rows(); ++i) {
      if (!F.row(i).allFinite() || !segs[i].centroid.allFinite()) {
        ++skipped;
        continue;
      }
      const auto& ex = sc.features->excess;
      if (opt.max_out_of_range > 0.f && ex.size() == F.rows() && ex[i] > opt.max_out_of_range) {
        ++out_of_range;
        continue;
      }
      for (int j = 0; j < dim; ++j) q[j] = F(i, j);
      // Eq. 4 within each vocabulary; a pooled codebook's vocabularies weigh 1 / V each.
      int gpart = -1;
      for (int v = 0; v < vocabularies; ++v) {
        const int n = index.Nearest(q.data(), act, idx.data(), d2.data(), bound, v);
        double wsum = 0.0;
        int used = 0;
        for (int a = 0; a < n; ++a) {
          const double dist = std::sqrt(std::max(0.f, d2[a]));
          if (opt.max_distance > 0.f && dist > opt.max_distance) break;  // nearest first
          d2[a] = static_cast<float>(dist);
          wv[a] = 1.0 / (dist + 1e-6);
          wsum += wv[a];
          ++used;
        }
        if (used == 0) continue;
        if (gpart < 0) {
          gpart = static_cast<int>(parts.size());
          parts.push_back({static_cast<int>(s), static_cast<int>(i), pose * segs[i].centroid});
        }
        for (int a = 0; a < used; ++a) {
          float pa = static_cast<float>(wv[a] / wsum / vocabularies);
          if (opt.inverse_distance) pa /= 1.f + d2[a];
          acts.push_back({gpart, static_cast<int>(idx[a]), pa});
        }
      }
    }
  }
  if (skipped) spdlog::warn("voter: skipped {} scene parts with non-finite features", skipped);
  if (out_of_range)
    spdlog::debug("voter: {} scene parts lie more than {} training ranges outside the training features",
                  out_of_range, opt.max_out_of_range);
  // Height consistency: an element votes only when its training part sat at about the scene
  // part's height above the floor (objects stand on the floor).
  const bool gate = opt.height_tolerance > 0.f && !book.element_height.empty();
  const bool column = opt.column_radius > 0.f;
  std::vector<float> part_height(gate ? parts.size() : 0);  // above the scan's ground, once per part
  for (size_t i = 0; i < part_height.size(); ++i) {
    const Scan* sc = scenes[parts[i].scene].scan;
    part_height[i] = sc ? sc->HeightAboveGround(parts[i].world) : parts[i].world.z();
  }
  auto height_ok = [&](int part, int e) {
    return !gate || std::abs(part_height[part] - book.element_height[e]) <= opt.height_tolerance;
  };

  // ---- votes x_v = l + d with weight p(A_i|f) / #(A_i, o) (eq. 5), grouped by class ----
  VoteSet votes;
  votes.class_begin.assign(C + 1, 0);
  if (!gate) {
    std::vector<int> word_class(static_cast<size_t>(K) * C, 0);
    for (int k = 0; k < K; ++k)
      for (int e = book.element_begin[k]; e < book.element_begin[k + 1]; ++e)
        ++word_class[static_cast<size_t>(k) * C + book.element_class[e]];
    for (const auto& a : acts)
      for (int c = 0; c < C; ++c)
        if (active[c]) votes.class_begin[c + 1] += word_class[static_cast<size_t>(a.word) * C + c];
  } else {
    for (const auto& a : acts)
      for (int e = book.element_begin[a.word]; e < book.element_begin[a.word + 1]; ++e)
        if (active[book.element_class[e]] && height_ok(a.part, e)) ++votes.class_begin[book.element_class[e] + 1];
  }
  std::partial_sum(votes.class_begin.begin(), votes.class_begin.end(), votes.class_begin.begin());
  const size_t total = votes.class_begin.back();
  votes.x.resize(total);
  votes.y.resize(total);
  votes.z.resize(total);
  votes.w.resize(total);
  votes.part.resize(total);
  res.votes.resize(total);
  {
    std::vector<size_t> next(votes.class_begin.begin(), votes.class_begin.end() - 1);
    std::vector<Eigen::Vector3f> rd(book.d.size());
    int rd_scene = -1;
    for (const auto& a : acts) {
      const PartRef& pr = parts[a.part];
      if (pr.scene != rd_scene) {  // d turns with the scene sensor's heading
        rd_scene = pr.scene;
        const Eigen::Matrix3f rz =
            Eigen::AngleAxisf(scene_yaw[rd_scene], Eigen::Vector3f::UnitZ()).toRotationMatrix();
        for (size_t e = 0; e < book.d.size(); ++e) rd[e] = rz * book.d[e];
      }
      for (int e = book.element_begin[a.word]; e < book.element_begin[a.word + 1]; ++e) {
        const int c = book.element_class[e];
        if (!active[c] || !height_ok(a.part, e)) continue;
        const size_t i = next[c]++;
        const Eigen::Vector3f x = pr.world + rd[e];
        votes.x[i] = x.x();
        votes.y[i] = x.y();
        votes.z[i] = x.z();
        votes.w[i] = a.weight * book.element_norm[e];
        votes.part[i] = a.part;
        res.votes[i] = Eigen::Vector4f(x.x(), x.y(), static_cast<float>(c), votes.w[i]);
      }
    }
  }

  // ---- accumulation on the floor plane (eq. 6) ----
  float cell = opt.cell;
  Eigen::Vector2f lo(std::numeric_limits<float>::max(), std::numeric_limits<float>::max());
  Eigen::Vector2f hi = -lo;
  for (size_t i = 0; i < total; ++i) {
    lo = lo.cwiseMin(Eigen::Vector2f(votes.x[i], votes.y[i]));
    hi = hi.cwiseMax(Eigen::Vector2f(votes.x[i], votes.y[i]));
  }
  float max_half = 0.f;
  for (int c = 0; c < C; ++c)
    if (active[c]) max_half = std::max(max_half, 0.5f * opt.window_scale * book.classes[c].width);
  const float margin = std::max(max_half, 3.f * opt.smoothing) + opt.cell;
  int W = 0, H = 0;
  Eigen::Vector2f origin = Eigen::Vector2f::Zero();
  if (total > 0) {
    origin = lo - Eigen::Vector2f::Constant(margin);
    const Eigen::Vector2f extent = hi - lo + Eigen::Vector2f::Constant(2 * margin);
    auto dims = [&](float c) {
      W = static_cast<int>(std::ceil(extent.x() / c)) + 1;
      H = static_cast<int>(std::ceil(extent.y() / c)) + 1;
    };
    dims(cell);
    const double cells = static_cast<double>(W) * H;
    if (cells > static_cast<double>(opt.max_grid_cells)) {
      cell *= static_cast<float>(std::sqrt(cells / static_cast<double>(opt.max_grid_cells)) * 1.01);
      dims(cell);
      spdlog::warn("voter: votes span {:.1f} x {:.1f} m; grid cell enlarged to {:.3f} m", extent.x(),
                   extent.y(), cell);
    }
  }

  std::unique_ptr<ColumnIndex> columns;
  if (column) columns = std::make_unique<ColumnIndex>(scenes, opt.column_radius);
  size_t column_dropped = 0;
  for (int c = 0; c < C; ++c) {
    if (!active[c]) continue;
    const ClassModel& cm = book.classes[c];
    const bool clear = opt.column_clear_classes.empty() ||
                       std::find(opt.column_clear_classes.begin(), opt.column_clear_classes.end(), cm.name) !=
                           opt.column_clear_classes.end();
    std::function<bool(const Hypothesis&)> keep;
    if (columns)
      keep = [&, clear](const Hypothesis& h) {
        int object = 0, above = 0;
        columns->Count(h.center.x(), h.center.y(), opt.column_radius, cm.height + opt.column_margin, object, above);
        const bool ok = object >= opt.column_min_points &&
                        (!clear || above <= opt.column_max_above * static_cast<float>(object + above));
        column_dropped += !ok;
        return ok;
      };
    VoteGrid grid;
    grid.cls = book.classes[c].name;
    grid.origin = origin;
    grid.cell = cell;
    grid.width = W;
    grid.height = H;
    const size_t vb = votes.class_begin[c], ve = votes.class_begin[c + 1];
    if (spdlog::should_log(spdlog::level::debug)) {
      double mass = 0.0;
      for (size_t i = vb; i < ve; ++i) mass += votes.w[i];
      spdlog::debug("voter: class {}: {} votes, mass {:.2f}", grid.cls, ve - vb, mass);
    }
    if (vb == ve || W == 0) {
      grid.width = grid.height = 0;
    } else {
      for (auto& h : SelectClass(votes, vb, ve, parts, cm, opt, grid, keep))
        res.hypotheses.push_back(std::move(h));
    }
    res.grids.push_back(std::move(grid));
  }
  if (columns) spdlog::debug("voter: column check dropped {} hypotheses", column_dropped);
  std::stable_sort(res.hypotheses.begin(), res.hypotheses.end(),
                   [](const Hypothesis& a, const Hypothesis& b) { return a.score > b.score; });
  return res;
}

}  // namespace furnihost::voting
