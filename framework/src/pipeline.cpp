#include "furnihost/pipeline.hpp"

#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "furnihost/ground.hpp"
#include "furnihost/io.hpp"
#include "furnihost/log.hpp"

namespace fs = std::filesystem;

namespace furnihost {

namespace {
const char kMagic[] = "furnihost-model\n";

nlohmann::json StageKey(const StageConfig* s) {
  if (!s) return nullptr;
  return {{"type", s->type}, {"version", s->version},
          {"params", s->training_params.is_null() ? s->params : s->training_params}};
}

// nlohmann's CBOR reader recurses once per nesting level, so a tampered model of 10^6 nested
// arrays overflows the stack. This DOM builder stops the reader at a depth no model needs.
class DepthLimitedSax : public nlohmann::detail::json_sax_dom_parser<nlohmann::json> {
 public:
  static constexpr int kMaxDepth = 256;
  explicit DepthLimitedSax(nlohmann::json& j) : json_sax_dom_parser(j, true) {}
  bool start_object(std::size_t n) { return Enter() && json_sax_dom_parser::start_object(n); }
  bool start_array(std::size_t n) { return Enter() && json_sax_dom_parser::start_array(n); }
  bool end_object() { --depth_; return json_sax_dom_parser::end_object(); }
  bool end_array() { --depth_; return json_sax_dom_parser::end_array(); }
  bool too_deep = false;

 private:
  bool Enter() {
    too_deep = ++depth_ > kMaxDepth;
    return !too_deep;
  }
  int depth_ = 0;
};

// The configured cap on points per scan (0 = none), for sensors without a max_points of their own.
size_t MaxPoints(const GraphConfig& g) {
  const auto& r = g.resolved;
  if (r.is_object() && r.contains("limits") && r["limits"].is_object() && r["limits"].contains("max_points") &&
      r["limits"]["max_points"].is_number_unsigned())
    return r["limits"]["max_points"].get<size_t>();
  return 0;
}
}  // namespace

template <class F>
auto Pipeline::Call(const StageConfig& s, F&& f) -> decltype(f()) {
  const std::string who = "stage '" + s.tag + "' (" + s.type + "): ";
  try {
    return f();
  } catch (const InputError& e) {
    throw InputError(who + e.what());
  } catch (const StageError& e) {
    throw StageError(who + e.what(), e.IsInputError());
  } catch (const std::bad_alloc&) {
    throw StageError(who + "out of memory", false);
  } catch (const std::exception& e) {
    throw StageError(who + e.what(), false);
  } catch (...) {
    throw StageError(who + "unknown exception", false);
  }
}

nlohmann::json TrainingKey(const GraphConfig& g) {
  const StageConfig* tr = g.training_sensor.empty() ? nullptr : g.Find(g.training_sensor);
  return {{"seed", g.seed},
          {"training_sensor", StageKey(tr)},
          {"segmenter", StageKey(g.FirstOfKind(StageKind::Segmenter))},
          {"features", StageKey(g.FirstOfKind(StageKind::Features))},
          {"voter", StageKey(g.FirstOfKind(StageKind::Voter))}};
}

void SaveModel(const std::string& path, const TrainedModel& m) {
  nlohmann::json j = {{"format_version", m.format_version}, {"training_config", m.training_config},
                      {"catalog_hash", m.catalog_hash},     {"voter_type", m.voter_type},
                      {"normaliser", m.normaliser.ToJson()}, {"voter_model", m.voter_model},
                      {"summary", m.summary}};
  const std::vector<uint8_t> cbor = nlohmann::json::to_cbor(j);
  AtomicWrite(path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out.write(kMagic, sizeof(kMagic) - 1);
    out.write(reinterpret_cast<const char*>(cbor.data()), cbor.size());
    out.flush();
    if (!out) throw InputError(tmp + ": write failed");
  });
}

TrainedModel LoadModel(const std::string& path) {
  RequireRegularFile(path, "model file");
  std::ifstream in(path, std::ios::binary);
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t ml = sizeof(kMagic) - 1;
  if (data.size() < ml || data.compare(0, ml, kMagic) != 0)
    throw InputError(path + ": not a furnihost model file (bad magic)");
  nlohmann::json j;
  try {
    DepthLimitedSax sax(j);
    const bool ok = nlohmann::json::sax_parse(data.begin() + ml, data.end(), &sax, nlohmann::json::input_format_t::cbor);
    if (sax.too_deep)
      throw InputError(path + ": corrupt model file (nested deeper than " + std::to_string(DepthLimitedSax::kMaxDepth) +
                       " levels); delete it to retrain");
    if (!ok) throw InputError(path + ": corrupt or truncated model file; delete it to retrain");
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    throw InputError(path + ": corrupt or truncated model file (" + std::string(e.what()) + "); delete it to retrain");
  }
  try {
    TrainedModel m;
    const auto& version = j.at("format_version");
    if (!version.is_number_integer() || version.get<long long>() < 0 || version.get<long long>() > 1000000)
      throw InputError(path + ": corrupt model file (format_version " + version.dump().substr(0, 40) +
                       "); delete it to retrain");
    m.format_version = version.get<int>();
    if (m.format_version != kModelFormatVersion)
      throw InputError(path + ": model file format version " + std::to_string(m.format_version) +
                       ", this furnihost reads version " + std::to_string(kModelFormatVersion) +
                       "; retrain with `furnihost train --graph <config>`");
    m.training_config = j.at("training_config");
    m.catalog_hash = j.at("catalog_hash").get<std::string>();
    m.voter_type = j.at("voter_type").get<std::string>();
    m.normaliser = Normaliser::FromJson(j.at("normaliser"));
    if (!m.normaliser.min.allFinite() || !m.normaliser.max.allFinite())
      throw InputError(path + ": corrupt model file (non-finite normaliser); delete it to retrain");
    m.voter_model = j.at("voter_model");
    m.summary = j.value("summary", nlohmann::json::object());
    return m;
  } catch (const InputError& e) {
    const std::string what = e.what();
    if (what.rfind(path, 0) == 0) throw;
    throw InputError(path + ": " + what + "; delete it to retrain");  // e.g. from Normaliser::FromJson
  } catch (const std::exception& e) {
    throw InputError(path + ": model file is missing a field (" + std::string(e.what()) + "); delete it to retrain");
  }
}

std::string Incompatibility(const TrainedModel& m, const GraphConfig& g, const std::string& catalog_hash) {
  if (m.catalog_hash != catalog_hash) return "the catalog changed (hash " + m.catalog_hash + " -> " + catalog_hash + ")";
  const nlohmann::json want = TrainingKey(g);
  for (auto it = want.begin(); it != want.end(); ++it) {
    if (!m.training_config.contains(it.key()) || m.training_config[it.key()] != it.value()) {
      const nlohmann::json have = m.training_config.value(it.key(), nlohmann::json());
      nlohmann::json diff = nlohmann::json::diff(have, it.value());
      std::string d = diff.dump();
      if (d.size() > 200) d = d.substr(0, 197) + "...";
      return "'" + it.key() + "' differs from the model's: " + d;
    }
  }
  return "";
}

Pipeline::Pipeline(const GraphConfig& graph, const Registry& registry) : graph_(graph) {
  input_cfg_ = graph_.FirstOfKind(StageKind::Sensor);
  train_cfg_ = graph_.training_sensor.empty() ? nullptr : graph_.Find(graph_.training_sensor);
  seg_cfg_ = graph_.FirstOfKind(StageKind::Segmenter);
  prop_cfg_ = graph_.FirstOfKind(StageKind::Proposer);
  feat_cfg_ = graph_.FirstOfKind(StageKind::Features);
  voter_cfg_ = graph_.FirstOfKind(StageKind::Voter);
  // Fitters in chain order (the graph's stages are topologically sorted).
  fitter_cfgs_ = graph_.AllOfKind(StageKind::Fitter);
  auto make = [&](const StageConfig* c) { return Call(*c, [&] { return registry.Create(c->type, c->params); }); };
  if (input_cfg_) input_ = std::dynamic_pointer_cast<Sensor>(make(input_cfg_));
  if (train_cfg_) training_ = std::dynamic_pointer_cast<Sensor>(make(train_cfg_));
  if (seg_cfg_) segmenter_ = std::dynamic_pointer_cast<Segmenter>(make(seg_cfg_));
  if (prop_cfg_) proposer_ = std::dynamic_pointer_cast<Proposer>(make(prop_cfg_));
  if (feat_cfg_) features_ = std::dynamic_pointer_cast<Features>(make(feat_cfg_));
  if (voter_cfg_) voter_ = std::dynamic_pointer_cast<Voter>(make(voter_cfg_));
  for (const auto* f : fitter_cfgs_) fitters_.push_back(std::dynamic_pointer_cast<Fitter>(make(f)));
}

std::vector<std::string> Pipeline::MissingStages() const {
  std::vector<std::string> m;
  if (!input_) m.push_back("sensor (scan reader)");
  // A recogniser of proposals needs neither part features nor a fitter to decide.
  const bool recogniser = proposer_ && voter_;
  if (!segmenter_ && !recogniser) m.push_back("segmenter");
  if (!features_ && !recogniser) m.push_back("features");
  if (!voter_) m.push_back("voter");
  if (fitters_.empty() && !recogniser) m.push_back("fitter");
  return m;
}

TrainedModel Pipeline::Train(const Catalog& catalog, const RunContext& ctx) {
  if (!training_) throw InputError(graph_.path + ":/training/sensor: the graph names no training sensor");
  if (!voter_) throw InputError(graph_.path + ": training needs a voter stage");
  // A voter of part features needs the parts of every view; a recogniser of whole proposals
  // (no features stage in the graph) learns from the views' points alone.
  if (features_ && !segmenter_) throw InputError(graph_.path + ": a features stage needs a segmenter");
  if (catalog.models.empty()) throw InputError(catalog.path + ": no usable models to train from");
  std::vector<TrainingView> views;
  double t_sim = 0, t_seg = 0, t_feat = 0;
  std::map<std::string, std::pair<int, int>> per_class;  // class -> (views, parts)
  Progress progress("train: scanning models", catalog.models.size());
  for (const auto& model : catalog.models) {
    SensorRequest req;
    req.objects.push_back({&model, Eigen::Isometry3f::Identity()});
    Stopwatch sw;
    std::vector<Scan> scans = Call(*train_cfg_, [&] { return training_->Acquire(req, ctx); });
    t_sim += sw.Ms();
    for (size_t v = 0; v < scans.size(); ++v) {
      if (scans[v].points.size() < 3) continue;
      TrainingView tv;
      tv.cls = model.cls;
      tv.model_id = model.id;
      tv.view = static_cast<int>(v);
      tv.object_size = model.size;
      tv.model = &model;
      tv.scan = std::move(scans[v]);
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (const auto& p : tv.scan.points) c += p.cast<double>();
      tv.object_centroid = (c / static_cast<double>(tv.scan.points.size())).cast<float>();
      if (features_) {
        Stopwatch s2;
        tv.segmentation = Call(*seg_cfg_, [&] { return segmenter_->Segment(tv.scan, ctx); });
        t_seg += s2.Ms();
        Stopwatch s3;
        tv.features = Call(*feat_cfg_, [&] { return features_->Compute(tv.scan, tv.segmentation, ctx); });
        t_feat += s3.Ms();
      }
      if (tv.features.values.rows() != static_cast<Eigen::Index>(tv.segmentation.parts.size()))
        throw StageError("stage '" + feat_cfg_->tag + "': returned " + std::to_string(tv.features.values.rows()) +
                         " rows for " + std::to_string(tv.segmentation.parts.size()) + " parts", false);
      per_class[model.cls].first++;
      per_class[model.cls].second += static_cast<int>(tv.segmentation.parts.size());
      views.push_back(std::move(tv));
    }
    progress.Tick();
  }
  progress.Done();
  std::vector<const FeatureMatrix*> fm;
  for (const auto& v : views) fm.push_back(&v.features);
  TrainedModel m;
  if (features_) {
    m.normaliser = Normaliser::Fit(fm);
    if (m.normaliser.min.size() == 0) throw StageError("training produced no parts: check the segmenter parameters", true);
    for (auto& v : views) m.normaliser.Apply(v.features);
  }
  Stopwatch sv;
  m.voter_model = Call(*voter_cfg_, [&] { return voter_->Train(views, ctx); });
  const double t_vote = sv.Ms();
  m.training_config = TrainingKey(graph_);
  m.catalog_hash = catalog.hash;
  m.voter_type = voter_cfg_->type;
  nlohmann::json classes = nlohmann::json::object();
  size_t parts = 0;
  for (const auto& [c, vp] : per_class) {
    classes[c] = {{"views", vp.first}, {"parts", vp.second}};
    parts += vp.second;
  }
  m.summary = {{"models", catalog.models.size()},
               {"views", views.size()},
               {"parts", parts},
               {"classes", classes},
               {"time_ms", {{"simulate", t_sim}, {"segment", t_seg}, {"features", t_feat}, {"voter", t_vote}}}};
  // Through Call: an exception escaping the plugin is caught while its library is loaded.
  Call(*voter_cfg_, [&] { voter_->Load(m.voter_model); return 0; });
  loaded_model_id_ = m.catalog_hash + TrainingKey(graph_).dump();
  return m;
}

Pipeline::Result Pipeline::Detect(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                                  const Catalog* catalog, const RunContext& ctx) {
  if (!input_) throw InputError(graph_.path + ": the graph has no input sensor stage (e.g. sensors.scan_file)");
  Result r;
  auto timed = [&](const std::string& tag, double ms) {
    for (auto& t : r.timings_ms)
      if (t.first == tag) { t.second += ms; return; }
    r.timings_ms.emplace_back(tag, ms);
  };
  Eigen::Isometry3d world_to_user = Eigen::Isometry3d::Identity();
  for (const auto& sc : scenes) {
    SensorRequest req;
    req.path = sc.path;
    req.origin = sc.origin;
    req.shift = sc.frame.shift;
    Stopwatch sw;
    auto got = Call(*input_cfg_, [&] { return input_->Acquire(req, ctx); });
    timed(input_cfg_->tag, sw.Ms());
    // The working frame (z up) and the ground, once per scan, before any stage sees it.
    Stopwatch sg;
    for (auto& s : got) {
      FrameOptions fo = sc.frame;
      fo.canonical = fo.canonical && graph_.canonical_frame;
      ToWorkingFrame(s, fo);
      GroundOptions go = graph_.ground;
      go.fixed_z += float(s.frame.canonical.translation().z());  // given in the z-up frame
      if (!s.ground || graph_.ground.kind == "fixed") s.ground = EstimateGround(s.points, go);
      const GroundModel& g = *s.ground;
      spdlog::info("{}: ground {} ({}): z = {:.4f} x + {:.4f} y + {:.3f} m{}", s.source, ToString(g.kind), g.source,
                   g.plane.a, g.plane.b, g.plane.c,
                   g.kind == GroundKind::HeightMap
                       ? fmt::format(", {}x{} cells of {:.2f} m, {:.1f} m2 of floor seen", g.width, g.height, g.cell,
                                     g.observed_area_m2)
                       : std::string());
    }
    timed("ground", sg.Ms());
    // Sensors that declare max_points refuse before reading; this catches the others.
    if (const size_t cap = MaxPoints(graph_))
      for (const auto& s : got)
        if (s.points.size() > cap)
          throw InputError("stage '" + input_cfg_->tag + "' (" + input_cfg_->type + "): " + sc.path + ": " +
                           std::to_string(s.points.size()) + " points exceed /limits/max_points = " + std::to_string(cap));
    for (auto& s : got) {
      // The world frame is the first scan's working frame; a scan's pose maps its working
      // frame there (through its z-up frame and the pose given for it).
      if (r.scans.empty()) {
        world_to_user = sc.pose.cast<double>() * s.frame.canonical.inverse();
        r.world_to_user = world_to_user.cast<float>();
        s.pose = Eigen::Isometry3f::Identity();
      } else {
        s.pose = (world_to_user.inverse() * sc.pose.cast<double>() * s.frame.canonical.inverse()).cast<float>();
      }
      r.scans.push_back(std::move(s));
    }
  }
  if (!segmenter_ && !proposer_) return r;
  for (const auto& scan : r.scans) {
    if (!segmenter_) break;
    Stopwatch sw;
    r.segmentations.push_back(Call(*seg_cfg_, [&] { return segmenter_->Segment(scan, ctx); }));
    timed(seg_cfg_->tag, sw.Ms());
    spdlog::info("{}: {} points -> {} parts ({} points discarded)", scan.source, scan.points.size(),
                 r.segmentations.back().parts.size(), r.segmentations.back().discarded_points);
  }
  if (proposer_) {
    for (size_t i = 0; i < r.scans.size(); ++i) {
      Stopwatch sw;
      const Segmentation* seg = i < r.segmentations.size() ? &r.segmentations[i] : nullptr;
      r.proposals.push_back(Call(*prop_cfg_, [&] { return proposer_->Propose(r.scans[i], seg, ctx); }));
      timed(prop_cfg_->tag, sw.Ms());
      spdlog::info("{}: {} proposals (spacing {:.3f} m)", r.scans[i].source, r.proposals.back().items.size(),
                   r.proposals.back().spacing);
    }
  }
  if (!features_ && !(proposer_ && voter_)) return r;
  for (size_t i = 0; i < r.scans.size() && features_; ++i) {
    Stopwatch sw;
    r.features.push_back(Call(*feat_cfg_, [&] { return features_->Compute(r.scans[i], r.segmentations[i], ctx); }));
    timed(feat_cfg_->tag, sw.Ms());
    if (r.features.back().values.rows() != static_cast<Eigen::Index>(r.segmentations[i].parts.size()))
      throw StageError("stage '" + feat_cfg_->tag + "': feature rows do not match the parts", false);
    if (model) r.clamped_features += model->normaliser.Apply(r.features.back());
  }
  if (r.clamped_features) spdlog::info("features: {} values outside the training range were clamped", r.clamped_features);
  if (!voter_ || !model) return r;
  const std::string id = model->catalog_hash + model->training_config.dump();
  if (loaded_model_id_ != id) {
    // A model its voter cannot load is a corrupt or foreign cache file: bad input (exit 2),
    // whatever the plugin threw, with the way out in the message.
    const std::string fix = graph_.model_cache.empty() ? std::string(" (retrain with --retrain)")
                                                       : " (model " + graph_.model_cache + "; retrain with --retrain)";
    try {
      Call(*voter_cfg_, [&] { voter_->Load(model->voter_model); return 0; });
    } catch (const std::exception& e) {
      throw InputError(std::string(e.what()) + fix);
    }
    loaded_model_id_ = id;
  }
  std::vector<SceneParts> parts;
  for (size_t i = 0; i < r.scans.size(); ++i)
    parts.push_back({&r.scans[i], i < r.segmentations.size() ? &r.segmentations[i] : nullptr,
                     i < r.features.size() ? &r.features[i] : nullptr, i < r.proposals.size() ? &r.proposals[i] : nullptr});
  Stopwatch sv;
  r.votes = Call(*voter_cfg_, [&] { return voter_->Vote(parts, ctx); });
  timed(voter_cfg_->tag, sv.Ms());
  r.voted = true;
  if (catalog && sized_catalog_ != catalog) {
    class_size_ = TypicalClassSizes(*catalog);
    sized_catalog_ = catalog;
  }
  for (const auto& h : r.votes.hypotheses) {
    Detection d;
    d.cls = h.cls;
    d.center = h.center;
    d.score = h.score;
    d.support = h.support;
    d.proposal = h.proposal;
    d.proposal_scene = h.scene;
    d.model = h.model;
    d.evidence = h.evidence;
    if (h.model_pose) d.model_pose = *h.model_pose;
    if (h.accepted) {
      d.verified = *h.accepted;
      d.checks = h.checks;
      r.fitted = true;  // decided: the eval counts accepted detections as verified
    }
    if (h.box) {
      d.box = h.box;
      d.box_source = "voter";
    } else if (auto it = class_size_.find(h.cls); it != class_size_.end() && !r.scans.empty()) {
      OrientedBox b;
      b.size = it->second;
      const float g = r.scans.front().GroundZ(h.center.x(), h.center.y());
      b.center = Eigen::Vector3f(h.center.x(), h.center.y(), g + 0.5f * b.size.z());
      d.box = b;
      d.box_source = "class_size";
    }
    r.detections.push_back(d);
  }
  if (fitters_.empty() || !catalog) return r;
  FitContext fc;
  fc.scenes = parts;
  for (const auto& m : catalog->models) fc.catalog.push_back(&m);
  fc.run = ctx;
  for (size_t i = 0; i < fitters_.size(); ++i) {
    Stopwatch sw;
    r.detections = Call(*fitter_cfgs_[i], [&] { return fitters_[i]->Fit(r.detections, fc); });
    timed(fitter_cfgs_[i]->tag, sw.Ms());
  }
  r.fitted = true;
  return r;
}

TrainedModel EnsureModel(Pipeline& p, const Catalog& catalog, const RunContext& ctx, bool force) {
  const std::string cache = p.Graph().model_cache;
  if (!force && !cache.empty() && fs::exists(cache)) {
    try {
      TrainedModel m = LoadModel(cache);
      std::string why = Incompatibility(m, p.Graph(), catalog.hash);
      if (why.empty()) {
        spdlog::info("model: using cached {}", cache);
        return m;
      }
      spdlog::warn("model: cached {} is stale: {}; retraining", cache, why);
    } catch (const InputError& e) {
      spdlog::warn("model: {}; retraining", e.what());
    }
  }
  spdlog::info("model: training from {} ({} models)", catalog.path, catalog.models.size());
  Stopwatch sw;
  TrainedModel m = p.Train(catalog, ctx);
  spdlog::info("model: trained in {:.1f} s: {}", sw.Ms() / 1000.0, m.summary.dump());
  if (!cache.empty()) {
    SaveModel(cache, m);
    spdlog::info("model: written to {}", cache);
  }
  return m;
}

std::map<std::string, Eigen::Vector3f> TypicalClassSizes(const Catalog& catalog) {
  std::map<std::string, std::vector<Eigen::Vector3f>> by_class;
  for (const auto& m : catalog.models) by_class[m.cls].push_back(m.size);
  std::map<std::string, Eigen::Vector3f> out;
  for (auto& [cls, sizes] : by_class) {
    Eigen::Vector3f med;
    for (int k = 0; k < 3; ++k) {
      std::vector<float> v;
      for (const auto& s : sizes) v.push_back(s[k]);
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      med[k] = v[v.size() / 2];
    }
    out[cls] = med;
  }
  return out;
}

Detection TransformDetection(Detection d, const Eigen::Isometry3f& t) {
  const float turn = std::atan2(t.linear()(1, 0), t.linear()(0, 0));
  auto wrap = [](float a) { return std::remainder(a, float(2 * M_PI)); };
  d.center = t * d.center;
  d.yaw = wrap(d.yaw + turn);
  d.model_pose = t * d.model_pose;
  if (d.box) {
    d.box->center = t * d.box->center;
    d.box->yaw = wrap(d.box->yaw + turn);
  }
  return d;
}

namespace {
nlohmann::json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
}  // namespace

nlohmann::json DetectionToJson(const Detection& d, const Scan* scan) {
  const ScanFrame frame = scan ? scan->frame : ScanFrame{};
  // World (fused) frame -> the scan's working frame -> its file's frame.
  const Eigen::Isometry3f to_scan = scan ? scan->pose.inverse() : Eigen::Isometry3f::Identity();
  auto P = [&](const Eigen::Vector3f& w) { return Vec(frame.ToFile(to_scan * w)); };
  auto D = [&](const Eigen::Vector3f& w) { return Vec(frame.DirectionToFile(to_scan.linear() * w)); };
  nlohmann::json j = {{"class", d.cls},
                      {"center", P(d.center)},
                      {"yaw", d.yaw},
                      {"yaw_deg", d.yaw * 180.0 / M_PI},
                      {"score", d.score},
                      {"model", d.model.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.model)},
                      {"verified", d.verified ? nlohmann::json(*d.verified) : nlohmann::json(nullptr)}};
  if (d.coverage) j["coverage"] = *d.coverage;
  j["free_space_ratio"] = d.free_space_ratio ? nlohmann::json(*d.free_space_ratio) : nlohmann::json(nullptr);
  if (d.rms) j["rms_m"] = *d.rms;
  if (d.iterations) j["iterations"] = d.iterations;
  if (!d.checks.empty()) {
    nlohmann::json checks = nlohmann::json::array();
    for (const Check& c : d.checks)
      checks.push_back({{"name", c.name}, {"value", c.value}, {"limit", c.limit},
                        {"test", c.at_least ? ">=" : "<="}, {"passed", c.passed}});
    j["checks"] = checks;
  }
  if (const std::string why = d.Rejection(); !why.empty()) j["rejection"] = why;
  if (!d.notes.empty()) j["notes"] = d.notes;
  if (scan && scan->ground) j["height_above_ground"] = scan->HeightAboveGround(d.center);
  if (d.box) {
    const OrientedBox& b = *d.box;
    nlohmann::json corners = nlohmann::json::array();
    Eigen::AlignedBox3d aabb;
    for (const auto& c : b.Corners()) {
      corners.push_back(P(c));
      aabb.extend(frame.ToFile(to_scan * c));
    }
    const Eigen::Vector3f ax(std::cos(b.yaw), std::sin(b.yaw), 0.f), ay(-std::sin(b.yaw), std::cos(b.yaw), 0.f);
    j["box"] = {{"source", d.box_source},
                {"center", P(b.center)},
                {"size", {b.size.x(), b.size.y(), b.size.z()}},
                {"yaw", b.yaw},
                {"axes", {D(ax), D(ay), D(Eigen::Vector3f::UnitZ())}},
                {"corners", corners},
                {"aabb", {{"min", Vec(aabb.min())}, {"max", Vec(aabb.max())}}}};
    if (scan && scan->ground) j["box"]["bottom_above_ground"] = scan->HeightAboveGround(b.center) - 0.5f * b.size.z();
  }
  if (!d.evidence.empty()) j["evidence"] = d.evidence;
  nlohmann::json sup = nlohmann::json::array();
  for (const auto& s : d.support) sup.push_back({{"scene", s.scene}, {"part", s.part}, {"weight", s.weight}});
  j["supporting_parts"] = sup;
  return j;
}

}  // namespace furnihost
