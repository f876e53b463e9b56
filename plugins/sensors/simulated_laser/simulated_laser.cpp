// sensors.simulated_laser — simulated range sensor (paper Sect. IV): Embree 3 ray casting
// against placed catalog models (and optional room geometry), range-dependent Gaussian depth
// noise, optional dropout and voxel downsampling; for training views that look like the scans
// they are compared with, a depth camera's disparity quantisation and flying pixels, and a
// reconstruction's holes and missing floor contacts, bundled as presets ("preset":
// "room_reconstruction" | "depth_camera"; the parameters a config sets override its values).
//
// Frames and units: metres; world z up, floor at z = 0. A sensor pose maps sensor -> world,
// sensor x forward, y left, z up. Scans are returned in the WORLD frame (Scan::pose = identity)
// with Scan::origin = sensor position in the world.
//
// Determinism: each ray's random numbers come from a counter-based generator keyed by
// (seed, view, ray index), so results do not depend on the thread count or scheduling.
//
// Embree is loaded (dlopen) and its device created on the first simulation, not with the
// plugin: every graph names its training sensor, so the host loads this plugin on each
// detection, and a detection with a cached model never simulates (Embree and its OpenMP
// runtime took ~4 ms to load and ~1.5 ms to start, on the critical path of a 0.3 s run).
#include <embree3/rtcore.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <memory>
#include <mutex>
#include <sstream>
#include <type_traits>

#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/plugin.hpp"
#include "embree.hpp"

namespace furnihost::sensors {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// Options of the sensor; one field per declared parameter.
struct SimulatedLaserOptions {
  std::string pattern = "pan_tilt";   // "pan_tilt" | "depth_camera"
  // pan_tilt: a line scanner (Hokuyo) on a pan-tilt unit, sampled as an azimuth x elevation
  // grid in the sensor frame (azimuth about z from +x, elevation from the xy plane).
  double angular_resolution_deg = 0.25;  // azimuth step
  double tilt_resolution_deg = 0.25;     // elevation step
  double horizontal_fov_deg = 180.0;     // centred on +x
  double tilt_min_deg = -60.0;
  double tilt_max_deg = 30.0;
  double min_range_m = 0.1;
  double max_range_m = 30.0;
  // depth_camera: pinhole, optical axis = sensor +x, image u to the right (-y), v down (-z).
  int width = 640;
  int height = 480;
  double focal_px = 525.0;
  double camera_min_range_m = 0.45;
  double camera_max_range_m = 4.5;
  // Default training views (request without poses).
  double sensor_height_m = 1.5;  // sensor z above the floor
  double distance_m = 2.0;       // horizontal distance to the objects' bbox centre
  int views = 16;                // evenly spaced around the up axis
  int fuse = 1;                  // each default view fuses this many casts evenly around the up axis
  int noise_draws = 1;           // each default view is scanned this many times, each its own noise draw
  // Range noise: sigma(r) = noise_a + noise_b * r^2 [m], along the ray.
  double noise_a = 0.008;
  double noise_b = 0.0005;
  double dropout = 0.0;          // probability that a return is lost
  double voxel_m = 0.0;          // voxel-grid downsampling edge [m], 0 = off
  // A depth camera's artefacts (pattern depth_camera).
  double disparity_quantum = 0.0;  // 1/depth is quantised in steps of this [1/m] (0 = off)
  double flying_pixels = 0.0;      // probability that a pixel at a depth edge returns a depth between
  double edge_jump_m = 0.05;       // a depth edge: neighbouring pixels' ranges differ by more [m]
  // A reconstruction's gaps.
  double floor_gap_m = 0.0;        // the objects' returns this close above the floor (z = 0) are lost [m]
  double holes = 0.0;              // share of the surface lost in patches of hole_size_m
  double hole_size_m = 0.1;        // edge of the world-anchored cells a hole takes out [m]
  std::string preset = "none";     // the preset whose values fill the parameters not given (Resolve)
  // Embree's kernels: "portable" (the x86-64 baseline's, the same points on every CPU), "native"
  // (the CPU's widest) or one instruction set by name.
  std::string embree_isa = "portable";
};

// The presets' values (ParamSchema::Resolve applies them to the parameters a config leaves out).
// room_reconstruction: what a hand-held RGB-D reconstruction such as ScanNet's holds: a walk
//   around the object at hand height (8 casts of a wide pitched camera fused per view, so no
//   undersides), 2 cm voxels (the rooms' 1.4-3.3 cm spacing), a fused surface's ~4 mm noise,
//   floor contacts missing (3 cm) and a tenth of the surface lost in 10 cm holes.
// depth_camera: a raw Kinect-v1-class frame: range noise 1.5 mm + 1.9 mm/m^2 (Nguyen et al. 2012,
//   ~1.3 cm at 3 m), 1/8-pixel disparity steps (f 580 px, baseline 7.5 cm: 2.9 mm/m^2, 1.1 cm at
//   2 m), flying pixels at half the depth edges, 2 % dropout; 320 x 240 px at a Kinect's field of
//   view, from 1.3 m.
nlohmann::json Presets() {
  return {{"room_reconstruction",
           {{"pattern", "depth_camera"}, {"width", 160}, {"height", 120}, {"focal_px", 131.25},
            {"camera_min_range_m", 0.3}, {"camera_max_range_m", 4.0}, {"sensor_height_m", 1.3},
            {"distance_m", 1.6}, {"views", 4}, {"fuse", 8}, {"noise_a", 0.004}, {"noise_b", 0.0},
            {"dropout", 0.0}, {"voxel_m", 0.02}, {"floor_gap_m", 0.03}, {"holes", 0.3}, {"hole_size_m", 0.1}}},
          {"depth_camera",
           {{"pattern", "depth_camera"}, {"width", 320}, {"height", 240}, {"focal_px", 262.5},
            {"camera_min_range_m", 0.45}, {"camera_max_range_m", 4.5}, {"sensor_height_m", 1.3},
            {"distance_m", 2.0}, {"views", 16}, {"fuse", 1}, {"noise_a", 0.0015}, {"noise_b", 0.0019},
            {"dropout", 0.02}, {"voxel_m", 0.0}, {"disparity_quantum", 0.00285}, {"flying_pixels", 0.5},
            {"edge_jump_m", 0.05}}}};
}

// Each parameter declared once; its default is SimulatedLaserOptions{}'s.
const ParamBinding<SimulatedLaserOptions>& Binding() {
  using O = SimulatedLaserOptions;
  static const auto b =
      ParamBinding<O>()
          .Enum("pattern", &O::pattern, {"pan_tilt", "depth_camera"},
                "pan_tilt: Hokuyo line scanner on a pan-tilt unit (the paper's); depth_camera: "
                "Kinect-style pinhole camera")
          .Number("angular_resolution_deg", &O::angular_resolution_deg, 0.01, 10.0, "deg",
                  "pan_tilt: azimuth step between rays [deg] (Hokuyo UTM-30LX: 0.25)")
          .Number("tilt_resolution_deg", &O::tilt_resolution_deg, 0.01, 10.0, "deg",
                  "pan_tilt: elevation step between scan lines of the tilt sweep")
          .Number("horizontal_fov_deg", &O::horizontal_fov_deg, 0.1, 360.0, "deg",
                  "pan_tilt: azimuth field of view centred on the sensor's +x [deg]; 360 = all around")
          .Number("tilt_min_deg", &O::tilt_min_deg, -90.0, 90.0, "deg",
                  "pan_tilt: lowest elevation of the sweep [deg] (negative = below the horizon)")
          .Number("tilt_max_deg", &O::tilt_max_deg, -90.0, 90.0, "deg", "pan_tilt: highest elevation of the sweep")
          .Number("min_range_m", &O::min_range_m, 0.0, 100.0, "m", "pan_tilt: returns closer than this are lost")
          .Number("max_range_m", &O::max_range_m, 0.1, 1000.0, "m", "pan_tilt: maximum range [m] (UTM-30LX: 30)")
          .Int("width", &O::width, 1, 8192, "px", "depth_camera: image width")
          .Int("height", &O::height, 1, 8192, "px", "depth_camera: image height")
          .Number("focal_px", &O::focal_px, 1.0, 1e5, "px", "depth_camera: focal length [px] (Kinect v1: 525)")
          .Number("camera_min_range_m", &O::camera_min_range_m, 0.0, 100.0, "m", "depth_camera: minimum depth range")
          .Number("camera_max_range_m", &O::camera_max_range_m, 0.1, 1000.0, "m", "depth_camera: maximum range")
          .Number("sensor_height_m", &O::sensor_height_m, 0.0, 10.0, "m",
                  "default training views: sensor height above the floor [m] (paper: ~1.5)")
          .Number("distance_m", &O::distance_m, 0.1, 100.0, "m",
                  "default training views: horizontal distance from the objects' bbox centre")
          .Int("views", &O::views, 1, 720, "count",
               "default training views: number of views evenly around the up axis (paper: 16)")
          .Int("fuse", &O::fuse, 1, 64, "count",
               "default training views: each view is the union of this many casts evenly around the up axis, "
               "starting at the view's own position (its origin and viewing frame), voxelised once: what a "
               "reconstruction from a walk around the object holds (not in the paper; 1 = single views, paper)")
          .Int("noise_draws", &O::noise_draws, 1, 64, "count",
               "default training views: each view is scanned this many times from the same pose, each scan "
               "with its own draw of range noise, dropout and holes, all of them training views: a model "
               "learns the views' parts rather than one draw's (not in the paper; 1 = one scan a view, paper)")
          .Number("noise_a", &O::noise_a, 0.0, 1.0, "m",
                  "range noise sigma = noise_a + noise_b * r^2: constant part [m] (Hokuyo ~1 cm at 2 m)")
          .Number("noise_b", &O::noise_b, 0.0, 1.0, "1/m",
                  "range noise sigma = noise_a + noise_b * r^2: quadratic part")
          .Number("dropout", &O::dropout, 0.0, 0.999, "1", "probability that a return is lost")
          .Number("voxel_m", &O::voxel_m, 0.0, 1.0, "m",
                  "voxel-grid downsampling edge [m], grid anchored at the world origin; 0 = off. "
                  "Use the same value for the scans you detect in (density matching)")
          .Number("disparity_quantum", &O::disparity_quantum, 0.0, 1.0, "1/m",
                  "depth_camera: 1/depth is quantised in steps of this, so the depth steps grow with its square "
                  "(Kinect v1: 0.00285, 1.1 cm at 2 m); 0 = off")
          .Number("flying_pixels", &O::flying_pixels, 0.0, 1.0, "1",
                  "depth_camera: probability that a pixel at a depth edge (its right or lower neighbour's range "
                  "differs by more than edge_jump_m) returns a depth between the two (mixed pixels)")
          .Number("edge_jump_m", &O::edge_jump_m, 0.001, 100.0, "m", "depth_camera: the range step of a depth edge")
          .Number("floor_gap_m", &O::floor_gap_m, 0.0, 1.0, "m",
                  "returns of the objects less than this above the floor (z = 0) are lost: the floor contacts a "
                  "room reconstruction misses")
          .Number("holes", &O::holes, 0.0, 0.999, "1",
                  "share of the surface lost in holes: world-anchored cells of hole_size_m are dropped at random "
                  "(a reconstruction's unscanned patches)")
          .Number("hole_size_m", &O::hole_size_m, 0.005, 10.0, "m", "holes: edge of the cells a hole takes out")
          .String("preset", &O::preset,
                  "a named set of values for the parameters the config does not give: 'room_reconstruction' (a "
                  "hand-held reconstruction: walk around the object, fused, 2 cm voxels, holes, no floor contacts), "
                  "'depth_camera' (a raw Kinect-class frame: range noise, disparity steps, flying pixels, dropout) "
                  "or 'none'; see presets")
          .Enum("embree_isa", &O::embree_isa, {"portable", "native", "sse2", "sse4.2", "avx", "avx2", "avx512"},
                "the ray tracer's kernels: 'portable' casts every ray with the x86-64 baseline's (SSE2) kernels, so "
                "a scan, and a model trained on such scans, is the same bit for bit on every CPU; 'native' takes "
                "the CPU's widest (AVX2's and AVX-512's fused multiply-adds round differently, so the points "
                "differ in their last bits from CPU to CPU); an instruction set's name takes its kernels (the "
                "CPU must have it): what a CPU whose widest they are computes")
          .Object("presets", Presets(),
                  "the presets' values by name; a config's own entries add presets or redefine these",
                  [](O&, const nlohmann::json&) {})
          // Rules between fields (single-field ranges are enforced by the schema).
          .Rule([](const O& o) {
            return o.pattern == "depth_camera" || (o.disparity_quantum == 0.0 && o.flying_pixels == 0.0)
                       ? ""
                       : "disparity_quantum and flying_pixels model a depth camera: set pattern to depth_camera";
          })
          .Rule([](const O& o) {
            return o.tilt_min_deg <= o.tilt_max_deg ? std::string()
                                                    : "tilt_min_deg (" + std::to_string(o.tilt_min_deg) +
                                                          ") > tilt_max_deg (" + std::to_string(o.tilt_max_deg) + ")";
          })
          .Rule([](const O& o) { return o.min_range_m < o.max_range_m ? "" : "min_range_m must be < max_range_m"; })
          .Rule([](const O& o) {
            return o.camera_min_range_m < o.camera_max_range_m ? "" : "camera_min_range_m must be < camera_max_range_m";
          });
  return b;
}

// ---- counter-based random numbers --------------------------------------------------------

// Standard normal quantile (P. J. Acklam's rational approximation, relative error < 1.2e-9):
// one uniform per sample and no log/cos in the central 95 %, the costliest part of a
// Box-Muller sample per ray.
inline double NormalQuantile(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                                 1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                 6.680131188771972e+01,  -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                 -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                 3.754408661907416e+00};
  constexpr double kLow = 0.02425;
  if (p >= kLow && p <= 1.0 - kLow) {
    const double q = p - 0.5, r = q * q;
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
           (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1.0);
  }
  const double q = std::sqrt(-2.0 * std::log(p < kLow ? p : 1.0 - p));
  const double x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
                   ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1.0);
  return p < kLow ? x : -x;
}

struct RayRng {
  uint64_t state;
  RayRng(uint64_t seed, uint64_t view, uint64_t ray)
      : state(SplitMix64(SplitMix64(SplitMix64(seed) ^ view) ^ ray)) {}
  double Uniform() { return UnitOpen(state = SplitMix64(state)); }  // (0, 1], never 0 (log-safe)
  double Gauss() { return NormalQuantile(Uniform()); }
};

Eigen::AlignedBox3f WorldBox(const Mesh& mesh, const Eigen::Isometry3f& pose) {
  Eigen::AlignedBox3f b;
  for (const auto& v : mesh.vertices) b.extend(pose * v);
  return b;
}

// Unit ray directions of the pattern in the sensor frame, row-major (elevation/row major,
// azimuth/column minor) so neighbouring rays are coherent for packet tracing.
struct Pattern {
  std::vector<Eigen::Vector3f> dirs;
  float min_range = 0.f, max_range = 0.f;
};

Pattern MakePattern(const SimulatedLaserOptions& o, double horizontal_fov_deg) {
  Pattern p;
  if (o.pattern == "depth_camera") {
    p.min_range = static_cast<float>(o.camera_min_range_m);
    p.max_range = static_cast<float>(o.camera_max_range_m);
    p.dirs.reserve(size_t(o.width) * o.height);
    const double cx = 0.5 * o.width, cy = 0.5 * o.height;
    for (int v = 0; v < o.height; ++v)
      for (int u = 0; u < o.width; ++u) {
        // pixel centres; image right = sensor -y, image down = sensor -z
        Eigen::Vector3d d(1.0, -(u + 0.5 - cx) / o.focal_px, -(v + 0.5 - cy) / o.focal_px);
        p.dirs.push_back(d.normalized().cast<float>());
      }
    return p;
  }
  p.min_range = static_cast<float>(o.min_range_m);
  p.max_range = static_cast<float>(o.max_range_m);
  const double res = o.angular_resolution_deg;
  const bool full_circle = horizontal_fov_deg >= 360.0 - 1e-9;
  // A full circle must not sample -180 and +180 twice.
  const int nx = full_circle ? std::max(1, static_cast<int>(std::lround(360.0 / res)))
                             : static_cast<int>(std::floor(horizontal_fov_deg / res + 1e-9)) + 1;
  const double az0 = full_circle ? -180.0 : -0.5 * (nx - 1) * res;
  const int ny = static_cast<int>(std::floor((o.tilt_max_deg - o.tilt_min_deg) /
                                             o.tilt_resolution_deg + 1e-9)) + 1;
  p.dirs.reserve(size_t(nx) * ny);
  for (int iy = 0; iy < ny; ++iy) {
    const double el = (o.tilt_max_deg - iy * o.tilt_resolution_deg) * kDeg;
    for (int ix = 0; ix < nx; ++ix) {
      const double az = (az0 + ix * res) * kDeg;
      p.dirs.emplace_back(static_cast<float>(std::cos(el) * std::cos(az)),
                          static_cast<float>(std::cos(el) * std::sin(az)),
                          static_cast<float>(std::sin(el)));
    }
  }
  return p;
}

// Sensor -> world pose at `pos` whose +x looks at `target`: level (yaw only) for the pan-tilt
// unit, whose base is level on the robot; pitched as well for a camera.
Eigen::Isometry3f LookAt(const Eigen::Vector3f& pos, const Eigen::Vector3f& target, bool pitch) {
  Eigen::Vector3f x = target - pos;
  if (!pitch) x.z() = 0.f;
  if (x.norm() < 1e-6f) x = Eigen::Vector3f::UnitX();
  x.normalize();
  Eigen::Vector3f y = Eigen::Vector3f::UnitZ().cross(x);
  if (y.norm() < 1e-6f) y = Eigen::Vector3f::UnitY();  // looking straight down/up
  y.normalize();
  const Eigen::Vector3f z = x.cross(y);
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.linear().col(0) = x;
  t.linear().col(1) = y;
  t.linear().col(2) = z;
  t.translation() = pos;
  return t;
}

}  // namespace

class SimulatedLaser : public Sensor {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }

  explicit SimulatedLaser(const nlohmann::json& p) : opt_(Binding().Parse(p)) {}

  std::vector<Scan> Acquire(const SensorRequest& request, const RunContext& ctx) override {
    if (!request.path.empty())
      throw StageError("simulates scenes from catalog models; it does not read files (got path " +
                       request.path + ")");
    std::vector<Scan> scans;
    auto run = [&] { scans = AcquireImpl(request, ctx); };
    if (ctx.threads > 0) {
      tbb::task_arena arena(ctx.threads);
      arena.execute(run);
    } else {
      run();
    }
    return scans;
  }

 private:
  std::vector<Scan> AcquireImpl(const SensorRequest& req, const RunContext& ctx) const {
    RTCDevice dev = Device();
    ScenePtr scene(Embree().NewScene(dev));
    ThrowIfEmbreeError(dev, "creating a scene");

    const unsigned n_obj = static_cast<unsigned>(req.objects.size());
    std::vector<GroundTruthObject> truth;
    Eigen::AlignedBox3f all;
    for (unsigned i = 0; i < n_obj; ++i) {
      const PlacedObject& o = req.objects[i];
      if (!o.model) throw StageError("object " + std::to_string(i) + " has no model", false);
      const std::string name = "object " + std::to_string(i) + " (" + o.model->id + ")";
      AddMesh(dev, scene.get(), o.model->mesh, o.pose, i, name);
      const Eigen::AlignedBox3f b = WorldBox(o.model->mesh, o.pose);
      all.extend(b);
      GroundTruthObject g;
      g.cls = o.model->cls;
      g.model = o.model->id;
      g.center = b.center();
      g.size = b.sizes();
      const Eigen::Matrix3f r = o.pose.linear();
      g.yaw = std::atan2(r(1, 0), r(0, 0));
      truth.push_back(g);
    }
    AddMesh(dev, scene.get(), req.extra, Eigen::Isometry3f::Identity(), n_obj, "extra geometry");
    Embree().CommitScene(scene.get());
    ThrowIfEmbreeError(dev, "building the scene");

    std::vector<Eigen::Isometry3f> poses = req.poses;
    std::vector<std::vector<Eigen::Isometry3f>> fused;  // extra casts per default view
    const bool camera = opt_.pattern == "depth_camera";
    if (poses.empty()) {
      if (all.isEmpty()) {
        if (req.extra.vertices.empty())
          throw StageError("nothing to scan: no objects, no extra geometry and no poses");
        all = WorldBox(req.extra, Eigen::Isometry3f::Identity());
      }
      const Eigen::Vector3f c = all.center();
      auto pose_at = [&](double th) {  // on the circle around c, looking at c
        const Eigen::Vector3f pos(c.x() + static_cast<float>(opt_.distance_m * std::cos(th)),
                                  c.y() + static_cast<float>(opt_.distance_m * std::sin(th)),
                                  static_cast<float>(opt_.sensor_height_m));
        return LookAt(pos, c, camera);
      };
      for (int k = 0; k < opt_.views; ++k) {
        const double th = 2.0 * kPi * k / opt_.views;
        poses.push_back(pose_at(th));
        fused.emplace_back();
        for (int j = 1; j < opt_.fuse; ++j) fused.back().push_back(pose_at(th + 2.0 * kPi * j / opt_.fuse));
      }
    }

    const Pattern pat = MakePattern(opt_, opt_.horizontal_fov_deg);
    std::vector<Scan> scans;
    scans.reserve(poses.size());
    Buffers buf;
    buf.points.resize(pat.dirs.size());
    buf.instance.resize(pat.dirs.size());
    if (opt_.flying_pixels > 0.0) buf.range.resize(pat.dirs.size());
    // Draw d > 0 of a default view takes its noise streams from view index v + d * 2^40, beyond
    // every view and fused-cast index of draw 0, which keeps the single-draw streams.
    const int draws = fused.empty() ? 1 : opt_.noise_draws;
    for (size_t v = 0; v < poses.size(); ++v) {
      std::vector<Eigen::Isometry3f> casts{poses[v]};
      if (v < fused.size()) casts.insert(casts.end(), fused[v].begin(), fused[v].end());
      for (int d = 0; d < draws; ++d) {
        Scan s = CastView(scene.get(), pat, casts, n_obj, ctx.seed, v + (uint64_t(d) << 40), buf);
        std::ostringstream src;
        src << "sensors.simulated_laser " << opt_.pattern << " view " << v + 1 << "/" << poses.size();
        if (draws > 1) src << " noise draw " << d + 1 << "/" << draws;
        s.source = src.str();
        s.truth = truth;
        // Models stand on z = 0 (catalog models' bottom centre is their origin; scene files put
        // the floor there): the ground is known, not estimated.
        s.ground = GroundModel::Level(0.f, "known");
        scans.push_back(std::move(s));
      }
    }
    return scans;
  }

  // Per-ray results of one view, reused across views (one page-faulting allocation per call).
  struct Buffers {
    std::vector<Eigen::Vector3f> points;
    std::vector<int32_t> instance;  // -1 = no return
    std::vector<float> range;       // of each return (flying pixels)
  };

  // One scan from the casts' union (origin: the first cast's), voxelised once.
  Scan CastView(RTCScene scene, const Pattern& pat, const std::vector<Eigen::Isometry3f>& casts,
                unsigned n_obj, uint64_t seed, size_t view, Buffers& buf) const {
    Scan s;
    s.origin = casts.front().translation();
    Points compact;
    std::vector<int32_t> labels;
    for (size_t j = 0; j < casts.size(); ++j)
      // The first cast keeps the single-view noise stream (view), the others get their own.
      CastRays(scene, pat, casts[j], n_obj, seed, j == 0 ? view : view + 1000003 * j, buf, compact, labels);
    if (opt_.holes > 0.0) PunchHoles(seed, view, compact, labels);
    if (opt_.voxel_m > 0.0) {
      // The host's own downsampling (sensors.scan_file uses it too): a training view and a
      // scene scan with the same voxel_m see the same world-anchored voxels. Each voxel's
      // label is that of its first point.
      std::vector<int> first;
      compact = VoxelDownsample(compact, static_cast<float>(opt_.voxel_m), &first);
      std::vector<int32_t> l2;
      l2.reserve(first.size());
      for (int r : first) l2.push_back(labels[r]);
      labels = std::move(l2);
    }
    s.points = std::move(compact);
    // 1-based index of the placed object each point hit, 0 = extra geometry (floor, walls).
    s.attributes["instance"] = std::move(labels);
    return s;
  }

  // Holes: each world-anchored cell of hole_size_m is lost with probability `holes`, drawn per
  // view (a reconstruction's unscanned patches differ from one walk to the next).
  void PunchHoles(uint64_t seed, size_t view, Points& pts, std::vector<int32_t>& labels) const {
    const double cell = opt_.hole_size_m;
    const uint64_t key = SplitMix64(SplitMix64(seed ^ 0x486f6c6573ull) ^ view);
    size_t kept = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      uint64_t h = key;
      for (int a = 0; a < 3; ++a) h = SplitMix64(h ^ uint64_t(int64_t(std::floor(double(pts[i][a]) / cell))));
      if (UnitOpen(h) < opt_.holes) continue;
      pts[kept] = pts[i];
      labels[kept++] = labels[i];
    }
    pts.resize(kept);
    labels.resize(kept);
  }

  // Casts the pattern from `pose` and appends the returns (ray order) to compact / labels.
  void CastRays(RTCScene scene, const Pattern& pat, const Eigen::Isometry3f& pose, unsigned n_obj,
                uint64_t seed, size_t view, Buffers& buf, Points& compact, std::vector<int32_t>& labels) const {
    const size_t n = pat.dirs.size();
    const Eigen::Matrix3f rot = pose.linear();
    const Eigen::Vector3f org = pose.translation();
    // Compaction after the parallel loop keeps the ray order (thread-independent).
    std::vector<Eigen::Vector3f>& pts = buf.points;
    std::vector<int32_t>& inst = buf.instance;
    std::fill(inst.begin(), inst.end(), -1);
    constexpr size_t kPacket = 16;
    const size_t n_packets = (n + kPacket - 1) / kPacket;
    const float a = static_cast<float>(opt_.noise_a), b = static_cast<float>(opt_.noise_b);
    const bool noisy = a > 0.f || b > 0.f;
    const double dropout = opt_.dropout;
    const double quantum = opt_.disparity_quantum;
    const bool flying = opt_.flying_pixels > 0.0 && opt_.pattern == "depth_camera";

    const auto intersect16 = Embree().Intersect16;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n_packets, 32), [&](const tbb::blocked_range<size_t>& r) {
      RTCIntersectContext ictx;
      rtcInitIntersectContext(&ictx);
      ictx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
      alignas(64) RTCRayHit16 rh;
      alignas(64) int valid[kPacket];
      Eigen::Vector3f dirs[kPacket];
      for (size_t p = r.begin(); p != r.end(); ++p) {
        const size_t i0 = p * kPacket;
        for (size_t k = 0; k < kPacket; ++k) {
          const size_t i = i0 + k;
          valid[k] = i < n ? -1 : 0;
          const Eigen::Vector3f d = i < n ? Eigen::Vector3f(rot * pat.dirs[i]) : Eigen::Vector3f::UnitX();
          dirs[k] = d;
          rh.ray.org_x[k] = org.x();
          rh.ray.org_y[k] = org.y();
          rh.ray.org_z[k] = org.z();
          rh.ray.dir_x[k] = d.x();
          rh.ray.dir_y[k] = d.y();
          rh.ray.dir_z[k] = d.z();
          // tnear = 0: a surface inside the minimum range still blocks the beam.
          rh.ray.tnear[k] = 0.f;
          rh.ray.tfar[k] = pat.max_range;
          rh.ray.time[k] = 0.f;
          rh.ray.mask[k] = 0xFFFFFFFFu;
          rh.ray.id[k] = static_cast<unsigned>(k);
          rh.ray.flags[k] = 0;
          rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        }
        intersect16(valid, scene, &ictx, &rh);
        for (size_t k = 0; k < kPacket; ++k) {
          const size_t i = i0 + k;
          if (i >= n || rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID) continue;
          float range = rh.ray.tfar[k];
          if (range < pat.min_range) continue;
          if (dropout > 0.0 || noisy) {
            RayRng rng(seed, view, i);
            if (dropout > 0.0 && rng.Uniform() < dropout) continue;
            if (noisy) range += static_cast<float>((a + b * range * range) * rng.Gauss());
          }
          if (quantum > 0.0 && range > 0.f) {
            // The depth along the optical axis (sensor +x) from 1/depth rounded to the quantum.
            const double cosine = pat.dirs[i].x();
            const double steps = std::round(1.0 / (double(range) * cosine * quantum));
            if (!(steps > 0.0)) continue;
            range = static_cast<float>(1.0 / (steps * quantum * cosine));
          }
          if (!(range > 0.f)) continue;
          if (flying) buf.range[i] = range;
          pts[i] = org + range * dirs[k];
          const unsigned g = rh.hit.geomID[k];
          inst[i] = g < n_obj ? static_cast<int32_t>(g + 1) : 0;
        }
      }
    });

    if (flying) FlyingPixels(pat, rot, org, seed, view, buf);
    // Floor contacts: the objects' returns just above the floor are lost.
    if (opt_.floor_gap_m > 0.0)
      for (size_t i = 0; i < n; ++i)
        if (inst[i] > 0 && pts[i].z() < static_cast<float>(opt_.floor_gap_m)) inst[i] = -1;
    size_t hits = 0;
    for (size_t i = 0; i < n; ++i) hits += inst[i] >= 0;
    compact.reserve(compact.size() + hits);
    labels.reserve(labels.size() + hits);
    for (size_t i = 0; i < n; ++i)
      if (inst[i] >= 0) {
        compact.push_back(pts[i]);
        labels.push_back(inst[i]);
      }
  }

  // Flying pixels: a camera pixel straddling a depth edge mixes the two surfaces' returns. With
  // probability flying_pixels, a pixel whose right or lower neighbour's range differs by more
  // than edge_jump_m takes a range drawn uniformly between its own and that neighbour's, along
  // its own ray. Decided on the ranges before any pixel moves (row-major image, ray order).
  void FlyingPixels(const Pattern& pat, const Eigen::Matrix3f& rot, const Eigen::Vector3f& org, uint64_t seed,
                    size_t view, Buffers& buf) const {
    const size_t w = size_t(opt_.width), h = size_t(opt_.height);
    if (pat.dirs.size() != w * h) return;
    const float jump = static_cast<float>(opt_.edge_jump_m);
    std::vector<float> moved(buf.range.size(), -1.f);
    tbb::parallel_for(size_t(0), h, [&](size_t y) {
      for (size_t x = 0; x < w; ++x) {
        const size_t i = y * w + x;
        if (buf.instance[i] < 0) continue;
        float other = -1.f;
        if (x + 1 < w && buf.instance[i + 1] >= 0 && std::abs(buf.range[i + 1] - buf.range[i]) > jump)
          other = buf.range[i + 1];
        else if (y + 1 < h && buf.instance[i + w] >= 0 && std::abs(buf.range[i + w] - buf.range[i]) > jump)
          other = buf.range[i + w];
        if (other < 0.f) continue;
        RayRng rng(seed, view ^ 0x466c79ull << 40, i);
        if (rng.Uniform() >= opt_.flying_pixels) continue;
        moved[i] = buf.range[i] + static_cast<float>(rng.Uniform()) * (other - buf.range[i]);
      }
    });
    for (size_t i = 0; i < moved.size(); ++i)
      if (moved[i] > 0.f) buf.points[i] = org + moved[i] * (rot * pat.dirs[i]);
  }

  SimulatedLaserOptions opt_;
  // The Embree device, made on the first simulation (Acquire may run on several threads), with
  // the kernels embree_isa names (Embree's own choice is the CPU's widest).
  RTCDevice Device() const {
    std::call_once(device_once_, [this] {
      const std::string isa = opt_.embree_isa == "portable" ? "sse2" : opt_.embree_isa;
      // Embree runs the kernels it is told to whatever the CPU has: a missing instruction set
      // would end in SIGILL, so it is refused here.
      if (isa != "native" && !CpuRuns(isa))
        throw StageError("embree_isa '" + isa + "': this CPU lacks the instructions of Embree's " + isa + " kernels",
                         true);
      const std::string config = isa == "native" ? "verbose=0" : "verbose=0,isa=" + isa;
      device_.reset(Embree().NewDevice(config.c_str()));
      if (!device_) throw StageError("embree: cannot create a device (" + config + ")", false);
    });
    return device_.get();
  }
  mutable std::once_flag device_once_;
  mutable DevicePtr device_;
};

}  // namespace furnihost::sensors

FURNIHOST_PLUGIN(furnihost::sensors::SimulatedLaser, "sensors.simulated_laser", "1.4.0",
                 "simulated pan-tilt laser / depth camera: Embree ray casting of catalog models "
                 "with range noise (paper Sect. IV)")
