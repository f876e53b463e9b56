// Detections as the user gets them: moved between frames, and as JSON (detections.json).
#pragma once
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "furnihost/types.hpp"

namespace furnihost {

// A detection moved by an upright transform t (a turn about z and a translation): centre, yaw,
// model pose and box.
FURNIHOST_API Detection TransformDetection(Detection d, const Eigen::Isometry3f& t);

// Detection JSON as written to detections.json. With a scan, geometry (centre, box, model
// pose) is written in the scan's file frame (ScanFrame) and the height above its ground is
// added; without, in the working frame.
FURNIHOST_API nlohmann::json DetectionToJson(const Detection& d, const Scan* scan = nullptr);

}  // namespace furnihost
