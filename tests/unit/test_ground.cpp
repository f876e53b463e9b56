// The ground model (level, plane, height map), scan frames (up axes, transforms, global
// shift) and the box IoU of the ScanNet rule.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <set>

#include "furnihost/host/evaluation.hpp"
#include "furnihost/host/frame.hpp"
#include "furnihost/host/config.hpp"
#include "furnihost/host/ground_estimation.hpp"
#include "furnihost/host/io.hpp"

namespace fs = std::filesystem;
using namespace furnihost;

namespace {

// A room 5 x 4 m whose floor follows `floor(x, y)` (1 cm noise), with a table top (0.75 m
// above the floor, 1 x 1 m), a large box top (0.4 m, 1.5 x 1.5 m) hiding the floor under it, and
// a wall: the floor points are drawn everywhere except under the box. `dense` multiplies every
// count (a dense laser scan of the same room).
Points Room(const std::function<float(float, float)>& floor, uint32_t seed = 3, int dense = 1) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::normal_distribution<float> noise(0.f, 0.01f);
  Points p;
  for (int i = 0; i < 40000 * dense; ++i) {
    const float x = 5.f * u(rng), y = 4.f * u(rng);
    if (x > 3.f && x < 4.5f && y > 2.f && y < 3.5f) continue;  // under the box
    p.emplace_back(x, y, floor(x, y) + noise(rng));
  }
  for (int i = 0; i < 6000 * dense; ++i) {
    const float x = 1.f + u(rng), y = 1.f + u(rng);
    p.emplace_back(x, y, floor(x, y) + 0.75f);
  }
  for (int i = 0; i < 9000 * dense; ++i) {
    const float x = 3.f + 1.5f * u(rng), y = 2.f + 1.5f * u(rng);
    p.emplace_back(x, y, floor(x, y) + 0.4f);
  }
  for (int i = 0; i < 8000 * dense; ++i) p.emplace_back(0.f, 4.f * u(rng), floor(0.f, 2.f) + 2.5f * u(rng));
  return p;
}

GroundOptions Kind(const std::string& k) {
  GroundOptions o;
  o.kind = k;
  return o;
}

}  // namespace

// A level floor 1.3 m below the origin (a camera's frame): every kind finds it within 1.5 cm
// (1 cm range noise; the height map takes a cell's low 20th percentile), table and box tops are well above it, and a fixed ground is taken as given.
TEST(Ground, LevelFloorBelowTheOrigin) {
  const Points room = Room([](float, float) { return -1.3f; });
  for (const char* k : {"auto", "level", "plane", "height_map"}) {
    const GroundModel g = EstimateGround(room, Kind(k));
    for (float x : {0.5f, 2.5f, 3.7f, 4.8f})
      for (float y : {0.3f, 2.7f, 3.8f}) EXPECT_NEAR(g.HeightAt(x, y), -1.3f, 0.015f) << k << " " << x << "," << y;
    EXPECT_NEAR(g.Above(Eigen::Vector3f(1.5f, 1.5f, -0.55f)), 0.75f, 0.01f) << k;
    EXPECT_EQ(g.source, "estimated");
  }
  EXPECT_EQ(EstimateGround(room, Kind("auto")).kind, GroundKind::HeightMap);
  GroundOptions fixed = Kind("fixed");
  fixed.z_m = -1.25f;
  const GroundModel f = EstimateGround(room, fixed);
  EXPECT_EQ(f.kind, GroundKind::Level);
  EXPECT_EQ(f.source, "fixed");
  EXPECT_FLOAT_EQ(f.HeightAt(7.f, -3.f), -1.25f);
}

// A tilted floor (0.3 m over 5 m): level is wrong at one end, the plane and the height map
// follow it; deterministic.
TEST(Ground, TiltedFloor) {
  auto tilt = [](float x, float) { return -0.1f + 0.06f * x; };
  const Points room = Room(tilt);
  const GroundModel level = EstimateGround(room, Kind("level"));
  EXPECT_GT(std::max(std::abs(level.HeightAt(0, 0) - tilt(0, 0)), std::abs(level.HeightAt(5, 0) - tilt(5, 0))), 0.1f);
  for (const char* k : {"plane", "height_map"}) {
    const GroundModel g = EstimateGround(room, Kind(k));
    for (float x : {0.2f, 2.5f, 3.7f, 4.8f})
      for (float y : {0.2f, 2.7f, 3.8f}) EXPECT_NEAR(g.HeightAt(x, y), tilt(x, y), 0.015f) << k << " " << x << "," << y;
  }
  EXPECT_EQ(EstimateGround(room, Kind("height_map")).heights, EstimateGround(room, Kind("height_map")).heights);
}

// A warped floor (a reconstruction that bends 0.4 m across the room, as ScanNet's scene0001_00
// does): no plane fits it, the height map does within 2 cm, also under the box where the floor
// is hidden (filled from its neighbours), and it does not climb onto the box or the table.
TEST(Ground, WarpedFloorHeightMap) {
  auto warp = [](float x, float y) { return 0.4f * (x / 5.f) * (x / 5.f) + 0.05f * std::sin(y); };
  const Points room = Room(warp);
  const GroundModel g = EstimateGround(room, Kind("height_map"));
  ASSERT_EQ(g.kind, GroundKind::HeightMap);
  float worst = 0.f;
  for (float x = 0.2f; x < 4.9f; x += 0.3f)
    for (float y = 0.2f; y < 3.9f; y += 0.3f) {
      const float e = std::abs(g.HeightAt(x, y) - warp(x, y));
      EXPECT_LT(e, 0.03f) << x << ", " << y;
      worst = std::max(worst, e);
    }
  EXPECT_NEAR(g.HeightAt(3.75f, 2.75f), warp(3.75f, 2.75f), 0.03f);  // under the box
  EXPECT_NEAR(g.HeightAt(1.5f, 1.5f), warp(1.5f, 1.5f), 0.02f);      // under the table
  const GroundModel plane = EstimateGround(room, Kind("plane"));
  float plane_worst = 0.f;
  for (float x = 0.2f; x < 4.9f; x += 0.3f) plane_worst = std::max(plane_worst, std::abs(plane.HeightAt(x, 2.f) - warp(x, 2.f)));
  EXPECT_GT(plane_worst, 0.05f);
  EXPECT_GT(g.observed_area_m2, 10.f);
  EXPECT_LT(g.observed_area_m2, 20.f - 2.25f + 1.f);  // the box's footprint is not seen floor
}

// A dense scan of the warped room (0.6M points, more than the height map's 300k sample): the map
// from the stride sample follows the floor as closely as the sparse scan's map does.
TEST(Ground, DenseScanMapsFromASample) {
  auto warp = [](float x, float y) { return 0.4f * (x / 5.f) * (x / 5.f) + 0.05f * std::sin(y); };
  const Points room = Room(warp, 5, 10);
  ASSERT_GT(room.size(), 500000u);
  const GroundModel g = EstimateGround(room, Kind("height_map"));
  ASSERT_EQ(g.kind, GroundKind::HeightMap);
  for (float x = 0.2f; x < 4.9f; x += 0.3f)
    for (float y = 0.2f; y < 3.9f; y += 0.3f) EXPECT_NEAR(g.HeightAt(x, y), warp(x, y), 0.03f) << x << ", " << y;
  EXPECT_NEAR(g.HeightAt(1.5f, 1.5f), warp(1.5f, 1.5f), 0.02f);  // under the table
  EXPECT_GT(g.observed_area_m2, 10.f);
  EXPECT_LT(g.observed_area_m2, 20.f - 2.25f + 1.f);
}

// Degenerate input: nothing, one point, all points equal, NaN: a level ground, no crash.
TEST(Ground, DegenerateClouds) {
  EXPECT_EQ(EstimateGround({}, Kind("auto")).HeightAt(0, 0), 0.f);
  EXPECT_EQ(EstimateGround({Eigen::Vector3f(1, 2, 3)}, Kind("auto")).HeightAt(0, 0), 3.f);
  const Points same(100000, Eigen::Vector3f(0.5f, 0.5f, -1.f));
  EXPECT_NEAR(EstimateGround(same, Kind("auto")).HeightAt(9, 9), -1.f, 1e-5f);
  const Points nan(10, Eigen::Vector3f(NAN, 0, 0));
  EXPECT_EQ(EstimateGround(nan, Kind("height_map")).HeightAt(0, 0), 0.f);
}

TEST(Ground, OptionsAreChecked) {
  EXPECT_THROW(GroundOptionsFromJson({{"kind", "q"}}, "g.json:/ground"), InputError);
  EXPECT_THROW(GroundOptionsFromJson({{"cell_m", 0}}, "g.json:/ground"), InputError);
  EXPECT_THROW(GroundOptionsFromJson({{"nope", 1}}, "g.json:/ground"), InputError);
  try {
    GroundOptionsFromJson({{"kind", "q"}}, "g.json:/ground");
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("g.json:/ground/kind"), std::string::npos) << e.what();
  }
  EXPECT_EQ(GroundOptionsFromJson({{"kind", "fixed"}, {"z_m", -1.2}}, "x").z_m, -1.2f);
  // The binding's defaults are the struct's, and the resolved section names its members.
  const GroundOptions d = GroundOptionsFromJson(nullptr, "x");
  EXPECT_EQ(ToJson(d), ToJson(GroundOptions{}));
  EXPECT_EQ(GroundOptionsFromJson(ToJson(d), "x").cell_m, GroundOptions{}.cell_m);
  // Check() reports at the command line's option as at a config's pointer.
  GroundOptions bad;
  bad.step_m = 0;
  try {
    bad.Check("--ground: ");
    ADD_FAILURE() << "step_m 0 accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "--ground: step_m: must be above 0");
  }
}

// Every number of the host's sections has a unit ("1" for a ratio), as `furnihost plugins` lists it.
TEST(Ground, HostSectionsDeclareEveryParameterOnce) {
  std::set<std::string> sections;
  for (const auto& [name, schema] : HostSectionSchemas()) {
    sections.insert(name);
    for (const auto& s : schema.Specs()) {
      if (s.type == ParamType::Number || s.type == ParamType::Int) {
        EXPECT_FALSE(s.unit.empty()) << name << "." << s.name;
      }
    }
  }
  EXPECT_EQ(sections, (std::set<std::string>{"ground", "frame", "ensemble", "calibration"}));
}

// Up axes keep frames right-handed; the optical frame (-y up) becomes ROS's camera_link axes.
TEST(Frame, UpAxisRotations) {
  for (const char* a : {"+x", "-x", "+y", "-y", "+z", "-z"}) {
    const Eigen::Matrix3d r = UpAxisRotation(a, "--up");
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12) << a;
    EXPECT_TRUE((r * r.transpose()).isIdentity(1e-12)) << a;
  }
  const Eigen::Matrix3d opt = UpAxisRotation("-y", "--up");
  EXPECT_TRUE((opt * Eigen::Vector3d(0, -1, 0)).isApprox(Eigen::Vector3d(0, 0, 1)));  // up
  EXPECT_TRUE((opt * Eigen::Vector3d(0, 0, 1)).isApprox(Eigen::Vector3d(1, 0, 0)));   // forward
  EXPECT_TRUE(UpAxisRotation("+z", "--up").isIdentity());
  try {
    UpAxisRotation("q", "--up");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--up"), std::string::npos);
  }
}

TEST(Frame, TransformsAreParsedAndChecked) {
  const Eigen::Isometry3d t = ParseTransform("1,2,3,0,0,1.5707963267948966", "--transform");
  EXPECT_TRUE((t * Eigen::Vector3d(1, 0, 0)).isApprox(Eigen::Vector3d(1, 3, 3), 1e-9));
  const Eigen::Isometry3d m = ParseTransform("0,-1,0,1, 1,0,0,2, 0,0,1,3, 0,0,0,1", "--transform");
  EXPECT_TRUE((m * Eigen::Vector3d(1, 0, 0)).isApprox(Eigen::Vector3d(1, 3, 3), 1e-9));
  for (const char* bad : {"1,2,3", "0,0,0,0, 0,0,0,0, 0,0,0,0, 0,0,0,1", "2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1",
                          "-1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1", "nan,0,0,0,0,0", "1,0,0,0, 0,1,0,0, 0,0,1,0, 1,0,0,1"}) {
    try {
      ParseTransform(bad, "--transform");
      FAIL() << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--transform"), std::string::npos) << e.what();
    }
  }
}

// A room in a camera's optical frame (y down): --up -y turns it z up; --up auto finds the same
// up axis from the floor; the points come back to the file frame exactly.
TEST(Frame, WorkingFrameOfAnOpticalScan) {
  const Points room = Room([](float, float) { return 0.f; });
  Scan s;
  for (const auto& p : room) s.points.emplace_back(p.x(), -p.z() + 1.4f, p.y());  // optical: y down
  s.origin = Eigen::Vector3f::Zero();
  Scan a = s, b = s;
  FrameOptions up;
  up.up = "-y";
  up.canonical = false;  // the z-up frame itself: the floor stays 1.4 m below the camera
  ToWorkingFrame(a, up);
  EXPECT_NEAR(EstimateGround(a.points, Kind("auto")).HeightAt(2, 2), -1.4f, 0.02f);
  for (size_t i = 0; i < s.points.size(); i += 997)
    EXPECT_TRUE(a.frame.ToFile(a.points[i]).isApprox(s.points[i].cast<double>(), 1e-5));
  FrameOptions au;
  au.up = "auto";
  ToWorkingFrame(b, au);
  const Eigen::Vector3d z = b.frame.to_upright.linear().row(2).transpose();
  EXPECT_GT(z.dot(Eigen::Vector3d(0, -1, 0)), 0.999) << z.transpose();
  // The canonical working frame (the default) comes back to the file frame as exactly.
  Scan c = s;
  up.canonical = true;
  ToWorkingFrame(c, up);
  EXPECT_FALSE(c.frame.canonical.matrix().isIdentity());
  for (size_t i = 0; i < s.points.size(); i += 997)
    EXPECT_TRUE(c.frame.ToFile(c.points[i]).isApprox(s.points[i].cast<double>(), 1e-5));
}

// A camera pitched down, in its optical frame: --up -y leaves its floor tilted by the pitch (the
// ground model then sees a slope); with level the floor is level again within half a degree and
// the points still map back to the file exactly. A tilt under 8 degrees (SUN RGB-D's upright
// views: 1-5) is left alone, and so is one past 35 degrees (no floor within reach of the axis: a
// wall is not taken for it).
TEST(Frame, LevelAPitchedCamerasFloor) {
  const Points room = Room([](float, float) { return 0.f; });
  auto view = [&](double pitch_deg) {
    // Camera body frame (x forward, z up) pitched down about its y axis, then its optical frame.
    const Eigen::Matrix3f pitch = Eigen::AngleAxisf(float(pitch_deg * M_PI / 180.0), Eigen::Vector3f::UnitY()).toRotationMatrix();
    Scan s;
    for (const auto& p : room) {
      const Eigen::Vector3f b = pitch.transpose() * (p - Eigen::Vector3f(-1.f, 2.f, 1.4f));
      s.points.emplace_back(-b.y(), -b.z(), b.x());
    }
    return s;
  };
  // The angle between the working frame's up and the room's, both in the file's axes.
  auto floor_tilt_deg = [](const Scan& s, double pitch_deg) {
    const Eigen::Vector3d b =
        Eigen::AngleAxisd(pitch_deg * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix().transpose() *
        Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d up(-b.y(), -b.z(), b.x());
    return std::acos(std::clamp(s.frame.to_upright.linear().row(2).dot(up), -1.0, 1.0)) * 180.0 / M_PI;
  };
  FrameOptions axis;
  axis.up = "-y";
  axis.canonical = false;
  FrameOptions level = axis;
  level.level = true;
  const Scan pitched = view(20.0);
  Scan a = pitched, b = pitched;
  ToWorkingFrame(a, axis);
  ToWorkingFrame(b, level);
  EXPECT_NEAR(floor_tilt_deg(a, 20.0), 20.0, 1e-6);
  EXPECT_LT(floor_tilt_deg(b, 20.0), 0.5);
  EXPECT_NE(b.frame.up.find("levelled"), std::string::npos) << b.frame.up;
  for (size_t i = 0; i < pitched.points.size(); i += 997)
    EXPECT_TRUE(b.frame.ToFile(b.points[i]).isApprox(pitched.points[i].cast<double>(), 1e-5));
  for (double small : {6.0, 50.0}) {
    const Scan p = view(small);
    Scan c = p, d = p;
    ToWorkingFrame(c, axis);
    ToWorkingFrame(d, level);
    EXPECT_TRUE(d.frame.to_upright.isApprox(c.frame.to_upright)) << small;
  }
}

// The canonical frame of a room turned about z by any angle and shifted anywhere puts the room
// the same way (up to a quarter turn) on the axes, centred on the origin: the wall's normal on
// an axis. A room without walls turns by the major axis of its floor plan.
TEST(Frame, CanonicalFrameIsTheSameWhateverTheTurnAndShift) {
  const Points room = Room([](float, float) { return 0.f; });
  const Eigen::Isometry3d c0 = EstimateCanonicalFrame(room);
  Points w0(room.size());
  for (size_t i = 0; i < room.size(); ++i) w0[i] = (c0 * room[i].cast<double>()).cast<float>();
  // The room's wall stands at x = 0: it stays on an axis (a turn of 0 mod 90 degrees).
  const double turn0 = std::atan2(c0.linear()(1, 0), c0.linear()(0, 0));
  EXPECT_NEAR(std::remainder(turn0, M_PI / 2), 0.0, 0.02) << turn0;
  Eigen::AlignedBox3f box;
  for (const auto& p : w0) box.extend(p);
  EXPECT_LT(box.center().norm(), 1e-4f);
  for (double yaw : {0.3, 1.2, M_PI / 2, -2.5}) {
    SCOPED_TRACE(yaw);
    const Eigen::Isometry3d t = Eigen::Translation3d(120.5, -33.25, 1.5) * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ());
    Points moved(room.size());
    for (size_t i = 0; i < room.size(); ++i) moved[i] = (t * room[i].cast<double>()).cast<float>();
    const Eigen::Isometry3d c = EstimateCanonicalFrame(moved);
    double best = INFINITY;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Matrix3f q = Eigen::AngleAxisf(float(k * M_PI / 2), Eigen::Vector3f::UnitZ()).toRotationMatrix();
      double worst = 0;
      for (size_t i = 0; i < room.size(); i += 101)
        worst = std::max(worst, double(((c * moved[i].cast<double>()).cast<float>() - q * w0[i]).norm()));
      best = std::min(best, worst);
    }
    EXPECT_LT(best, 2e-3) << "the working points differ by up to " << best << " m";
  }
  // No walls: the floor plan's long side (5 x 2 m, turned by 0.4 rad) comes onto an axis.
  Points floor;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int i = 0; i < 20000; ++i)
    floor.push_back(Eigen::AngleAxisf(0.4f, Eigen::Vector3f::UnitZ()) * Eigen::Vector3f(5.f * u(rng), 2.f * u(rng), 0.f));
  const Eigen::Isometry3d cf = EstimateCanonicalFrame(floor);
  EXPECT_NEAR(std::remainder(std::atan2(cf.linear()(1, 0), cf.linear()(0, 0)) + 0.4, M_PI / 2), 0.0, 0.05);
}

// Georeferenced coordinates: shifted automatically in double at read time (the local points
// keep millimetres that float would round away at 5e6 m), written back in double.
TEST(Frame, GlobalShiftKeepsMillimetres) {
  const fs::path dir = fs::temp_directory_path() / ("furnihost_shift_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string ply = (dir / "utm.ply").string();
  {
    std::ofstream out(ply);
    out << "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nend_header\n";
    out << "691000.123 5335000.456 401.789\n691001.001 5335002.002 402.003\n691000.5 5335000.5 400.5\n";
  }
  const Scan s = ReadScan(ply);
  EXPECT_TRUE(s.frame.shift.isApprox(Eigen::Vector3d(691000, 5335000, 400)));
  EXPECT_NEAR(s.points[0].x(), 0.123f, 1e-5f);
  EXPECT_NEAR(s.points[0].y(), 0.456f, 1e-5f);
  EXPECT_NEAR(s.frame.ToFile(s.points[1]).y(), 5335002.002, 1e-4);
  ShiftOption manual;
  manual.shift = Eigen::Vector3d(691000, 5335000, 400);
  EXPECT_NEAR(ReadScan(ply, nullptr, 0, manual).points[0].z(), 1.789f, 1e-5f);
  ShiftOption none;
  none.automatic = false;
  EXPECT_THROW(ReadScan(ply, nullptr, 0, none), InputError);  // beyond 1e6 m without a shift
  const std::string back = (dir / "back.ply").string();
  WritePlyInFrame(back, s.points, s.frame);
  const Scan r = ReadScan(back, nullptr, 0, manual);
  EXPECT_NEAR(r.frame.ToFile(r.points[1]).x(), 691001.001, 1e-4);
  // A room 100 m and more off the origin is shifted too; one that straddles that distance is
  // shifted whole by its first point (a depth camera's (0, 0, 0) and garbage decide nothing),
  // never torn in two.
  auto read_xyz = [&](const std::string& name, const std::string& text) {
    const std::string f = (dir / name).string();
    std::ofstream(f) << text;
    return ReadScan(f);
  };
  const Scan straddle = read_xyz("straddle.xyz", "0 0 0\n1e30 0 0\n100.25 -25 1\n99.75 -25 1\n100.5 -24 2\n");
  EXPECT_TRUE(straddle.frame.shift.isApprox(Eigen::Vector3d(100, 0, 0)));
  ASSERT_EQ(straddle.points.size(), 4u);  // the garbage point dropped as far
  EXPECT_NEAR(straddle.points[2].x(), -0.25f, 1e-5f);
  EXPECT_NEAR(straddle.points[3].x(), 0.5f, 1e-5f);
  EXPECT_NEAR(straddle.frame.ToFile(straddle.points[2]).x(), 99.75, 1e-6);
  const Scan below = read_xyz("below.xyz", "99.75 -25 1\n100.25 -25 1\n");
  EXPECT_TRUE(below.frame.shift.isZero());
  EXPECT_NEAR(below.points[1].x(), 100.25f, 1e-4f);
  fs::remove_all(dir);
}

// Box IoU: identical 1, disjoint 0, half-overlapping unit cubes 1/3, an oriented box turned by
// 90 degrees has the same axis-aligned extents as its turned sizes.
TEST(Evaluation, BoxIou) {
  const Eigen::AlignedBox3f a(Eigen::Vector3f(0, 0, 0), Eigen::Vector3f(1, 1, 1));
  EXPECT_FLOAT_EQ(BoxIou(a, a), 1.f);
  EXPECT_FLOAT_EQ(BoxIou(a, Eigen::AlignedBox3f(Eigen::Vector3f(2, 0, 0), Eigen::Vector3f(3, 1, 1))), 0.f);
  EXPECT_NEAR(BoxIou(a, Eigen::AlignedBox3f(Eigen::Vector3f(0.5f, 0, 0), Eigen::Vector3f(1.5f, 1, 1))), 1.0 / 3.0, 1e-6);
  EXPECT_FLOAT_EQ(BoxIou(a, Eigen::AlignedBox3f()), 0.f);
  OrientedBox b{Eigen::Vector3f(0, 0, 0.5f), Eigen::Vector3f(2, 1, 1), float(M_PI / 2)};
  EXPECT_TRUE(b.Aabb().sizes().isApprox(Eigen::Vector3f(1, 2, 1), 1e-5f));
}

// AP25: the higher-scored of two detections on one chair is the TP; a detection whose box
// overlaps the chair by less than 0.25 is a FP; the table's detection counts for the table.
TEST(Evaluation, IouMatchingAndAp25) {
  ClassMap cm;
  cm.classes = {"chair", "table"};
  auto object = [](const char* cls, Eigen::Vector3f c, Eigen::Vector3f size) {
    GroundTruthObject g;
    g.cls = cls;
    g.center = c;
    g.size = size;
    return g;
  };
  const GroundTruthObject chair = object("chair", {0, 0, 0.5f}, {0.5f, 0.5f, 1.f});
  const GroundTruthObject table = object("table", {2, 0, 0.4f}, {1.f, 1.f, 0.8f});
  auto det = [](const char* cls, Eigen::Vector3f c, Eigen::Vector3f size, float score) {
    Detection d;
    d.cls = cls;
    d.center = c;
    d.score = score;
    d.box = OrientedBox{c, size, 0.f};
    return d;
  };
  std::vector<Detection> dets = {det("chair", {0.05f, 0, 0.5f}, {0.5f, 0.5f, 1}, 0.9f),
                                 det("chair", {0, 0.02f, 0.5f}, {0.5f, 0.5f, 1}, 0.8f),
                                 det("chair", {0.4f, 0, 0.5f}, {0.5f, 0.5f, 1}, 0.95f),
                                 det("table", {2, 0, 0.4f}, {1, 1, 0.8f}, 0.5f)};
  const SceneMatch m = MatchSceneIou(dets, {chair, table}, cm, 0.25f);
  EXPECT_EQ(m.det_to_gt[2], SceneMatch::kUnmatched);  // IoU 0.11
  EXPECT_EQ(m.det_to_gt[0], 0);
  EXPECT_EQ(m.det_to_gt[1], SceneMatch::kUnmatched);  // the chair is taken
  EXPECT_EQ(m.det_to_gt[3], 1);
  SceneEval se;
  se.detections = dets;
  se.truth = {chair, table};
  const EvalMetrics e = Evaluate({se}, cm, WidthConvention::Max);
  // chair: FP (0.95), TP (0.9), FP (0.8): precision envelope 0.5 at recall 1.
  EXPECT_NEAR(e.classes[0].ap25, 0.5, 1e-9);
  EXPECT_NEAR(e.classes[1].ap25, 1.0, 1e-9);
  EXPECT_NEAR(e.map25, 0.75, 1e-9);
}
