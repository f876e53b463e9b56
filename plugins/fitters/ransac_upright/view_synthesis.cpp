#include "view_synthesis.hpp"

#include "furnihost/hash.hpp"
#include "model_cloud.hpp"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace furnihost::ransac_upright {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}  // namespace

void RangeImageOptions::Check() const {
  if (!(pixel_scale > 0.f)) throw StageError("view pixel_scale must be > 0");
  if (!(min_pixel_rad > 0.f) || !(max_pixel_rad >= min_pixel_rad))
    throw StageError("view pixel bounds: need 0 < min <= max");
  if (levels < 1 || levels > 8) throw StageError("view levels: 1 to 8");
}

void CompareOptions::Check() const {
  if (!(seen_tolerance > 0.f)) throw StageError("seen_tolerance_m must be > 0");
  if (!(free_margin >= seen_tolerance)) throw StageError("free_margin_m must be >= seen_tolerance_m");
  if (!(seen_per_m2 >= 0.f)) throw StageError("seen tolerance per m^2 must be >= 0");
  if (!(pixel_per_spacing > 0.f)) throw StageError("pixel_per_spacing must be > 0");
}

float AngularSpacing(const Points& points, const Eigen::Vector3f& origin) {
  if (points.size() < 10) return 0.f;
  // A cube map of 1/57 rad (about 1 degree) pixels at the faces' centres.
  constexpr int kRes = 57, kSide = 2 * kRes;
  std::vector<uint8_t> hit(size_t(6) * kSide * kSide, 0);
  size_t n = 0;
  for (const auto& p : points) {
    const Eigen::Vector3f d = p - origin;
    if (!d.allFinite()) continue;
    const float ax = std::abs(d.x()), ay = std::abs(d.y()), az = std::abs(d.z());
    int face;
    float depth, a, b;
    if (ax >= ay && ax >= az) face = d.x() >= 0.f ? 0 : 1, depth = ax, a = d.y(), b = d.z();
    else if (ay >= az) face = d.y() >= 0.f ? 2 : 3, depth = ay, a = d.x(), b = d.z();
    else face = d.z() >= 0.f ? 4 : 5, depth = az, a = d.x(), b = d.y();
    if (!(depth > 1e-6f)) continue;
    const int u = std::clamp(int(a / depth * kRes + kRes), 0, kSide - 1);
    const int v = std::clamp(int(b / depth * kRes + kRes), 0, kSide - 1);
    hit[(size_t(face) * kSide + size_t(v)) * kSide + size_t(u)] = 1;
    ++n;
  }
  if (n < 10) return 0.f;
  double omega = 0.0;
  for (int f = 0; f < 6; ++f)
    for (int v = 0; v < kSide; ++v)
      for (int u = 0; u < kSide; ++u) {
        if (!hit[(size_t(f) * kSide + size_t(v)) * kSide + size_t(u)]) continue;
        const double a = (u + 0.5 - kRes) / kRes, b = (v + 0.5 - kRes) / kRes;
        omega += 1.0 / (double(kRes) * kRes) / std::pow(1.0 + a * a + b * b, 1.5);
      }
  return float(std::sqrt(omega / double(n)));
}

RangeImage::RangeImage(const Points& points, const std::vector<uint8_t>& object, const Eigen::Vector3f& origin,
                       const RangeImageOptions& o)
    : origin_(origin) {
  o.Check();
  const float spacing = AngularSpacing(points, origin);
  const float pixel = std::clamp(spacing > 0.f ? o.pixel_scale * spacing : o.max_pixel_rad, o.min_pixel_rad,
                                 o.max_pixel_rad);
  levels_.resize(size_t(o.levels));
  for (int l = 0; l < o.levels; ++l) {
    Level& L = levels_[size_t(l)];
    L.res = 1.f / (pixel * float(1 << l));
    L.side = std::max(2, int(std::ceil(2.f * L.res)));
    L.res = 0.5f * float(L.side);  // the face's [-1, 1] spans whole pixels
  }
  // Which faces hold measurements: only those get pixels (a camera's view covers one to three).
  std::array<bool, 6> used{};
  for (const auto& p : points) {
    if (!p.allFinite()) continue;
    const Eigen::Vector3f d = p - origin;
    const float ax = std::abs(d.x()), ay = std::abs(d.y()), az = std::abs(d.z());
    if (!(std::max({ax, ay, az}) > 1e-6f)) continue;
    used[ax >= ay && ax >= az ? (d.x() >= 0.f ? 0 : 1) : ay >= az ? (d.y() >= 0.f ? 2 : 3) : (d.z() >= 0.f ? 4 : 5)] = true;
  }
  for (Level& L : levels_) {
    int64_t next = 1;  // pixel 0: the unknown directions
    for (int f = 0; f < 6; ++f) {
      L.offset[size_t(f)] = used[size_t(f)] ? next : -1;
      if (used[size_t(f)]) next += int64_t(L.side) * L.side;
    }
    L.depth.assign(size_t(next), kInf);
    L.object.assign(size_t(next), 0);
  }
  // Level 0: the nearest point per pixel.
  {
    Level& L = levels_[0];
    for (size_t i = 0; i < points.size(); ++i) {
      if (!points[i].allFinite()) continue;
      uint32_t id;
      float d;
      if (!Project(points[i], 0, &id, &d) || id == 0) continue;
      if (d < L.depth[id]) {
        L.depth[id] = d;
        L.object[id] = object.empty() ? 1 : object[i];
      }
    }
    // Holes: a pixel with nothing measured whose 8 neighbours on its face mostly have a
    // measurement takes their nearest (a sparse surface's gaps between points).
    std::vector<float> fill = L.depth;
    std::vector<uint8_t> fill_obj = L.object;
    const int S = L.side;
    for (int f = 0; f < 6; ++f) {
      if (L.offset[size_t(f)] < 0) continue;
      const size_t base = size_t(L.offset[size_t(f)]);
      for (int v = 1; v + 1 < S; ++v)
        for (int u = 1; u + 1 < S; ++u) {
          const size_t id = base + size_t(v) * S + size_t(u);
          if (L.depth[id] < kInf) continue;
          int k = 0;
          float best = kInf;
          uint8_t obj = 0;
          for (int dv = -1; dv <= 1; ++dv)
            for (int du = -1; du <= 1; ++du) {
              const size_t j = base + size_t(v + dv) * S + size_t(u + du);
              if (L.depth[j] < kInf) {
                ++k;
                if (L.depth[j] < best) best = L.depth[j], obj = L.object[j];
              }
            }
          if (k >= 5) fill[id] = best, fill_obj[id] = obj;
        }
    }
    L.depth.swap(fill);
    L.object.swap(fill_obj);
  }
  // Coarser levels: the nearest of each 2 x 2 block below.
  for (size_t l = 1; l < levels_.size(); ++l) {
    const Level& B = levels_[l - 1];
    Level& L = levels_[l];
    const float scale = L.res / B.res;  // pixel centres of B mapped onto L's grid
    for (int f = 0; f < 6; ++f) {
      if (B.offset[size_t(f)] < 0) continue;
      const size_t bb = size_t(B.offset[size_t(f)]), lb = size_t(L.offset[size_t(f)]);
      for (int v = 0; v < B.side; ++v)
        for (int u = 0; u < B.side; ++u) {
          const size_t j = bb + size_t(v) * B.side + size_t(u);
          if (!(B.depth[j] < kInf)) continue;
          const int lu = std::min(L.side - 1, int((float(u) + 0.5f - B.res) * scale + L.res));
          const int lv = std::min(L.side - 1, int((float(v) + 0.5f - B.res) * scale + L.res));
          const size_t id = lb + size_t(lv) * L.side + size_t(lu);
          if (B.depth[j] < L.depth[id]) L.depth[id] = B.depth[j], L.object[id] = B.object[j];
        }
    }
  }
}

RangeImage::~RangeImage() = default;

float RangeImage::PixelRad(int level) const { return 1.f / levels_[size_t(level)].res; }

RenderCloud MakeRenderCloud(const Points& outer, const Eigen::AlignedBox3f& bounds, int target, float min_spacing,
                            float max_spacing) {
  RenderCloud rc;
  rc.bounds = bounds;
  if (outer.empty()) return rc;
  auto thin = [&](float cell) {
    std::unordered_map<uint64_t, uint32_t> first;
    Points out;
    for (const auto& p : outer) {
      const int64_t x = int64_t(std::floor(p.x() / cell)), y = int64_t(std::floor(p.y() / cell)),
                    z = int64_t(std::floor(p.z() / cell));
      const uint64_t k = (uint64_t(x & 0x1fffff) << 42) | (uint64_t(y & 0x1fffff) << 21) | uint64_t(z & 0x1fffff);
      if (first.emplace(k, uint32_t(out.size())).second) out.push_back(p);
    }
    return out;
  };
  // The cell edge whose thinning leaves about `target` samples (a surface: count ~ 1 / edge^2).
  float cell = min_spacing;
  Points pts = thin(cell);
  for (int it = 0; it < 4 && pts.size() > size_t(target) && cell < max_spacing; ++it) {
    cell = std::min(max_spacing, cell * std::sqrt(float(pts.size()) / float(target)));
    pts = thin(cell);
  }
  rc.points = std::move(pts);
  rc.spacing = cell;
  return rc;
}

namespace {
constexpr char kRenderMagic[8] = {'F', 'H', 'R', 'C', 'L', 'D', '0', '1'};
}  // namespace

uint64_t RenderCloud::CacheKey(uint64_t cloud_key, int target) {
  uint64_t h = Fnv1a(kRenderMagic, sizeof(kRenderMagic), kFnvOffsetTruncated);
  h = Fnv1a(&cloud_key, sizeof(cloud_key), h);
  return Fnv1a(&target, sizeof(target), h);
}

void RenderCloud::Save(const std::string& path, uint64_t key) const {
  WriteCacheFile(path, [&](std::ostream& out) {
    const uint64_t n = points.size();
    out.write(kRenderMagic, sizeof(kRenderMagic));
    out.write(reinterpret_cast<const char*>(&key), sizeof(key));
    out.write(reinterpret_cast<const char*>(&spacing), sizeof(spacing));
    out.write(reinterpret_cast<const char*>(bounds.min().data()), 3 * sizeof(float));
    out.write(reinterpret_cast<const char*>(bounds.max().data()), 3 * sizeof(float));
    out.write(reinterpret_cast<const char*>(&n), sizeof(n));
    out.write(reinterpret_cast<const char*>(points.data()), std::streamsize(n * sizeof(Eigen::Vector3f)));
    out.write(kRenderMagic, sizeof(kRenderMagic));
  });
}

std::shared_ptr<const RenderCloud> RenderCloud::Load(const std::string& path, uint64_t key) {
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(path, ec);
  if (ec || size < 56) return nullptr;
  std::ifstream in(path, std::ios::binary);
  char magic[sizeof(kRenderMagic)];
  uint64_t got = 0, n = 0;
  auto r = std::make_shared<RenderCloud>();
  Eigen::Vector3f lo, hi;
  if (!in.read(magic, sizeof(magic)) || std::memcmp(magic, kRenderMagic, sizeof(magic)) != 0 ||
      !in.read(reinterpret_cast<char*>(&got), sizeof(got)) || got != key ||
      !in.read(reinterpret_cast<char*>(&r->spacing), sizeof(float)) ||
      !in.read(reinterpret_cast<char*>(lo.data()), 3 * sizeof(float)) ||
      !in.read(reinterpret_cast<char*>(hi.data()), 3 * sizeof(float)) || !in.read(reinterpret_cast<char*>(&n), sizeof(n)))
    return nullptr;
  if (n == 0 || n > size / sizeof(Eigen::Vector3f)) return nullptr;
  r->points.resize(n);
  if (!in.read(reinterpret_cast<char*>(r->points.data()), std::streamsize(n * sizeof(Eigen::Vector3f))) ||
      !in.read(magic, sizeof(magic)) || std::memcmp(magic, kRenderMagic, sizeof(magic)) != 0)
    return nullptr;
  bool ok = std::isfinite(r->spacing) && r->spacing > 0.f && lo.allFinite() && hi.allFinite() && (lo.array() <= hi.array()).all();
  for (size_t i = 0; ok && i < r->points.size(); ++i) ok = r->points[i].allFinite();
  if (!ok) return nullptr;
  r->bounds = Eigen::AlignedBox3f(lo, hi);
  return r;
}

Eigen::Vector3f ModelPlacement::Apply(const Eigen::Vector3f& m) const {
  const float c = std::cos(yaw), s = std::sin(yaw);
  const float mx = m.x() * sx, my = m.y() * sy;
  return Eigen::Vector3f(x + c * mx - s * my, y + s * mx + c * my, z + m.z() * sz);
}

Eigen::Isometry3f ModelPlacement::Rigid() const {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3f(x, y, z);
  return t;
}

std::vector<float>& Scratch::Buffer(size_t view, int level, size_t pixels) {
  if (buf_.size() <= view) buf_.resize(view + 1);
  auto& per_level = buf_[view];
  if (per_level.size() <= size_t(level)) per_level.resize(size_t(level) + 1);
  std::vector<float>& b = per_level[size_t(level)];
  if (b.size() != pixels) b.assign(pixels, kInf);
  return b;
}

Comparison ComparePose(const RenderCloud& model, const ModelPlacement& pose, const std::vector<View>& views,
                       const CompareOptions& o, Scratch* scratch, std::vector<uint64_t>* explained,
                       std::vector<float>* areas, int key_level, Points* observable) {
  Comparison c;
  if (model.points.empty()) return c;
  const float c0 = std::cos(pose.yaw), s0 = std::sin(pose.yaw);
  // A model sample where the pose puts it (world frame; ModelPlacement::Apply with the turn's
  // sine and cosine computed once).
  auto posed = [&](const Eigen::Vector3f& m) {
    const float mx = m.x() * pose.sx, my = m.y() * pose.sy;
    return Eigen::Vector3f(pose.x + c0 * mx - s0 * my, pose.y + s0 * mx + c0 * my, pose.z + m.z() * pose.sz);
  };
  // The samples' stretched extent: the spacing the pixels must exceed.
  const float stretch = std::max({pose.sx, pose.sy, pose.sz, 1e-3f});
  const float spacing = model.spacing * stretch;
  const Eigen::Vector3f centre = pose.Apply(model.bounds.center());
  for (size_t v = 0; v < views.size(); ++v) {
    const RangeImage& img = *views[v].image;
    const Eigen::Isometry3f& T = views[v].to_scan;
    const Eigen::Matrix3f R = T.linear();
    const Eigen::Vector3f t = T.translation();
    const float depth_c = std::max((T * centre - img.Origin()).norm(), 0.1f);
    // The finest level whose pixels at the object's depth are pixel_per_spacing samples wide
    // (no holes in the rendered surface, through which its back faces would show).
    int lev = img.Levels() - 1;
    for (int l = 0; l < img.Levels(); ++l)
      if (img.PixelRad(l) * depth_c >= o.pixel_per_spacing * spacing) {
        lev = l;
        break;
      }
    std::vector<float>& z = scratch->Buffer(v, lev, img.Pixels(lev));
    std::vector<uint32_t>& touched = scratch->touched;
    std::vector<uint32_t>& front = scratch->front;
    const bool keep_front = explained || observable;
    if (keep_front && front.size() < z.size()) front.resize(z.size());
    touched.clear();
    for (size_t k = 0; k < model.points.size(); ++k) {
      const Eigen::Vector3f w = posed(model.points[k]);
      uint32_t id;
      float d;
      if (!img.Project(R * w + t, lev, &id, &d)) continue;
      if (z[id] == kInf) touched.push_back(id);
      if (d < z[id]) {
        z[id] = d;
        if (keep_front) front[id] = uint32_t(k);
      }
    }
    if (observable) {
      // Every sample within the depth tolerance of its pixel's front-most one (not hidden by the
      // model itself), where the sensor measured that front surface or through it.
      for (size_t k = 0; k < model.points.size(); ++k) {
        const Eigen::Vector3f w = posed(model.points[k]);
        uint32_t id;
        float d;
        if (!img.Project(R * w + t, lev, &id, &d)) continue;
        const float dm = z[id], dobs = img.Depth(lev, id);
        const float range_term = o.seen_per_m2 * dm * dm;
        if (!(d - dm <= o.seen_tolerance + range_term) || !(dobs < kInf)) continue;
        if (std::abs(dobs - dm) <= o.seen_tolerance + range_term || dobs > dm + o.free_margin + range_term)
          observable->push_back(w);
      }
    }
    for (uint32_t id : touched) {
      const float dm = z[id];
      z[id] = kInf;
      const float a = img.PixelArea(lev, dm);
      const float dobs = img.Depth(lev, id);
      if (!(dobs < kInf)) {
        c.unknown += a;
        continue;
      }
      const float range_term = o.seen_per_m2 * dm * dm;
      const float tol = o.seen_tolerance + range_term;
      const bool is_seen = std::abs(dobs - dm) <= tol, is_free = !is_seen && dobs > dm + o.free_margin + range_term;
      if (is_seen) {
        if (img.Object(lev, id)) {
          c.seen_object += a;
          if (explained) {
            const Eigen::Vector3f w = posed(model.points[front[id]]);
            uint32_t key;
            float d;
            if (img.Project(R * w + t, std::min(key_level, img.Levels() - 1), &key, &d)) {
              explained->push_back(PixelKey(v, key));
              if (areas) areas->push_back(a);
            }
          }
        } else {
          c.seen_other += a;
        }
      } else if (dobs < dm) {
        c.occluded += a;
      } else if (is_free) {
        c.free += a;
      } else {
        c.unknown += a;  // a little behind the model, within the free margin: no evidence either way
      }
    }
  }
  return c;
}

void PointPixels(const Points& world, const std::vector<View>& views, int level, const CompareOptions& o,
                 std::vector<uint64_t>* keys, std::vector<float>* areas) {
  std::vector<std::pair<uint64_t, float>> kv;
  for (size_t v = 0; v < views.size(); ++v) {
    const RangeImage& img = *views[v].image;
    const int lev = std::min(level, img.Levels() - 1);
    for (const auto& w : world) {
      uint32_t id;
      float d;
      if (!img.Project(views[v].to_scan * w, lev, &id, &d) || !img.Object(lev, id)) continue;
      const float dobs = img.Depth(lev, id);
      if (!(std::abs(dobs - d) <= o.seen_tolerance + o.seen_per_m2 * d * d)) continue;
      kv.emplace_back(PixelKey(v, id), img.PixelArea(lev, dobs));
    }
  }
  std::sort(kv.begin(), kv.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  kv.erase(std::unique(kv.begin(), kv.end(), [](const auto& a, const auto& b) { return a.first == b.first; }), kv.end());
  keys->clear();
  areas->clear();
  for (const auto& [k, a] : kv) keys->push_back(k), areas->push_back(a);
}

namespace {
float AabbIou(const Eigen::AlignedBox3f& a, const Eigen::AlignedBox3f& b) {
  if (a.isEmpty() || b.isEmpty()) return 0.f;
  const Eigen::AlignedBox3f i = a.intersection(b);
  if (i.isEmpty()) return 0.f;
  const float vi = i.volume(), u = a.volume() + b.volume() - vi;
  return u > 0.f ? vi / u : 0.f;
}
}  // namespace

std::vector<Choice> ExplainAway(const std::vector<ExplainedPixels>& c, float min_new_share, float max_box_iou) {
  std::vector<size_t> order(c.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return c[a].score > c[b].score; });
  std::vector<Choice> out(c.size());
  std::vector<size_t> kept;
  std::unordered_map<uint64_t, char> claimed;
  for (size_t i : order) {
    double total = 0.0, fresh = 0.0;
    for (size_t k = 0; k < c[i].keys.size(); ++k) {
      total += c[i].areas[k];
      if (!claimed.count(c[i].keys[k])) fresh += c[i].areas[k];
    }
    Choice& ch = out[i];
    ch.share = total > 0.0 ? float(fresh / total) : 1.f;
    for (size_t j : kept) ch.overlap = std::max(ch.overlap, AabbIou(c[i].box, c[j].box));
    if (ch.overlap > max_box_iou) ch.share = std::min(ch.share, 1.f - ch.overlap);
    ch.kept = total > 0.0 && ch.share >= min_new_share && ch.overlap <= max_box_iou;
    if (ch.kept) {
      kept.push_back(i);
      for (uint64_t k : c[i].keys) claimed.emplace(k, 1);
    }
  }
  return out;
}

}  // namespace furnihost::ransac_upright
