// voters.catalog_shape: the model: every catalog model's size, the top-view height profile of its
// views fused and its one-eye profiles, from the training views or the mesh (Train, Load).
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <tuple>
#include <unordered_map>

#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/log.hpp"
#include "furnihost/plugin.hpp"
#include "shape/shape.hpp"
#include "catalog_shape.hpp"

namespace furnihost::catalog_shape {

namespace {

// The share of a model's inner footprint (model frame: bounding-box bottom centre at the
// origin, size = extents) whose floor one of its training views' sensors sees: the segment
// from the floor cell's centre to the sensor passes no point of that view within 3 cm.
float OpenFloor(const std::vector<const TrainingView*>& views, const Eigen::Vector3f& size) {
  constexpr float clear = 0.03f;
  int cells = 0, open = 0;
  auto key = [&](const Eigen::Vector3f& p, int dx = 0, int dy = 0, int dz = 0) {
    const int64_t x = int64_t(std::floor(p.x() / clear)) + dx, y = int64_t(std::floor(p.y() / clear)) + dy,
                  z = int64_t(std::floor(p.z() / clear)) + dz;
    return (uint64_t(x & 0x1fffff) << 42) | (uint64_t(y & 0x1fffff) << 21) | uint64_t(z & 0x1fffff);
  };
  std::vector<std::unordered_map<uint64_t, std::vector<Eigen::Vector3f>>> occupied(views.size());
  for (size_t v = 0; v < views.size(); ++v)
    for (const auto& p : views[v]->scan.points) {
      const Eigen::Vector3f w = views[v]->scan.pose * p;
      occupied[v][key(w)].push_back(w);
    }
  auto near = [&](size_t v, const Eigen::Vector3f& q) {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          auto it = occupied[v].find(key(q, dx, dy, dz));
          if (it == occupied[v].end()) continue;
          for (const auto& p : it->second)
            if ((p - q).squaredNorm() < clear * clear) return true;
        }
    return false;
  };
  ForEachInnerCell(Eigen::Vector2f::Zero(), std::max(size.x(), size.y()), std::min(size.x(), size.y()),
                   size.x() >= size.y() ? 0.f : float(M_PI / 2), [&](const Eigen::Vector2f& q) {
                     ++cells;
                     const Eigen::Vector3f g(q.x(), q.y(), 0.01f);
                     for (size_t v = 0; v < views.size(); ++v) {
                       if (!views[v]->scan.origin) continue;
                       const Eigen::Vector3f o = views[v]->scan.pose * *views[v]->scan.origin;
                       const float len = (o - g).norm();
                       bool blocked = false;
                       for (float t = 0.04f; t < len && !blocked; t += 0.02f) blocked = near(v, g + (o - g) * (t / len));
                       if (!blocked) {
                         ++open;
                         return;
                       }
                     }
                   });
  return cells ? float(open) / float(cells) : 0.f;
}

// The same two from the model's mesh, as a sensor around it at 1.4 m sees it (8 eyes 1.5 m
// beyond its footprint): dense surface samples, the visible ones for the profile; the floor
// under a cell is seen when the segment to an eye passes no sample within 3 cm. Noiseless, so
// a column's top is the surface's, not a range error above it.
struct MeshShape {
  shape::Profile profile;
  float open = 0.f;
  std::vector<shape::Profile> views;  // the profile each eye around it sees alone
  Eigen::Vector2f top_offset = Eigen::Vector2f::Zero();  // Model::top_offset
};
MeshShape FromMesh(const CatalogModel& m, float cell) {
  double area = 0;
  const int nv = int(m.mesh.vertices.size());
  for (const auto& t : m.mesh.triangles)
    if (t.minCoeff() >= 0 && t.maxCoeff() < nv)
      area += 0.5 * double((m.mesh.vertices[t[1]] - m.mesh.vertices[t[0]]).cross(m.mesh.vertices[t[2]] - m.mesh.vertices[t[0]]).norm());
  const Points samples = area > 0 ? SampleSurface(m.mesh, float(40000.0 / area), 0) : Points{};
  const Eigen::Vector3f size = m.size;
  const Points eyes = shape::EyesAround(size);
  // The profile of the samples some eye of `from` sees: all eyes fused, then each alone.
  auto profile_seen = [&](const Points& from) {
    const std::vector<uint8_t> vis = shape::VisibleFrom(samples, from);
    std::vector<Eigen::Vector2f> xy;
    std::vector<float> h;
    for (size_t i = 0; i < samples.size(); ++i)
      if (vis[i]) xy.push_back(samples[i].head<2>()), h.push_back(samples[i].z());
    return shape::TopViewProfile(xy, h, size.z(), cell);
  };
  const shape::Profile prof = profile_seen(eyes);
  std::vector<shape::Profile> views;
  views.reserve(eyes.size());
  for (const auto& e : eyes) views.push_back(profile_seen(Points{e}));
  // Open floor: blockers are every 4th sample, hashed in 3 cm cells.
  constexpr float clear = 0.03f;
  auto key = [&](const Eigen::Vector3f& p, int dx, int dy, int dz) {
    const int64_t x = int64_t(std::floor(p.x() / clear)) + dx, y = int64_t(std::floor(p.y() / clear)) + dy,
                  z = int64_t(std::floor(p.z() / clear)) + dz;
    return (uint64_t(x & 0x1fffff) << 42) | (uint64_t(y & 0x1fffff) << 21) | uint64_t(z & 0x1fffff);
  };
  std::unordered_map<uint64_t, std::vector<Eigen::Vector3f>> blockers;
  for (size_t i = 0; i < samples.size(); i += 4) blockers[key(samples[i], 0, 0, 0)].push_back(samples[i]);
  auto near = [&](const Eigen::Vector3f& q) {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          auto it = blockers.find(key(q, dx, dy, dz));
          if (it == blockers.end()) continue;
          for (const auto& p : it->second)
            if ((p - q).squaredNorm() < clear * clear) return true;
        }
    return false;
  };
  int cells = 0, open = 0;
  ForEachInnerCell(Eigen::Vector2f::Zero(), size.x(), size.y(), 0.f, [&](const Eigen::Vector2f& q) {
    ++cells;
    const Eigen::Vector3f g(q.x(), q.y(), 0.01f);
    for (const auto& e : eyes) {
      const float len = (e - g).norm();
      const int steps = int(std::ceil(len / 0.02f));
      bool blocked = false;
      for (int s = 0; s < steps && !blocked; ++s) {
        const float t = 0.02f + 0.98f * float(s) / float(std::max(steps - 1, 1));
        blocked = near(g + t * (e - g));
      }
      if (!blocked) {
        ++open;
        return;
      }
    }
  });
  // The top quarter's centroid (the mesh's bounding-box bottom centre is the origin).
  Eigen::Vector2d top = Eigen::Vector2d::Zero();
  size_t n_top = 0;
  for (const auto& q : samples)
    if (q.z() >= 0.75f * size.z()) top += q.head<2>().cast<double>(), ++n_top;
  Eigen::Vector2f top_offset = Eigen::Vector2f::Zero();
  if (n_top > 0 && size.x() > 0.f && size.y() > 0.f)
    top_offset = Eigen::Vector2f(float(top.x() / double(n_top)) / size.x(), float(top.y() / double(n_top)) / size.y());
  return {prof, cells ? float(open) / float(cells) : 0.f, std::move(views), top_offset};
}

}  // namespace

nlohmann::json CatalogShapeVoter::Train(const std::vector<TrainingView>& views, const RunContext&) {
  // One entry per model: its size and the profile of all its views fused.
  std::map<std::string, std::pair<const TrainingView*, std::vector<const TrainingView*>>> by_model;
  std::vector<std::string> order;
  for (const auto& v : views) {
    auto [it, fresh] = by_model.try_emplace(v.model_id, &v, std::vector<const TrainingView*>{});
    if (fresh) order.push_back(v.model_id);
    it->second.second.push_back(&v);
  }
  // Each model's shape on its own (in parallel: a catalog of thousands of meshes), then the
  // model file in the views' order.
  std::vector<MeshShape> shapes(order.size());
  Progress progress("train: voters.catalog_shape learning models", order.size());
  tbb::parallel_for(size_t(0), order.size(), [&](size_t k) {
    const auto& [first, vs] = by_model.at(order[k]);
    const Eigen::Vector3f s = first->object_size;
    MeshShape& ms = shapes[k];
    if (first->model && !first->model->mesh.triangles.empty()) {
      ms = FromMesh(*first->model, o_.cell);
    } else {  // views without their mesh: what the views saw, fused and one by one
      std::vector<Eigen::Vector2f> xy;
      std::vector<float> h;
      for (const TrainingView* v : vs) {
        const size_t from = xy.size();
        for (const auto& p : v->scan.points) {
          const Eigen::Vector3f w = v->scan.pose * p;
          xy.push_back(w.head<2>());
          h.push_back(v->scan.HeightAboveGround(w));
        }
        if (xy.size() > from)
          ms.views.push_back(shape::TopViewProfile({xy.begin() + long(from), xy.end()},
                                                   {h.begin() + long(from), h.end()}, s.z(), o_.cell));
      }
      ms.profile = shape::TopViewProfile(xy, h, s.z(), o_.cell);
      ms.open = OpenFloor(vs, s);
    }
    progress.Tick();
  });
  progress.Done();
  nlohmann::json models = nlohmann::json::array();
  for (size_t k = 0; k < order.size(); ++k) {
    const std::string& id = order[k];
    const TrainingView* first = by_model.at(id).first;
    const Eigen::Vector3f s = first->object_size;
    const MeshShape& ms = shapes[k];
    const shape::Profile& prof = ms.profile;
    models.push_back({{"id", id},
                      {"class", first->cls},
                      {"size", {s.x(), s.y(), s.z()}},
                      {"profile", std::vector<float>(prof.begin(), prof.end())},
                      {"open", ms.open},
                      {"top_offset", {ms.top_offset.x(), ms.top_offset.y()}}});
    if (!ms.views.empty()) {
      nlohmann::json vp = nlohmann::json::array();
      for (const auto& v : ms.views) vp.push_back(std::vector<float>(v.begin(), v.end()));
      models.back()["view_profiles"] = std::move(vp);
    }
  }
  return {{"format", "catalog_shape/1"}, {"profile_cell_m", o_.cell}, {"models", models}};
}

nlohmann::json CatalogShapeVoter::Merge(const std::vector<nlohmann::json>& parts) {
  nlohmann::json models = nlohmann::json::array();
  for (const nlohmann::json& part : parts) {
    if (!part.is_object() || part.value("format", "") != "catalog_shape/1" || !part.contains("models") ||
        !part.at("models").is_array())
      throw InputError("not a voters.catalog_shape model (format catalog_shape/1)");
    if (part.value("profile_cell_m", -1.f) != o_.cell)
      throw InputError("voters.catalog_shape: a part was trained with another profile_cell_m");
    for (const nlohmann::json& m : part.at("models")) models.push_back(m);
  }
  return {{"format", "catalog_shape/1"}, {"profile_cell_m", o_.cell}, {"models", std::move(models)}};
}

void CatalogShapeVoter::Load(const nlohmann::json& m) {
  if (!m.is_object() || m.value("format", "") != "catalog_shape/1")
    throw InputError("not a voters.catalog_shape model (format catalog_shape/1)");
  models_.clear();
  for (const auto& j : m.at("models")) {
    Model md;
    md.id = j.at("id").get<std::string>();
    const std::string cls = j.at("class").get<std::string>();
    auto it = o_.class_map.find(cls);
    md.cls = it == o_.class_map.end() ? cls : it->second;
    const auto size = j.at("size").get<std::vector<float>>();
    const auto prof = j.at("profile").get<std::vector<float>>();
    if (size.size() != 3 || prof.size() != size_t(shape::kProfileBins))
      throw InputError("catalog_shape model " + md.id + ": bad size or profile");
    for (float v : size)
      if (!(v > 0.f) || !std::isfinite(v)) throw InputError("catalog_shape model " + md.id + ": bad size");
    md.length = std::max(size[0], size[1]);
    md.width = std::min(size[0], size[1]);
    md.height = size[2];
    md.wide = size[0] >= size[1];
    std::copy(prof.begin(), prof.end(), md.profile.begin());
    md.open = j.value("open", 0.f);
    if (j.contains("top_offset")) {
      const auto& t = j.at("top_offset");
      if (!t.is_array() || t.size() != 2 || !t[0].is_number() || !t[1].is_number() ||
          !std::isfinite(t[0].get<float>()) || !std::isfinite(t[1].get<float>()))
        throw InputError("catalog_shape model " + md.id + ": bad top_offset");
      md.top_offset = Eigen::Vector2f(t[0].get<float>(), t[1].get<float>());
    }
    if (j.contains("view_profiles")) {
      const auto& vs = j.at("view_profiles");
      if (!vs.is_array()) throw InputError("catalog_shape model " + md.id + ": bad view_profiles");
      for (const auto& v : vs) {
        const bool numbers = v.is_array() && std::all_of(v.begin(), v.end(), [](const auto& x) { return x.is_number(); });
        const auto f = numbers ? v.get<std::vector<float>>() : std::vector<float>();
        if (f.size() != size_t(shape::kProfileBins) ||
            !std::all_of(f.begin(), f.end(), [](float x) { return std::isfinite(x) && x >= 0.f; }))
          throw InputError("catalog_shape model " + md.id + ": bad view profile");
        shape::Profile q{};
        std::copy(f.begin(), f.end(), q.begin());
        md.views.push_back(q);
      }
    }
    if (!(md.open >= 0.f && md.open <= 1.f)) throw InputError("catalog_shape model " + md.id + ": bad open share");
    spdlog::debug("catalog_shape: model {} ({}) {:.2f} x {:.2f} x {:.2f} m, open floor {:.2f}, profile {:.3f}", md.id,
                  md.cls, md.length, md.width, md.height, md.open, fmt::join(md.profile, " "));
    models_.push_back(md);
  }
  classes_.clear();
  for (const auto& md : models_)
    if (std::find(classes_.begin(), classes_.end(), md.cls) == classes_.end()) classes_.push_back(md.cls);
  // Each class's index: per model its log sizes, open floor and the range of its profiles'
  // ChunkSums (the fused one's, and with view_profiles each eye's too).
  static_assert(SizeIndex::kDims == 4 + kProfileChunks, "the index's coordinates");
  index_.clear();
  for (const auto& c : classes_) {
    std::vector<int> ids;
    std::vector<SizeIndex::Box> boxes;
    for (size_t m = 0; m < models_.size(); ++m)
      if (const Model& md = models_[m]; md.cls == c) {
        constexpr size_t K = SizeIndex::kDims;
        SizeIndex::Box b;
        b[0] = std::log(double(md.length)), b[1] = std::log(double(md.width)), b[2] = std::log(double(md.height));
        b[3] = double(md.open);
        const auto fused = ChunkSums(md.profile);
        for (size_t k = 0; k < size_t(kProfileChunks); ++k) b[4 + k] = fused[k];
        for (size_t a = 0; a < K; ++a) b[a + K] = b[a];
        if (o_.view_profiles)
          for (const auto& v : md.views) {
            const auto sums = ChunkSums(v);
            for (size_t k = 0; k < size_t(kProfileChunks); ++k)
              b[4 + k] = std::min(b[4 + k], sums[k]), b[K + 4 + k] = std::max(b[K + 4 + k], sums[k]);
          }
        // The profile bound's allowance for float rounding holds for shares >= 0 (histograms, as
        // training writes them); a model file with other profiles gets no profile bound.
        if (!std::all_of(md.profile.begin(), md.profile.end(), [](float x) { return std::isfinite(x) && x >= 0.f; }))
          for (size_t k = 0; k < size_t(kProfileChunks); ++k) b[4 + k] = -1e30, b[K + 4 + k] = 1e30;
        ids.push_back(int(m));
        boxes.push_back(b);
      }
    // Per coordinate, the energy's growth: 1 / spread (of a log size, of the open floor share),
    // and 1 / (bins * profile spread) for a run's cumulative sum.
    const ClassParams& cp = o_.Of(c);
    std::array<double, SizeIndex::kDims> scale;
    scale[0] = 1.0 / double(std::min(cp.long_small, cp.long_big));
    scale[1] = 1.0 / double(std::min(cp.short_small, cp.short_big));
    scale[2] = 1.0 / double(std::min(cp.top_small, cp.top_big));
    scale[3] = o_.floor_term ? 1.0 / double(std::min(cp.floor_under, cp.floor_over)) : 0.0;
    for (size_t k = 0; k < size_t(kProfileChunks); ++k) scale[4 + k] = 1.0 / (shape::kProfileBins * double(cp.profile));
    index_.emplace_back(std::move(ids), std::move(boxes), scale);
  }
  // Which proposals each class is scored on.
  source_.clear();
  for (const auto& c : classes_) {
    std::string src = o_.Of(c).source;
    if (src == "catalog") {
      std::vector<float> h;
      for (const auto& md : models_)
        if (md.cls == c) h.push_back(md.height);
      std::nth_element(h.begin(), h.begin() + h.size() / 2, h.end());
      src = h[h.size() / 2] > o_.tall_class ? "segs" : "all";
    }
    source_[c] = src;
  }
}

}  // namespace furnihost::catalog_shape
