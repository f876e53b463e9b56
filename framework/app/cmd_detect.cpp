// `furnihost [--graph G] SCAN...` (detection) and `furnihost train --graph G`.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <random>
#include <tbb/task_group.h>

#include "cancel_on_unwind.hpp"
#include "cli_common.hpp"
#include "mpi_train.hpp"
#include "commands.hpp"
#include "furnihost/geometry.hpp"
#include "furnihost/host/catalog.hpp"
#include "furnihost/host/detector.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/log.hpp"
#include "furnihost/scan_reader.hpp"
#if __has_include("birdseye.hpp")
#include "birdseye.hpp"
#define FURNIHOST_HAVE_BIRDSEYE 1
#endif

namespace fs = std::filesystem;

namespace furnihost::app {

namespace {

// How far apart the scans of one fused group may be [m]: a building's rooms, and more.
constexpr double kMaxPoseSpread = 1e4;

// The segmentation, a random colour per part, in the scan's file frame (it overlays the
// user's scan in CloudCompare / RViz).
void WriteParts(const std::string& path, const Scan& scan, const Segmentation& seg, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> c(40, 255);
  Points pts;
  std::vector<std::array<uint8_t, 3>> cols;
  for (const auto& part : seg.parts) {
    const std::array<uint8_t, 3> col{static_cast<uint8_t>(c(rng)), static_cast<uint8_t>(c(rng)), static_cast<uint8_t>(c(rng))};
    for (int i : part.indices) {
      pts.push_back(scan.points[i]);
      cols.push_back(col);
    }
  }
  WritePlyInFrame(path, pts, scan.frame, &cols);
}

// Every point of the scan, those of an object proposal in a random colour per proposal (a point
// in several, as the variants of one cluster are, takes the first), the rest grey: what a
// proposer made of the scan.
void WriteProposals(const std::string& path, const Scan& scan, const Proposals& proposals, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> c(40, 255);
  std::vector<std::array<uint8_t, 3>> cols(scan.points.size(), std::array<uint8_t, 3>{128, 128, 128});
  std::vector<char> taken(scan.points.size(), 0);
  for (const Proposal& p : proposals.items) {
    const std::array<uint8_t, 3> col{static_cast<uint8_t>(c(rng)), static_cast<uint8_t>(c(rng)), static_cast<uint8_t>(c(rng))};
    for (int i : p.indices)
      if (i >= 0 && size_t(i) < scan.points.size() && !taken[size_t(i)]) {
        taken[size_t(i)] = 1;
        cols[size_t(i)] = col;
      }
  }
  Points pts;
  std::vector<std::array<uint8_t, 3>> kept;
  for (size_t i = 0; i < scan.points.size(); ++i)
    if (scan.points[i].allFinite()) {
      pts.push_back(scan.points[i]);
      kept.push_back(cols[i]);
    }
  WritePlyInFrame(path, pts, scan.frame, &kept);
}

// The verified CAD models, coloured by class, in the file frame of `scan` (the first scan of
// a fused group: detections are in its world frame).
void WriteFitted(const std::string& path, const std::vector<Detection>& dets, const Catalog& catalog, const Scan& scan) {
  Points pts;
  std::vector<std::array<uint8_t, 3>> cols;
  const Eigen::Isometry3f to_scan = scan.pose.inverse();
  for (size_t i = 0; i < dets.size(); ++i) {
    const auto& d = dets[i];
    if (d.model.empty() || !d.verified.value_or(false)) continue;
    const CatalogModel* m = catalog.Find(d.model);
    if (!m) continue;
    for (const auto& p : SampleSurface(m->mesh, 4000.f, i)) {
      pts.push_back(to_scan * (d.model_pose * p));
      cols.push_back(ClassColor(d.cls));
    }
  }
  WritePlyInFrame(path, pts, scan.frame, &cols);
}

// What a rejection is grouped by: the first failed check without its measured value, so
// "coverage 0.12 < 0.3" and "coverage 0.25 < 0.3" are one reason, "coverage < 0.3".
std::string RejectionReason(const Detection& d) {
  for (const Check& c : d.checks)
    if (!c.passed) {
      char limit[32];
      std::snprintf(limit, sizeof limit, "%.4g", c.limit);
      return c.name + (c.at_least ? " < " : " > ") + limit;
    }
  return "no reason given";
}

// One line per detection: class, model, x, y [m] (+ `shift`), yaw [deg], score, coverage.
void PrintTable(std::ostream& os, const std::vector<const Detection*>& dets, const Eigen::Vector3d& shift) {
  size_t wc = 5, wm = 5;
  for (const Detection* d : dets) {
    wc = std::max(wc, d->cls.size());
    wm = std::max(wm, d->model.size());
  }
  os << "    " << std::left << std::setw(int(wc)) << "class" << "  " << std::setw(int(wm)) << "model" << std::right
     << "   x [m]   y [m]  yaw [deg]   score  coverage\n";
  for (const Detection* d : dets) {
    os << "    " << std::left << std::setw(int(wc)) << d->cls << "  " << std::setw(int(wm))
       << (d->model.empty() ? "-" : d->model) << std::right << std::fixed << std::setprecision(2) << std::setw(8)
       << d->center.x() + shift.x() << std::setw(8) << d->center.y() + shift.y() << std::setprecision(0) << std::setw(11)
       << d->yaw * 180 / M_PI << std::setprecision(3) << std::setw(8) << d->score;
    if (d->coverage) os << std::setprecision(2) << std::setw(10) << *d->coverage;
    else os << std::setw(10) << "-";
    os << "\n";
  }
}

// Verified detections first, one line each; the rejected hypotheses as one summary line per
// class and reason (the full list is in detections.json); hypotheses no fitter looked at
// (graphs without a fitter) one line each, they are the result then.
void PrintDetections(std::ostream& os, const std::vector<Detection>& dets, const Eigen::Vector3d& shift) {
  std::vector<const Detection*> verified, unverified;
  std::map<std::string, std::map<std::string, int>> rejected;  // class -> reason -> count
  size_t n_rejected = 0;
  for (const auto& d : dets) {
    if (!d.verified) unverified.push_back(&d);
    else if (*d.verified) verified.push_back(&d);
    else {
      ++rejected[d.cls][RejectionReason(d)];
      ++n_rejected;
    }
  }
  const size_t fitted = verified.size() + n_rejected;
  if (fitted > 0) {
    os << "  verified " << verified.size() << " of " << fitted << " hypotheses" << (verified.empty() ? "\n" : ":\n");
    if (!verified.empty()) PrintTable(os, verified, shift);
  }
  if (n_rejected > 0) {
    os << "  rejected " << n_rejected << ":";
    const char* sep = " ";
    for (const auto& [cls, reasons] : rejected) {
      int total = 0;
      std::vector<std::pair<int, std::string>> by_count;
      for (const auto& [why, count] : reasons) {
        total += count;
        by_count.emplace_back(-count, why);
      }
      std::sort(by_count.begin(), by_count.end());  // most frequent first, then by name
      os << sep << cls << " " << total << " (";
      for (size_t i = 0; i < by_count.size(); ++i)
        os << (i ? ", " : "") << -by_count[i].first << " " << by_count[i].second;
      os << ")";
      sep = "; ";
    }
    os << " -- all in detections.json\n";
  }
  if (!unverified.empty()) {
    os << "  " << unverified.size() << (unverified.size() == 1 ? " hypothesis" : " hypotheses")
       << (fitted > 0 ? " not verified:\n" : " (no fitter ran):\n");
    PrintTable(os, unverified, shift);
  }
}

// The pose of scan i from --pose x,y,z,yaw_deg, checked against the others: the scans of a
// fused group vote in one space, whose grids span them all, so a pose far from the rest (1e9 m:
// "cannot create std::vector larger than max_size()") is refused here, naming it.
Eigen::Isometry3f ParsePose(const std::vector<std::string>& poses, size_t i) {
  const auto p = ParseNumbers(poses[i], 4, "--pose");
  const std::string which = "--pose " + poses[i] + " (scan " + std::to_string(i + 1) + ")";
  if (!(std::abs(p[0]) <= kMaxScanCoordinate && std::abs(p[1]) <= kMaxScanCoordinate &&
        std::abs(p[2]) <= kMaxScanCoordinate))
    throw InputError(which + ": x, y, z lie beyond " + std::to_string(static_cast<long long>(kMaxScanCoordinate)) +
                     " m: poses are metres in the group's common frame");
  if (!(std::abs(p[3]) <= 36000.0)) throw InputError(which + ": the yaw is degrees, got " + std::to_string(p[3]));
  const auto first = ParseNumbers(poses[0], 4, "--pose");
  const double apart = Eigen::Vector3d(p[0] - first[0], p[1] - first[1], p[2] - first[2]).norm();
  if (!(apart <= kMaxPoseSpread))
    throw InputError(which + ": lies " + std::to_string(static_cast<long long>(std::llround(apart))) +
                     " m from the first scan's pose; the scans of a fused group lie within " +
                     std::to_string(static_cast<long long>(kMaxPoseSpread)) + " m of each other");
  return UprightPose(p[0], p[1], p[2], static_cast<float>(p[3] * M_PI / 180.0));
}

}  // namespace

int RunTrain(const std::vector<std::string>& args) {
  CLI::App app{"Train the model of a graph from its catalog (simulate views, segment, features, vocabulary; a voter that learns from meshes, as voters.catalog_shape, reads the models' meshes instead of views).", "train"};
  CommonOptions common;
  std::string graph, out;
  bool strict = false;
  common.Add(app);
  app.add_option("--graph,-g", graph, "graph config (JSON)")->required();
  app.add_option("--out,-o", out, "model file to write (default: the graph's model_cache)");
  app.add_flag("--strict", strict, "invalid catalog entries are fatal instead of skipped");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  std::shared_ptr<const Registry> reg = common.MakeRegistry();
  GraphConfig g = common.LoadGraph(graph, *reg);
  if (!out.empty()) {
    CheckModelCacheTarget(out, "--out ");
    g.model_cache = out;
  }
  if (g.model_cache.empty()) throw InputError(graph + ":/model_cache: missing (or pass --out)");
  // The model is trained with the graph's seed, which its cache records: --seed sets it.
  if (common.seed) g.seed = *common.seed;
  DetectorOptions options;
  options.strict_catalog = strict;
  // Under mpirun the ranks share the catalog's models; rank 0 writes the model.
  const World& world = World::Get();
  ShareTraining(world, options);
  Detector detector(g, reg, common.Context(g.seed), options);
  const TrainedModel& m = detector.Train();
  if (world.Root())
    std::cout << "trained " << g.model_cache << ": " << m.summary.dump() << ", time per step [ms] "
              << m.timings_ms.dump() << "\n";
  return 0;
}

namespace {
// The graph of a run without --graph (DefaultGraph), chosen by whether the scans have a sensor
// origin (--origin, or each file's own), said in one log line.
std::string ChooseDefaultGraph(const std::vector<std::string>& scans, bool origin_given) {
  size_t with_origin = 0;
  std::string why;
  for (const auto& scan : scans) {
    const std::optional<Eigen::Vector3d> o = ScanFileOrigin(scan);
    if (origin_given || o) ++with_origin;
    if (why.empty() && o)
      why = fmt::format("{} has a sensor origin (VIEWPOINT {:g} {:g} {:g})", scan, o->x(), o->y(), o->z());
  }
  if (with_origin > 0 && with_origin < scans.size())
    throw InputError("no --graph given, and " + std::to_string(with_origin) + " of the " + std::to_string(scans.size()) +
                     " scans have a sensor origin (VIEWPOINT) and the others none: give --graph G.json or --origin x,y,z");
  const bool one_spot = with_origin > 0;
  if (origin_given) why = "--origin gives a sensor origin";
  if (!one_spot) why = scans.size() == 1 ? scans.front() + " has no sensor origin (no VIEWPOINT, no --origin)"
                                         : "the scans have no sensor origin (no VIEWPOINT, no --origin)";
  const std::string graph = DefaultGraph(one_spot);
  spdlog::info("no --graph: {}: the {} route, --graph {}", why, one_spot ? "one-spot laser scan" : "room reconstruction",
               graph);
  return graph;
}
}  // namespace

int RunDetect(const std::vector<std::string>& args) {
  CLI::App app{"Detect furniture in scans: segment, describe parts, vote, fit and verify CAD models.\n"
               "usage: furnihost [detect] SCAN [SCAN ...] [--graph G.json] [options]", "detect"};
  CommonOptions common;
  std::string graph, out, origin_text;
  std::vector<std::string> scans, poses;
  bool fuse = false, save_parts = false, retrain = false, strict = false;
  FrameCli frame_cli;
  common.Add(app);
  common.AddMinConfidence(app);
  app.add_option("--graph,-g", graph,
                 "graph config (JSON), e.g. configs/paper.json; default: configs/laser_room.json for scans with a "
                 "sensor origin (a PCD's VIEWPOINT, or --origin), configs/room.json for scans without (room "
                 "reconstructions)");
  app.add_option("scans", scans, "scan files (.pcd, .ply, .xyz)")->required();
  app.add_option("--out,-o", out, "output folder (default furnihost-out/<scan stem>/)");
  app.add_option("--origin", origin_text, "sensor origin x,y,z (in the file's coordinates) for scans without VIEWPOINT");
  frame_cli.Add(app);
  app.add_option("--pose", poses, "pose x,y,z,yaw_deg of each scan in the common frame (once per scan, with --fuse)")
      ->allow_extra_args(false);
  app.add_flag("--fuse", fuse, "vote with all scans in one common space (multi-view fusion, paper Sect. VII-C)");
  app.add_flag("--save-parts", save_parts,
               "write parts.ply: the segmentation, a random colour per part (a graph with a proposer and no "
               "segmenter: proposals.ply, a colour per object proposal, the other points grey)");
  app.add_flag("--retrain", retrain, "retrain the model even if the cache is valid");
  app.add_flag("--strict", strict, "invalid catalog entries are fatal instead of skipped");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  std::shared_ptr<const Registry> reg = common.MakeRegistry();
  const FrameOptions frame = frame_cli.Frame();  // bad values exit 2 before the graph loads
  if (!poses.empty() && poses.size() != scans.size())
    throw InputError("--pose: given " + std::to_string(poses.size()) + " times for " + std::to_string(scans.size()) + " scans");
  std::optional<Eigen::Vector3f> origin;
  if (!origin_text.empty()) {
    auto o = ParseNumbers(origin_text, 3, "--origin");
    // In the file's coordinates, which a global shift may take that far; the scan decides the
    // rest (CheckSensorOrigin, before any stage).
    for (double c : o)
      if (!(std::abs(c) <= kMaxGlobalShift + kMaxScanCoordinate))
        throw InputError("--origin: " + origin_text + " lies beyond 1e8 m of the file's origin");
    origin = Eigen::Vector3f(o[0], o[1], o[2]);
  }
  if (graph.empty()) graph = ChooseDefaultGraph(scans, origin.has_value());
  GraphConfig g = common.LoadGraph(graph, *reg);
  frame_cli.ApplyGround(g);
  // Checked before any work, so a bad --out never wastes a training run.
  if (!out.empty() && fs::exists(out) && !fs::is_directory(out))
    throw InputError("--out " + out + ": exists and is not a folder");
  std::vector<Pipeline::SceneInput> inputs;
  for (size_t i = 0; i < scans.size(); ++i) {
    RequireRegularFile(scans[i], "scan file");
    Pipeline::SceneInput in;
    in.path = scans[i];
    in.origin = origin;
    in.frame = frame;
    if (!poses.empty()) in.pose = ParsePose(poses, i);
    inputs.push_back(in);
  }
  DetectorOptions options;
  options.strict_catalog = strict;
  options.retrain = retrain;
  Detector detector(g, reg, common.Context(g.seed), options);
  const RunContext& ctx = detector.Context();
  // The catalog and the model (loaded from the cache, or trained) are made on a worker while
  // the first scan is read, framed and grounded, which need neither: the start of a detection
  // left a core idle (~0.04 s of a 0.3 s detection of a 50k-point room). Detect waits for them
  // before its first stage; an error of theirs is thrown there.
  detector.StartLoading();
#ifdef FURNIHOST_HAVE_BIRDSEYE
  // The plots' first text, off the tail. Declared after what its task uses; if the scan fails
  // first, `unwind` cancels it and waits for it.
  tbb::task_group fonts;
  CancelOnUnwind unwind(fonts);
  if (detector.HasDetectionChain()) fonts.run([] { WarmUpPlotFonts(); });
#endif
  const auto missing = detector.MissingStages();
  if (!missing.empty()) {
    std::string m;
    for (const auto& s : missing) m += (m.empty() ? "" : ", ") + s;
    const bool only_fitter = missing.size() == 1 && missing.front() == "fitter";
    spdlog::warn("{}: the graph has no {} stage: running the stages that exist; {}", graph, m,
                 only_fitter ? "the voter's hypotheses are the detections (neither fitted nor verified)"
                       : "no detections are made without a segmenter, features and a voter");
  }

  std::vector<std::vector<Pipeline::SceneInput>> groups;
  if (fuse) groups.push_back(inputs);
  else
    for (const auto& in : inputs) groups.push_back({in});
  // Each group's output folder is named after its (first) scan: a name of its own, inside the
  // output folder whatever the file is called (a stem "..", two scans named room.pcd).
  std::vector<std::string> stems;
  for (const auto& group : groups)
    stems.push_back(fs::path(group.front().path).stem().string() + (group.size() > 1 ? "_fused" : ""));
  const std::vector<std::string> folders = UniqueSafeNames(stems);
  for (size_t gi = 0; gi < groups.size(); ++gi) {
    const auto& group = groups[gi];
    const std::string& stem = stems[gi];
    const std::string dir = !out.empty() ? (groups.size() > 1 ? (fs::path(out) / folders[gi]).string() : out)
                                         : (fs::path("furnihost-out") / folders[gi]).string();
    Stopwatch total;
    auto r = detector.Detect(group);
#ifdef FURNIHOST_HAVE_BIRDSEYE
    fonts.wait();  // before the plots draw text
#endif
    fs::create_directories(dir);
    if (save_parts) {
      for (size_t i = 0; i < r.segmentations.size(); ++i) {
        const std::string name = r.segmentations.size() > 1 ? "parts_" + std::to_string(i) + ".ply" : "parts.ply";
        WriteParts((fs::path(dir) / name).string(), r.scans[i], r.segmentations[i], ctx.seed);
      }
      for (size_t i = 0; r.segmentations.empty() && i < r.proposals.size() && i < r.scans.size(); ++i) {
        const std::string name = r.proposals.size() > 1 ? "proposals_" + std::to_string(i) + ".ply" : "proposals.ply";
        WriteProposals((fs::path(dir) / name).string(), r.scans[i], r.proposals[i], ctx.seed);
      }
      if (r.segmentations.empty() && r.proposals.empty())
        spdlog::warn("--save-parts: the graph has no segmenter or proposer");
    }
    const nlohmann::json j = DetectionsDocument(r, group, graph, ctx.seed, missing, total.Ms());
    const Scan* frame_scan = r.scans.empty() ? nullptr : &r.scans.front();
    // The output files are independent: written side by side on the host's threads (the plots
    // and fitted.ply were ~0.09 s of one core on a 50k-point room, most of a process's tail).
    tbb::task_group outputs;
    outputs.run([&] { WriteJson((fs::path(dir) / "detections.json").string(), j); });
#ifdef FURNIHOST_HAVE_BIRDSEYE
    if (r.voted)
      outputs.run([&] {
        std::vector<const Scan*> sp;
        for (const auto& s : r.scans) sp.push_back(&s);
        WriteBirdsEye((fs::path(dir) / "votes").string(), sp, r.votes, r.detections, r.world_to_user);
      });
#endif
    if (r.fitted && frame_scan)
      outputs.run([&] {
        WriteFitted((fs::path(dir) / "fitted.ply").string(), r.detections, detector.GetCatalog(), *frame_scan);
      });
    outputs.wait();  // rethrows the first error, as the files were written one after another

    std::cout << stem << ": " << j["points"] << " points, " << j["parts"] << " parts";
    if (!r.voted) std::cout << "; no voter ran, so no detections";
    std::cout << " -> " << dir << "/detections.json\n";
    if (r.voted && r.detections.empty()) std::cout << "  no hypotheses\n";
    // Printed in the scan's z-up frame with any global shift added back (the user's numbers).
    std::vector<Detection> shown;
    for (const auto& d : r.detections) shown.push_back(TransformDetection(d, r.world_to_user));
    const Eigen::Vector3d shift =
        frame_scan ? Eigen::Vector3d(frame_scan->frame.to_upright.linear() * frame_scan->frame.shift) : Eigen::Vector3d::Zero();
    if (r.sinks.size() <= 1) {
      PrintDetections(std::cout, shown, shift);
      continue;
    }
    for (const auto& sink : r.sinks) {  // several sinks: each one's detections apart
      std::vector<Detection> of;
      for (const auto& d : shown)
        if (d.chain == sink) of.push_back(d);
      std::cout << "  chain " << sink << ": " << of.size() << (of.size() == 1 ? " detection\n" : " detections\n");
      PrintDetections(std::cout, of, shift);
    }
  }
  return 0;
}

}  // namespace furnihost::app
