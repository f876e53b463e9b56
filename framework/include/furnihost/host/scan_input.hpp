// Scan input: the scans of one detection as every stage sees them. Each scene's file is read by
// the graph's sensor (jittered when asked), turned into its working frame (FrameOptions), given
// its ground (GroundOptions), held to the graph's point limit, and posed in the world frame:
// the first scan's working frame.
#pragma once
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "furnihost/host/config.hpp"
#include "furnihost/host/frame.hpp"
#include "furnihost/stage.hpp"

namespace furnihost {

// Time per stage tag [ms], in the order the stages first ran.
using StageTimes = std::vector<std::pair<std::string, double>>;
FURNIHOST_API void AddTime(StageTimes& times, const std::string& tag, double ms);

// One scan file to detect in.
struct SceneInput {
  std::string path;
  // A scan already in memory (ScanFromPoints with frame.shift): the input sensor takes it
  // instead of reading `path`, which then only names it.
  std::shared_ptr<const Scan> scan;
  std::optional<Eigen::Vector3f> origin;  // in the file's frame
  std::string origin_name = "--origin";   // where `origin` came from, for messages
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
  FrameOptions frame;                      // up axis / transform / global shift
  // Gaussian noise [m] added to the points as read, before the frame and every stage
  // (JitterPoints with jitter_seed; 0 = none): `furnihost eval --jitter`.
  float jitter_m = 0.f;
  uint64_t jitter_seed = 0;
};

// An ensemble's run after the first: each scan jittered as read, the noise drawn along the
// axes of the first run's working frame of that scan (`reference`: the first run's scans).
struct RunJitter {
  float sigma_m = 0.f;
  uint64_t seed = 0;
  const std::vector<Scan>* reference = nullptr;
};

struct SceneScans {
  std::vector<Scan> scans;  // in their working frames, grounded, posed in the world frame
  // The world frame (the first scan's working frame) -> the frame the user gave the scans in:
  // the first scan's z-up frame, moved by its pose.
  Eigen::Isometry3f world_to_user = Eigen::Isometry3f::Identity();
};

// Reads the scenes through `sensor` (the graph's stage `sensor_stage`). `neighbours`: what the
// stages ask of every scan (StageNeeds::neighbours). Adds the sensor's and the ground's time
// to `times`. InputError on a bad file or a scan above /limits/max_points.
FURNIHOST_API SceneScans ReadScenes(const std::vector<SceneInput>& scenes, const GraphConfig& graph,
                                    const StageConfig& sensor_stage, Sensor& sensor, int neighbours,
                                    const RunJitter& jitter, const RunContext& ctx, StageTimes& times);

}  // namespace furnihost
