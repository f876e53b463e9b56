// Shared data types of every stage. Frames and units: metres, z up, floor at z = 0 for rooms.
// Point sets are std::vector<Eigen::Vector3f> (N points, 12 bytes each, no alignment needs).
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "furnihost/error.hpp"

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

// A point cloud as acquired by a sensor, in the scan frame.
// `pose` maps scan coordinates to the common (world) frame used for multi-view fusion.
struct Scan {
  std::string source;                 // file path or a description of the simulation
  Points points;
  std::optional<Eigen::Vector3f> origin;  // sensor origin in the scan frame, when known
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
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
};

// A training view: one simulated scan of one catalog model, segmented and described.
struct TrainingView {
  std::string cls;
  std::string model_id;
  int view = 0;
  Eigen::Vector3f object_centroid = Eigen::Vector3f::Zero();  // centre of mass of the view's points
  Eigen::Vector3f object_size = Eigen::Vector3f::Zero();      // catalog model extents [m]
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

struct Hypothesis {
  std::string cls;
  Eigen::Vector3f center = Eigen::Vector3f::Zero();  // world frame; z is the mean vote height
  float score = 0.f;
  std::vector<Support> support;
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
  std::string model;          // fitted catalog model id ("" before fitting)
  std::optional<bool> verified;  // unset when no fitter ran
  float coverage = -1.f;         // share of part points covered by the model, -1 = not computed
  float free_space_ratio = -1.f; // share of visible model surface in free space, -1 = skipped
  float rms = -1.f;              // RMS point distance of covered points [m]
  int iterations = 0;
  std::string rejection;         // why verification rejected it ("" when accepted)
  std::vector<std::string> notes;
  std::vector<Support> support;
  Eigen::Isometry3f model_pose = Eigen::Isometry3f::Identity();  // model -> world
};

}  // namespace furnihost
