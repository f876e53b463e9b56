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
#include "host/graph/executor.hpp"
#include "host/graph/training.hpp"

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

namespace {
// What shapes one voter's model: the segmenter and features it learns through, and itself.
nlohmann::json VoterKey(const GraphConfig& g, const StageConfig* voter) {
  const StageConfig* features = voter ? g.Input(*voter, InputRole::Features) : nullptr;
  return {{"segmenter", StageKey(voter ? g.SegmenterOf(*voter) : nullptr)},
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
  const auto voters = g.Trained();
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

Pipeline::Pipeline(const GraphConfig& graph, const Registry& registry)
    : graph_(graph), stages_(std::make_shared<graph::StageInstances>()) {
  input_ = graph_.FirstOfKind(StageKind::Sensor);  // validation allows one detection sensor
  for (const auto& s : graph_.stages) {
    auto plugin = graph::CallStage(s, [&] { return registry.Create(s.type, s.params); });
    neighbours_ = std::max(neighbours_, plugin->Needs().neighbours);
    stages_->by_tag[s.tag].plugin = std::move(plugin);
  }
}

bool Pipeline::HasDetectionChain() const { return !graph_.Sinks().empty(); }

std::vector<std::string> Pipeline::MissingStages() const {
  auto any = [&](StageKind k) { return !graph_.AllOfKind(k).empty(); };
  std::vector<std::string> m;
  if (!input_) m.push_back("sensor (scan reader)");
  // A recogniser of proposals needs neither part features nor a fitter to decide.
  const bool voter = any(StageKind::Voter), recogniser = any(StageKind::Proposer) && voter;
  if (!any(StageKind::Segmenter) && !recogniser) m.push_back("segmenter");
  if (!any(StageKind::Features) && !recogniser) m.push_back("features");
  if (!voter) m.push_back("voter");
  if (!any(StageKind::Fitter) && !recogniser) m.push_back("fitter");
  return m;
}

TrainedModel Pipeline::Train(const Catalog& catalog, const RunContext& ctx) {
  return graph::TrainGraph(graph_, *stages_, catalog, ctx);
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
  auto& sensor = stages_->at(input_->tag).As<Sensor>(*input_);
  Eigen::Isometry3d world_to_user = Eigen::Isometry3d::Identity();
  uint64_t jittered_scans = 0;
  for (const auto& sc : scenes) {
    SensorRequest req;
    req.path = sc.path;
    req.origin = sc.origin;
    req.shift = sc.frame.shift;
    Stopwatch sw;
    auto got = graph::CallStage(*input_, [&] { return sensor.Acquire(req, ctx); });
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
    timed(input_->tag, sw.Ms());
    // The working frame (z up) and the ground, once per scan, before any stage sees it.
    Stopwatch sg;
    for (auto& s : got) {
      FrameOptions fo = sc.frame;
      fo.canonical = fo.canonical && graph_.canonical_frame;
      fo.neighbours = neighbours_;  // what the stages ask for
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
          throw InputError("stage '" + input_->tag + "' (" + input_->type + "): " + sc.path + ": " +
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
  graph::Run run(graph_, r.scans, ctx);
  run.model = model;
  run.catalog = catalog;
  run.timings_ms = std::move(r.timings_ms);
  graph::RunStages(run, *stages_);
  r.timings_ms = std::move(run.timings_ms);
  graph::CollectResult(run, r);
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
