// sensors.scan_file: a depth camera's invalid pixels written as (0, 0, 0), the camera's own
// position, are dropped when the scan has a sensor origin there, with the points' labels; a
// scan without an origin keeps every point.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <vector>

#include "furnihost/host/io.hpp"
#include "furnihost/scan_reader.hpp"
#include "furnihost/stage.hpp"
#include "test_stages.hpp"
#include "test_support.hpp"

namespace furnihost {
namespace {

TEST(ScanFile, ReturnsAtTheSensorOriginAreDropped) {
  const std::string dir = testing::TempDir("scan_file_origin");
  // 5 points on a wall 2 m ahead, labelled 1..5, between 3 invalid pixels at the origin.
  std::string ply = "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n"
                    "property int label\nend_header\n0 0 0 9\n";
  for (int i = 1; i <= 5; ++i) ply += "2 " + std::to_string(0.1 * i) + " 0.5 " + std::to_string(i) + "\n";
  ply += "0 0 0 9\n0 0 0 9\n";
  AtomicWriteText(dir + "/view.ply", ply);
  auto sensor = testing::MakeStage<Sensor>("sensors.scan_file");
  RunContext ctx;
  SensorRequest req;
  req.path = dir + "/view.ply";
  const Scan none = sensor->Acquire(req, ctx).at(0);
  EXPECT_EQ(none.points.size(), 8u);  // no origin: nothing is known to be invalid
  req.origin = Eigen::Vector3f::Zero();
  const Scan view = sensor->Acquire(req, ctx).at(0);
  ASSERT_EQ(view.points.size(), 5u);
  const auto& label = view.attributes.at("label");
  ASSERT_EQ(label.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(label[size_t(i)], i + 1);
    EXPECT_FLOAT_EQ(view.points[size_t(i)].x(), 2.f);
  }
  // An origin elsewhere: the zeros are points like any other.
  req.origin = Eigen::Vector3f(0.f, 0.f, 1.f);
  EXPECT_EQ(sensor->Acquire(req, ctx).at(0).points.size(), 8u);
}

// A scan a program holds (SensorRequest::scan, made by ScanFromPoints: the Python module's
// arrays) is taken as if read from its file: the same points after the sensor's voxel grid and
// its drop of returns at the sensor origin, the same colours; a scan beyond max_points is refused.
TEST(ScanFile, AScanInMemoryIsTakenAsIfReadFromItsFile) {
  const std::string dir = testing::TempDir("scan_file_memory");
  std::string ply = "ply\nformat ascii 1.0\nelement vertex 300\nproperty float x\nproperty float y\nproperty float z\n"
                    "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  std::vector<double> xyz;
  std::vector<uint8_t> rgb;
  for (int i = 0; i < 300; ++i) {
    // Every tenth point at the sensor origin (0, 0, 1), the others on a wall, several per voxel.
    const float p[3] = {i % 10 == 0 ? 0.f : 2.f, i % 10 == 0 ? 0.f : 0.013f * float(i), i % 10 == 0 ? 1.f : 0.5f};
    char line[96];
    std::snprintf(line, sizeof line, "%.9g %.9g %.9g %d %d %d\n", p[0], p[1], p[2], i % 256, 7, 200);
    ply += line;
    for (float v : p) xyz.push_back(v);
    for (int c : {i % 256, 7, 200}) rgb.push_back(uint8_t(c));
  }
  AtomicWriteText(dir + "/wall.ply", ply);
  auto sensor = testing::MakeStage<Sensor>("sensors.scan_file", {{"voxel_m", 0.05}});
  RunContext ctx;
  SensorRequest file;
  file.path = dir + "/wall.ply";
  file.origin = Eigen::Vector3f(0.f, 0.f, 1.f);
  const Scan from_file = sensor->Acquire(file, ctx).at(0);
  const Scan held = ScanFromPoints("points", xyz.data(), 300, rgb.data());
  SensorRequest memory = file;
  memory.path = "points";
  memory.scan = &held;
  const Scan from_memory = sensor->Acquire(memory, ctx).at(0);
  ASSERT_LT(from_file.points.size(), 270u);  // the origin's returns dropped and the voxels thinned
  EXPECT_EQ(from_memory.points, from_file.points);
  EXPECT_EQ(from_memory.colors, from_file.colors);
  EXPECT_EQ(from_memory.origin, from_file.origin);
  EXPECT_EQ(held.points.size(), 300u);  // the caller's scan is left as it was
  auto capped = testing::MakeStage<Sensor>("sensors.scan_file", {{"max_points", 100}});
  try {
    capped->Acquire(memory, ctx);
    ADD_FAILURE() << "300 points passed max_points 100";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("points: 300 points exceed the limit of 100"), std::string::npos) << e.what();
  }
}

// ScanFromPoints applies the readers' rules: non-finite rows dropped and counted, coordinates far
// from the origin shifted in double before rounding (the shift recorded in the frame), an array
// with no finite row refused naming it.
TEST(ScanFile, ScanFromPointsFollowsTheReadersRules) {
  const double xyz[] = {500123.25, 4100000.5, 12.0, NAN, 0, 0, 500124.75, 4100001.0, 13.5};
  ReadStats stats;
  const Scan s = ScanFromPoints("utm", xyz, 3, nullptr, &stats);
  ASSERT_EQ(s.points.size(), 2u);
  EXPECT_EQ(stats.read, 3u);
  EXPECT_EQ(stats.non_finite, 1u);
  EXPECT_EQ(s.frame.shift, Eigen::Vector3d(500100.0, 4100000.0, 0.0));
  EXPECT_EQ(s.points[0], Eigen::Vector3f(23.25f, 0.5f, 12.f));
  EXPECT_EQ(s.points[1], Eigen::Vector3f(24.75f, 1.f, 13.5f));
  EXPECT_TRUE(s.colors.empty());
  const double none[] = {NAN, NAN, NAN};
  try {
    ScanFromPoints("empty rows", none, 1);
    ADD_FAILURE() << "a scan of no finite point passed";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "empty rows: holds no finite points");
  }
}

// ScanFromPoints follows the readers' shift and stray-return rules as ReadScan does on a file of
// the same points: a stray first point near the origin does not decide the global shift (the
// bulk is taken again with its own), and a return far above the bulk is dropped.
TEST(ScanFile, ScanFromPointsTakesStrayReturnsAsTheReaders) {
  std::vector<double> xyz = {0.5, 0.5, 0.0};  // the stray first point
  for (int i = 0; i < 2000; ++i)
    xyz.insert(xyz.end(), {651000.0 + 0.1 * (i % 50), 5423000.0 + 0.1 * (i / 50), 1.0});
  xyz.insert(xyz.end(), {651001.0, 5423001.0, 501.0});  // 500 m above the room
  const size_t n = xyz.size() / 3;
  const std::string dir = testing::TempDir("scan_file_stray"), path = dir + "/utm.xyz";
  {
    std::ofstream out(path);
    out.precision(12);
    for (size_t i = 0; i < n; ++i) out << xyz[3 * i] << " " << xyz[3 * i + 1] << " " << xyz[3 * i + 2] << "\n";
  }
  ReadStats stats;
  const Scan held = ScanFromPoints("utm", xyz.data(), n, nullptr, &stats);
  const Scan read = ReadScan(path);
  std::filesystem::remove_all(dir);
  EXPECT_EQ(stats.read, n);
  ASSERT_EQ(held.points.size(), 2000u);
  EXPECT_EQ(held.frame.shift, Eigen::Vector3d(651000.0, 5423000.0, 0.0));
  EXPECT_EQ(held.points, read.points);
  EXPECT_EQ(held.frame.shift, read.frame.shift);
}

}  // namespace
}  // namespace furnihost
