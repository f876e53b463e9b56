// Analysis by synthesis for scans with a known sensor origin: what the sensor saw is kept as a
// range image around the origin; a catalog model posed in the scan (upright, yaw, a scale per
// axis) is rendered into the same image (a z-buffer of its surface samples: only the surfaces
// the sensor would have seen count), and every pixel of it is compared with what was measured
// there:
//   seen      the measured surface lies within the depth tolerance of the model's: the model
//             explains it (an "object" pixel when its point is neither floor nor wall);
//   occluded  something nearer was measured: the model may be there, hidden (no evidence);
//   free      the sensor measured well behind the model's surface: its ray passed where the
//             model stands (evidence against the pose);
//   unknown   nothing was measured in that direction (outside the view, no return).
// Areas are metric (a pixel's area at the model's depth), so near and far objects, dense and
// sparse scans weigh alike.
//
// Frames: model samples in the catalog model frame (bounding-box bottom centre at the origin,
// z up); poses map it to the world frame; each range image is in its scan's frame, `to_scan`
// (Scan::pose inverse) maps world points there. Units: metres, radians.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost::ransac_upright {

struct RangeImageOptions {
  float pixel_scale = 1.5f;      // pixel edge as a multiple of the scan's mean angular point spacing
  float min_pixel_rad = 0.0015f;  // bounds of the pixel edge [rad]
  float max_pixel_rad = 0.02f;
  int levels = 5;                // pyramid levels, each pixel twice the edge of the level below
  void Check() const;
};

// Nearest measured surface per pixel of a cube map around a sensor origin (six faces of a
// gnomonic projection; a pixel's depth is the distance along its face's axis), with a pyramid
// of coarser levels (the nearest of each 2 x 2 block) for objects whose samples or points are
// sparser than the finest pixels. Pixels without a measurement are filled from their
// neighbours when most of those have one (holes between the points of a sparse surface).
class RangeImage {
 public:
  // `points` in the scan frame; `object[i]` != 0 for points that may belong to furniture
  // (empty = all); `origin` the sensor in the scan frame.
  RangeImage(const Points& points, const std::vector<uint8_t>& object, const Eigen::Vector3f& origin,
             const RangeImageOptions& options);
  ~RangeImage();
  RangeImage(const RangeImage&) = delete;
  RangeImage& operator=(const RangeImage&) = delete;

  int Levels() const { return int(levels_.size()); }
  // Pixel edge at a face's centre at `level` [rad].
  float PixelRad(int level) const;
  // Pixels at `level` (ids run from 0 to Pixels(level) - 1; id 0 is every direction of the faces
  // where nothing was measured, always unknown).
  size_t Pixels(int level) const { return levels_[size_t(level)].depth.size(); }
  // The pixel id and depth of scan-frame point p at `level`; false when p is the origin.
  bool Project(const Eigen::Vector3f& p, int level, uint32_t* id, float* depth) const {
    const Eigen::Vector3f d = p - origin_;
    const float ax = std::abs(d.x()), ay = std::abs(d.y()), az = std::abs(d.z());
    int face;
    float depth_, a, b;
    if (ax >= ay && ax >= az) {
      face = d.x() >= 0.f ? 0 : 1, depth_ = ax, a = d.y(), b = d.z();
    } else if (ay >= az) {
      face = d.y() >= 0.f ? 2 : 3, depth_ = ay, a = d.x(), b = d.z();
    } else {
      face = d.z() >= 0.f ? 4 : 5, depth_ = az, a = d.x(), b = d.y();
    }
    if (!(depth_ > 1e-6f)) return false;
    const Level& L = levels_[size_t(level)];
    const float inv = L.res / depth_;
    const int u = std::min(L.side - 1, std::max(0, int((a * inv) + L.res)));
    const int v = std::min(L.side - 1, std::max(0, int((b * inv) + L.res)));
    // Faces nothing was measured on have no pixels: their directions share the unknown pixel 0.
    const int64_t off = L.offset[size_t(face)];
    *id = off < 0 ? 0u : uint32_t(off + int64_t(v) * L.side + u);
    *depth = depth_;
    return true;
  }
  // Nearest measured depth of pixel `id` at `level` (+inf: nothing measured).
  float Depth(int level, uint32_t id) const { return levels_[size_t(level)].depth[id]; }
  // Whether that nearest measurement is a furniture point (RangeImage's `object`).
  bool Object(int level, uint32_t id) const { return levels_[size_t(level)].object[id] != 0; }
  // Area [m^2] a pixel of `level` covers at `depth` (at the face's centre).
  float PixelArea(int level, float depth) const {
    const float e = depth / levels_[size_t(level)].res;
    return e * e;
  }
  const Eigen::Vector3f& Origin() const { return origin_; }

 private:
  struct Level {
    float res = 1.f;  // pixels per unit of the face's tangent plane (pixel edge 1/res rad at its centre)
    int side = 2;     // pixels per face side
    std::array<int64_t, 6> offset{};  // first pixel id of each face; -1: no pixels (nothing measured on it)
    std::vector<float> depth;
    std::vector<uint8_t> object;
  };
  Eigen::Vector3f origin_;
  std::vector<Level> levels_;
};

// A catalog model's surface as the renderer draws it: its outer samples thinned to about
// `spacing` [m] (model frame).
struct RenderCloud {
  Points points;
  float spacing = 0.02f;
  Eigen::AlignedBox3f bounds;  // of the model (ModelCloud::Bounds)

  // Disk cache: the key mixes the sampled cloud's (ModelCloud::CacheKey) with the thinning's
  // target; Load returns null for a missing, truncated or foreign file.
  static uint64_t CacheKey(uint64_t cloud_key, int target);
  void Save(const std::string& path, uint64_t key) const;  // temp file + rename; throws on I/O errors
  static std::shared_ptr<const RenderCloud> Load(const std::string& path, uint64_t key);
};
// Thins `outer` (dense outer-surface samples) to one sample per cell of an edge chosen so that
// about `target` samples remain (between min_spacing and max_spacing [m]).
RenderCloud MakeRenderCloud(const Points& outer, const Eigen::AlignedBox3f& bounds, int target = 2500,
                            float min_spacing = 0.015f, float max_spacing = 0.06f);

// An upright placement of a model: origin (bounding-box bottom centre) at (x, y, z), turned by
// yaw about +z, stretched by sx, sy, sz along the model's own axes before the turn.
struct ModelPlacement {
  float x = 0.f, y = 0.f, z = 0.f, yaw = 0.f;
  float sx = 1.f, sy = 1.f, sz = 1.f;
  Eigen::Vector3f Apply(const Eigen::Vector3f& m) const;
  Eigen::Isometry3f Rigid() const;  // without the stretch (model -> world)
};

struct CompareOptions {
  float seen_tolerance = 0.06f;    // |measured - model depth| within this (+ seen_per_m2 * depth^2) is seen [m]
  float seen_per_m2 = 0.004f;      // range-dependent part of the tolerance [1/m] (depth noise grows with range^2)
  float free_margin = 0.12f;       // measured this far (+ the range term) behind the model surface: free [m]
  float pixel_per_spacing = 1.5f;  // pixels at least this many sample spacings wide (no holes in the model)
  void Check() const;
};

// What one pose of one model explains in one or more range images. Areas in m^2.
struct Comparison {
  double seen_object = 0.0;  // model surface matching a measured furniture point
  double seen_other = 0.0;   // ... matching floor or wall points
  double occluded = 0.0;     // behind something measured nearer
  double free = 0.0;         // where the sensor measured through it
  double unknown = 0.0;      // where nothing was measured
  double Visible() const { return seen_object + seen_other + occluded + free + unknown; }
};

// One scan's image and the world -> scan transform.
struct View {
  const RangeImage* image = nullptr;
  Eigen::Isometry3f to_scan = Eigen::Isometry3f::Identity();
};

// Reusable per-thread buffers of the z-buffer (one per image and level, filled lazily).
class Scratch {
 public:
  std::vector<float>& Buffer(size_t view, int level, size_t pixels);
  std::vector<uint32_t> touched;
  std::vector<uint32_t> front;  // per pixel of the current buffer: its front-most sample (when keys are asked for)

 private:
  std::vector<std::vector<std::vector<float>>> buf_;
};

// Renders `model` at `pose` into every view (at the level that suits its depth and sample
// spacing) and compares. With `explained`, also appends the keys (PixelKey) of the furniture
// pixels it explains as pixels of `key_level` (the pixel of `key_level` holding each explained
// pixel's front-most sample; comparable between candidates whatever level each was rendered at),
// with their explained areas in `areas` (a key may repeat: several rendered pixels in one).
// With `observable`, also appends (world frame) the samples the sensor would have measured:
// those within the seen tolerance of their pixel's front-most sample where that is seen or in
// free space (neither hidden behind something nearer nor outside what the sensor measured): the
// part of the posed model the sensor should see.
Comparison ComparePose(const RenderCloud& model, const ModelPlacement& pose, const std::vector<View>& views,
                       const CompareOptions& options, Scratch* scratch, std::vector<uint64_t>* explained = nullptr,
                       std::vector<float>* areas = nullptr, int key_level = 0, Points* observable = nullptr);

// The key ComparePose uses for pixel `id` of view `view`.
inline uint64_t PixelKey(size_t view, uint32_t id) { return (uint64_t(view) << 32) | id; }

// The measured furniture pixels at `level` that world points fall in and measured (their depth
// within the seen tolerance of the pixel's), each once, ascending, with their areas: the pixels
// a proposal's points make.
void PointPixels(const Points& world, const std::vector<View>& views, int level, const CompareOptions& compare,
                 std::vector<uint64_t>* keys, std::vector<float>* areas);

// The joint choice of the objects that explain a view: candidates (each with the sorted keys
// of the furniture pixels it explains and their areas, and its box) taken by descending score;
// each keeps the share of its explained area that no candidate kept before it explains. A
// candidate keeps its pixels (is kept) when that share is at least `min_new_share` and its box
// overlaps no kept one's by more than `max_box_iou` (two objects do not stand in one place; a
// chair under a table overlaps it by less); else it is explained away (a duplicate of a kept
// object, another reading of it, or several kept objects read as one) and its share is at most
// 1 - that IoU.
struct ExplainedPixels {
  double score = 0.0;
  std::vector<uint64_t> keys;  // ascending
  std::vector<float> areas;
  Eigen::AlignedBox3f box;     // empty: no box test
};
struct Choice {
  float share = 1.f;    // of its explained area, what no better kept candidate explains (1: explains nothing)
  float overlap = 0.f;  // largest box IoU with a better kept candidate
  bool kept = false;
};
std::vector<Choice> ExplainAway(const std::vector<ExplainedPixels>& candidates, float min_new_share, float max_box_iou);

// The sensor's mean angular point spacing [rad]: the solid angle the points cover (counted on a
// cube map of about 1 degree pixels) per point, square-rooted. 0 for fewer than 10 points.
float AngularSpacing(const Points& points, const Eigen::Vector3f& origin);

}  // namespace furnihost::ransac_upright
