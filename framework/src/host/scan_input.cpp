#include "furnihost/host/scan_input.hpp"

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "furnihost/geometry.hpp"
#include "furnihost/host/ground_estimation.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/log.hpp"
#include "host/graph/executor.hpp"

namespace furnihost {

namespace {
// The configured cap on points per scan (0 = none), for sensors without a max_points of their own.
size_t MaxPoints(const GraphConfig& g) {
  const auto& r = g.resolved;
  if (r.is_object() && r.contains("limits") && r["limits"].is_object() && r["limits"].contains("max_points") &&
      r["limits"]["max_points"].is_number_unsigned())
    return r["limits"]["max_points"].get<size_t>();
  return 0;
}

// The ground, its per-voxel work spread over the threads.
GroundModel Ground(const Points& points, const GroundOptions& o) {
  return EstimateGround(points, o, [](size_t b, size_t e, const std::function<void(size_t, size_t)>& body) {
    tbb::parallel_for(tbb::blocked_range<size_t>(b, e, 1024),
                      [&](const tbb::blocked_range<size_t>& r) { body(r.begin(), r.end()); });
  });
}
}  // namespace

void AddTime(StageTimes& times, const std::string& tag, double ms) {
  for (auto& t : times)
    if (t.first == tag) {
      t.second += ms;
      return;
    }
  times.emplace_back(tag, ms);
}

SceneScans ReadScenes(const std::vector<SceneInput>& scenes, const GraphConfig& graph, const StageConfig& sensor_stage,
                      Sensor& sensor, int neighbours, const RunJitter& jitter, const RunContext& ctx,
                      StageTimes& times) {
  SceneScans out;
  Eigen::Isometry3d world_to_user = Eigen::Isometry3d::Identity();
  uint64_t jittered_scans = 0;
  for (const auto& sc : scenes) {
    SensorRequest req;
    req.path = sc.path;
    req.scan = sc.scan.get();
    req.origin = sc.origin;
    req.shift = sc.frame.shift;
    Stopwatch sw;
    std::vector<Scan> got = graph::CallStage(sensor_stage, [&] { return sensor.Acquire(req, ctx); });
    for (const auto& s : got) CheckSensorOrigin(s, sc.origin ? sc.origin_name : std::string());
    if (sc.jitter_m > 0.f)
      for (size_t k = 0; k < got.size(); ++k) JitterPoints(got[k].points, sc.jitter_m, sc.jitter_seed + k);
    // An ensemble run's noise, drawn by point index along the first run's working axes: the same
    // noise in the scene whatever frame the file gives the points in. The run then frames its
    // jittered scan anew (the frame's estimate is among the decisions the runs average).
    if (jitter.sigma_m > 0.f)
      for (auto& s : got) {
        const size_t j = jittered_scans++;
        if (j >= jitter.reference->size()) throw std::logic_error("ensemble: a run read more scans than the first");
        const Eigen::Matrix3f axes = (*jitter.reference)[j].frame.ToWorking().linear().transpose().cast<float>();
        JitterPoints(s.points, jitter.sigma_m, SplitMix64(jitter.seed) + j, axes);
      }
    AddTime(times, sensor_stage.tag, sw.Ms());
    // The working frame (z up) and the ground, once per scan, before any stage sees it.
    Stopwatch sg;
    for (auto& s : got) {
      FrameOptions fo = sc.frame;
      fo.canonical = fo.canonical && graph.canonical_frame;
      fo.neighbours = neighbours;
      fo.level = fo.level || graph.level_frame;
      ToWorkingFrame(s, fo);
      GroundOptions go = graph.ground;
      go.fixed_z += float(s.frame.canonical.translation().z());  // given in the z-up frame
      if (!s.ground || graph.ground.kind == "fixed") s.ground = Ground(s.points, go);
      const GroundModel& g = *s.ground;
      spdlog::info("{}: ground {} ({}): z = {:.4f} x + {:.4f} y + {:.3f} m{}", s.source, ToString(g.kind), g.source,
                   g.plane.a, g.plane.b, g.plane.c,
                   g.kind == GroundKind::HeightMap
                       ? fmt::format(", {}x{} cells of {:.2f} m, {:.1f} m2 of floor seen", g.width, g.height, g.cell,
                                     g.observed_area_m2)
                       : std::string());
    }
    AddTime(times, "ground", sg.Ms());
    // Sensors that declare max_points refuse before reading; this catches the others.
    if (const size_t cap = MaxPoints(graph))
      for (const auto& s : got)
        if (s.points.size() > cap)
          throw InputError("stage '" + sensor_stage.tag + "' (" + sensor_stage.type + "): " + sc.path + ": " +
                           std::to_string(s.points.size()) + " points exceed /limits/max_points = " + std::to_string(cap));
    for (auto& s : got) {
      // The world frame is the first scan's working frame; a scan's pose maps its working
      // frame there (through its z-up frame and the pose given for it).
      if (out.scans.empty()) {
        world_to_user = sc.pose.cast<double>() * s.frame.canonical.inverse();
        out.world_to_user = world_to_user.cast<float>();
        s.pose = Eigen::Isometry3f::Identity();
      } else {
        s.pose = (world_to_user.inverse() * sc.pose.cast<double>() * s.frame.canonical.inverse()).cast<float>();
      }
      out.scans.push_back(std::move(s));
    }
  }
  return out;
}

}  // namespace furnihost
