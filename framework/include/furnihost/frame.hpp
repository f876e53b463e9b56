// Scan frames: how the user's coordinates become the working frame every stage sees (metres,
// z up), and back. A scan in a robot's or a camera's own frame is turned with an up axis
// (--up -y for a camera optical frame: x right, y down, z forward) or a full transform (a 4x4
// matrix, or x, y, z, roll, pitch, yaw as a ROS static transform gives it); --up auto takes
// the normal of the scan's dominant large plane that has the scene above it (the floor).
// Georeferenced coordinates are shifted (ShiftOption in io.hpp). Outputs are mapped back.
#pragma once
#include <Eigen/Geometry>
#include <optional>
#include <string>

#include "furnihost/io.hpp"
#include "furnihost/types.hpp"

namespace furnihost {

struct FrameOptions {
  std::string up = "+z";                        // "+x", "-x", "+y", "-y", "+z", "-z" or "auto"
  std::optional<Eigen::Isometry3d> transform;   // file (after the shift) -> working; excludes `up`
  ShiftOption shift;
  bool IsDefault() const { return up == "+z" && !transform && !shift.shift && shift.automatic; }
};

// The rotation (working = R * file) that makes file axis `axis` ("+z", "-y", ...) point up, the
// other two kept right-handed: "-y" (optical frame) gives x forward (= file z), y left (= file
// -x), z up (= file -y), ROS's camera_link from its optical frame. InputError naming `option`
// for an unknown axis.
FURNIHOST_API Eigen::Matrix3d UpAxisRotation(const std::string& axis, const std::string& option);

// "m00,m01,...,m33" (16 numbers, row-major, last row 0 0 0 1) or "x,y,z,roll,pitch,yaw"
// (metres and radians, R = Rz(yaw) Ry(pitch) Rx(roll), as tf2 reads a static transform). The
// rotation must be orthonormal with determinant +1 (within 1e-4). InputError naming `option`.
FURNIHOST_API Eigen::Isometry3d ParseTransform(const std::string& text, const std::string& option);

// The up axis of a cloud (file frame, after the shift) for --up auto: the normal, among the
// dominant plane directions, of the largest plane that has (nearly) all points on one side,
// signed to point at them. nullopt when no plane direction dominates.
FURNIHOST_API std::optional<Eigen::Vector3d> EstimateUpAxis(const Points& points);

// Applies the frame options to a scan just read (its points and origin are in the file's frame,
// shifted): turns them into the working frame and records the transform in scan.frame.
// InputError naming `option` when --up auto finds no up axis.
FURNIHOST_API void ToWorkingFrame(Scan& scan, const FrameOptions& options);

// Frame as JSON (detections.json): shift, the 4x4 file -> working matrix, the up choice.
FURNIHOST_API nlohmann::json ToJson(const ScanFrame& frame);

}  // namespace furnihost
