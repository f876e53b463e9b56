// sensors.scan_file: a depth camera's invalid pixels written as (0, 0, 0), the camera's own
// position, are dropped when the scan has a sensor origin there, with the points' labels; a
// scan without an origin keeps every point.
#include <gtest/gtest.h>

#include "furnihost/host/io.hpp"
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

}  // namespace
}  // namespace furnihost
