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

RunFigures Detector::Evaluate(const EvalRunInput& in, uint64_t seed) {
  if (!in.dataset || !in.truth || in.truth->size() != in.dataset->scenes.size())
    throw std::logic_error("Detector::Evaluate: the dataset and its ground truth do not match");
  WaitLoaded();
  RunContext ctx = ctx_;
  ctx.seed = seed;
  const auto& scenes = in.dataset->scenes;
  const size_t n = scenes.size();
  const bool reset_ok = ResetPeakRss();
  std::vector<Pipeline::Result> results(n);
  std::vector<SceneRecord> records(n);
  std::vector<std::vector<Eigen::Vector3f>> voter_centres(n);  // before a fitter moved them
  std::vector<std::optional<std::vector<GroundTruthObject>>> truth_working(n);
  // With detections_dir: each scene's frame, pose and ground (no points), so its detections
  // are written in the file's frame like detect's detections.json.
  std::vector<std::optional<Scan>> frame_of(n);
  std::vector<std::unique_ptr<Pipeline>> workers;  // the pipelines of the workers after the first
  Progress progress("eval " + in.name + " seed " + std::to_string(seed), n);
  const bool chain = HasDetectionChain();
  const TrainedModel* model = chain ? &model_ : nullptr;
  const Catalog* catalog = chain ? &catalog_ : nullptr;

  auto run_scene = [&](Pipeline& p, size_t i) {
    Pipeline::SceneInput si;
    si.path = scenes[i].scan;
    si.origin = scenes[i].origin;
    si.origin_name = in.dataset->path + ":/scenes/" + std::to_string(i) + "/origin";
    si.frame = scenes[i].frame;
    si.jitter_m = float(in.jitter_m);
    si.jitter_seed = SplitMix64(ctx.seed) ^ Fnv1a(scenes[i].scan);
    Stopwatch sw;
    Pipeline::Result r;
    // Name the scene: the stage's message alone does not say which of many scans failed.
    try {
      r = p.Detect({si}, model, catalog, ctx);
    } catch (const InputError& e) {
      throw InputError(scenes[i].scan + ": " + e.what());
    } catch (const StageError& e) {
      throw StageError(scenes[i].scan + ": " + e.what(), e.IsInputError());
    }
    records[i].scan = scenes[i].scan;
    records[i].total_ms = sw.Ms();
    records[i].detections = static_cast<int>(r.detections.size());
    records[i].timings_ms = r.timings_ms;
    // Keep only what the evaluation needs: scans and features of every scene would add up.
    // Compared in the scan's z-up frame: the detections from the working frame, the ground
    // truth from the file's.
    for (const auto& h : r.votes.hypotheses) voter_centres[i].push_back(r.world_to_user * h.center);
    for (auto& d : r.detections) d = TransformDetection(d, r.world_to_user);
    if (!r.scans.empty()) {
      const ScanFrame& fr = r.scans.front().frame;
      if (!fr.shift.isZero() || !fr.to_upright.matrix().isIdentity()) truth_working[i] = ToUpright((*in.truth)[i], fr);
    }
    if (!in.detections_dir.empty() && !r.scans.empty()) {
      Scan& f = frame_of[i].emplace();
      f.frame = r.scans.front().frame;
      f.pose = r.world_to_user * r.scans.front().pose;  // the detections are in the z-up frame now
      f.ground = r.scans.front().ground;
    }
    Pipeline::Result keep;
    keep.detections = std::move(r.detections);
    keep.fitted = r.fitted;
    keep.voted = r.voted;
    results[i] = std::move(keep);
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
    const int by_memory = std::isfinite(avail) && reset_ok ? static_cast<int>(0.5 * avail / per_scene) : cores;
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

  RunFigures f;
  f.seed = seed;
  f.wall_ms = wall.Ms();
  f.jobs = jobs;
  f.model_source = model_source_;
  std::vector<SceneEval> evals(n);
  for (size_t i = 0; i < n; ++i) {
    evals[i].detections = std::move(results[i].detections);
    evals[i].truth = truth_working[i] ? *truth_working[i] : (*in.truth)[i];
    evals[i].fitted = results[i].fitted;
    evals[i].name = fs::path(scenes[i].scan).stem().string();
    evals[i].voter_centres = std::move(voter_centres[i]);
    for (const auto& [tag, ms] : records[i].timings_ms) {
      auto it = std::find_if(f.stage_ms.begin(), f.stage_ms.end(), [&](const auto& t) { return t.first == tag; });
      if (it == f.stage_ms.end()) f.stage_ms.emplace_back(tag, ms);
      else it->second += ms;
    }
  }
  f.scenes = std::move(records);
  if (!in.detections_dir.empty()) {
    // Named inside detections_dir whatever the scans and the label are called.
    std::vector<std::string> stems;
    for (const auto& s : scenes) stems.push_back(fs::path(s.scan).stem().string());
    const std::vector<std::string> scene_files = UniqueSafeNames(stems);
    const std::string config_file = in.file.empty() ? SafeName(in.name) : in.file;
    for (size_t i = 0; i < n; ++i) {
      json j = {{"scan", scenes[i].scan}, {"seed", seed}, {"detections", json::array()}};
      const Scan* frame = frame_of[i] ? &*frame_of[i] : nullptr;
      for (const auto& d : evals[i].detections) j["detections"].push_back(DetectionToJson(d, frame));
      WriteJson((fs::path(in.detections_dir) / config_file / std::to_string(seed) / (scene_files[i] + ".json")).string(), j);
    }
  }
  f.metrics = furnihost::Evaluate(evals, in.dataset->classes, in.width);
  f.peak_rss_mb = PeakRssMb(reset_ok);
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
