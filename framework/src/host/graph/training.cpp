#include "training.hpp"

#include <optional>

#include "furnihost/log.hpp"

namespace furnihost::graph {

namespace {
// One trained stage and the views it learns from.
struct Learner {
  const StageConfig* stage;
  const StageConfig* features;   // the stage whose features its views carry, or null
  const StageConfig* segmenter;  // the stage whose parts its views carry, or null
  std::vector<TrainingView> views;
  struct Count {
    int views = 0, parts = 0, meshes = 0;  // meshes: models learned from their mesh alone (view -1)
  };
  std::map<std::string, Count> per_class;
};

TrainingView View(const CatalogModel& model, int view, Scan scan) {
  TrainingView tv;
  tv.cls = model.cls;
  tv.model_id = model.id;
  tv.view = view;
  tv.object_size = model.size;
  tv.model = &model;
  tv.scan = std::move(scan);
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : tv.scan.points) c += p.cast<double>();
  tv.object_centroid = (c / static_cast<double>(tv.scan.points.size())).cast<float>();
  return tv;
}

// The learners of the graph's trained stages, in the graph's order, their views empty.
std::vector<Learner> Learners(const GraphConfig& g) {
  const std::set<std::string> through = TrainingStages(g);
  std::vector<Learner> learners;
  for (const StageConfig* t : g.Trained()) {
    const StageConfig* features = g.Input(*t, InputRole::Features);
    if (features && !through.count(features->tag)) features = nullptr;
    learners.push_back({t, features, features ? g.SegmenterOf(*features) : nullptr, {}, {}});
  }
  return learners;
}

// Whether every trained stage learns `model` from its mesh alone (StageNeeds::training_scans):
// then the model is not scanned.
bool FromMeshAlone(const GraphConfig& g, StageInstances& stages, const CatalogModel& model) {
  if (model.mesh.triangles.empty()) return false;
  for (const StageConfig* t : g.Trained())
    if (stages.at(t->tag).As<Voter>(*t).Needs().training_scans) return false;
  return true;
}

const StageConfig& CheckTraining(const GraphConfig& g, const Catalog& catalog) {
  const StageConfig* sensor_cfg = g.training_sensor.empty() ? nullptr : g.Find(g.training_sensor);
  if (!sensor_cfg) throw InputError(g.path + ":/training/sensor: the graph names no training sensor");
  if (g.Trained().empty()) throw InputError(g.path + ": training needs a voter stage");
  if (catalog.models.empty()) throw InputError(catalog.path + ": no usable models to train from");
  return *sensor_cfg;
}
}  // namespace

ModelViews ScanModel(const GraphConfig& g, StageInstances& stages, const Catalog& catalog, size_t index,
                     const RunContext& ctx) {
  const StageConfig& sensor_cfg = CheckTraining(g, catalog);
  const CatalogModel& model = catalog.models.at(index);
  auto& sensor = stages.at(sensor_cfg.tag).As<Sensor>(sensor_cfg);
  // Each view runs through the stages training views pass through, each once whichever trained
  // stages share it; a stage learns from the parts and features its training inputs give (none
  // for a recogniser of whole proposals: it learns from the views' points).
  const std::set<std::string> through = TrainingStages(g);
  const std::vector<Learner> learners = Learners(g);
  ModelViews out;
  out.branches.resize(learners.size());
  if (FromMeshAlone(g, stages, model)) {
    // One view of no points: the learners read the mesh (TrainingView::model).
    for (auto& branch : out.branches) {
      TrainingView tv;
      tv.cls = model.cls;
      tv.model_id = model.id;
      tv.view = -1;
      tv.object_size = model.size;
      tv.model = &model;
      tv.object_centroid = model.mesh.Bounds().center();
      branch.push_back(std::move(tv));
    }
    return out;
  }
  SensorRequest req;
  req.objects.push_back({&model, Eigen::Isometry3f::Identity()});
  Stopwatch sw;
  std::vector<Scan> scans = CallStage(sensor_cfg, [&] { return sensor.Acquire(req, ctx); });
  out.time_ms[sensor_cfg.tag] += sw.Ms();
  for (size_t v = 0; v < scans.size(); ++v) {
    if (scans[v].points.size() < 3) continue;
    std::vector<Scan> view;
    view.push_back(std::move(scans[v]));
    Run run(g, view, ctx);
    run.log = false;
    RunStages(run, stages, &through);
    for (const auto& [tag, ms] : run.timings_ms) out.time_ms[tag] += ms;
    for (size_t b = 0; b < learners.size(); ++b) {
      const Learner& l = learners[b];
      TrainingView tv = View(model, int(v), b + 1 == learners.size() ? std::move(view[0]) : view[0]);
      if (l.features) {
        tv.segmentation = run.Of(*l.segmenter).segmentations.at(0);
        tv.features = run.Of(*l.features).features.at(0);
      }
      out.branches[b].push_back(std::move(tv));
    }
  }
  return out;
}

TrainedModel TrainFromViews(const GraphConfig& g, StageInstances& stages, const Catalog& catalog,
                            std::vector<ModelViews> scanned, const RunContext& ctx) {
  CheckTraining(g, catalog);
  if (scanned.size() != catalog.models.size())
    throw std::logic_error("TrainFromViews: " + std::to_string(scanned.size()) + " models scanned of " +
                           std::to_string(catalog.models.size()));
  std::vector<Learner> learners = Learners(g);
  std::map<std::string, double> time_ms;  // by stage tag
  size_t from_meshes = 0;  // models no learner got a scan of
  for (size_t i = 0; i < scanned.size(); ++i) {
    ModelViews& mv = scanned[i];
    bool mesh_only = !mv.branches.empty();
    for (const auto& branch : mv.branches)
      for (const TrainingView& tv : branch) mesh_only = mesh_only && tv.view < 0;
    from_meshes += mesh_only ? 1 : 0;
    if (mv.branches.size() != learners.size()) throw std::logic_error("TrainFromViews: trained stages differ");
    for (const auto& [tag, ms] : mv.time_ms) time_ms[tag] += ms;
    for (size_t b = 0; b < learners.size(); ++b) {
      Learner& l = learners[b];
      for (TrainingView& tv : mv.branches[b]) {
        tv.model = &catalog.models[i];  // the views of another process point at this catalog
        Learner::Count& count = l.per_class[tv.cls];
        (tv.view < 0 ? count.meshes : count.views)++;
        count.parts += static_cast<int>(tv.segmentation.parts.size());
        l.views.push_back(std::move(tv));
      }
    }
    mv.branches.clear();
  }
  TrainedModel m;
  m.training_config = TrainingKey(g);
  m.catalog_hash = catalog.hash;
  nlohmann::json per_voter = nlohmann::json::object();
  for (Learner& l : learners) {
    TrainedVoter tvr;
    tvr.voter_type = l.stage->type;
    if (l.features) {
      std::vector<const FeatureMatrix*> fm;
      for (const auto& v : l.views) fm.push_back(&v.features);
      tvr.normaliser = Normaliser::Fit(fm);
      if (tvr.normaliser.min.size() == 0)
        throw StageError("training produced no parts: check the parameters of segmenter '" + l.segmenter->tag + "'",
                         true);
      for (auto& v : l.views) tvr.normaliser.Apply(v.features);
    }
    StageInstance& instance = stages.at(l.stage->tag);
    Voter& voter = instance.As<Voter>(*l.stage);
    Stopwatch sv;
    tvr.voter_model = CallStage(*l.stage, [&] { return voter.Train(l.views, ctx); });
    time_ms[l.stage->tag] += sv.Ms();
    l.views.clear();
    l.views.shrink_to_fit();
    nlohmann::json classes = nlohmann::json::object();
    size_t parts = 0, views = 0, meshes = 0;
    for (const auto& [c, n] : l.per_class) {
      classes[c] = {{"views", n.views}, {"parts", n.parts}};
      if (n.meshes > 0) classes[c]["meshes"] = n.meshes;
      parts += size_t(n.parts);
      views += size_t(n.views);
      meshes += size_t(n.meshes);
    }
    per_voter[l.stage->tag] = {{"views", views}, {"parts", parts}, {"classes", classes}};
    if (meshes > 0) per_voter[l.stage->tag]["meshes"] = meshes;
    // Through CallStage: an exception escaping the plugin is caught while its library is loaded.
    CallStage(*l.stage, [&] {
      voter.Load(tvr.voter_model);
      return 0;
    });
    instance.loaded_model = m.catalog_hash + m.training_config.dump();
    m.voters[l.stage->tag] = std::move(tvr);
  }
  if (from_meshes > 0)
    spdlog::info("train: {} of {} models learned from their meshes alone (their voters need no scans)", from_meshes,
                 catalog.models.size());
  // The summary describes what was learned; the times go to `timings_ms` (not saved), so that the
  // same inputs give the same model file byte for byte, however many processes trained it.
  m.summary = {{"models", catalog.models.size()}, {"voters", per_voter}};
  m.timings_ms = time_ms;
  return m;
}

TrainedModel TrainGraph(const GraphConfig& g, StageInstances& stages, const Catalog& catalog, const RunContext& ctx) {
  CheckTraining(g, catalog);
  std::vector<ModelViews> views;
  size_t scans = 0;  // models the training sensor scans (the others' voters read their meshes)
  for (const CatalogModel& model : catalog.models) scans += FromMeshAlone(g, stages, model) ? 0 : 1;
  std::optional<Progress> progress;
  if (scans > 0) progress.emplace("train: scanning models", catalog.models.size());
  for (size_t i = 0; i < catalog.models.size(); ++i) {
    views.push_back(ScanModel(g, stages, catalog, i, ctx));
    if (progress) progress->Tick();
  }
  if (progress) progress->Done();
  return TrainFromViews(g, stages, catalog, std::move(views), ctx);
}

}  // namespace furnihost::graph
