#include "training.hpp"

#include "furnihost/log.hpp"

namespace furnihost::graph {

namespace {
// One trained stage and the views it learns from.
struct Learner {
  const StageConfig* stage;
  const StageConfig* features;   // the stage whose features its views carry, or null
  const StageConfig* segmenter;  // the stage whose parts its views carry, or null
  std::vector<TrainingView> views;
  std::map<std::string, std::pair<int, int>> per_class;  // class -> (views, parts)
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
}  // namespace

TrainedModel TrainGraph(const GraphConfig& g, StageInstances& stages, const Catalog& catalog, const RunContext& ctx) {
  const StageConfig* sensor_cfg = g.training_sensor.empty() ? nullptr : g.Find(g.training_sensor);
  if (!sensor_cfg) throw InputError(g.path + ":/training/sensor: the graph names no training sensor");
  const auto trained = g.Trained();
  if (trained.empty()) throw InputError(g.path + ": training needs a voter stage");
  if (catalog.models.empty()) throw InputError(catalog.path + ": no usable models to train from");
  auto& sensor = stages.at(sensor_cfg->tag).As<Sensor>(*sensor_cfg);
  // Each view runs through the stages training views pass through, each once whichever trained
  // stages share it; a stage learns from the parts and features its training inputs give (none
  // for a recogniser of whole proposals: it learns from the views' points).
  const std::set<std::string> through = TrainingStages(g);
  std::vector<Learner> learners;
  for (const StageConfig* t : trained) {
    const StageConfig* features = g.Input(*t, InputRole::Features);
    if (features && !through.count(features->tag)) features = nullptr;
    learners.push_back({t, features, features ? g.SegmenterOf(*features) : nullptr, {}, {}});
  }
  std::map<std::string, double> time_ms;  // by stage tag
  Progress progress("train: scanning models", catalog.models.size());
  for (const auto& model : catalog.models) {
    SensorRequest req;
    req.objects.push_back({&model, Eigen::Isometry3f::Identity()});
    Stopwatch sw;
    std::vector<Scan> scans = CallStage(*sensor_cfg, [&] { return sensor.Acquire(req, ctx); });
    time_ms[sensor_cfg->tag] += sw.Ms();
    for (size_t v = 0; v < scans.size(); ++v) {
      if (scans[v].points.size() < 3) continue;
      std::vector<Scan> view;
      view.push_back(std::move(scans[v]));
      Run run(g, view, ctx);
      run.log = false;
      RunStages(run, stages, &through);
      for (const auto& [tag, ms] : run.timings_ms) time_ms[tag] += ms;
      for (size_t b = 0; b < learners.size(); ++b) {
        Learner& l = learners[b];
        TrainingView tv = View(model, int(v), b + 1 == learners.size() ? std::move(view[0]) : view[0]);
        if (l.features) {
          tv.segmentation = run.Of(*l.segmenter).segmentations.at(0);
          tv.features = run.Of(*l.features).features.at(0);
        }
        l.per_class[model.cls].first++;
        l.per_class[model.cls].second += static_cast<int>(tv.segmentation.parts.size());
        l.views.push_back(std::move(tv));
      }
    }
    progress.Tick();
  }
  progress.Done();
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
    size_t parts = 0, views = 0;
    for (const auto& [c, vp] : l.per_class) {
      classes[c] = {{"views", vp.first}, {"parts", vp.second}};
      parts += vp.second;
      views += vp.first;
    }
    per_voter[l.stage->tag] = {{"views", views}, {"parts", parts}, {"classes", classes}};
    // Through CallStage: an exception escaping the plugin is caught while its library is loaded.
    CallStage(*l.stage, [&] {
      voter.Load(tvr.voter_model);
      return 0;
    });
    instance.loaded_model = m.catalog_hash + m.training_config.dump();
    m.voters[l.stage->tag] = std::move(tvr);
  }
  m.summary = {{"models", catalog.models.size()}, {"voters", per_voter}, {"time_ms", time_ms}};
  return m;
}

}  // namespace furnihost::graph
