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
  std::map<std::string, TrainingCount> per_class;
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

namespace {
// Every model's views of `scanned` (the catalog's models from `begin` on) handed to the learners,
// with the counts and times the model summary and the log give.
struct Gathered {
  std::vector<Learner> learners;
  std::map<std::string, double> time_ms;  // by stage tag
  size_t from_meshes = 0;                 // models no learner got a scan of
};

Gathered Gather(const GraphConfig& g, const Catalog& catalog, size_t begin, std::vector<ModelViews> scanned) {
  Gathered out;
  out.learners = Learners(g);
  for (size_t k = 0; k < scanned.size(); ++k) {
    ModelViews& mv = scanned[k];
    bool mesh_only = !mv.branches.empty();
    for (const auto& branch : mv.branches)
      for (const TrainingView& tv : branch) mesh_only = mesh_only && tv.view < 0;
    out.from_meshes += mesh_only ? 1 : 0;
    if (mv.branches.size() != out.learners.size()) throw std::logic_error("TrainFromViews: trained stages differ");
    for (const auto& [tag, ms] : mv.time_ms) out.time_ms[tag] += ms;
    for (size_t b = 0; b < out.learners.size(); ++b) {
      Learner& l = out.learners[b];
      for (TrainingView& tv : mv.branches[b]) {
        tv.model = &catalog.models[begin + k];  // the views of another process point at this catalog
        TrainingCount& count = l.per_class[tv.cls];
        (tv.view < 0 ? count.meshes : count.views)++;
        count.parts += static_cast<int>(tv.segmentation.parts.size());
        l.views.push_back(std::move(tv));
      }
    }
    mv.branches.clear();
  }
  return out;
}

// Voter::Train on a learner's views (its features normalised first, the normaliser kept in `tvr`).
nlohmann::json TrainLearner(StageInstances& stages, Learner& l, TrainedVoter& tvr, std::map<std::string, double>& time_ms,
                            const RunContext& ctx) {
  if (l.features) {
    std::vector<const FeatureMatrix*> fm;
    for (const auto& v : l.views) fm.push_back(&v.features);
    tvr.normaliser = Normaliser::Fit(fm);
    if (tvr.normaliser.min.size() == 0)
      throw StageError("training produced no parts: check the parameters of segmenter '" + l.segmenter->tag + "'",
                       true);
    for (auto& v : l.views) tvr.normaliser.Apply(v.features);
  }
  Voter& voter = stages.at(l.stage->tag).As<Voter>(*l.stage);
  Stopwatch sv;
  nlohmann::json model = CallStage(*l.stage, [&] { return voter.Train(l.views, ctx); });
  time_ms[l.stage->tag] += sv.Ms();
  l.views.clear();
  l.views.shrink_to_fit();
  return model;
}

// The model of the learners' voter models (tvr.voter_model set): each voter loads its model, and
// the summary describes what was learned. The times go to `timings_ms` (not saved), so that the
// same inputs give the same model file byte for byte, however many processes trained it.
TrainedModel Finish(const GraphConfig& g, StageInstances& stages, const Catalog& catalog, std::vector<Learner>& learners,
                    std::vector<TrainedVoter> voters, std::map<std::string, double> time_ms, size_t from_meshes) {
  TrainedModel m;
  m.training_config = TrainingKey(g);
  m.catalog_hash = catalog.hash;
  nlohmann::json per_voter = nlohmann::json::object();
  for (size_t b = 0; b < learners.size(); ++b) {
    const Learner& l = learners[b];
    TrainedVoter& tvr = voters[b];
    tvr.voter_type = l.stage->type;
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
    StageInstance& instance = stages.at(l.stage->tag);
    Voter& voter = instance.As<Voter>(*l.stage);
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
  m.summary = {{"models", catalog.models.size()}, {"voters", per_voter}};
  m.timings_ms = std::move(time_ms);
  return m;
}
}  // namespace

TrainedModel TrainFromViews(const GraphConfig& g, StageInstances& stages, const Catalog& catalog,
                            std::vector<ModelViews> scanned, const RunContext& ctx) {
  CheckTraining(g, catalog);
  if (scanned.size() != catalog.models.size())
    throw std::logic_error("TrainFromViews: " + std::to_string(scanned.size()) + " models scanned of " +
                           std::to_string(catalog.models.size()));
  Gathered all = Gather(g, catalog, 0, std::move(scanned));
  std::vector<TrainedVoter> voters(all.learners.size());
  for (size_t b = 0; b < all.learners.size(); ++b)
    voters[b].voter_model = TrainLearner(stages, all.learners[b], voters[b], all.time_ms, ctx);
  return Finish(g, stages, catalog, all.learners, std::move(voters), std::move(all.time_ms), all.from_meshes);
}

bool TrainingMerges(const GraphConfig& g, StageInstances& stages) {
  if (g.Trained().empty()) return false;
  for (const Learner& l : Learners(g))
    if (l.features || !stages.at(l.stage->tag).As<Voter>(*l.stage).Needs().training_merges) return false;
  return true;
}

TrainedRun TrainRun(const GraphConfig& g, StageInstances& stages, const Catalog& catalog, size_t begin, size_t end,
                    const RunContext& ctx) {
  CheckTraining(g, catalog);
  if (!TrainingMerges(g, stages)) throw std::logic_error("TrainRun: a trained stage of the graph does not merge");
  if (begin >= end || end > catalog.models.size())
    throw std::logic_error("TrainRun: models " + std::to_string(begin) + ".." + std::to_string(end) + " of " +
                           std::to_string(catalog.models.size()));
  std::vector<ModelViews> scanned;
  for (size_t i = begin; i < end; ++i) scanned.push_back(ScanModel(g, stages, catalog, i, ctx));
  Gathered run = Gather(g, catalog, begin, std::move(scanned));
  TrainedRun out;
  out.begin = begin;
  out.end = end;
  out.from_meshes = run.from_meshes;
  for (Learner& l : run.learners) {
    TrainedVoter unused;  // no normaliser: a learner with features does not merge
    out.voter_models.push_back(TrainLearner(stages, l, unused, run.time_ms, ctx));
    out.counts.push_back(std::move(l.per_class));
  }
  out.time_ms = std::move(run.time_ms);
  return out;
}

TrainedModel MergeRuns(const GraphConfig& g, StageInstances& stages, const Catalog& catalog, std::vector<TrainedRun> runs,
                       const RunContext&) {
  CheckTraining(g, catalog);
  std::vector<Learner> learners = Learners(g);
  size_t next = 0, from_meshes = 0;
  std::map<std::string, double> time_ms;
  for (const TrainedRun& r : runs) {
    if (r.begin != next || r.end <= r.begin || r.voter_models.size() != learners.size() ||
        r.counts.size() != learners.size())
      throw std::logic_error("MergeRuns: the runs do not cover the catalog's models in order");
    next = r.end;
    from_meshes += r.from_meshes;
    for (const auto& [tag, ms] : r.time_ms) time_ms[tag] += ms;
  }
  if (next != catalog.models.size()) throw std::logic_error("MergeRuns: the runs end before the catalog does");
  std::vector<TrainedVoter> voters(learners.size());
  for (size_t b = 0; b < learners.size(); ++b) {
    Learner& l = learners[b];
    std::vector<nlohmann::json> parts;
    for (TrainedRun& r : runs) {
      parts.push_back(std::move(r.voter_models[b]));
      for (const auto& [c, n] : r.counts[b]) {
        TrainingCount& sum = l.per_class[c];
        sum.views += n.views;
        sum.parts += n.parts;
        sum.meshes += n.meshes;
      }
    }
    Voter& voter = stages.at(l.stage->tag).As<Voter>(*l.stage);
    Stopwatch sw;
    voters[b].voter_model = CallStage(*l.stage, [&] { return voter.Merge(parts); });
    time_ms[l.stage->tag] += sw.Ms();
  }
  return Finish(g, stages, catalog, learners, std::move(voters), std::move(time_ms), from_meshes);
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
