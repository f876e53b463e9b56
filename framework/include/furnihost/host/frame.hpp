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

#include "furnihost/host/io.hpp"
#include "furnihost/types.hpp"

namespace furnihost {

struct FrameOptions {
  std::string up = "+z";                        // "+x", "-x", "+y", "-y", "+z", "-z" or "auto"
  std::optional<Eigen::Isometry3d> transform;   // file (after the shift) -> z up; excludes `up`
  ShiftOption shift;
  // Stages see the scan in its canonical frame (EstimateCanonicalFrame); off: in the z-up frame
  // itself (then detections depend on where the file's origin and axes happen to lie).
  bool canonical = true;
  // After an up axis (--up AXIS, not auto or a transform): turn the frame so that the floor is
  // level when it is tilted by more than kLevelMinDeg (and at most kLevelMaxDeg) from that axis:
  // a camera pitched down, read in its optical frame with --up -y. The floor is the dominant
  // plane within kLevelMaxDeg of the axis with the scene above it (EstimateUpAxis). Smaller
  // tilts are left to the ground model (a reconstruction's warped floor, a view a few degrees
  // off).
  bool level = false;
  // With the canonical frame: > 0 keeps this many nearest neighbours per point of the ones its
  // estimate searches, as Scan::neighbours (ScanNeighbours), for the stages that ask for them
  // (StageNeeds::neighbours). The estimate's own plane fits use the first 12 whatever is kept.
  int neighbours = 0;
};
constexpr double kLevelMinDeg = 8.0, kLevelMaxDeg = 35.0;

// The rotation (working = R * file) that makes file axis `axis` ("+z", "-y", ...) point up, the
// other two kept right-handed: "-y" (optical frame) gives x forward (= file z), y left (= file
// -x), z up (= file -y), ROS's camera_link from its optical frame. InputError naming `option`
// for an unknown axis.
FURNIHOST_API Eigen::Matrix3d UpAxisRotation(const std::string& axis, const std::string& option);

// "m00,m01,...,m33" (16 numbers, row-major, last row 0 0 0 1) or "x,y,z,roll,pitch,yaw"
// (metres and radians, R = Rz(yaw) Ry(pitch) Rx(roll), as tf2 reads a static transform). The
// rotation must be orthonormal with determinant +1 (within 1e-4). InputError naming `option`.
FURNIHOST_API Eigen::Isometry3d ParseTransform(const std::string& text, const std::string& option);

// InputError naming `option` unless every coordinate of a global shift is within
// kMaxGlobalShift (--shift, a dataset's "shift").
FURNIHOST_API void CheckShift(const Eigen::Vector3d& shift, const std::string& option);

// The farthest a sensor origin may lie from its scan's points [m]: beyond any laser scanner's
// range (terrestrial scanners reach a few km).
constexpr double kMaxSensorRange = 1e4;
// A scan just read (file frame, shifted): InputError "<file>: the sensor origin given by <name>
// ..." when its origin is not finite, beyond kMaxScanCoordinate, or farther than kMaxSensorRange
// from its points' bounding box. `given_as` names where the origin came from (--origin, a
// dataset's /scenes/3/origin); empty: the file's VIEWPOINT or the sensor's "origin" parameter.
// Checked before any stage runs, so a wrong origin is named before it costs a detection.
FURNIHOST_API void CheckSensorOrigin(const Scan& scan, const std::string& given_as);

// The up axis of a cloud (file frame, after the shift) for --up auto: the normal, among the
// dominant plane directions, of the largest plane that has (nearly) all points on one side,
// signed to point at them. nullopt when no plane direction dominates. With `near`: only plane
// directions within `max_deg` of it count, signed its way (levelling a frame whose up is known
// roughly).
FURNIHOST_API std::optional<Eigen::Vector3d> EstimateUpAxis(const Points& points,
                                                            const std::optional<Eigen::Vector3d>& near = std::nullopt,
                                                            double max_deg = 180.0);

// The canonical working frame of a z-up cloud: upright -> working = a turn about z that puts
// the dominant directions of its vertical surfaces (walls, furniture sides) on the x and y axes,
// then a translation that puts the centre of its bounding box at the origin. The direction is
// the circular mean of 4 x the azimuth of the surface normals (k nearest neighbours over a
// sample of at most ~30k points taken by index, so the same points whatever the frame), which a
// turn of the cloud turns with it; without vertical surfaces, the major axis of the points on
// the floor plane. Equivariant: the cloud turned about z and shifted gives the same working
// points up to rounding (and, for turns of a quarter, up to that quarter turn).
// Identity for fewer than 10 finite points.
FURNIHOST_API Eigen::Isometry3d EstimateCanonicalFrame(const Points& upright);
// The same, and when the sample is every point (at most ~60k finite points), the points' `k`
// nearest positions (at most kMaxScanNeighbours; the first 12 of them are those the normals are
// fitted to, so the frame is the same) into *neighbours; otherwise *neighbours is left empty
// (k = 0).
constexpr int kMaxScanNeighbours = 255;
FURNIHOST_API Eigen::Isometry3d EstimateCanonicalFrame(const Points& upright, ScanNeighbours* neighbours, int k);

// Applies the frame options to a scan just read (its points and origin are in the file's frame,
// shifted): turns them into the z-up frame and then into the canonical one (unless
// options.canonical is off), and records both transforms in scan.frame.
// InputError naming `option` when --up auto finds no up axis.
FURNIHOST_API void ToWorkingFrame(Scan& scan, const FrameOptions& options);

// Frame as JSON (detections.json): shift, the 4x4 file -> working matrix, the up choice.
FURNIHOST_API nlohmann::json ToJson(const ScanFrame& frame);

}  // namespace furnihost
