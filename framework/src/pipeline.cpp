#include "furnihost/pipeline.hpp"

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "furnihost/geometry.hpp"
#include "furnihost/ground.hpp"
#include "furnihost/hash.hpp"
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

namespace {
// What shapes one voter's model: the segmenter and features it learns through, and itself.
nlohmann::json VoterKey(const GraphConfig& g, const StageConfig* voter) {
  const StageConfig* features = voter ? g.InputOfKind(*voter, StageKind::Features) : nullptr;
  return {{"segmenter", StageKey(voter ? g.SegmenterOfVoter(*voter) : nullptr)},
          {"features", StageKey(features)},
          {"voter", StageKey(voter)}};
}

nlohmann::json VoterModelJson(const std::string& type, const Normaliser& n, const nlohmann::json& model) {
  return {{"voter_type", type}, {"normaliser", n.ToJson()}, {"voter_model", model}};
}
}  // namespace

const TrainedVoter* TrainedModel::FindVoter(const std::string& tag) const {
  if (voters.empty()) return nullptr;
  auto it = voters.find(tag);
  return it == voters.end() ? nullptr : &it->second;
}

nlohmann::json TrainingKey(const GraphConfig& g) {
  const StageConfig* tr = g.training_sensor.empty() ? nullptr : g.Find(g.training_sensor);
  nlohmann::json key = {{"seed", g.seed}, {"training_sensor", StageKey(tr)}};
  const auto voters = g.AllOfKind(StageKind::Voter);
  if (voters.size() <= 1) {
    key.update(VoterKey(g, voters.empty() ? nullptr : voters.front()));
    return key;
  }
  key["voters"] = nlohmann::json::object();
  for (const auto* v : voters) key["voters"][v->tag] = VoterKey(g, v);
  return key;
}

void SaveModel(const std::string& path, const TrainedModel& m) {
  nlohmann::json j = {{"format_version", m.format_version}, {"training_config", m.training_config},
                      {"catalog_hash", m.catalog_hash},     {"voter_type", m.voter_type},
                      {"normaliser", m.normaliser.ToJson()}, {"voter_model", m.voter_model},
                      {"summary", m.summary}};
  if (!m.voters.empty()) {
    j["voters"] = nlohmann::json::object();
    for (const auto& [tag, v] : m.voters) j["voters"][tag] = VoterModelJson(v.voter_type, v.normaliser, v.voter_model);
  }
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
    if (j.contains("voters")) {
      const auto& vs = j.at("voters");
      if (!vs.is_object()) throw InputError(path + ": corrupt model file (voters is not an object); delete it to retrain");
      for (auto it = vs.begin(); it != vs.end(); ++it) {
        TrainedVoter v;
        v.voter_type = it->at("voter_type").get<std::string>();
        v.normaliser = Normaliser::FromJson(it->at("normaliser"));
        if (!v.normaliser.min.allFinite() || !v.normaliser.max.allFinite())
          throw InputError(path + ": corrupt model file (non-finite normaliser of voter '" + it.key() +
                           "'); delete it to retrain");
        v.voter_model = it->at("voter_model");
        m.voters[it.key()] = std::move(v);
      }
    }
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
  input_cfg_ = graph_.FirstOfKind(StageKind::Sensor);  // validation allows one detection sensor
  train_cfg_ = graph_.training_sensor.empty() ? nullptr : graph_.Find(graph_.training_sensor);
  auto make = [&](const StageConfig* c) { return Call(*c, [&] { return registry.Create(c->type, c->params); }); };
  if (input_cfg_) input_ = std::dynamic_pointer_cast<Sensor>(make(input_cfg_));
  if (train_cfg_) training_ = std::dynamic_pointer_cast<Sensor>(make(train_cfg_));
  for (const auto& s : graph_.stages) {
    if (s.kind == StageKind::Sensor) continue;
    if (s.kind == StageKind::Voter)
      voters_[s.tag].voter = std::dynamic_pointer_cast<Voter>(make(&s));
    else
      stages_[s.tag] = make(&s);
  }
}

template <class T>
T& Pipeline::StageAs(const StageConfig& s) const {
  auto it = stages_.find(s.tag);
  T* t = it == stages_.end() ? nullptr : dynamic_cast<T*>(it->second.get());
  if (!t) throw StageError("stage '" + s.tag + "' (" + s.type + "): not a " + ToString(s.kind) + " plugin", false);
  return *t;
}

std::vector<std::string> Pipeline::MissingStages() const {
  auto any = [&](StageKind k) { return !graph_.AllOfKind(k).empty(); };
  std::vector<std::string> m;
  if (!input_) m.push_back("sensor (scan reader)");
  // A recogniser of proposals needs neither part features nor a fitter to decide.
  const bool recogniser = any(StageKind::Proposer) && !voters_.empty();
  if (!any(StageKind::Segmenter) && !recogniser) m.push_back("segmenter");
  if (!any(StageKind::Features) && !recogniser) m.push_back("features");
  if (voters_.empty()) m.push_back("voter");
  if (!any(StageKind::Fitter) && !recogniser) m.push_back("fitter");
  return m;
}

TrainedModel Pipeline::Train(const Catalog& catalog, const RunContext& ctx) {
  if (!training_) throw InputError(graph_.path + ":/training/sensor: the graph names no training sensor");
  const auto voter_cfgs = graph_.AllOfKind(StageKind::Voter);
  if (voter_cfgs.empty()) throw InputError(graph_.path + ": training needs a voter stage");
  if (catalog.models.empty()) throw InputError(catalog.path + ": no usable models to train from");
  // Each voter learns through its own branch: a voter of part features needs the parts of every
  // view (its features' segmenter); a recogniser of whole proposals (no features input) learns
  // from the views' points alone.
  struct Branch {
    const StageConfig *voter, *seg, *feat;
    std::vector<TrainingView> views;
    std::map<std::string, std::pair<int, int>> per_class;  // class -> (views, parts)
  };
  std::vector<Branch> branches;
  for (const auto* v : voter_cfgs) {
    const StageConfig* feat = graph_.InputOfKind(*v, StageKind::Features);
    branches.push_back({v, feat ? graph_.InputOfKind(*feat, StageKind::Segmenter) : nullptr, feat, {}, {}});
  }
  double t_sim = 0, t_seg = 0, t_feat = 0;
  Progress progress("train: scanning models", catalog.models.size());
  for (const auto& model : catalog.models) {
    SensorRequest req;
    req.objects.push_back({&model, Eigen::Isometry3f::Identity()});
    Stopwatch sw;
    std::vector<Scan> scans = Call(*train_cfg_, [&] { return training_->Acquire(req, ctx); });
    t_sim += sw.Ms();
    for (size_t v = 0; v < scans.size(); ++v) {
      if (scans[v].points.size() < 3) continue;
      // Each segmenter and features stage runs once per view, whichever voters share it.
      std::map<std::string, Segmentation> segs;
      std::map<std::string, FeatureMatrix> feats;
      for (size_t b = 0; b < branches.size(); ++b) {
        Branch& br = branches[b];
        TrainingView tv;
        tv.cls = model.cls;
        tv.model_id = model.id;
        tv.view = static_cast<int>(v);
        tv.object_size = model.size;
        tv.model = &model;
        tv.scan = b + 1 == branches.size() ? std::move(scans[v]) : scans[v];
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (const auto& p : tv.scan.points) c += p.cast<double>();
        tv.object_centroid = (c / static_cast<double>(tv.scan.points.size())).cast<float>();
        if (br.feat) {
          if (!segs.count(br.seg->tag)) {
            Stopwatch s2;
            segs[br.seg->tag] = Call(*br.seg, [&] { return StageAs<Segmenter>(*br.seg).Segment(tv.scan, ctx); });
            t_seg += s2.Ms();
          }
          tv.segmentation = segs[br.seg->tag];
          if (!feats.count(br.feat->tag)) {
            Stopwatch s3;
            feats[br.feat->tag] =
                Call(*br.feat, [&] { return StageAs<Features>(*br.feat).Compute(tv.scan, tv.segmentation, ctx); });
            t_feat += s3.Ms();
          }
          tv.features = feats[br.feat->tag];
          if (tv.features.values.rows() != static_cast<Eigen::Index>(tv.segmentation.parts.size()))
            throw StageError("stage '" + br.feat->tag + "': returned " + std::to_string(tv.features.values.rows()) +
                                 " rows for " + std::to_string(tv.segmentation.parts.size()) + " parts",
                             false);
        }
        br.per_class[model.cls].first++;
        br.per_class[model.cls].second += static_cast<int>(tv.segmentation.parts.size());
        br.views.push_back(std::move(tv));
      }
    }
    progress.Tick();
  }
  progress.Done();
  TrainedModel m;
  m.training_config = TrainingKey(graph_);
  m.catalog_hash = catalog.hash;
  double t_vote = 0;
  nlohmann::json per_voter = nlohmann::json::object();
  for (Branch& br : branches) {
    TrainedVoter tvr;
    tvr.voter_type = br.voter->type;
    if (br.feat) {
      std::vector<const FeatureMatrix*> fm;
      for (const auto& v : br.views) fm.push_back(&v.features);
      tvr.normaliser = Normaliser::Fit(fm);
      if (tvr.normaliser.min.size() == 0)
        throw StageError("training produced no parts: check the parameters of segmenter '" + br.seg->tag + "'", true);
      for (auto& v : br.views) tvr.normaliser.Apply(v.features);
    }
    Voter& voter = *voters_.at(br.voter->tag).voter;
    Stopwatch sv;
    tvr.voter_model = Call(*br.voter, [&] { return voter.Train(br.views, ctx); });
    t_vote += sv.Ms();
    br.views.clear();
    br.views.shrink_to_fit();
    nlohmann::json classes = nlohmann::json::object();
    size_t parts = 0;
    size_t views = 0;
    for (const auto& [c, vp] : br.per_class) {
      classes[c] = {{"views", vp.first}, {"parts", vp.second}};
      parts += vp.second;
      views += vp.first;
    }
    per_voter[br.voter->tag] = {{"views", views}, {"parts", parts}, {"classes", classes}};
    // Through Call: an exception escaping the plugin is caught while its library is loaded.
    Call(*br.voter, [&] { voter.Load(tvr.voter_model); return 0; });
    voters_.at(br.voter->tag).loaded_model_id = m.catalog_hash + m.training_config.dump();
    if (branches.size() == 1) {
      m.voter_type = tvr.voter_type;
      m.normaliser = tvr.normaliser;
      m.voter_model = std::move(tvr.voter_model);
    } else {
      m.voters[br.voter->tag] = std::move(tvr);
    }
  }
  const nlohmann::json time_ms = {{"simulate", t_sim}, {"segment", t_seg}, {"features", t_feat}, {"voter", t_vote}};
  if (branches.size() == 1) {
    const nlohmann::json& only = per_voter.begin().value();
    m.summary = {{"models", catalog.models.size()}, {"views", only["views"]}, {"parts", only["parts"]},
                 {"classes", only["classes"]}, {"time_ms", time_ms}};
  } else {
    m.summary = {{"models", catalog.models.size()}, {"voters", per_voter}, {"time_ms", time_ms}};
  }
  return m;
}

Pipeline::Result Pipeline::Detect(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                                  const Catalog* catalog, const RunContext& ctx,
                                  const std::function<void()>& before_stages) {
  const EnsembleOptions& e = graph_.ensemble;
  Result first = DetectOnce(scenes, model, catalog, ctx, before_stages, {});
  if (e.runs <= 1) return first;
  std::vector<std::vector<Detection>> runs;
  runs.push_back(std::move(first.detections));
  for (int k = 1; k < e.runs; ++k) {
    Result rk = DetectOnce(scenes, model, catalog, ctx, {},
                           {float(e.jitter_m), SplitMix64(ctx.seed ^ 0x656e73656d626c65ull) + uint64_t(k), &first.scans});
    // Each run's world is its first scan's working frame, estimated anew on its jittered points:
    // its detections are moved into the first run's (both frames are z up: an upright move).
    const Eigen::Isometry3f to_first = first.world_to_user.inverse() * rk.world_to_user;
    if (!to_first.isApprox(Eigen::Isometry3f::Identity()))
      for (auto& d : rk.detections) d = TransformDetection(std::move(d), to_first);
    for (const auto& [tag, ms] : rk.timings_ms)
      for (auto& t : first.timings_ms)
        if (t.first == tag) t.second += ms;
    runs.push_back(std::move(rk.detections));
    spdlog::info("ensemble: run {} of {} (jitter {:.2f} mm): {} detections", k + 1, e.runs, e.jitter_m * 1000.0,
                 runs.back().size());
  }
  Stopwatch sf;
  first.detections = FuseDetections(runs, e.join_iou);
  first.timings_ms.emplace_back("ensemble", sf.Ms());
  return first;
}

Pipeline::Result Pipeline::DetectOnce(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                                      const Catalog* catalog, const RunContext& ctx,
                                      const std::function<void()>& before_stages, const RunJitter& run_jitter) {
  if (!input_) throw InputError(graph_.path + ": the graph has no input sensor stage (e.g. sensors.scan_file)");
  Result r;
  auto timed = [&](const std::string& tag, double ms) {
    for (auto& t : r.timings_ms)
      if (t.first == tag) { t.second += ms; return; }
    r.timings_ms.emplace_back(tag, ms);
  };
  Eigen::Isometry3d world_to_user = Eigen::Isometry3d::Identity();
  uint64_t jittered_scans = 0;
  for (const auto& sc : scenes) {
    SensorRequest req;
    req.path = sc.path;
    req.scan = sc.scan.get();
    req.origin = sc.origin;
    req.shift = sc.frame.shift;
    Stopwatch sw;
    auto got = Call(*input_cfg_, [&] { return input_->Acquire(req, ctx); });
    if (sc.jitter_m > 0.f)
      for (size_t k = 0; k < got.size(); ++k) JitterPoints(got[k].points, sc.jitter_m, sc.jitter_seed + k);
    // An ensemble run's noise, drawn by point index along the first run's working axes: the same
    // noise in the scene whatever frame the file gives the points in. The run then frames its
    // jittered scan anew (the frame's estimate is among the decisions the runs average).
    if (run_jitter.sigma_m > 0.f)
      for (auto& s : got) {
        const size_t j = jittered_scans++;
        if (j >= run_jitter.reference->size()) throw std::logic_error("ensemble: a run read more scans than the first");
        const Eigen::Matrix3f axes = (*run_jitter.reference)[j].frame.ToWorking().linear().transpose().cast<float>();
        JitterPoints(s.points, run_jitter.sigma_m, SplitMix64(run_jitter.seed) + j, axes);
      }
    timed(input_cfg_->tag, sw.Ms());
    // The working frame (z up) and the ground, once per scan, before any stage sees it.
    Stopwatch sg;
    for (auto& s : got) {
      FrameOptions fo = sc.frame;
      fo.canonical = fo.canonical && graph_.canonical_frame;
      fo.neighbours = !graph_.AllOfKind(StageKind::Proposer).empty();  // proposals.clusters takes them
      fo.level = fo.level || graph_.level_frame;
      ToWorkingFrame(s, fo);
      GroundOptions go = graph_.ground;
      go.fixed_z += float(s.frame.canonical.translation().z());  // given in the z-up frame
      if (!s.ground || graph_.ground.kind == "fixed")
        s.ground = EstimateGround(s.points, go, [](size_t b, size_t e, const std::function<void(size_t, size_t)>& body) {
          tbb::parallel_for(tbb::blocked_range<size_t>(b, e, 1024),
                            [&](const tbb::blocked_range<size_t>& r) { body(r.begin(), r.end()); });
        });
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

  if (before_stages) before_stages();
  // The executor: every stage in execution (topological) order, each given the outputs of the
  // stages its `inputs` name, which are kept by tag until the end of the run.
  struct Output {
    std::vector<Segmentation> segmentations;  // segmenter: one per scan
    std::vector<Proposals> proposals;         // proposer: one per scan
    std::vector<FeatureMatrix> features;      // features: raw; voter: its input, normalised
    std::vector<SceneParts> parts;            // voter: what it voted with (and its fitters fit)
    VoteResult votes;                         // voter
    std::vector<Detection> detections;        // voter: its hypotheses; fitter: its output
    bool ran = false, fitted = false;
  };
  std::map<std::string, Output> out;
  const size_t n = r.scans.size();
  const StageConfig *first_seg = nullptr, *first_prop = nullptr, *first_feat = nullptr, *first_voter = nullptr;
  std::map<std::string, FitContext> fit_contexts;  // by root voter (and proposer) of a fitter chain
  for (const StageConfig& s : graph_.stages) {
    if (s.kind == StageKind::Sensor) continue;  // the input sensor ran above; the training sensor trains
    Output& o = out[s.tag];
    switch (s.kind) {
      case StageKind::Sensor: break;
      case StageKind::Segmenter: {
        auto& seg = StageAs<Segmenter>(s);
        for (const auto& scan : r.scans) {
          Stopwatch one;
          o.segmentations.push_back(Call(s, [&] { return seg.Segment(scan, ctx); }));
          timed(s.tag, one.Ms());
          spdlog::info("{}: {} points -> {} parts ({} points discarded)", scan.source, scan.points.size(),
                       o.segmentations.back().parts.size(), o.segmentations.back().discarded_points);
        }
        if (!first_seg) first_seg = &s;
        break;
      }
      case StageKind::Proposer: {
        auto& prop = StageAs<Proposer>(s);
        const StageConfig* seg_cfg = graph_.InputOfKind(s, StageKind::Segmenter);
        for (size_t i = 0; i < n; ++i) {
          Stopwatch one;
          const Segmentation* seg = seg_cfg ? &out.at(seg_cfg->tag).segmentations.at(i) : nullptr;
          o.proposals.push_back(Call(s, [&] { return prop.Propose(r.scans[i], seg, ctx); }));
          timed(s.tag, one.Ms());
          spdlog::info("{}: {} proposals (spacing {:.3f} m)", r.scans[i].source, o.proposals.back().items.size(),
                       o.proposals.back().spacing);
        }
        if (!first_prop) first_prop = &s;
        break;
      }
      case StageKind::Features: {
        auto& feat = StageAs<Features>(s);
        const auto& segs = out.at(graph_.InputOfKind(s, StageKind::Segmenter)->tag).segmentations;
        for (size_t i = 0; i < n; ++i) {
          Stopwatch one;
          o.features.push_back(Call(s, [&] { return feat.Compute(r.scans[i], segs.at(i), ctx); }));
          timed(s.tag, one.Ms());
          if (o.features.back().values.rows() != static_cast<Eigen::Index>(segs[i].parts.size()))
            throw StageError("stage '" + s.tag + "': feature rows do not match the parts", false);
        }
        if (!first_feat) first_feat = &s;
        break;
      }
      case StageKind::Voter: {
        if (!model) break;  // features computed, nothing to vote with
        const bool several = voters_.size() > 1;
        const std::string fix = graph_.model_cache.empty() ? std::string(" (retrain with --retrain)")
                                                           : " (model " + graph_.model_cache + "; retrain with --retrain)";
        const Normaliser* norm = &model->normaliser;
        const nlohmann::json* voter_model = &model->voter_model;
        if (several || !model->voters.empty()) {
          const TrainedVoter* tv = model->FindVoter(s.tag);
          if (!tv)
            throw InputError("stage '" + s.tag + "' (" + s.type + "): the model has no model for this voter" + fix);
          norm = &tv->normaliser;
          voter_model = &tv->voter_model;
        }
        const StageConfig* feat_cfg = graph_.InputOfKind(s, StageKind::Features);
        const StageConfig* prop_cfg = graph_.InputOfKind(s, StageKind::Proposer);
        const StageConfig* seg_cfg = graph_.SegmenterOfVoter(s);
        size_t clamped = 0;
        if (feat_cfg) {
          o.features = out.at(feat_cfg->tag).features;  // normalised by this voter's model
          for (auto& f : o.features) clamped += norm->Apply(f);
        }
        r.clamped_features += clamped;
        if (clamped)
          spdlog::info("features{}: {} values outside the training range were clamped",
                       several ? " of voter '" + s.tag + "'" : std::string(), clamped);
        VoterSlot& slot = voters_.at(s.tag);
        const std::string id = model->catalog_hash + model->training_config.dump();
        if (slot.loaded_model_id != id) {
          // A model its voter cannot load is a corrupt or foreign cache file: bad input (exit 2),
          // whatever the plugin threw, with the way out in the message.
          try {
            Call(s, [&] { slot.voter->Load(*voter_model); return 0; });
          } catch (const std::exception& e) {
            throw InputError(std::string(e.what()) + fix);
          }
          slot.loaded_model_id = id;
        }
        for (size_t i = 0; i < n; ++i)
          o.parts.push_back({&r.scans[i], seg_cfg ? &out.at(seg_cfg->tag).segmentations.at(i) : nullptr,
                             feat_cfg ? &o.features[i] : nullptr,
                             prop_cfg ? &out.at(prop_cfg->tag).proposals.at(i) : nullptr});
        Stopwatch sv;
        o.votes = Call(s, [&] { return slot.voter->Vote(o.parts, ctx); });
        timed(s.tag, sv.Ms());
        o.ran = true;
        r.voted = true;
        if (catalog && sized_catalog_ != catalog) {
          class_size_ = TypicalClassSizes(*catalog);
          sized_catalog_ = catalog;
        }
        for (const auto& h : o.votes.hypotheses) {
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
            o.fitted = true;  // decided: the eval counts accepted detections as verified
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
          o.detections.push_back(d);
        }
        if (!first_voter) first_voter = &s;
        break;
      }
      case StageKind::Fitter: {
        // Fitters verify against the catalog; without one the chain stops at what ran before.
        const Output& in = out.at(graph_.DetectionsInput(s)->tag);
        if (!catalog || !in.ran) break;
        // The scenes its voter voted with; a proposer among its inputs gives the proposals.
        const StageConfig* root = graph_.VoterOf(s);
        const StageConfig* prop_cfg = graph_.InputOfKind(s, StageKind::Proposer);
        const std::string key = root->tag + (prop_cfg ? "/" + prop_cfg->tag : std::string());
        auto fc = fit_contexts.find(key);
        if (fc == fit_contexts.end()) {
          FitContext c;
          c.scenes = out.at(root->tag).parts;
          if (prop_cfg)
            for (size_t i = 0; i < n; ++i) c.scenes[i].proposals = &out.at(prop_cfg->tag).proposals.at(i);
          for (const auto& m : catalog->models) c.catalog.push_back(&m);
          c.run = ctx;
          fc = fit_contexts.emplace(key, std::move(c)).first;
        }
        auto& fitter = StageAs<Fitter>(s);
        Stopwatch sf;
        o.detections = Call(s, [&] { return fitter.Fit(in.detections, fc->second); });
        timed(s.tag, sf.Ms());
        o.ran = o.fitted = true;
        break;
      }
    }
  }

  // The sinks' detections. A sink that did not run (a fitter without a catalog, a voter
  // without a model) gives those of the last stage of its chain that did, once.
  const auto sinks = graph_.Sinks();
  std::set<std::string> given;
  for (const StageConfig* sink : sinks) {
    const StageConfig* c = sink;
    for (size_t hops = 0; c && !out.at(c->tag).ran && c->kind == StageKind::Fitter && hops <= graph_.stages.size(); ++hops)
      c = graph_.DetectionsInput(*c);
    if (!c || !out.at(c->tag).ran || !given.insert(c->tag).second) continue;
    Output& o = out.at(c->tag);
    r.sinks.push_back(c->tag);
    r.fitted = r.fitted || o.fitted;
    for (auto& d : o.detections) {
      if (sinks.size() > 1) d.chain = c->tag;
      r.detections.push_back(std::move(d));
    }
  }
  // The first stage of each kind fills the single-chain fields of the result.
  if (first_seg) r.segmentations = std::move(out.at(first_seg->tag).segmentations);
  if (first_prop) r.proposals = std::move(out.at(first_prop->tag).proposals);
  if (first_voter && graph_.InputOfKind(*first_voter, StageKind::Features))
    r.features = std::move(out.at(first_voter->tag).features);
  else if (first_feat)
    r.features = std::move(out.at(first_feat->tag).features);
  if (first_voter) r.votes = std::move(out.at(first_voter->tag).votes);
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
  if (!d.chain.empty()) j["chain"] = d.chain;
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
