// Helpers for tests that build stages through the registry and catalog models from boxes
// (proposals, recognisers): one copy instead of one per plugin test.
#pragma once
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "furnihost/host/catalog.hpp"
#include "furnihost/geometry.hpp"
#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace furnihost::testing {

// The build tree's registry, loaded once per test binary.
inline Registry& SharedRegistry() {
  static auto reg = MakeRegistry();
  return *reg;
}

// A stage of plugin `type` with `params` resolved against its schema (defaults filled).
template <class T>
std::shared_ptr<T> MakeStage(const std::string& type, const nlohmann::json& params = nlohmann::json::object()) {
  const auto* entry = SharedRegistry().Find(type);
  if (!entry) throw std::runtime_error("plugin not found: " + type);
  return SharedRegistry().CreateAs<T>(type, entry->params.Resolve(params, "test"));
}

// Appends the closed axis-aligned box [lo, hi] (12 outward triangles) to `m`.
inline void AddBox(Mesh& m, Eigen::Vector3f lo, Eigen::Vector3f hi) {
  const int b = static_cast<int>(m.vertices.size());
  for (int i = 0; i < 8; ++i) m.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) m.triangles.emplace_back(b + t[0], b + t[1], b + t[2]);
}

// Catalog models stand with their bounding-box bottom centre at the origin.
// A 1.2 x 0.8 x 0.75 m table: a 4 cm top on four 5 cm legs.
inline CatalogModel BoxTable() {
  CatalogModel m;
  m.id = "test_table";
  m.cls = "table";
  AddBox(m.mesh, {-0.6f, -0.4f, 0.71f}, {0.6f, 0.4f, 0.75f});
  for (float x : {-0.55f, 0.5f})
    for (float y : {-0.35f, 0.3f}) AddBox(m.mesh, {x, y, 0.f}, {x + 0.05f, y + 0.05f, 0.71f});
  m.size = m.mesh.Bounds().sizes();
  return m;
}

// A 0.9 x 0.5 x 1.2 m closed cabinet.
inline CatalogModel BoxCabinet() {
  CatalogModel m;
  m.id = "test_cabinet";
  m.cls = "cabinet";
  AddBox(m.mesh, {-0.45f, -0.25f, 0.f}, {0.45f, 0.25f, 1.2f});
  m.size = m.mesh.Bounds().sizes();
  return m;
}

// Training views of `models` as a recogniser's Train gets them: 8 simulated laser views each at
// 2 cm voxels (sensors.simulated_laser), with class, model id and size.
inline std::vector<TrainingView> SimulatedTrainingViews(const std::vector<const CatalogModel*>& models) {
  auto sensor = MakeStage<Sensor>("sensors.simulated_laser", {{"voxel_m", 0.02}, {"views", 8}});
  std::vector<TrainingView> out;
  RunContext ctx;
  for (const CatalogModel* m : models) {
    SensorRequest req;
    req.objects.push_back({m, Eigen::Isometry3f::Identity()});
    int v = 0;
    for (auto& s : sensor->Acquire(req, ctx)) {
      TrainingView tv;
      tv.cls = m->cls;
      tv.model_id = m->id;
      tv.view = v++;
      tv.object_size = m->size;
      tv.scan = std::move(s);
      out.push_back(std::move(tv));
    }
  }
  return out;
}

}  // namespace furnihost::testing
