// Upright RANSAC model fitting (paper Sect. VI-C): x, y and yaw of catalog models standing on
// the floor, scored by the number of scene points they cover.
//
// Frames: scene points and normals in the world frame (z up, metres); model clouds in the
// model frame. Assumption: every object stands on the floor plane z = floor_z, so a model's
// frame origin (its bounding-box bottom centre) is placed at height floor_z and only x, y and
// the yaw about +z are searched.
#pragma once
#include <cstdint>
#include <vector>

#include "furnihost/types.hpp"
#include "model_cloud.hpp"

namespace furnihost::ransac_upright {

struct RansacOptions {
  float floor_z = 0.f;                 // [m] world height of the floor the models stand on
  Eigen::Vector2f prior_xy = Eigen::Vector2f::Zero();  // [m] world x, y of the hypothesis' centre
  float max_shift = 0.f;               // [m] poses placing the model origin farther than this from
                                       // prior_xy are not scored (0 = no limit)
  float height_tolerance = 0.01f;      // [m] candidate model points: |z_model - z_scene| below this
  float correspondence_fraction = 0.5f;  // share of the candidates tried per sample (paper ~50 %)
  int max_correspondences = 0;         // cap per sample after the fraction; 0 = none
  float min_horizontal_normal = 0.5f;  // |n_xy| above this: the yaw comes from the normals
  float normal_z_tolerance = 0.3f;     // candidates need ||n_z,model| - |n_z,scene|| below this
  bool normal_sign_ambiguous = true;   // try yaw and yaw + 180° (normals' signs are arbitrary)
  float score_fraction = 0.5f;         // share of the scene points a candidate is scored on
  int max_score_points = 2000;         // ... at most this many (0 = no cap); ICP and the final
                                       // coverage use at most 4x as many (an even subset)
  double p_success = 0.99;             // eq. 7
  int max_iterations = 200;            // samples per model, cap of eq. 7
  int min_iterations = 10;             // samples per model, floor of eq. 7 once any pose reached the bound
  float min_coverage = 0.5f;           // candidates that cannot reach it are abandoned early
  float model_tie_tolerance = 0.02f;   // models within this coverage of the best are tie-broken
  int refine_iterations = 0;           // upright ICP steps on the result
  bool refine_plane = true;            // ICP distances along the model's normals (else point-to-point)
  void Check() const;
};

// Points of the hypothesis' parts. normals: same size, unit, NaN when unknown.
struct ScenePoints {
  Points points;
  Points normals;
  // All scan points around the hypothesis (world frame), supporting or not: what a model's
  // points are explained by when near-tied poses and models are ranked. Empty = `points`.
  Points context;
};

struct ModelTrial {
  int samples = 0;          // RANSAC iterations spent on this model
  float subset_coverage = -1.f;  // best coverage on the scoring subset; -1: none reached the bound
};

struct FitResult {
  int model = -1;               // index into the models; -1 when no pose was generated at all
  bool reached_bound = false;   // false: the pose is the best abandoned candidate (a weak fit)
  float x = 0.f, y = 0.f, yaw = 0.f;  // model origin in the world, yaw about +z [rad]
  Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();  // model -> world
  int covered = 0, total = 0;   // scene points within the inlier distance / scene points tested
                                // (all, or an even subset of 4 x max_score_points)
  float coverage = 0.f;         // covered / total
  float rms = -1.f;             // RMS nearest-point distance of the covered points [m]
  double explained_share = -1.0;  // share of the model's points within the inlier distance of
                                  // scene points; computed only to rank tied models (else -1)
  int iterations = 0;           // samples over all models
  std::vector<ModelTrial> trials;  // one per model
  // The winning model's other poses whose subset coverage was within model_tie_tolerance of
  // its best (x, y, yaw; best first, unrefined): what a verification that refuses the pose
  // (free space) may try next (FinishAt).
  std::vector<Eigen::Vector3f> alternatives;
};

// Eq. 7 with p_good = covered / all; +inf when p_good == 0.
double RequiredIterations(double p_success, double p_good);

Eigen::Isometry3f UprightIsometry(float x, float y, float z, float yaw);

// The refinement (refine_iterations) and final figures of `model` (index `index`) placed at
// (x, y, yaw): FitUpright's last step, for a pose chosen elsewhere (an alternative).
FitResult FinishAt(const ScenePoints& scene, const ModelCloud& model, int index, const RansacOptions& options,
                   float x, float y, float yaw);

// Fits every model (tried in the given order, sharing the best score for early termination)
// and returns the best. Deterministic for a seed, whatever the number of TBB threads.
FitResult FitUpright(const ScenePoints& scene, const std::vector<const ModelCloud*>& models,
                     const RansacOptions& options, uint64_t seed);

namespace detail {
// One candidate pose scored as FitUpright scores it (points `ev` in the model's height range
// of a subset of E, floor and slack as there, `best` the batch's best so far): the exact covered
// count, or -1 and the covered count when it was abandoned. blocks: 8 look-ups at a time
// (CPUs with AVX2), else one at a time. Here for the tests.
struct ScoreResult {
  int score = -1, partial = 0;
};
ScoreResult ScorePose(const ModelCloud& model, const std::vector<Eigen::Vector3f>& ev, int E, int floor, int slack,
                      float yaw, float tx, float ty, int best, bool blocks);
}  // namespace detail

}  // namespace furnihost::ransac_upright
