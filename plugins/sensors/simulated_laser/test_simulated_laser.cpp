// Tests of sensors.simulated_laser, created by type name through the registry.
#include <cmath>
#include <array>
#include <map>
#include <set>

#include "furnihost/stage.hpp"
#include "test_support.hpp"

namespace furnihost {
namespace {

using nlohmann::json;

std::shared_ptr<Sensor> MakeSensor(const json& params) {
  static auto reg = testing::MakeRegistry();
  const PluginEntry* e = reg->Find("sensors.simulated_laser");
  if (!e) throw std::runtime_error("sensors.simulated_laser not found in " + testing::PluginDir());
  return reg->CreateAs<Sensor>("sensors.simulated_laser", e->params.Resolve(params, "test"));
}

// Axis-aligned box mesh [lo, hi] with 12 triangles.
Mesh Box(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  Mesh m;
  for (int i = 0; i < 8; ++i)
    m.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
  const int f[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
  for (const auto& q : f) {
    m.triangles.emplace_back(q[0], q[1], q[2]);
    m.triangles.emplace_back(q[0], q[2], q[3]);
  }
  return m;
}

// A unit cube as the catalog would give it: bottom centre at the origin.
CatalogModel UnitCube() {
  CatalogModel c;
  c.id = "cube";
  c.cls = "box";
  c.mesh = Box({-0.5f, -0.5f, 0.f}, {0.5f, 0.5f, 1.f});
  c.size = Eigen::Vector3f::Ones();
  return c;
}

Eigen::Isometry3f Pose(float x, float y, float z, float yaw_deg) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.translate(Eigen::Vector3f(x, y, z));
  t.rotate(Eigen::AngleAxisf(yaw_deg * float(M_PI) / 180.f, Eigen::Vector3f::UnitZ()));
  return t;
}

// Sensor pose at `pos`, level, with +x towards `target` (x, y only).
Eigen::Isometry3f Facing(const Eigen::Vector3f& pos, const Eigen::Vector3f& target) {
  const float yaw = std::atan2(target.y() - pos.y(), target.x() - pos.x());
  return Pose(pos.x(), pos.y(), pos.z(), yaw * 180.f / float(M_PI));
}

// Ray/box intersection in the box frame (slab method); returns the entry distance or -1.
float RayBox(const Eigen::Vector3f& o, const Eigen::Vector3f& d, const Eigen::Vector3f& lo,
             const Eigen::Vector3f& hi) {
  float t0 = 0.f, t1 = 1e9f;
  for (int a = 0; a < 3; ++a) {
    const float inv = 1.f / d[a];
    float ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 ? t0 : -1.f;
}

const Eigen::Vector3f kCubePos(2.f, 1.f, 0.f);
const float kCubeYawDeg = -30.f;
const Eigen::Vector3f kOrigin(0.f, 0.f, 1.5f);

json CubeParams() {
  return {{"angular_resolution_deg", 0.5}, {"tilt_resolution_deg", 0.5},
          {"horizontal_fov_deg", 60}, {"tilt_min_deg", -50}, {"tilt_max_deg", 10}};
}

std::vector<Scan> ScanCube(const json& params, uint64_t seed, int threads = 0) {
  static const CatalogModel cube = UnitCube();
  SensorRequest req;
  req.objects.push_back({&cube, Pose(kCubePos.x(), kCubePos.y(), 0.f, kCubeYawDeg)});
  req.poses.push_back(Facing(kOrigin, kCubePos));
  RunContext ctx;
  ctx.seed = seed;
  ctx.threads = threads;
  return MakeSensor(params)->Acquire(req, ctx);
}

// Per point: which cube face (0..5: -x +x -y +y -z +z in the cube frame) and distance to it.
struct FaceHit {
  int face;
  float dist;
};
FaceHit NearestFace(const Eigen::Vector3f& world) {
  const Eigen::Vector3f p = Pose(kCubePos.x(), kCubePos.y(), 0.f, kCubeYawDeg).inverse() * world;
  const float d[6] = {std::abs(p.x() + 0.5f), std::abs(p.x() - 0.5f), std::abs(p.y() + 0.5f),
                      std::abs(p.y() - 0.5f), std::abs(p.z()),        std::abs(p.z() - 1.f)};
  int best = 0;
  for (int i = 1; i < 6; ++i)
    if (d[i] < d[best]) best = i;
  return {best, d[best]};
}

TEST(SimulatedLaser, NoiselessCubePointsLieOnTheVisibleFaces) {
  json p = CubeParams();
  p["noise_a"] = 0.0;
  p["noise_b"] = 0.0;
  const auto scans = ScanCube(p, 1);
  ASSERT_EQ(scans.size(), 1u);
  const Scan& s = scans[0];
  ASSERT_TRUE(s.origin.has_value());
  EXPECT_LT((*s.origin - kOrigin).norm(), 1e-6f);
  ASSERT_GT(s.points.size(), 1000u);
  // From (0, 0, 1.5) the cube at (2, 1) yawed -30 deg shows its top, -x and -y faces only.
  std::map<int, int> per_face;
  for (const auto& q : s.points) {
    const FaceHit h = NearestFace(q);
    EXPECT_LT(h.dist, 1e-4f) << q.transpose();
    ++per_face[h.face];
  }
  EXPECT_GT(per_face[0], 100);
  EXPECT_GT(per_face[2], 100);
  EXPECT_GT(per_face[5], 100);
  EXPECT_EQ(per_face[1] + per_face[3] + per_face[4], 0);
  ASSERT_EQ(s.attributes.at("instance").size(), s.points.size());
  for (int32_t i : s.attributes.at("instance")) EXPECT_EQ(i, 1);
  ASSERT_EQ(s.truth.size(), 1u);
  EXPECT_EQ(s.truth[0].cls, "box");
  EXPECT_EQ(s.truth[0].model, "cube");
  EXPECT_LT((s.truth[0].center - Eigen::Vector3f(2.f, 1.f, 0.5f)).norm(), 1e-5f);
  const float fp = std::cos(30.f * float(M_PI) / 180.f) + std::sin(30.f * float(M_PI) / 180.f);
  EXPECT_LT((s.truth[0].size - Eigen::Vector3f(fp, fp, 1.f)).norm(), 1e-5f);
  ASSERT_TRUE(s.truth[0].yaw.has_value());
  EXPECT_NEAR(*s.truth[0].yaw, kCubeYawDeg * float(M_PI) / 180.f, 1e-5f);
}

// A scan is the same on every CPU. Embree takes the CPU's widest kernels unless told otherwise,
// and AVX2's and AVX-512's fused multiply-adds round the hit distances differently from the
// baseline's: a CPU with AVX2 alone got other points than one with AVX-512, then other training
// views, other models and another `furnihost gap` table. By default every ray goes through the
// x86-64 baseline's (SSE2) kernels, which every such CPU has: what a CPU with SSE2 alone computes.
TEST(SimulatedLaser, SameScanOnEveryCpu) {
  auto points = [](const json& extra) {
    json p = CubeParams();
    p.update(extra);
    const auto scans = ScanCube(p, 7);
    EXPECT_EQ(scans.size(), 1u);
    return scans.empty() ? Points{} : scans[0].points;
  };
  auto same = [](const Points& a, const Points& b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](const auto& x, const auto& y) {
             return x.x() == y.x() && x.y() == y.y() && x.z() == y.z();
           });
  };
  const Points dflt = points(json::object());
  ASSERT_GT(dflt.size(), 1000u);
  EXPECT_TRUE(same(dflt, points({{"embree_isa", "portable"}})));
  EXPECT_TRUE(same(dflt, points({{"embree_isa", "sse2"}}))) << "the default scan is not a baseline CPU's";
  // The CPU's own kernels: the same rays, hits within a few rounding steps of the portable ones
  // (noise is drawn per ray, so the points pair up in order).
  const Points native = points({{"embree_isa", "native"}});
  ASSERT_EQ(native.size(), dflt.size());
  float worst = 0.f;
  for (size_t i = 0; i < dflt.size(); ++i) worst = std::max(worst, (native[i] - dflt[i]).norm());
  EXPECT_LT(worst, 1e-4f);
}

TEST(SimulatedLaser, RangeNoiseMatchesTheModel) {
  json p = CubeParams();
  p["noise_a"] = 0.01;
  p["noise_b"] = 0.002;
  const auto scans = ScanCube(p, 3);
  const Scan& s = scans.at(0);
  ASSERT_GT(s.points.size(), 1000u);
  const Eigen::Isometry3f inv = Pose(kCubePos.x(), kCubePos.y(), 0.f, kCubeYawDeg).inverse();
  const Eigen::Vector3f o = inv * kOrigin;
  double sum = 0, sum2 = 0;
  int n = 0;
  for (const auto& q : s.points) {
    const Eigen::Vector3f pq = inv * q;
    const Eigen::Vector3f d = (pq - o).normalized();
    const float t = RayBox(o, d, {-0.5f, -0.5f, 0.f}, {0.5f, 0.5f, 1.f});
    ASSERT_GT(t, 0.f);
    const double sigma = 0.01 + 0.002 * t * t;
    const double z = ((pq - o).norm() - t) / sigma;
    EXPECT_LT(std::abs(z), 6.0);  // 6 sigma: a false alarm every ~10^9 points
    sum += z;
    sum2 += z * z;
    ++n;
  }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  // Normalised residuals ~ N(0, 1); n > 1000 keeps the bounds > 5 standard errors wide.
  EXPECT_LT(std::abs(mean), 0.15);
  EXPECT_NEAR(sd, 1.0, 0.1);
}

TEST(SimulatedLaser, DeterministicForASeedAndAnyThreadCount) {
  json p = CubeParams();
  p["dropout"] = 0.2;
  const auto a = ScanCube(p, 11, 1);
  const auto b = ScanCube(p, 11, 2);
  const auto c = ScanCube(p, 11, 0);
  const auto d = ScanCube(p, 12, 2);
  ASSERT_EQ(a[0].points.size(), b[0].points.size());
  ASSERT_EQ(a[0].points.size(), c[0].points.size());
  for (size_t i = 0; i < a[0].points.size(); ++i) {
    ASSERT_EQ(a[0].points[i], b[0].points[i]) << i;
    ASSERT_EQ(a[0].points[i], c[0].points[i]) << i;
  }
  bool differs = a[0].points.size() != d[0].points.size();
  for (size_t i = 0; !differs && i < a[0].points.size(); ++i) differs = a[0].points[i] != d[0].points[i];
  EXPECT_TRUE(differs) << "seed 12 gave the same scan as seed 11";
}

TEST(SimulatedLaser, DropoutRemovesTheGivenShare) {
  json p = CubeParams();
  const size_t full = ScanCube(p, 5)[0].points.size();
  p["dropout"] = 0.3;
  const size_t kept = ScanCube(p, 5)[0].points.size();
  ASSERT_GT(full, 2000u);
  // Binomial: sd = sqrt(n 0.3 0.7) < 1.5 % of n for n > 2000; 4 % is > 2.5 sd.
  EXPECT_NEAR(double(kept) / full, 0.7, 0.04);
}

TEST(SimulatedLaser, DefaultViewsCircleTheObject) {
  static const CatalogModel cube = UnitCube();
  SensorRequest req;
  req.objects.push_back({&cube, Pose(3.f, -1.f, 0.f, 0.f)});
  RunContext ctx;
  const auto scans = MakeSensor({{"angular_resolution_deg", 1.0}, {"tilt_resolution_deg", 1.0}})
                         ->Acquire(req, ctx);
  ASSERT_EQ(scans.size(), 16u);
  std::set<int> octants;
  for (const auto& s : scans) {
    ASSERT_TRUE(s.origin);
    const Eigen::Vector3f o = *s.origin;
    EXPECT_NEAR(o.z(), 1.5f, 1e-5f);
    EXPECT_NEAR(std::hypot(o.x() - 3.f, o.y() + 1.f), 2.f, 1e-4f);
    octants.insert(int(std::floor((std::atan2(o.y() + 1.f, o.x() - 3.f) + M_PI) / (M_PI / 4))) % 8);
    EXPECT_GT(s.points.size(), 100u);  // the cube is in front of every view
    ASSERT_EQ(s.truth.size(), 1u);
    EXPECT_LT((s.truth[0].center - Eigen::Vector3f(3.f, -1.f, 0.5f)).norm(), 1e-5f);
    EXPECT_LT((s.truth[0].size - Eigen::Vector3f::Ones()).norm(), 1e-5f);
  }
  EXPECT_EQ(octants.size(), 8u);
}

TEST(SimulatedLaser, FusedViewsSeeEverySideFromTheFirstCastsOrigin) {
  // fuse = 4: each default view is the union of 4 casts 90 degrees apart, so it holds points on
  // all four side faces of the cube (a single view from 2 m sees at most two), and keeps the
  // origin of its own first cast (the viewing frame the voter learns in).
  static const CatalogModel cube = UnitCube();
  SensorRequest req;
  req.objects.push_back({&cube, Pose(3.f, -1.f, 0.f, 0.f)});
  RunContext ctx;
  json p = {{"angular_resolution_deg", 1.0}, {"tilt_resolution_deg", 1.0}, {"views", 4},
            {"noise_a", 0.0}, {"noise_b", 0.0}};
  const auto single = MakeSensor(p)->Acquire(req, ctx);
  p["fuse"] = 4;
  const auto fused = MakeSensor(p)->Acquire(req, ctx);
  ASSERT_EQ(single.size(), 4u);
  ASSERT_EQ(fused.size(), 4u);
  auto faces = [](const Scan& s) {
    std::set<int> seen;  // 0: x = 2.5, 1: x = 3.5, 2: y = -1.5, 3: y = -0.5
    for (const auto& q : s.points) {
      if (q.z() < 0.05f || q.z() > 0.95f) continue;  // side faces only
      if (std::fabs(q.x() - 2.5f) < 1e-3f) seen.insert(0);
      if (std::fabs(q.x() - 3.5f) < 1e-3f) seen.insert(1);
      if (std::fabs(q.y() + 1.5f) < 1e-3f) seen.insert(2);
      if (std::fabs(q.y() + 0.5f) < 1e-3f) seen.insert(3);
    }
    return seen.size();
  };
  for (size_t v = 0; v < 4; ++v) {
    ASSERT_TRUE(single[v].origin && fused[v].origin);
    EXPECT_LT((*single[v].origin - *fused[v].origin).norm(), 1e-6f);
    EXPECT_LE(faces(single[v]), 2u);
    EXPECT_EQ(faces(fused[v]), 4u);
    EXPECT_GT(fused[v].points.size(), single[v].points.size());
    EXPECT_EQ(fused[v].attributes.at("instance").size(), fused[v].points.size());
  }
}

TEST(SimulatedLaser, NoiseDrawsScanEachViewAgainWithItsOwnNoise) {
  // noise_draws = 3: each default view three times from its pose; the first draw is the scan of
  // noise_draws = 1, the others differ from it and from each other only in their noise.
  static const CatalogModel cube = UnitCube();
  SensorRequest req;
  req.objects.push_back({&cube, Pose(3.f, -1.f, 0.f, 0.f)});
  RunContext ctx;
  json p = {{"angular_resolution_deg", 1.0}, {"tilt_resolution_deg", 1.0}, {"views", 4}};
  const auto one = MakeSensor(p)->Acquire(req, ctx);
  p["noise_draws"] = 3;
  const auto three = MakeSensor(p)->Acquire(req, ctx);
  ASSERT_EQ(one.size(), 4u);
  ASSERT_EQ(three.size(), 12u);
  for (size_t v = 0; v < 4; ++v) {
    const Scan& first = three[3 * v];
    ASSERT_EQ(first.points.size(), one[v].points.size());
    for (size_t i = 0; i < first.points.size(); ++i) ASSERT_EQ(first.points[i], one[v].points[i]) << v << " " << i;
    for (size_t d = 1; d < 3; ++d) {
      const Scan& again = three[3 * v + d];
      ASSERT_TRUE(again.origin && one[v].origin);
      EXPECT_LT((*again.origin - *one[v].origin).norm(), 1e-6f);
      // The same rays hit (no dropout): the same count, other ranges.
      ASSERT_EQ(again.points.size(), first.points.size());
      EXPECT_NE(again.points, first.points);
      EXPECT_NE(again.points, three[3 * v + 3 - d].points);
      EXPECT_NE(again.source.find("noise draw " + std::to_string(d + 1) + "/3"), std::string::npos) << again.source;
    }
  }
}

TEST(SimulatedLaser, DepthCameraImageGeometryAndRanges) {
  // A 10 m x 10 m wall (extra geometry, no truth) 3 m in front of a level camera.
  SensorRequest req;
  req.extra = Box({3.f, -5.f, -5.f}, {3.1f, 5.f, 5.f});
  req.poses.push_back(Eigen::Isometry3f::Identity());
  RunContext ctx;
  json p = {{"pattern", "depth_camera"}, {"width", 64}, {"height", 48}, {"focal_px", 52.5},
            {"noise_a", 0.0}, {"noise_b", 0.0}};
  const auto s = MakeSensor(p)->Acquire(req, ctx).at(0);
  ASSERT_EQ(s.points.size(), 64u * 48u);
  EXPECT_TRUE(s.truth.empty());
  for (const auto& q : s.points) EXPECT_NEAR(q.x(), 3.f, 1e-4f);
  // Row-major from the top-left pixel: left = +y, up = +z.
  const Eigen::Vector3f first = s.points.front(), last = s.points.back();
  EXPECT_NEAR(first.y(), 3.f * (32.f - 0.5f) / 52.5f, 1e-3f);
  EXPECT_NEAR(first.z(), 3.f * (24.f - 0.5f) / 52.5f, 1e-3f);
  EXPECT_NEAR(last.y(), -first.y(), 1e-3f);
  EXPECT_NEAR(last.z(), -first.z(), 1e-3f);
  for (int32_t i : s.attributes.at("instance")) EXPECT_EQ(i, 0);

  // Beyond camera_max_range_m (4.5 m by default): nothing.
  SensorRequest far = req;
  far.extra = Box({5.f, -5.f, -5.f}, {5.1f, 5.f, 5.f});
  EXPECT_TRUE(MakeSensor(p)->Acquire(far, ctx).at(0).points.empty());
}

TEST(SimulatedLaser, SurfaceInsideMinimumRangeBlocksTheBeam) {
  // A plate 3 cm in front of the sensor (every beam of the sweep meets it within 9 cm, under
  // the 10 cm minimum range) hides the cube and yields no returns itself.
  SensorRequest req;
  static const CatalogModel cube = UnitCube();
  req.objects.push_back({&cube, Pose(2.f, 0.f, 0.f, 0.f)});
  req.extra = Box({0.03f, -3.f, -3.f}, {0.04f, 3.f, 3.f});
  req.poses.push_back(Pose(0.f, 0.f, 0.5f, 0.f));
  RunContext ctx;
  const auto s = MakeSensor({{"horizontal_fov_deg", 90}})->Acquire(req, ctx).at(0);
  EXPECT_TRUE(s.points.empty()) << s.points.size() << " points";
}

TEST(SimulatedLaser, VoxelGridKeepsOnePointPerWorldVoxel) {
  using Cell = std::tuple<int, int, int>;
  auto cell = [](const Eigen::Vector3f& q) {
    return Cell(int(std::floor(q.x() / 0.05f)), int(std::floor(q.y() / 0.05f)), int(std::floor(q.z() / 0.05f)));
  };
  json p = CubeParams();
  const Scan dense = ScanCube(p, 9)[0];
  p["voxel_m"] = 0.05;
  const Scan s = ScanCube(p, 9)[0];
  ASSERT_GT(s.points.size(), 50u);
  EXPECT_LT(s.points.size(), dense.points.size() / 2);
  EXPECT_EQ(s.attributes.at("instance").size(), s.points.size());
  // Same seed, same rays: one centroid per cell the dense scan occupies, in the same cells
  // (a centroid stays inside its convex cell), the grid anchored at the world origin.
  std::set<Cell> dense_cells, cells;
  for (const auto& q : dense.points) dense_cells.insert(cell(q));
  for (const auto& q : s.points) cells.insert(cell(q));
  EXPECT_EQ(cells.size(), s.points.size()) << "two points fell into the same voxel";
  EXPECT_EQ(cells, dense_cells);
}

TEST(SimulatedLaser, RefusesFilesAndInconsistentParameters) {
  SensorRequest req;
  req.path = "scan.pcd";
  RunContext ctx;
  EXPECT_THROW(MakeSensor(json::object())->Acquire(req, ctx), StageError);
  EXPECT_ANY_THROW(MakeSensor({{"tilt_min_deg", 20}, {"tilt_max_deg", -20}}));
  EXPECT_ANY_THROW(MakeSensor({{"pattern", "sonar"}}));
  // Nothing to scan.
  SensorRequest empty;
  EXPECT_THROW(MakeSensor(json::object())->Acquire(empty, ctx), StageError);
}


// ---- presets and the scans' artefacts --------------------------------------------------------

const ParamSchema& Schema() {
  static auto reg = testing::MakeRegistry();
  return reg->Find("sensors.simulated_laser")->params;
}

TEST(SimulatedLaser, PresetFillsOnlyWhatTheConfigLeavesOut) {
  const json r = Schema().Resolve({{"preset", "room_reconstruction"}, {"voxel_m", 0.03}}, "g.json:/stages/sim/params");
  EXPECT_EQ(r.at("pattern"), "depth_camera");
  EXPECT_EQ(r.at("fuse"), 8);
  EXPECT_DOUBLE_EQ(r.at("floor_gap_m").get<double>(), 0.03);
  EXPECT_DOUBLE_EQ(r.at("voxel_m").get<double>(), 0.03);  // given: the preset's 0.02 does not apply
  const json cam = Schema().Resolve({{"preset", "depth_camera"}}, "");
  EXPECT_GT(cam.at("disparity_quantum").get<double>(), 0.0);
  EXPECT_GT(cam.at("flying_pixels").get<double>(), 0.0);
  // No preset: the declared defaults (the paper's laser).
  const json none = Schema().Resolve({{"preset", "none"}}, "");
  EXPECT_EQ(none.at("pattern"), "pan_tilt");
  EXPECT_EQ(none.at("fuse"), 1);
  // A config's own preset, and one of its values out of range: named.
  const json own = Schema().Resolve({{"preset", "mine"}, {"presets", {{"mine", {{"views", 3}}}}}}, "");
  EXPECT_EQ(own.at("views"), 3);
  try {
    Schema().Resolve({{"preset", "kinect2"}}, "g.json:/stages/sim/params");
    FAIL() << "an unknown preset was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("g.json:/stages/sim/params/preset: unknown preset \"kinect2\"; valid: none, "),
              std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("room_reconstruction"), std::string::npos) << e.what();
  }
  try {
    Schema().Resolve({{"preset", "mine"}, {"presets", {{"mine", {{"views", -3}}}}}}, "");
    FAIL() << "a preset's bad value was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("views"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Schema().Resolve({{"preset", "mine"}, {"presets", {{"mine", {{"colour", 3}}}}}}, ""), InputError);
  EXPECT_THROW(Schema().Resolve({{"preset", 7}}, ""), InputError);
  // The camera's artefacts need the camera.
  EXPECT_ANY_THROW(MakeSensor({{"flying_pixels", 0.5}}));
  EXPECT_ANY_THROW(MakeSensor({{"disparity_quantum", 0.003}}));
}

// A wall (2 x 4 m, 1 cm thick) with its front at x = 3, and optionally a panel in front of it
// (x 2.00-2.02), seen by a level camera at (0, 0, 1.5) looking along +x.
std::vector<Scan> ScanWall(json params, bool panel, uint64_t seed = 1) {
  static CatalogModel wall, front;
  wall.id = "wall";
  wall.cls = "wall";
  wall.mesh = Box({3.f, -2.f, 0.f}, {3.01f, 2.f, 3.f});
  front.id = "panel";
  front.cls = "panel";
  front.mesh = Box({2.f, -0.4f, 1.f}, {2.02f, 0.4f, 2.f});
  SensorRequest req;
  req.objects.push_back({&wall, Eigen::Isometry3f::Identity()});
  if (panel) req.objects.push_back({&front, Eigen::Isometry3f::Identity()});
  req.poses.push_back(Pose(0.f, 0.f, 1.5f, 0.f));
  params["pattern"] = "depth_camera";
  params["width"] = 160;
  params["height"] = 120;
  params["focal_px"] = 100.0;
  params["noise_a"] = 0.0;
  params["noise_b"] = 0.0;
  RunContext ctx;
  ctx.seed = seed;
  return MakeSensor(params)->Acquire(req, ctx);
}

TEST(SimulatedLaser, DisparityQuantisationPutsDepthsOnItsSteps) {
  const double q = 0.01;  // 1/depth in steps of 0.01 /m: 9 cm apart at 3 m
  const Scan exact = ScanWall(json::object(), false)[0];
  const Scan s = ScanWall({{"disparity_quantum", q}}, false)[0];
  ASSERT_GT(s.points.size(), 5000u);
  ASSERT_EQ(s.points.size(), exact.points.size());
  std::set<long> steps;
  for (size_t i = 0; i < s.points.size(); ++i) {
    const double depth = s.points[i].x();  // the optical axis is world +x
    const double k = 1.0 / (depth * q);
    EXPECT_NEAR(k, std::round(k), 1e-3) << depth;
    steps.insert(std::lround(k));
    // The nearest step to the true depth, along the same ray.
    EXPECT_NEAR(depth, 1.0 / (std::round(1.0 / (exact.points[i].x() * q)) * q), 1e-4);
    EXPECT_LT((s.points[i] - s.origin.value()).normalized().dot((exact.points[i] - s.origin.value()).normalized()), 1.0 + 1e-6);
    EXPECT_GT((s.points[i] - s.origin.value()).normalized().dot((exact.points[i] - s.origin.value()).normalized()), 1.0 - 1e-6);
  }
  EXPECT_EQ(steps.size(), 1u);  // a flat wall facing the camera: one depth (3.0 m -> 1/(33 q) = 3.03 m)
}

TEST(SimulatedLaser, FlyingPixelsLieBetweenTheSurfacesOfAnEdge) {
  auto between = [](const Scan& s) {
    int n = 0;
    for (const auto& p : s.points) n += p.x() > 2.05f && p.x() < 2.97f;
    return n;
  };
  const Scan clean = ScanWall(json::object(), true)[0];
  EXPECT_EQ(between(clean), 0);
  const Scan half = ScanWall({{"flying_pixels", 0.5}}, true)[0];
  const Scan all = ScanWall({{"flying_pixels", 1.0}}, true)[0];
  ASSERT_EQ(all.points.size(), clean.points.size());  // pixels move, none are lost
  // The panel's outline (0.8 x 1 m at 2 m, 100 px focal: ~40 + 50 px a side) gives ~180 edge
  // pixels on each side of the edge; at 0.5 about half of them fly.
  EXPECT_GT(between(all), 150);
  EXPECT_GT(between(half), between(all) / 4);
  EXPECT_LT(between(half), 3 * between(all) / 4);
  // A flying pixel stays on its own ray.
  for (size_t i = 0; i < all.points.size(); ++i) {
    const Eigen::Vector3f a = (all.points[i] - *all.origin).normalized(), c = (clean.points[i] - *clean.origin).normalized();
    ASSERT_GT(a.dot(c), 1.f - 1e-5f) << i;
  }
}

TEST(SimulatedLaser, FloorGapAndHolesRemoveWhatAReconstructionMisses) {
  json p = CubeParams();
  p["noise_a"] = 0.0;
  p["noise_b"] = 0.0;
  const Scan full = ScanCube(p, 4)[0];
  float lowest = 1e9f;
  for (const auto& q : full.points) lowest = std::min(lowest, q.z());
  ASSERT_LT(lowest, 0.05f);
  p["floor_gap_m"] = 0.1;
  const Scan gap = ScanCube(p, 4)[0];
  ASSERT_GT(gap.points.size(), 1000u);
  for (const auto& q : gap.points) ASSERT_GE(q.z(), 0.1f);
  // Holes: whole 20 cm cells go, about the given share of them; the others keep every point.
  p["floor_gap_m"] = 0.0;
  p["holes"] = 0.3;
  p["hole_size_m"] = 0.2;
  const Scan holed = ScanCube(p, 4)[0];
  using Cell = std::array<long, 3>;
  auto cell = [](const Eigen::Vector3f& q) {
    return Cell{long(std::floor(q.x() / 0.2)), long(std::floor(q.y() / 0.2)), long(std::floor(q.z() / 0.2))};
  };
  std::map<Cell, int> before, after;
  for (const auto& q : full.points) ++before[cell(q)];
  for (const auto& q : holed.points) ++after[cell(q)];
  int lost = 0;
  for (const auto& [c, n] : before) {
    const auto it = after.find(c);
    if (it == after.end()) ++lost;
    else EXPECT_EQ(it->second, n);  // a cell is kept whole or lost whole
  }
  EXPECT_EQ(after.size() + size_t(lost), before.size());
  ASSERT_GT(before.size(), 40u);
  EXPECT_GT(lost, int(before.size()) / 10);
  EXPECT_LT(lost, int(before.size()) / 2);
  // Another view of the same walk loses other cells (holes are drawn per view).
  EXPECT_NE(ScanCube(p, 5)[0].points.size(), holed.points.size());
}

TEST(SimulatedLaser, PresetsGiveTheirTrainingViews) {
  static const CatalogModel cube = UnitCube();
  SensorRequest req;
  req.objects.push_back({&cube, Pose(0.f, 0.f, 0.f, 0.f)});
  RunContext ctx;
  ctx.seed = 7;
  const json room = Schema().Resolve({{"preset", "room_reconstruction"}}, "");
  const auto views = MakeSensor(room)->Acquire(req, ctx);
  ASSERT_EQ(views.size(), 4u);
  for (const Scan& s : views) {
    ASSERT_GT(s.points.size(), 300u);
    float lo = 1e9f, hi = -1e9f;
    for (const auto& q : s.points) lo = std::min(lo, q.z()), hi = std::max(hi, q.z());
    EXPECT_GE(lo, 0.03f);  // floor contacts missing
    EXPECT_GT(hi, 0.95f);  // the top is seen
    // Fused around the object: points on all four sides.
    int sides[4] = {0, 0, 0, 0};
    for (const auto& q : s.points) {
      if (q.x() < -0.49f) ++sides[0];
      if (q.x() > 0.49f) ++sides[1];
      if (q.y() < -0.49f) ++sides[2];
      if (q.y() > 0.49f) ++sides[3];
    }
    for (int k : sides) EXPECT_GT(k, 20);
  }
  const json cam = Schema().Resolve({{"preset", "depth_camera"}, {"views", 2}}, "");
  const auto frames = MakeSensor(cam)->Acquire(req, ctx);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_GT(frames[0].points.size(), 2000u);
}

}  // namespace
}  // namespace furnihost
