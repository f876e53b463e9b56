// Shared data types of every stage. Frames and units: metres, z up (the scan's working frame,
// see ScanFrame); heights are measured above the scan's ground (Scan::ground), never above z = 0.
// Point sets are std::vector<Eigen::Vector3f> (N points, 12 bytes each, no alignment needs).
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "furnihost/error.hpp"
#include "furnihost/ground.hpp"

namespace furnihost {

using Points = std::vector<Eigen::Vector3f>;

// A triangle mesh, metres, z up. Triangles index `vertices`.
struct FURNIHOST_API Mesh {
  Points vertices;
  std::vector<Eigen::Vector3i> triangles;
  Eigen::AlignedBox3f Bounds() const;
};

// One model of a catalog after import: z up, metres, bounding-box bottom centre at origin.
struct CatalogModel {
  std::string id;
  std::string cls;       // class, e.g. "chair"
  std::string subclass;  // optional, e.g. "office chair"
  std::string mesh_path; // absolute path of the source file
  Mesh mesh;
  Eigen::Vector3f size = Eigen::Vector3f::Zero();  // bounding-box extents [m]
};

// Ground truth of one object in a scan (the format of *.gt.json).
struct GroundTruthObject {
  std::string cls;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // bounding-box centre [m]
  Eigen::Vector3f size = Eigen::Vector3f::Zero();    // axis-aligned extents [m]
  std::optional<float> yaw;                          // [rad] about +z, when known
  std::string model;                                 // catalog model id, when known
  // Turns about +z mapping the object onto itself, when known (furnihost::YawSymmetry of its
  // model): 0 = any turn, n = n-fold (1 = none). Yaw errors are folded by them.
  std::optional<int> yaw_symmetry;
};

// Global shift: coordinates are read in double and `shift` is subtracted before they are
// rounded to float (Scan::frame.shift records it). Unset + `automatic`: a file whose first
// finite point other than (0, 0, 0) lies 100 m or more from the origin (georeferenced: UTM,
// national grids; a site's frame) is shifted, every point of it, by that point rounded down to
// 100 m per far axis; the shift is logged.
struct ShiftOption {
  std::optional<Eigen::Vector3d> shift;
  bool automatic = true;
};

// How a scan's working frame (metres, z up: what every stage sees) relates to the
// coordinates of its file:
//   upright = to_upright * (file - shift)   the user's z-up frame
//   working = canonical * upright           what the stages see
// The shift is subtracted in double at read time (georeferenced files); to_upright turns the
// user's axes (a camera's optical frame: x right, y down, z forward; --up, --transform) so that
// z points up; canonical (a turn about z and a translation, see EstimateCanonicalFrame in
// frame.hpp) puts the scan's dominant wall directions on the axes and its box centre at the
// origin, so every grid a stage lays over the scan (normals, ground cells, Hough bins) falls
// the same way on the scan whatever frame the file came in: a scan shifted, turned or given
// in a sensor's frame gives the same detections, mapped back.
struct ScanFrame {
  Eigen::Vector3d shift = Eigen::Vector3d::Zero();
  Eigen::Isometry3d to_upright = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d canonical = Eigen::Isometry3d::Identity();
  std::string up = "+z";   // how to_upright was chosen: an axis, "transform" or "auto: <axis>"
  bool IsIdentity() const {
    return shift.isZero() && to_upright.matrix().isIdentity() && canonical.matrix().isIdentity();
  }
  // (file - shift) -> working.
  Eigen::Isometry3d ToWorking() const { return canonical * to_upright; }
  Eigen::Vector3d ToFile(const Eigen::Vector3f& working) const {
    return to_upright.inverse() * (canonical.inverse() * working.cast<double>()) + shift;
  }
  // A direction (unit vector) of the working frame in the file's axes.
  Eigen::Vector3d DirectionToFile(const Eigen::Vector3f& d) const {
    return to_upright.linear().transpose() * (canonical.linear().transpose() * d.cast<double>());
  }
};

// The nearest neighbours of every point of a scan, found once by the pipeline (while it estimates
// the canonical frame, which needs them too) for the stages that would search them again. The
// search runs over the distinct positions of the points (equal points are one position, as in a
// k-d tree over a cloud with copies): per position, its `k` nearest positions, itself first,
// nearest first (fewer when the scan has fewer positions). Distances are not kept: they are the
// scan's own, recomputed in its working frame (the search ran in the z-up frame, a turn and a
// shift away, so an order can differ from a search of the working points where two distances
// are within rounding of each other). Describes position.size() points: a stage that changes a
// scan's points must drop it.
struct ScanNeighbours {
  int k = 0;                       // positions listed per position
  std::vector<uint32_t> position;  // per point: its position
  std::vector<uint32_t> start;     // per position u: its points are members[start[u] .. start[u + 1]), ascending
  std::vector<uint32_t> members;
  std::vector<uint32_t> nearest;   // per position u: nearest[u * k .. u * k + count[u])
  std::vector<uint8_t> count;
  size_t Positions() const { return count.size(); }
  // Whether it describes a scan of n points.
  bool Describes(size_t n) const { return k > 0 && position.size() == n; }
};

// A point cloud as acquired by a sensor, in the scan's working frame.
// `pose` maps scan coordinates to the common (world) frame used for multi-view fusion.
struct Scan {
  std::string source;                 // file path or a description of the simulation
  Points points;
  std::optional<Eigen::Vector3f> origin;  // sensor origin in the scan frame, when known
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
  ScanFrame frame;                        // the file's frame (identity for simulated scans)
  // The floor under the scan in its working frame: set by simulated sensors ("known"), else
  // by the pipeline once per scan before any stage sees the scan.
  std::optional<GroundModel> ground;
  // Set by the pipeline with the working frame (ScanNeighbours); null when not found.
  std::shared_ptr<const ScanNeighbours> neighbours;
  // Height of a world-frame point above this scan's ground (poses are upright: yaw and
  // translation). Without a ground: the world z.
  float HeightAboveGround(const Eigen::Vector3f& world) const {
    if (!ground) return world.z();
    return ground->Above(pose.inverse() * world);
  }
  // World z of this scan's ground under the world point (x, y).
  float GroundZ(float x, float y) const {
    if (!ground) return 0.f;
    const Eigen::Vector3f s = pose.inverse() * Eigen::Vector3f(x, y, 0.f);
    return ground->HeightAt(s.x(), s.y()) + pose.translation().z();
  }
  std::vector<GroundTruthObject> truth;   // filled by simulated sensors
  // Extra per-point integer attributes read from files (e.g. "label", "instance"); may be empty.
  std::map<std::string, std::vector<int32_t>> attributes;
  // Per-point colour (r, g, b) when the file has one; empty otherwise.
  std::vector<std::array<uint8_t, 3>> colors;
};

// One part of a segmentation: indices into Scan::points.
struct Part {
  std::vector<int> indices;
  Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
};

// Output of a segmenter. normals/curvature are per point of the scan (NaN normal = unknown).
struct Segmentation {
  Points normals;
  std::vector<float> curvature;
  std::vector<Part> parts;
  int discarded_points = 0;  // points in parts that stayed too small
};

// One object proposal: scan points that may be one piece of furniture (working frame).
struct Proposal {
  std::vector<int> indices;   // into Scan::points
  Eigen::AlignedBox3f box;    // of the points, its bottom lowered to the ground where the object
                              // reaches within a few centimetres of it (floor contacts are not scanned)
  float ground_z = 0.f;       // ground height under the box centre
  std::vector<int> parts;     // segmentation parts with most of their points in the proposal
  // Proposals of one cluster (several radii, cuts, splits) share a group: alternatives for
  // the same points, of which a recogniser keeps the best per class.
  int group = -1;
  std::string how;            // how it was made, e.g. "all/r2.5+split2" (rule, radius in spacings, variant)
  std::string source;         // which removal of vertical structure it comes from (the proposer's rule names)
  // Occupied area in a shell around the box relative to the area inside it: a proposal cut out
  // of a larger structure (a wall's leftovers, half a bed) has a high one, a free-standing object ~0.
  float surround = 0.f;
};

struct Proposals {
  std::vector<Proposal> items;
  float spacing = 0.f;              // the scan's median point spacing [m]
  std::vector<uint8_t> removed;     // per scan point: 1 = wall, 2 = floor (empty = not reported)
};

// Features of the parts of one segmentation: rows = parts, columns = feature dimensions.
struct FeatureMatrix {
  Eigen::MatrixXf values;
  std::vector<std::string> names;  // one per column
  // Filled by Normaliser::Apply, one per row: how far the row's raw values lay outside the
  // training range before clamping, in units of each column's range (max over the columns;
  // 0 = inside). Voters use it to recognise parts unlike any training part (walls, floors).
  Eigen::VectorXf excess;
};

// The stage inputs of one scene for voting (several when views are fused).
struct SceneParts {
  const Scan* scan = nullptr;
  const Segmentation* segmentation = nullptr;
  const FeatureMatrix* features = nullptr;  // normalised to [0, 1]
  const Proposals* proposals = nullptr;     // when the graph has a proposer
};

// A training view: one simulated scan of one catalog model, segmented and described.
struct TrainingView {
  std::string cls;
  std::string model_id;
  int view = 0;  // -1: no scan, the model's mesh alone (StageNeeds::training_scans)
  Eigen::Vector3f object_centroid = Eigen::Vector3f::Zero();  // centre of mass of the view's points
  Eigen::Vector3f object_size = Eigen::Vector3f::Zero();      // catalog model extents [m]
  const CatalogModel* model = nullptr;  // the catalog model scanned (lives as long as training)
  Scan scan;
  Segmentation segmentation;
  FeatureMatrix features;  // normalised to [0, 1]
};

// A part that voted for a hypothesis: which scene, which part, with which total weight.
struct Support {
  int scene = 0;
  int part = 0;
  float weight = 0.f;
};

// Per-class vote density on the floor plane (world frame), row-major, cell (ix, iy) covers
// [origin + (ix, iy) * cell, +cell).
struct VoteGrid {
  std::string cls;
  Eigen::Vector2f origin = Eigen::Vector2f::Zero();
  float cell = 0.05f;
  int width = 0, height = 0;
  std::vector<float> values;
};

// An upright box in the working frame: centre, size (l along the yaw direction, w across it,
// h up) [m] and yaw [rad] about +z.
struct OrientedBox {
  Eigen::Vector3f center = Eigen::Vector3f::Zero();
  Eigen::Vector3f size = Eigen::Vector3f::Zero();
  float yaw = 0.f;
  // Corners: bottom four counter-clockwise from (-l/2, -w/2), then the top four above them.
  std::array<Eigen::Vector3f, 8> Corners() const {
    std::array<Eigen::Vector3f, 8> c;
    const float co = std::cos(yaw), si = std::sin(yaw);
    const float sx[4] = {-1, 1, 1, -1}, sy[4] = {-1, -1, 1, 1};
    for (int k = 0; k < 8; ++k) {
      const float x = 0.5f * size.x() * sx[k % 4], y = 0.5f * size.y() * sy[k % 4];
      c[k] = center + Eigen::Vector3f(co * x - si * y, si * x + co * y, (k < 4 ? -0.5f : 0.5f) * size.z());
    }
    return c;
  }
  Eigen::AlignedBox3f Aabb() const {
    Eigen::AlignedBox3f b;
    for (const auto& c : Corners()) b.extend(c);
    return b;
  }
};

// One test a stage applied to a hypothesis: what it measured, the limit, the verdict
// (e.g. {"coverage", 0.32, 0.5, at_least, failed}: "coverage 0.32 < 0.5"). Verification and
// recognisers that decide themselves list every check they ran, in order; the first failed one
// is why the hypothesis was rejected.
struct FURNIHOST_API Check {
  std::string name;      // an identifier: "score", "coverage", "free_space_ratio", "part_points", ...
  double value = 0.0;    // what was measured
  double limit = 0.0;    // the bound it is held to
  bool at_least = true;  // passes when value >= limit (else when value <= limit)
  bool passed = true;

  static Check AtLeast(std::string name, double value, double limit);
  static Check AtMost(std::string name, double value, double limit);
  // "coverage 0.32 < 0.5" when failed, "coverage 0.62 >= 0.5" when passed (4 significant digits).
  std::string Text() const;
};

// The text of the first failed check ("" when all passed or there are none).
FURNIHOST_API std::string FirstFailure(const std::vector<Check>& checks);

struct Hypothesis {
  std::string cls;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // world frame; z is the mean vote height
  float score = 0.f;
  std::vector<Support> support;
  std::optional<OrientedBox> box;  // when the voter knows the object's extent (e.g. from a proposal)
  int proposal = -1;               // index into the scene's Proposals::items, when made from one
  int scene = 0;                   // which scene's proposal
  // A recogniser that decides itself (a score against its operating threshold, no fitter
  // needed) sets these; the pipeline copies them into Detection::verified / checks.
  std::optional<bool> accepted;
  std::vector<Check> checks;
  // The catalog model that explains the object best, and where it stands (model -> world),
  // when the voter knows (e.g. by size and shape); no fitter has refined it.
  std::string model;
  std::optional<Eigen::Isometry3f> model_pose;
  // What the voter measured to score it (name -> value, e.g. "length_m", "profile_emd"), for
  // the user and for tuning; copied into Detection::evidence.
  std::map<std::string, float> evidence;
};

struct VoteResult {
  std::vector<Hypothesis> hypotheses;
  std::vector<VoteGrid> grids;
  // Raw votes (world frame) for plots: x, y, class index into `classes`, weight.
  std::vector<std::string> classes;
  std::vector<Eigen::Vector4f> votes;
};

// A detection after fitting and verification.
struct Detection {
  std::string cls;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();
  float yaw = 0.f;            // [rad] about +z
  float score = 0.f;          // voter score
  // Calibrated probability that the detection is a true positive (its box overlaps an object of
  // its class at 3D IoU >= 0.25), set by the host when the graph names a calibration.
  std::optional<float> confidence;
  std::string model;          // fitted catalog model id ("" before fitting)
  std::optional<bool> verified;            // unset when no fitter ran
  std::optional<float> coverage;           // share of part points covered by the model (when fitted)
  std::optional<float> free_space_ratio;   // share of visible model surface in free space (when tested)
  std::optional<float> rms;                // RMS point distance of covered points [m] (when fitted)
  int iterations = 0;
  std::vector<Check> checks;               // what verification tested, in order (Check)
  std::vector<std::string> notes;
  std::vector<Support> support;
  Eigen::Isometry3f model_pose = Eigen::Isometry3f::Identity();  // model -> world
  // The object's box (world frame): from the fitted CAD model ("model"), else the class's
  // typical catalog size standing on the ground at the centre ("class_size"), or a stage's own.
  std::optional<OrientedBox> box;
  std::string box_source;
  int proposal = -1, proposal_scene = 0;  // the proposal it was made from (Hypothesis::proposal)
  std::map<std::string, float> evidence;   // Hypothesis::evidence
  // The sink (voter or last fitter of a chain) that produced it, set by the pipeline when the
  // graph has several sinks (GraphConfig::Sinks); "" with one.
  std::string chain;

  // Why verification rejected it: the first failed check ("" when accepted or not verified).
  std::string Rejection() const { return FirstFailure(checks); }
};

}  // namespace furnihost
