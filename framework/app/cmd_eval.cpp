// `furnihost eval` (A/B evaluation of graph configs on a dataset manifest) and
// `furnihost compare` (the same table from two run records written by eval).
//
// Seeds: the trained model is the graph's (its cache is keyed by the graph's "seed"), so
// --seeds N varies the detection-time seed only (RunContext::seed = seed0 .. seed0 + N - 1,
// seed0 = --seed or the graph's seed): the spread shows the randomised detection stages
// (e.g. RANSAC fitting), not the variation of training.
//
// Parallelism: Pipeline::Detect is not thread-safe, so each worker thread owns a Pipeline
// (stages created once per worker). The first scene of a run is processed alone to measure
// its memory; --jobs 0 then runs as many workers as cores allow and half the available
// memory holds. Stage timings of parallel scenes include contention: compare timings of runs
// with the same --jobs (use --jobs 1 for clean per-stage times).
#include <sys/resource.h>
#include <sys/utsname.h>

#include <atomic>
#include <cctype>
#include <cstdio>
#include <ctime>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <thread>

#include "cli_common.hpp"
#include "git_info.hpp"
#include "commands.hpp"
#include "furnihost/host/catalog.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/log.hpp"
#include "furnihost/host/pipeline.hpp"
#include "mpi_jobs.hpp"
#include "mpi_train.hpp"
#include "plots.hpp"
#include "report.hpp"
#include "wire.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace furnihost::app {

namespace {

// ---- process facts -------------------------------------------------------------------------

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

// Git revision of the source checkout: $FURNIHOST_SOURCE_DIR, else the folder of the first
// graph (configs/ lives in the checkout). Read from its files, never by running git.
json GitInfo(const std::string& near) {
  std::vector<std::string> dirs;
  if (const char* s = std::getenv("FURNIHOST_SOURCE_DIR")) dirs.push_back(s);
  dirs.push_back(fs::absolute(fs::path(near)).parent_path().string());
  return app::GitInfo(dirs);
}

json MachineInfo() {
  json m;
  utsname u{};
  if (::uname(&u) == 0)
    m["uname"] = std::string(u.sysname) + " " + u.release + " " + u.version + " " + u.machine;
  m["nproc"] = std::thread::hardware_concurrency();
  std::ifstream cpu("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpu, line))
    if (line.rfind("model name", 0) == 0) {
      m["cpu"] = line.substr(line.find(':') + 2);
      break;
    }
  std::ifstream mem("/proc/meminfo");
  while (std::getline(mem, line))
    if (line.rfind("MemTotal:", 0) == 0) {
      m["memory_mb"] = std::strtod(line.c_str() + 9, nullptr) / 1024.0;
      break;
    }
  return m;
}

std::string UtcNow() {
  std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// ---- one config ----------------------------------------------------------------------------

struct Loaded {
  std::string name;  // the label (--name, or the graph's stem)
  std::string file;  // the name of its files: run_<file>.json, detections/<file>/ (UniqueSafeNames)
  GraphConfig graph;
  std::optional<Catalog> catalog;
  std::optional<TrainedModel> model;
};

// A length in metres as millimetres, "0.50 mm".
std::string Mm(double m) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f mm", m * 1000);
  return b;
}

struct RunInput {
  const Dataset* dataset;
  const std::vector<std::vector<GroundTruthObject>>* truth;
  WidthConvention width;
  int jobs;  // 0 = auto
  std::string detections_dir;  // when set: each scene's detections as <dir>/<config>/<seed>/<scene>.json
  std::vector<std::string> scene_files;  // <scene>: each scan's stem, made safe and distinct
  double jitter_m = 0;  // --jitter: noise added to each scene's points, drawn from the seed and the scan's path
  const World* world = nullptr;  // several ranks: the scenes are shared among them (mpi_jobs.hpp)
};

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

// What the evaluation keeps of one scene's detection: the detections (in the scan's z-up
// frame), whether a fitter ran and a voter voted, its record, the voter's centres before a
// fitter moved them, the ground truth in the z-up frame when the file's frame differs, and with
// --save-detections its frame, pose and ground (no points), so that its detections are written
// in the file's frame like detect's detections.json.
struct SceneOutcome {
  Pipeline::Result result;
  SceneRecord record;
  std::vector<Eigen::Vector3f> voter_centres;
  std::optional<std::vector<GroundTruthObject>> truth_working;
  std::optional<Scan> frame;
};

SceneOutcome RunScene(Pipeline& p, const Loaded& cfg, const RunContext& ctx, const RunInput& in, size_t i) {
  const auto& scene = in.dataset->scenes[i];
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
    r = p.Detect({si}, cfg.model ? &*cfg.model : nullptr, cfg.catalog ? &*cfg.catalog : nullptr, ctx);
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

// A scene's outcome as bytes (a rank's job in a shared eval), and back.
std::string EncodeScene(const SceneOutcome& o) {
  wire::Writer w;
  wire::Put(w, o.result.detections);
  w.Pod(o.result.fitted);
  w.Pod(o.result.voted);
  w.Pod(o.record.total_ms);
  w.Pod(o.record.detections);
  w.Pod(uint64_t(o.record.timings_ms.size()));
  for (const auto& [tag, ms] : o.record.timings_ms) w.Str(tag), w.Pod(ms);
  w.Pod(uint64_t(o.voter_centres.size()));
  for (const auto& c : o.voter_centres) w.Pod(c.x()), w.Pod(c.y()), w.Pod(c.z());
  w.Pod(uint8_t(o.truth_working.has_value()));
  if (o.truth_working) {
    w.Pod(uint64_t(o.truth_working->size()));
    for (const auto& g : *o.truth_working) wire::Put(w, g);
  }
  w.Pod(uint8_t(o.frame.has_value()));
  if (o.frame) wire::Put(w, *o.frame);
  return w.Take();
}

SceneOutcome DecodeScene(const std::string& bytes, const std::string& scan) {
  wire::Reader in(bytes, "the outcome of " + scan);
  SceneOutcome o;
  o.result.detections = wire::GetDetections(in);
  o.result.fitted = in.Pod<bool>();
  o.result.voted = in.Pod<bool>();
  o.record.scan = scan;
  o.record.total_ms = in.Pod<double>();
  o.record.detections = in.Pod<int>();
  for (uint64_t k = 0, m = in.Count(sizeof(uint64_t)); k < m; ++k) {
    std::string tag = in.Str();
    o.record.timings_ms.emplace_back(std::move(tag), in.Pod<double>());
  }
  o.voter_centres.resize(in.Count(3 * sizeof(float)));
  for (auto& c : o.voter_centres) {
    const float x = in.Pod<float>(), y = in.Pod<float>(), z = in.Pod<float>();
    c = Eigen::Vector3f(x, y, z);
  }
  if (in.Pod<uint8_t>()) {
    o.truth_working.emplace(in.Count(sizeof(uint64_t)));
    for (auto& g : *o.truth_working) g = wire::GetGroundTruthObject(in);
  }
  if (in.Pod<uint8_t>()) o.frame = wire::GetScan(in);
  in.End();
  return o;
}

// The figures of one run from its scenes' outcomes (run by this process or gathered from the
// ranks): the evaluation, the records, and with --save-detections each scene's detections.
RunFigures Figures(const Loaded& cfg, const RunContext& ctx, const RunInput& in, double wall_ms, int jobs, bool reset_ok,
                   std::vector<SceneOutcome>& outcomes) {
  const auto& scenes = in.dataset->scenes;
  const size_t n = scenes.size();
  RunFigures f;
  f.seed = ctx.seed;
  f.wall_ms = wall_ms;
  f.jobs = jobs;
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
  if (!in.detections_dir.empty())
    for (size_t i = 0; i < n; ++i) {
      json j = {{"scan", scenes[i].scan}, {"seed", ctx.seed}, {"detections", json::array()}};
      const Scan* frame = outcomes[i].frame ? &*outcomes[i].frame : nullptr;
      for (const auto& d : evals[i].detections) j["detections"].push_back(DetectionToJson(d, frame));
      WriteJson((fs::path(in.detections_dir) / cfg.file / std::to_string(ctx.seed) / (in.scene_files[i] + ".json")).string(), j);
    }
  f.metrics = Evaluate(evals, in.dataset->classes, in.width);
  f.peak_rss_mb = PeakRssMb(reset_ok);
  return f;
}

RunFigures RunOne(Loaded& cfg, const Registry& reg, const RunContext& ctx, const RunInput& in) {
  const auto& scenes = in.dataset->scenes;
  const size_t n = scenes.size();
  const bool reset_ok = ResetPeakRss();
  std::vector<SceneOutcome> outcomes(n);
  std::vector<std::unique_ptr<Pipeline>> pipelines;
  pipelines.push_back(std::make_unique<Pipeline>(cfg.graph, reg));
  Progress progress("eval " + cfg.name + " seed " + std::to_string(ctx.seed), n);
  auto run_scene = [&](Pipeline& p, size_t i) {
    outcomes[i] = RunScene(p, cfg, ctx, in, i);
    progress.Tick();
  };

  Stopwatch wall;
  const double rss0 = ProcStatusMb("VmRSS");
  run_scene(*pipelines[0], 0);
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
    for (int w = 1; w < jobs; ++w) pipelines.push_back(std::make_unique<Pipeline>(cfg.graph, reg));
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
    for (int w = 1; w < jobs; ++w) threads.emplace_back(worker, pipelines[w].get());
    worker(pipelines[0].get());
    for (auto& t : threads) t.join();
    if (error) std::rethrow_exception(error);
  }
  progress.Done();

  return Figures(cfg, ctx, in, wall.Ms(), jobs, reset_ok, outcomes);
}


// RunOne of every seed over the ranks of an MPI launch: the (seed, scene) jobs shared among them
// (ShareJobs, one at a time on each rank), rank 0 gathering each outcome, bit for bit what it
// would have computed itself. On rank 0 the figures of each seed, on the other ranks none.
std::vector<RunFigures> RunShared(Loaded& cfg, const Registry& reg, const std::vector<RunContext>& seeds,
                                  const RunInput& in) {
  const auto& scenes = in.dataset->scenes;
  const size_t n = scenes.size();
  const bool reset_ok = ResetPeakRss();
  Pipeline p(cfg.graph, reg);
  Progress progress("eval " + cfg.name + " (rank " + std::to_string(in.world->Rank()) + ")", seeds.size() * n);
  Stopwatch wall;
  const std::vector<std::string> got = ShareJobs(
      *in.world, seeds.size() * n,
      [&](size_t job) {
        const std::string bytes = EncodeScene(RunScene(p, cfg, seeds[job / n], in, job % n));
        progress.Tick();
        return bytes;
      },
      [&](size_t job) {
        return "scene " + scenes[job % n].scan + ", seed " + std::to_string(seeds[job / n].seed) + ", config " + cfg.name;
      });
  progress.Done();
  std::vector<RunFigures> figures;
  if (!in.world->Root()) return figures;  // rank 0 evaluates and writes
  const double wall_ms = wall.Ms();
  for (size_t k = 0; k < seeds.size(); ++k) {
    std::vector<SceneOutcome> outcomes;
    for (size_t i = 0; i < n; ++i) outcomes.push_back(DecodeScene(got[k * n + i], scenes[i].scan));
    // The wall clock of all seeds together: the ranks ran them interleaved.
    figures.push_back(Figures(cfg, seeds[k], in, wall_ms, in.world->Size(), reset_ok, outcomes));
  }
  return figures;
}

// --reproducible: removes what the run measured of itself from a summary or run record (per
// run: stage, wall and model times, peak memory, workers, the model's source; per scene: its
// times; the host and the creation time), recursively: what is left depends on the inputs only.
void Unmeasured(json& j) {
  if (j.is_array()) {
    for (auto& e : j) Unmeasured(e);
    return;
  }
  if (!j.is_object()) return;
  for (const char* key : {"stage_ms", "wall_ms", "model_ms", "model_source", "peak_rss_mb", "jobs", "total_ms",
                          "timings_ms", "machine", "created_utc"})
    j.erase(key);
  for (auto it = j.begin(); it != j.end(); ++it)
    if (it.key() != "config") Unmeasured(it.value());  // a graph's own parameters are inputs
}

std::vector<std::string> Names(const std::vector<std::string>& graphs, const std::vector<std::string>& given) {
  if (!given.empty() && given.size() != graphs.size())
    throw InputError("--name: given " + std::to_string(given.size()) + " times for " + std::to_string(graphs.size()) + " graphs");
  std::vector<std::string> names;
  for (size_t i = 0; i < graphs.size(); ++i) {
    std::string base = given.empty() ? fs::path(graphs[i]).stem().string() : given[i];
    std::string name = base;
    for (int k = 2; std::find(names.begin(), names.end(), name) != names.end(); ++k) name = base + "_" + std::to_string(k);
    names.push_back(name);
  }
  return names;
}

std::vector<std::string> IgnoredNotes(const std::vector<ConfigSummary>& configs) {
  std::map<std::string, int> gt, det;
  for (const auto& c : configs) {
    if (c.runs.empty()) continue;
    for (const auto& [k, v] : c.runs[0].metrics.ignored_gt) gt[k] = v;  // the same in every run
    for (const auto& r : c.runs)
      for (const auto& [k, v] : r.metrics.ignored_detections) det[k] += v;
  }
  std::vector<std::string> notes;
  auto list = [](const std::map<std::string, int>& m) {
    std::string s;
    for (const auto& [k, v] : m) s += (s.empty() ? "" : ", ") + k + " " + std::to_string(v);
    return s;
  };
  if (!gt.empty()) notes.push_back("ground truth not evaluated (class not in the dataset's classes or mapped to null): " + list(gt));
  if (!det.empty()) notes.push_back("detections not evaluated (class not in the dataset's classes), all configs and seeds: " + list(det));
  return notes;
}

// One PR plot per class: a curve per config and seed (extra seeds lighter).
std::vector<std::string> WritePlots(const std::string& dir, const std::vector<ConfigSummary>& configs,
                                    const std::vector<std::string>& classes) {
  std::vector<std::string> files;
  const std::vector<std::string> class_files = UniqueSafeNames(classes);
  // The paper's rule (pr_<class>) and the ScanNet rule, box IoU >= 0.25 (pr25_<class>).
  for (const bool iou : {false, true})
  for (const auto& cls : classes) {
    std::vector<PlotSeries> series;
    auto curve = [&](const ClassMetrics& cm) -> const std::vector<PrPoint>& { return iou ? cm.curve25 : cm.curve; };
    for (size_t c = 0; c < configs.size(); ++c) {
      std::vector<double> aps;
      for (const auto& r : configs[c].runs)
        for (const auto& cm : r.metrics.classes)
          if (cm.cls == cls) aps.push_back(iou ? cm.ap25 : cm.ap);
      const MeanStd ap = MeanAndStd(aps);
      for (size_t k = 0; k < configs[c].runs.size(); ++k) {
        PlotSeries s;
        s.color = static_cast<int>(c);
        s.alpha = k == 0 ? 1.0 : 0.35;
        if (k == 0) {
          char buf[64];
          std::snprintf(buf, sizeof(buf), iou ? " (AP25 %.3f)" : " (AP %.3f)", ap.mean);
          s.label = std::string(1, static_cast<char>('A' + c % 26)) + ": " + configs[c].name + (ap.n ? buf : " (AP n/a)");
        }
        for (const auto& cm : configs[c].runs[k].metrics.classes)
          if (cm.cls == cls)
            for (const auto& p : curve(cm)) s.points.push_back({1.0 - p.precision, p.recall});
        series.push_back(std::move(s));
      }
    }
    const std::string stem = (iou ? "pr25_" : "pr_") + class_files[size_t(&cls - classes.data())];
    WritePrPlot((fs::path(dir) / stem).string(),
                cls + (iou ? ": recall vs 1 - precision, box IoU >= 0.25" : ": recall vs 1 - precision, paper rule"),
                series);
    files.push_back(stem + ".png");
  }
  return files;
}

}  // namespace

int RunEval(const std::vector<std::string>& args) {
  CLI::App app{"A/B evaluation: run graph configs over a dataset manifest, match detections with ground truth\n"
               "(paper Sect. VII-A), write summary.json, report.md, pr_<class>.svg/.png and run_<name>.json.\n"
               "usage: furnihost eval --graph A.json [--graph B.json ...] --dataset D.json [--out DIR] [--seeds N]",
               "eval"};
  CommonOptions common;
  std::vector<std::string> graphs, names;
  std::string dataset_path, out = "furnihost-out/eval", width_text = "max";
  int seeds = 1, jobs = 0;
  double jitter = 0;
  bool retrain = false, strict = false, save_detections = false, reproducible = false;
  common.Add(app);
  app.add_option("--graph,-g", graphs, "graph config (repeat: the first is the baseline A)")->required();
  app.add_option("--name", names, "label per graph, in --graph order (default: the file stem)");
  app.add_option("--dataset,-d", dataset_path, "dataset manifest (JSON: scenes, class_map, classes)")->required();
  app.add_option("--out,-o", out, "output folder (default furnihost-out/eval)");
  app.add_option("--seeds", seeds, "detection seeds per config: seed0 .. seed0+N-1 (seed0 = --seed or the graph's); "
                                   "the trained model is not retrained per seed")
      ->check(CLI::Range(1, 1000));
  app.add_option("--jitter", jitter,
                 "add Gaussian noise of this standard deviation [m] to every scan's points as read, drawn anew for "
                 "each seed (with --seeds N: the spread of the figures under a perturbation far below the sensor's "
                 "noise, e.g. 0.0005; the noise floor of an A/B comparison)")
      ->check(CLI::Range(0.0, 0.05));
  app.add_option("--width", width_text, "ground-truth width for the match radius: max or min of the box's x/y size (default max)")
      ->check(CLI::IsMember({"max", "min"}));
  FrameCli ground_cli;
  app.add_option("--ground", ground_cli.ground,
                 "override every graph's ground: auto, level, plane, height_map, or a fixed floor height [m]");
  app.add_option("--jobs,-j", jobs, "scenes processed in parallel (0 = as cores and memory allow)")->check(CLI::Range(0, 1024));
  app.add_flag("--retrain", retrain, "retrain each graph's model even if its cache is valid");
  app.add_flag("--save-detections", save_detections,
               "also write every scene's detections (in its file's frame) to OUT/detections/<config>/<seed>/<scan "
               "stem>.json (for cross-validation scripts)");
  app.add_flag("--strict", strict, "invalid catalog entries are fatal instead of skipped");
  app.add_flag("--reproducible", reproducible,
               "leave the run's own measurements out of summary.json, report.md and run_<name>.json (times, memory, "
               "workers, whether the model came from its cache, host, creation time): two runs of the same inputs then "
               "write those files byte for byte the same, whatever --jobs, --threads or the number of MPI ranks");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  const WidthConvention width = *ParseWidthConvention(width_text);
  auto reg = common.MakeRegistry();

  // Everything that can be wrong with the inputs fails here, before any detection runs.
  const Dataset dataset = LoadDataset(dataset_path);
  std::vector<std::vector<GroundTruthObject>> truth;
  for (const auto& s : dataset.scenes) truth.push_back(ReadGroundTruth(s.gt));
  const std::string hash = HashDataset(dataset);
  const std::vector<std::string> config_names = Names(graphs, names);
  const std::vector<std::string> config_files = UniqueSafeNames(config_names);
  std::vector<Loaded> configs;
  for (size_t i = 0; i < graphs.size(); ++i) {
    configs.push_back({config_names[i], config_files[i], common.LoadGraph(graphs[i], *reg), {}, {}});
    ground_cli.ApplyGround(configs.back().graph);
  }
  spdlog::info("eval: {} configs x {} seeds on {} ({} scenes, {})", configs.size(), seeds, dataset_path,
               dataset.scenes.size(), hash);

  const json git = GitInfo(graphs.front());
  const json machine = MachineInfo();
  // Under mpirun the ranks share the scenes and the training.
  const World& world = World::Get();
  const json dataset_json = {{"path", dataset_path},
                             {"hash", hash},
                             {"scenes", dataset.scenes.size()},
                             {"classes", dataset.classes.classes},
                             {"class_map", [&] {
                                json m = json::object();
                                for (const auto& [k, v] : dataset.classes.map) m[k] = v ? json(*v) : json(nullptr);
                                return m;
                              }()}};
  std::vector<std::string> scene_stems;
  for (const auto& s : dataset.scenes) scene_stems.push_back(fs::path(s.scan).stem().string());
  const RunInput run_in{&dataset, &truth, width, jobs, save_detections ? (fs::path(out) / "detections").string() : "",
                        UniqueSafeNames(scene_stems), jitter, &world};
  std::vector<ConfigSummary> summaries;
  for (auto& cfg : configs) {
    ConfigSummary summary;
    summary.name = cfg.name;
    summary.graph = cfg.graph.path;
    const RunContext train_ctx = common.Context(cfg.graph.seed);
    Stopwatch model_clock;
    std::string model_source = "none";
    {
      Pipeline p(cfg.graph, *reg);
      if (const auto sinks = cfg.graph.Sinks(); sinks.size() > 1) {
        std::string tags;
        for (const auto* s : sinks) tags += (tags.empty() ? "" : ", ") + s->tag;
        spdlog::warn("{}: {} sinks ({}): their detections are evaluated together; to compare them, evaluate one "
                     "graph per alternative",
                     cfg.graph.path, sinks.size(), tags);
      }
      if (p.HasDetectionChain()) {
        cfg.catalog = LoadCatalog(cfg.graph.catalog, strict);
        const std::string cache = cfg.graph.model_cache;
        std::optional<fs::file_time_type> before;
        if (!cache.empty() && fs::exists(cache)) before = fs::last_write_time(cache);
        RunContext c = train_ctx;
        c.seed = cfg.graph.seed;  // the model is the graph's, whatever --seed says
        cfg.model = EnsureModelShared(world, p, *cfg.catalog, c, retrain);
        if (world.Root())
          model_source = before && fs::exists(cache) && fs::last_write_time(cache) == *before ? "cache" : "trained";
      } else {
        std::string m;
        for (const auto& s : p.MissingStages()) m += (m.empty() ? "" : ", ") + s;
        spdlog::warn("{}: the graph has no {} stage: it makes no detections (recall 0)", cfg.graph.path, m);
      }
    }
    const double model_ms = model_clock.Ms();
    const uint64_t seed0 = train_ctx.seed;
    std::vector<RunContext> contexts;
    for (int k = 0; k < seeds; ++k) {
      RunContext ctx = train_ctx;
      ctx.seed = seed0 + static_cast<uint64_t>(k);
      contexts.push_back(ctx);
    }
    std::vector<RunFigures> runs;
    if (world.Shared())
      runs = RunShared(cfg, *reg, contexts, run_in);  // rank 0 gets the figures
    else
      for (const RunContext& ctx : contexts) runs.push_back(RunOne(cfg, *reg, ctx, run_in));
    for (RunFigures& f : runs) {
      f.model_ms = model_ms;  // paid once per config; the same in every seed's figures
      f.model_source = model_source;
      spdlog::info("eval {} seed {}: mAP {:.3f}, {} detections, {:.1f} s, peak {:.0f} MB", cfg.name, f.seed,
                   f.metrics.map, f.metrics.hypotheses.tp + f.metrics.hypotheses.fp, f.wall_ms / 1000, f.peak_rss_mb);
      summary.runs.push_back(std::move(f));
    }
    if (!world.Root()) {
      cfg.model.reset();
      cfg.catalog.reset();
      continue;
    }
    // The run record: enough to reproduce this config's figures and compare with a later run.
    json plugins = json::array();
    for (const auto& s : cfg.graph.stages) {
      const PluginEntry* e = reg->Find(s.type);
      plugins.push_back({{"tag", s.tag}, {"type", s.type}, {"version", e ? e->version : "unknown"}});
    }
    json seeds_json = json::array();
    for (const auto& r : summary.runs) seeds_json.push_back(r.seed);
    json record = {{"format", "furnihost-run-record"},
                   {"format_version", 1},
                   {"furnihost_version", FURNIHOST_APP_VERSION},
                   {"created_utc", UtcNow()},
                   {"name", cfg.name},
                   {"graph", cfg.graph.path},
                   {"config", cfg.graph.resolved},
                   {"plugins", plugins},
                   {"git", git},
                   {"seed", summary.runs.front().seed},
                   {"seeds", seeds_json},
                   {"model_seed", cfg.graph.seed},
                   {"jitter_m", jitter},
                   {"width_convention", ToString(width)},
                   {"dataset", dataset_json},
                   {"machine", machine},
                   {"figures", ToJson(summary)}};
    if (reproducible) Unmeasured(record);
    WriteJson((fs::path(out) / ("run_" + cfg.file + ".json")).string(), record);
    summaries.push_back(std::move(summary));
    cfg.model.reset();  // free the model before the next config
    cfg.catalog.reset();
  }

  if (!world.Root()) return 0;
  const std::vector<std::string> plots = WritePlots(out, summaries, dataset.classes.classes);
  ReportInfo info;
  info.dataset = dataset_path;
  info.dataset_hash = hash;
  info.scenes = static_cast<int>(dataset.scenes.size());
  info.width = width;
  info.plots = plots;
  info.notes = IgnoredNotes(summaries);
  if (jitter > 0)
    info.notes.push_back("scans jittered: Gaussian noise of " + Mm(jitter) +
                         " on every coordinate, drawn anew for each seed (--jitter)");
  info.notes.push_back("git " + git["revision"].get<std::string>() + (git["dirty"] == true ? " (uncommitted changes)" : "") +
                       (reproducible ? std::string()
                                     : "; machine: " + machine.value("cpu", std::string("?")) + ", " +
                                           std::to_string(machine["nproc"].get<unsigned>()) + " threads"));
  info.measurements = !reproducible;
  const std::string report = RenderReport(summaries, info);
  json configs_json = json::array();
  for (size_t i = 0; i < summaries.size(); ++i) {
    json c = ToJson(summaries[i]);
    c["run_record"] = "run_" + configs[i].file + ".json";
    configs_json.push_back(c);
  }
  json summary_json = {{"dataset", dataset_json},
                       {"width_convention", ToString(width)},
                       {"matching", "TP: mapped classes equal and floor-plane (x, y) centre distance < " +
                                        std::string(ToString(width)) +
                                        "(gt size x, y) / 2; greedy by descending score, each gt object matched at most once"},
                       {"average_precision", "all-point interpolated (VOC 2010+)"},
                       {"git", git},
                       {"machine", machine},
                       {"configs", configs_json}};
  if (reproducible) Unmeasured(summary_json);
  WriteJson((fs::path(out) / "summary.json").string(), summary_json);
  AtomicWriteText((fs::path(out) / "report.md").string(), report);
  std::cout << report;
  std::cout << "-> " << (fs::path(out) / "report.md").string() << ", summary.json, pr_<class>.svg/.png, run_<name>.json\n";
  return 0;
}

int RunCompare(const std::vector<std::string>& args) {
  CLI::App app{"Compare two run records written by `furnihost eval` (run_<name>.json): prints A | B | B - A.\n"
               "usage: furnihost compare RUN_A.json RUN_B.json [--out report.md]",
               "compare"};
  std::string a, b, out;
  app.add_option("run_a", a, "baseline run record (A)")->required();
  app.add_option("run_b", b, "run record to compare (B)")->required();
  app.add_option("--out,-o", out, "also write the Markdown to this file");
  if (auto rc = Parse(app, args)) return *rc;
  std::vector<ConfigSummary> configs;
  std::vector<json> records;
  for (const auto& path : {a, b}) {
    json r = ReadJson(path);
    if (!r.is_object() || r.value("format", "") != "furnihost-run-record")
      throw InputError(path + ": not a furnihost run record (written by `furnihost eval` as run_<name>.json)");
    if (!r.contains("figures")) throw InputError(path + ":/figures: missing");
    configs.push_back(ConfigSummaryFromJson(r["figures"], path + ":/figures"));
    records.push_back(std::move(r));
  }
  if (configs[0].name == configs[1].name) configs[1].name += " (B)";
  ReportInfo info;
  info.title = "furnihost compare";
  const json& da = records[0]["dataset"];
  const json& db = records[1]["dataset"];
  info.dataset = da.value("path", "?");
  info.dataset_hash = da.value("hash", "?");
  info.scenes = da.value("scenes", 0);
  info.width = ParseWidthConvention(records[0].value("width_convention", "max")).value_or(WidthConvention::Max);
  if (da.value("hash", "") != db.value("hash", ""))
    info.notes.push_back("WARNING: the runs used different datasets (B: `" + db.value("path", "?") + "`, hash `" +
                         db.value("hash", "?") + "`): the figures are not comparable");
  if (records[0].value("jitter_m", 0.0) != records[1].value("jitter_m", 0.0))
    info.notes.push_back("WARNING: the runs jittered their scans differently (A: " +
                         Mm(records[0].value("jitter_m", 0.0)) + ", B: " +
                         Mm(records[1].value("jitter_m", 0.0)) + "; --jitter)");
  if (records[0].value("width_convention", "") != records[1].value("width_convention", ""))
    info.notes.push_back("WARNING: the runs used different width conventions (B: " +
                         records[1].value("width_convention", "?") + ")");
  for (size_t i = 0; i < 2; ++i) {
    const json& g = records[i]["git"];
    info.notes.push_back(std::string(i == 0 ? "A" : "B") + ": git " +
                         (g.is_object() ? g.value("revision", "unknown") : "unknown") + ", created " +
                         records[i].value("created_utc", "?") + ", machine " +
                         records[i].value("machine", json::object()).value("cpu", std::string("?")));
  }
  const std::string report = RenderReport(configs, info);
  std::cout << report;
  if (!out.empty()) AtomicWriteText(out, report);
  return 0;
}

}  // namespace furnihost::app
