// `furnihost eval` (A/B evaluation of graph configs on a dataset manifest) and
// `furnihost compare` (the same table from two run records written by eval).
//
// Seeds: the trained model is the graph's (its cache is keyed by the graph's "seed"), so
// --seeds N varies the detection-time seed only (RunContext::seed = seed0 .. seed0 + N - 1,
// seed0 = --seed or the graph's seed): the spread shows the randomised detection stages
// (e.g. RANSAC fitting), not the variation of training.
//
// Each config runs through a Detector (detector.hpp), the engine the Python module shares:
// Detector::Evaluate runs a graph over the dataset once per seed. Under mpirun the ranks share
// the training (mpi_train.hpp) and the (seed, scene) jobs (RunShared); rank 0 writes.
#include <sys/utsname.h>

#include <cstdio>
#include <ctime>
#include <filesystem>
#include <future>
#include <fstream>
#include <iostream>
#include <thread>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/host/detector.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/log.hpp"
#include "git_info.hpp"
#include "mpi_jobs.hpp"
#include "mpi_train.hpp"
#include "plots.hpp"
#include "report.hpp"
#include "wire.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace furnihost::app {

namespace {

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

// A length in metres as millimetres, "0.50 mm".
std::string Mm(double m) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f mm", m * 1000);
  return b;
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

// Detector::Evaluate of every seed over the ranks of an MPI launch: the (seed, scene) jobs shared
// among them (ShareJobs, one at a time on each rank), rank 0 gathering each outcome, bit for bit
// what it would have computed itself. On rank 0 the figures of each seed, on the other ranks none.
std::vector<RunFigures> RunShared(Detector& detector, const World& world, const std::vector<uint64_t>& seeds,
                                  const EvalRunInput& in) {
  const auto& scenes = in.dataset->scenes;
  const size_t n = scenes.size();
  Progress progress("eval " + in.name + " (rank " + std::to_string(world.Rank()) + ")", seeds.size() * n);
  Stopwatch wall;
  const std::vector<std::string> got = ShareJobs(
      world, seeds.size() * n,
      [&](size_t job) {
        const std::string bytes = EncodeScene(detector.EvaluateScene(in, seeds[job / n], job % n));
        progress.Tick();
        return bytes;
      },
      [&](size_t job) {
        return "scene " + scenes[job % n].scan + ", seed " + std::to_string(seeds[job / n]) + ", config " + in.name;
      });
  progress.Done();
  std::vector<RunFigures> figures;
  if (!world.Root()) return figures;  // rank 0 evaluates and writes
  const double wall_ms = wall.Ms();
  for (size_t k = 0; k < seeds.size(); ++k) {
    std::vector<SceneOutcome> outcomes;
    for (size_t i = 0; i < n; ++i) outcomes.push_back(DecodeScene(got[k * n + i], scenes[i].scan));
    // The wall clock of all seeds together: the ranks ran them interleaved.
    figures.push_back(detector.Figures(in, seeds[k], outcomes, wall_ms, world.Size()));
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

// One reliability diagram per class whose detections carry a confidence (a calibrated graph):
// the share of true detections against their mean confidence per bin, a curve per config (its
// first seed), and the diagonal a calibrated confidence lies on.
std::vector<std::string> WriteReliabilityPlots(const std::string& dir, const std::vector<ConfigSummary>& configs,
                                               const std::vector<std::string>& classes) {
  std::vector<std::string> files;
  const std::vector<std::string> class_files = UniqueSafeNames(classes);
  for (size_t k = 0; k < classes.size(); ++k) {
    std::vector<PlotSeries> series;
    series.push_back({"calibrated", {{0.0, 0.0}, {1.0, 1.0}}, 7, 0.4});
    for (size_t c = 0; c < configs.size(); ++c) {
      if (configs[c].runs.empty()) continue;
      for (const auto& cm : configs[c].runs.front().metrics.classes) {
        if (cm.cls != classes[k] || !cm.reliability) continue;
        PlotSeries s;
        s.color = static_cast<int>(c);
        char buf[96];
        std::snprintf(buf, sizeof(buf), " (ECE %.3f, %d detections)", cm.reliability->ece, cm.reliability->detections);
        s.label = std::string(1, static_cast<char>('A' + c % 26)) + ": " + configs[c].name + buf;
        for (const auto& b : cm.reliability->bins)
          if (b.n > 0) s.points.push_back({b.confidence, b.accuracy});
        series.push_back(std::move(s));
      }
    }
    if (series.size() == 1) continue;
    const std::string stem = "reliability_" + class_files[k];
    WriteLinePlot((fs::path(dir) / stem).string(), classes[k] + ": share true (IoU >= 0.25) vs confidence",
                  {"confidence (bin mean)", "share of true detections", 0, 1, 0, 1, true}, series);
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
  common.AddMinConfidence(app);
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
  std::shared_ptr<const Registry> reg = common.MakeRegistry();

  // Everything that can be wrong with the inputs fails here, before any detection runs.
  const Dataset dataset = LoadDataset(dataset_path);
  std::vector<std::vector<GroundTruthObject>> truth;
  for (const auto& s : dataset.scenes) truth.push_back(ReadGroundTruth(s.gt));
  const std::string hash = HashDataset(dataset);
  const std::vector<std::string> config_names = Names(graphs, names);
  // The names of each config's files: run_<file>.json, detections/<file>/, inside --out
  // whatever --name says.
  const std::vector<std::string> config_files = UniqueSafeNames(config_names);
  std::vector<GraphConfig> configs;
  for (size_t i = 0; i < graphs.size(); ++i) {
    configs.push_back(common.LoadGraph(graphs[i], *reg));
    ground_cli.ApplyGround(configs.back());
  }
  spdlog::info("eval: {} configs x {} seeds on {} ({} scenes, {})", configs.size(), seeds, dataset_path,
               dataset.scenes.size(), hash);

  const json git = GitInfo(graphs.front());
  const json machine = MachineInfo();
  const json dataset_json = DatasetJson(dataset, hash);
  // Under mpirun the ranks share the scenes and the training.
  const World& world = World::Get();
  EvalRunInput run_in;
  run_in.dataset = &dataset;
  run_in.truth = &truth;
  run_in.width = width;
  run_in.jobs = jobs;
  run_in.detections_dir = save_detections ? (fs::path(out) / "detections").string() : "";
  run_in.jitter_m = jitter;
  std::vector<ConfigSummary> summaries;
  for (size_t c = 0; c < configs.size(); ++c) {
    const GraphConfig& graph = configs[c];
    ConfigSummary summary;
    summary.name = config_names[c];
    summary.graph = graph.path;
    run_in.name = summary.name;
    run_in.file = config_files[c];
    if (const auto sinks = graph.Sinks(); sinks.size() > 1) {
      std::string tags;
      for (const auto* s : sinks) tags += (tags.empty() ? "" : ", ") + s->tag;
      spdlog::warn("{}: {} sinks ({}): their detections are evaluated together; to compare them, evaluate one "
                   "graph per alternative",
                   graph.path, sinks.size(), tags);
    }
    DetectorOptions options;
    options.strict_catalog = strict;
    options.retrain = retrain;
    ShareTraining(world, options);
    // Destroyed at the end of the config: its model is freed before the next config loads.
    Detector detector(graph, reg, common.Context(graph.seed), options);
    Stopwatch model_clock;
    if (detector.HasDetectionChain()) {
      detector.WaitLoaded();
    } else {
      std::string m;
      for (const auto& s : detector.MissingStages()) m += (m.empty() ? "" : ", ") + s;
      spdlog::warn("{}: the graph has no {} stage: it makes no detections (recall 0)", graph.path, m);
    }
    const double model_ms = model_clock.Ms();
    const uint64_t seed0 = detector.Context().seed;
    std::vector<uint64_t> run_seeds;
    for (int k = 0; k < seeds; ++k) run_seeds.push_back(seed0 + static_cast<uint64_t>(k));
    std::vector<RunFigures> runs;
    if (world.Shared())
      runs = RunShared(detector, world, run_seeds, run_in);  // rank 0 gets the figures
    else
      for (const uint64_t seed : run_seeds) runs.push_back(detector.Evaluate(run_in, seed));
    for (RunFigures& f : runs) {
      f.model_ms = model_ms;  // paid once per config; the same in every seed's figures
      spdlog::info("eval {} seed {}: mAP {:.3f}, {} detections, {:.1f} s, peak {:.0f} MB", summary.name, f.seed,
                   f.metrics.map, f.metrics.hypotheses.tp + f.metrics.hypotheses.fp, f.wall_ms / 1000, f.peak_rss_mb);
      summary.runs.push_back(std::move(f));
    }
    if (!world.Root()) continue;
    // The run record: enough to reproduce this config's figures and compare with a later run.
    json plugins = json::array();
    for (const auto& s : graph.stages) {
      const PluginEntry* e = reg->Find(s.type);
      plugins.push_back({{"tag", s.tag}, {"type", s.type}, {"version", e ? e->version : "unknown"}});
    }
    json seeds_json = json::array();
    for (const auto& r : summary.runs) seeds_json.push_back(r.seed);
    json record = {{"format", "furnihost-run-record"},
                   {"format_version", 1},
                   {"furnihost_version", FURNIHOST_APP_VERSION},
                   {"created_utc", UtcNow()},
                   {"name", summary.name},
                   {"graph", graph.path},
                   {"config", graph.resolved},
                   {"plugins", plugins},
                   {"git", git},
                   {"seed", summary.runs.front().seed},
                   {"seeds", seeds_json},
                   {"model_seed", graph.seed},
                   {"jitter_m", jitter},
                   {"width_convention", ToString(width)},
                   {"dataset", dataset_json},
                   {"machine", machine},
                   {"figures", ToJson(summary)}};
    if (reproducible) Unmeasured(record);
    WriteJson((fs::path(out) / ("run_" + config_files[c] + ".json")).string(), record);
    summaries.push_back(std::move(summary));
  }

  if (!world.Root()) return 0;
  auto write_report = [&] {
    std::vector<std::string> plots = WritePlots(out, summaries, dataset.classes.classes);
    for (auto& f : WriteReliabilityPlots(out, summaries, dataset.classes.classes)) plots.push_back(std::move(f));
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
    json summary_json = EvalSummaryJson(dataset, hash, width, summaries);
    for (size_t c = 0; c < summaries.size(); ++c)
      summary_json["configs"][c]["run_record"] = "run_" + config_files[c] + ".json";
    summary_json["git"] = git;
    summary_json["machine"] = machine;
    if (reproducible) Unmeasured(summary_json);
    WriteJson((fs::path(out) / "summary.json").string(), summary_json);
    AtomicWriteText((fs::path(out) / "report.md").string(), report);
    std::cout << report;
    std::cout << "-> " << (fs::path(out) / "report.md").string() << ", summary.json, pr_<class>.svg/.png, reliability_<class>.svg/.png (calibrated graphs), run_<name>.json\n";
  };
  if (!world.Shared()) {
    write_report();
    return 0;
  }
  // Under mpirun no more messages pass between the ranks: MPI's finalize (the ranks' last fence
  // and Open MPI's teardown) runs on this thread, which opened MPI and must close it, while
  // another writes the report.
  auto report = std::async(std::launch::async, write_report);
  World::Close();
  report.get();
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
