// The ensemble (EnsembleOptions): Pipeline::Detect's runs on the scans as read and on jittered
// copies, and FuseDetections, which makes their detections one.
#include "furnihost/host/ensemble.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "furnihost/host/calibration.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/log.hpp"
#include "furnihost/host/pipeline.hpp"

namespace furnihost {

std::vector<Detection> FuseDetections(const std::vector<std::vector<Detection>>& runs, double join_iou) {
  struct Item {
    size_t run, index;
    Eigen::AlignedBox3f box;
    bool boxed;
  };
  // Per class and chain, every run's detections from the highest score down (ties: earlier run,
  // then earlier detection).
  std::map<std::pair<std::string, std::string>, std::vector<Item>> groups;
  for (size_t r = 0; r < runs.size(); ++r)
    for (size_t i = 0; i < runs[r].size(); ++i) {
      const Detection& d = runs[r][i];
      groups[{d.cls, d.chain}].push_back({r, i, d.box ? d.box->Aabb() : Eigen::AlignedBox3f(), d.box.has_value()});
    }
  const double k = double(std::max<size_t>(runs.size(), 1));
  auto at = [&](const Item& it) -> const Detection& { return runs[it.run][it.index]; };
  std::vector<Detection> out;
  for (auto& [key, items] : groups) {
    std::stable_sort(items.begin(), items.end(), [&](const Item& a, const Item& b) { return at(a).score > at(b).score; });
    std::vector<char> used(items.size(), 0);
    for (size_t a = 0; a < items.size(); ++a) {
      if (used[a]) continue;
      used[a] = 1;
      std::vector<size_t> members{a};
      std::vector<char> has_run(runs.size(), 0);
      has_run[items[a].run] = 1;
      if (items[a].boxed)
        for (size_t b = a + 1; b < items.size(); ++b) {
          if (used[b] || has_run[items[b].run] || !items[b].boxed) continue;
          if (BoxIou(items[a].box, items[b].box) >= join_iou) {
            used[b] = 1;
            has_run[items[b].run] = 1;
            members.push_back(b);
          }
        }
      // The first run's member speaks for the rest when there is one: its proposal and support
      // index that run's proposals and parts, which are those the result keeps.
      size_t rep = a;
      for (size_t m : members)
        if (items[m].run == 0) rep = m;
      Detection f = at(items[rep]);
      if (items[rep].run != 0) {
        f.proposal = -1;
        f.support.clear();
      }
      double sum = 0;
      for (size_t m : members) sum += at(items[m]).score;
      f.score = float(sum / k);
      if (f.box) {
        Eigen::Vector3f centre = Eigen::Vector3f::Zero(), size = Eigen::Vector3f::Zero();
        for (size_t m : members) {
          OrientedBox b = *at(items[m]).box;
          // The same box a quarter turn off names its length and width the other way round.
          if (std::abs(std::remainder(double(b.yaw) - double(f.box->yaw), M_PI)) > M_PI / 4) std::swap(b.size.x(), b.size.y());
          centre += b.center;
          size += b.size;
        }
        centre /= float(members.size());
        const Eigen::Vector3f shift = centre - f.box->center;
        f.box->center = centre;
        f.box->size = size / float(members.size());
        f.center += shift;
        f.model_pose.pretranslate(shift);
      }
      // The score check decided again on the fused score: failing it rejects; passing it accepts
      // when no other check failed (a fitter's own verdicts stand).
      for (Check& c : f.checks)
        if (c.name == "score") {
          const bool was = c.passed;
          c.value = f.score;
          c.passed = c.at_least ? c.value >= c.limit : c.value <= c.limit;
          if (f.verified && was != c.passed) f.verified = c.passed && FirstFailure(f.checks).empty();
        }
      f.evidence["ensemble_runs"] = float(members.size());
      f.notes.push_back(fmt::format("ensemble: found in {} of {} runs", members.size(), runs.size()));
      out.push_back(std::move(f));
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const Detection& a, const Detection& b) { return a.score > b.score; });
  return out;
}

void Pipeline::Calibrate(std::vector<Detection>& detections) const {
  if (!graph_.calibration_map) return;
  graph_.calibration_map->Apply(detections, graph_.calibration.min_confidence);
  const size_t dropped =
      DropParts(detections, graph_.calibration.part_pairs, graph_.calibration.part_share);
  if (dropped > 0) spdlog::debug("calibration: {} detection(s) dropped as parts of a more probable whole (part_of)", dropped);
}

Pipeline::Result Pipeline::Detect(const std::vector<SceneInput>& scenes, const TrainedModel* model,
                                  const Catalog* catalog, const RunContext& ctx,
                                  const std::function<void()>& before_stages) {
  const EnsembleOptions& e = graph_.ensemble;
  Result first = DetectOnce(scenes, model, catalog, ctx, before_stages, {});
  if (e.runs <= 1) {
    Calibrate(first.detections);
    return first;
  }
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
  Calibrate(first.detections);
  return first;
}

}  // namespace furnihost
