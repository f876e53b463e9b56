// The pose of a catalog model that best explains a view (analysis by synthesis, view_synthesis.hpp):
// from a few starts (position, yaw, stretch), a pattern search over x, y, yaw and the stretch
// along the model's length, width and height, each kept within the class's catalog sizes,
// maximising the furniture surface the rendered model explains minus the surface it puts where
// the sensor saw through (free space).
//
// Frames: world (z up, metres); model samples in the model frame.
#pragma once
#include <vector>

#include "view_synthesis.hpp"

namespace furnihost::ransac_upright {

struct SearchOptions {
  float free_weight = 2.f;      // objective = seen furniture area - free_weight * free area
  float max_shift = 0.6f;       // [m] positions farther than this from their start are not tried
  float step_m = 0.08f;         // first position step [m], halved down to min_step_m
  float min_step_m = 0.02f;
  float step_yaw = 0.35f;       // first yaw step [rad], halved with the position step
  float step_scale = 0.12f;     // first stretch step (ln), halved with the position step
  int keep_starts = 2;          // the best starts searched from
  int max_evaluations = 45;     // per start searched
  void Check() const;
};

// Stretches allowed along the model's x, y, z axes (sx, sy, sz bounds).
struct StretchRange {
  Eigen::Vector3f lo = Eigen::Vector3f::Ones(), hi = Eigen::Vector3f::Ones();
};

struct Start {
  int model = 0;  // index into the models
  ModelPlacement pose;
};

struct SearchResult {
  int model = -1;
  ModelPlacement pose;
  Comparison comparison;
  double objective = -1e300;
  int evaluations = 0;
};

double Objective(const Comparison& c, const SearchOptions& o);

// The best pose over `starts` (each start's model among `models`, with its stretch range). The
// starts are compared as given, the best keep_starts searched. Deterministic.
SearchResult SearchPose(const std::vector<const RenderCloud*>& models, const std::vector<StretchRange>& ranges,
                        const std::vector<Start>& starts, const std::vector<View>& views, const CompareOptions& compare,
                        const SearchOptions& options, Scratch* scratch);

}  // namespace furnihost::ransac_upright
