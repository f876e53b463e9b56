// One evaluation run of a graph over a dataset (Detector::Evaluate): every scene detected, the
// detections matched with the ground truth, the figures of `furnihost eval` for one seed.
//
// Parallelism: Pipeline::Detect is not thread-safe, so each worker thread owns a Pipeline
// (stages created once per worker). The first scene of a run is processed alone to measure
// its memory; jobs 0 then runs as many workers as cores allow and half the available memory
// holds. Stage timings of parallel scenes include contention: compare timings of runs with the
// same jobs (jobs 1 for clean per-stage times).
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "furnihost/hash.hpp"
#include "furnihost/host/detections.hpp"
#include "furnihost/host/detector.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/log.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace furnihost {

namespace {

// A "Vm..." line of /proc/self/status in MB, NaN when unavailable.
double ProcStatusMb(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key + ":", 0) == 0) return std::strtod(line.c_str() + key.size() + 1, nullptr) / 1024.0;
  return NAN;
}

double MemAvailableMb() {
  std::ifstream in("/proc/meminfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("MemAvailable:", 0) == 0) return std::strtod(line.c_str() + 13, nullptr) / 1024.0;
  return NAN;
}

// Resets the kernel's peak-RSS mark (VmHWM) to the current RSS so each run gets its own peak.
// Returns false where /proc/self/clear_refs is not writable; then only the process-wide
// ru_maxrss is available.
bool ResetPeakRss() {
  std::ofstream out("/proc/self/clear_refs");
  if (!out) return false;
  out << "5";
  out.flush();
  return static_cast<bool>(out);
}

double PeakRssMb(bool reset_ok) {
  const double hwm = ProcStatusMb("VmHWM");
  if (reset_ok && std::isfinite(hwm)) return hwm;
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

// Ground-truth boxes (file frame) in a scan's z-up frame: centres mapped, sizes the extents
// of the mapped box (exact for axis turns such as an optical frame's), yaw about the new up.
std::vector<GroundTruthObject> ToUpright(std::vector<GroundTruthObject> truth, const ScanFrame& f) {
  const Eigen::Matrix3f r = f.to_upright.linear().cast<float>();
  for (auto& g : truth) {
    g.center = (f.to_upright * (g.center.cast<double>() - f.shift)).cast<float>();
    g.size = (r.cwiseAbs() * g.size).eval();
    if (g.yaw) {
      const Eigen::Vector3f d = r * Eigen::Vector3f(std::cos(*g.yaw), std::sin(*g.yaw), 0.f);
      g.yaw = std::atan2(d.y(), d.x());
    }
  }
  return truth;
}

}  // namespace

SceneOutcome Detector::RunScene(Pipeline& p, const EvalRunInput& in, const RunContext& ctx, size_t i) const {
  const auto& scene = in.dataset->scenes[i];
  const bool chain = HasDetectionChain();
  Pipeline::SceneInput si;
  si.path = scene.scan;
  si.origin = scene.origin;
  si.origin_name = in.dataset->path + ":/scenes/" + std::to_string(i) + "/origin";
  si.frame = scene.frame;
  si.jitter_m = float(in.jitter_m);
  si.jitter_seed = SplitMix64(ctx.seed) ^ Fnv1a(scene.scan);
  Stopwatch sw;
  Pipeline::Result r;
  // Name the scene: the stage's message alone does not say which of many scans failed.
  try {
    r = p.Detect({si}, chain ? &model_ : nullptr, chain ? &catalog_ : nullptr, ctx);
  } catch (const InputError& e) {
    throw InputError(scene.scan + ": " + e.what());
  } catch (const StageError& e) {
    throw StageError(scene.scan + ": " + e.what(), e.IsInputError());
  }
  SceneOutcome o;
  o.record.scan = scene.scan;
  o.record.total_ms = sw.Ms();
  o.record.detections = static_cast<int>(r.detections.size());
  o.record.timings_ms = r.timings_ms;
  // Keep only what the evaluation needs: scans and features of every scene would add up.
  // Compared in the scan's z-up frame: the detections from the working frame, the ground
  // truth from the file's.
  for (const auto& h : r.votes.hypotheses) o.voter_centres.push_back(r.world_to_user * h.center);
  for (auto& d : r.detections) d = TransformDetection(d, r.world_to_user);
  if (!r.scans.empty()) {
    const ScanFrame& fr = r.scans.front().frame;
    if (!fr.shift.isZero() || !fr.to_upright.matrix().isIdentity()) o.truth_working = ToUpright((*in.truth)[i], fr);
  }
  if (!in.detections_dir.empty() && !r.scans.empty()) {
    Scan& f = o.frame.emplace();
    f.frame = r.scans.front().frame;
    f.pose = r.world_to_user * r.scans.front().pose;  // the detections are in the z-up frame now
    f.ground = r.scans.front().ground;
  }
  o.result.detections = std::move(r.detections);
  o.result.fitted = r.fitted;
  o.result.voted = r.voted;
  return o;
}

namespace {

void CheckInput(const EvalRunInput& in) {
  if (!in.dataset || !in.truth || in.truth->size() != in.dataset->scenes.size())
    throw std::logic_error("Detector::Evaluate: the dataset and its ground truth do not match");
}

}  // namespace

SceneOutcome Detector::EvaluateScene(const EvalRunInput& in, uint64_t seed, size_t i) {
  CheckInput(in);
  if (i >= in.dataset->scenes.size()) throw std::logic_error("Detector::EvaluateScene: no scene " + std::to_string(i));
  WaitLoaded();
  if (!peak_reset_) peak_reset_ = ResetPeakRss();
  RunContext ctx = ctx_;
  ctx.seed = seed;
  return RunScene(pipeline_, in, ctx, i);
}

RunFigures Detector::Evaluate(const EvalRunInput& in, uint64_t seed) {
  CheckInput(in);
  WaitLoaded();
  RunContext ctx = ctx_;
  ctx.seed = seed;
  const size_t n = in.dataset->scenes.size();
  peak_reset_ = ResetPeakRss();
  std::vector<SceneOutcome> outcomes(n);
  std::vector<std::unique_ptr<Pipeline>> workers;  // the pipelines of the workers after the first
  Progress progress("eval " + in.name + " seed " + std::to_string(seed), n);
  auto run_scene = [&](Pipeline& p, size_t i) {
    outcomes[i] = RunScene(p, in, ctx, i);
    progress.Tick();
  };

  Stopwatch wall;
  const double rss0 = ProcStatusMb("VmRSS");
  if (n > 0) run_scene(pipeline_, 0);
  int jobs = in.jobs;
  if (jobs <= 0) {
    const int cores = ctx.threads > 0 ? ctx.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    // Memory one more worker costs: the growth of the peak while the first scene ran
    // (includes this worker's pipeline and model load, so it over- rather than underestimates).
    const double per_scene = std::max(1.0, ProcStatusMb("VmHWM") - rss0);
    const double avail = MemAvailableMb();
    const int by_memory = std::isfinite(avail) && peak_reset_ ? static_cast<int>(0.5 * avail / per_scene) : cores;
    jobs = std::max(1, std::min(cores, by_memory));
    spdlog::debug("eval: {} workers ({} cores, ~{:.0f} MB per scene, {:.0f} MB available)", jobs, cores, per_scene, avail);
  }
  jobs = static_cast<int>(std::min<size_t>(static_cast<size_t>(jobs), std::max<size_t>(n - 1, 1)));
  if (n > 1) {
    for (int w = 1; w < jobs; ++w) workers.push_back(std::make_unique<Pipeline>(graph_, *registry_));
    std::atomic<size_t> next{1};
    std::atomic<bool> stop{false};
    std::exception_ptr error;
    std::mutex error_mu;
    auto worker = [&](Pipeline* p) {
      while (!stop) {
        const size_t i = next++;
        if (i >= n) break;
        try {
          run_scene(*p, i);
        } catch (...) {
          std::lock_guard<std::mutex> lock(error_mu);
          if (!error) error = std::current_exception();
          stop = true;
        }
      }
    };
    std::vector<std::thread> threads;
    for (auto& w : workers) threads.emplace_back(worker, w.get());
    worker(&pipeline_);
    for (auto& t : threads) t.join();
    if (error) std::rethrow_exception(error);
  }
  progress.Done();
  return Figures(in, seed, outcomes, wall.Ms(), jobs);
}

RunFigures Detector::Figures(const EvalRunInput& in, uint64_t seed, std::vector<SceneOutcome>& outcomes,
                             double wall_ms, int jobs) const {
  CheckInput(in);
  const auto& scenes = in.dataset->scenes;
  const size_t n = scenes.size();
  if (outcomes.size() != n) throw std::logic_error("Detector::Figures: one outcome per scene expected");
  RunFigures f;
  f.seed = seed;
  f.wall_ms = wall_ms;
  f.jobs = jobs;
  f.model_source = model_source_;
  std::vector<SceneEval> evals(n);
  for (size_t i = 0; i < n; ++i) {
    SceneOutcome& o = outcomes[i];
    evals[i].detections = std::move(o.result.detections);
    evals[i].truth = o.truth_working ? *o.truth_working : (*in.truth)[i];
    evals[i].fitted = o.result.fitted;
    evals[i].name = fs::path(scenes[i].scan).stem().string();
    evals[i].voter_centres = std::move(o.voter_centres);
    for (const auto& [tag, ms] : o.record.timings_ms) {
      auto it = std::find_if(f.stage_ms.begin(), f.stage_ms.end(), [&](const auto& t) { return t.first == tag; });
      if (it == f.stage_ms.end()) f.stage_ms.emplace_back(tag, ms);
      else it->second += ms;
    }
    f.scenes.push_back(std::move(o.record));
  }
  if (!in.detections_dir.empty()) {
    // Named inside detections_dir whatever the scans and the label are called.
    std::vector<std::string> stems;
    for (const auto& s : scenes) stems.push_back(fs::path(s.scan).stem().string());
    const std::vector<std::string> scene_files = UniqueSafeNames(stems);
    const std::string config_file = in.file.empty() ? SafeName(in.name) : in.file;
    for (size_t i = 0; i < n; ++i) {
      json j = {{"scan", scenes[i].scan}, {"seed", seed}, {"detections", json::array()}};
      const Scan* frame = outcomes[i].frame ? &*outcomes[i].frame : nullptr;
      for (const auto& d : evals[i].detections) j["detections"].push_back(DetectionToJson(d, frame));
      WriteJson((fs::path(in.detections_dir) / config_file / std::to_string(seed) / (scene_files[i] + ".json")).string(), j);
    }
  }
  f.metrics = furnihost::Evaluate(evals, in.dataset->classes, in.width);
  f.peak_rss_mb = PeakRssMb(peak_reset_);
  return f;
}

json DatasetJson(const Dataset& dataset, const std::string& hash) {
  json m = json::object();
  for (const auto& [k, v] : dataset.classes.map) m[k] = v ? json(*v) : json(nullptr);
  return {{"path", dataset.path},
          {"hash", hash},
          {"scenes", dataset.scenes.size()},
          {"classes", dataset.classes.classes},
          {"class_map", m}};
}

json EvalSummaryJson(const Dataset& dataset, const std::string& hash, WidthConvention width,
                     const std::vector<ConfigSummary>& configs) {
  json configs_json = json::array();
  for (const auto& s : configs) configs_json.push_back(ToJson(s));
  return {{"dataset", DatasetJson(dataset, hash)},
          {"width_convention", ToString(width)},
          {"matching", "TP: mapped classes equal and floor-plane (x, y) centre distance < " + std::string(ToString(width)) +
                           "(gt size x, y) / 2; greedy by descending score, each gt object matched at most once"},
          {"average_precision", "all-point interpolated (VOC 2010+)"},
          {"configs", configs_json}};
}

}  // namespace furnihost
