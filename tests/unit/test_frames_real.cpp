// Issue 18: detection on a real dev scan (ScanNet room, SUN RGB-D view) gives the same
// detections, up to the transform, when the scan is shifted in z by +-1.5 m, turned about z,
// put into a camera optical frame (read with --up -y), or moved to UTM-sized coordinates
// (automatic global shift). Each variant is written as a double-precision PLY, detected by the
// furnihost binary with the shipped ScanNet config, and its detections.json (written in the
// variant's own frame) mapped back and matched against the original's.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "furnihost/io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

struct Det {
  std::string cls;
  Eigen::Vector3d center;
  double score;
  Eigen::Vector3d box_size;
};

// Writes the points as an ASCII PLY in double precision after `to_file`.
void WriteVariant(const std::string& path, const furnihost::Points& pts, const Eigen::Isometry3d& to_file) {
  std::ofstream o(path);
  o << "ply\nformat ascii 1.0\nelement vertex " << pts.size()
    << "\nproperty double x\nproperty double y\nproperty double z\nend_header\n";
  char line[128];
  for (const auto& p : pts) {
    const Eigen::Vector3d q = to_file * p.cast<double>();
    std::snprintf(line, sizeof line, "%.9f %.9f %.9f\n", q.x(), q.y(), q.z());
    o << line;
  }
}

// Runs detection; returns the accepted detections mapped by `to_original`.
std::vector<Det> Detect(const std::string& scan, const std::string& out, const std::string& extra,
                        const Eigen::Isometry3d& to_original) {
  const std::string cmd = std::string(FURNIHOST_TEST_BINARY) + " --graph " + furnihost::testing::SourceDir() +
                          "/configs/scannet.json -q --threads 2 --out " + out + " " + extra + " " + scan +
                          " >" + out + ".log 2>&1";
  const int status = std::system(cmd.c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << cmd;
  std::vector<Det> d;
  const auto j = furnihost::ReadJson(out + "/detections.json");
  for (const auto& e : j.at("detections")) {
    if (e.contains("verified") && e["verified"].is_boolean() && !e["verified"].get<bool>()) continue;
    const auto& c = e.at("center");
    Det x{e.at("class").get<std::string>(), to_original * Eigen::Vector3d(c[0], c[1], c[2]),
          e.at("score").get<double>(), Eigen::Vector3d::Zero()};
    if (e.contains("box")) {
      const auto& s = e["box"]["size"];
      x.box_size = Eigen::Vector3d(s[0], s[1], s[2]);
    }
    d.push_back(x);
  }
  return d;
}

// Every detection of `a` has one of `b` of its class within 5 cm, with a score and box size
// within 5 % (and the other way round): the same detections.
void ExpectSame(const std::vector<Det>& a, const std::vector<Det>& b, const std::string& what) {
  EXPECT_EQ(a.size(), b.size()) << what;
  auto covered = [](const std::vector<Det>& x, const std::vector<Det>& y) {
    int n = 0;
    for (const auto& p : x)
      for (const auto& q : y)
        if (p.cls == q.cls && (p.center - q.center).norm() < 0.05 &&
            std::abs(p.score - q.score) <= 0.05 * std::max(std::abs(p.score), 1e-3) + 1e-4 &&
            (p.box_size - q.box_size).cwiseAbs().maxCoeff() <= 0.05 * p.box_size.maxCoeff() + 1e-4) {
          ++n;
          break;
        }
    return n;
  };
  EXPECT_EQ(covered(a, b), static_cast<int>(a.size())) << what;
  EXPECT_EQ(covered(b, a), static_cast<int>(b.size())) << what;
}

void CheckInvariance(const std::string& scan_path, const std::string& origin_opt, size_t min_detections) {
  const std::string dir = furnihost::testing::TempDir("frames_" + fs::path(scan_path).stem().string());
  const furnihost::Scan scan = furnihost::ReadScan(scan_path);
  const Eigen::Isometry3d id = Eigen::Isometry3d::Identity();
  WriteVariant(dir + "/orig.ply", scan.points, id);
  const auto ref = Detect(dir + "/orig.ply", dir + "/orig", origin_opt, id);
  ASSERT_GE(ref.size(), min_detections) << "too few detections on " << scan_path << " to compare";

  struct Variant {
    std::string name, options;
    Eigen::Isometry3d to_file;
  };
  std::vector<Variant> variants;
  auto with_origin = [&](const Eigen::Isometry3d& t) {
    if (origin_opt.empty()) return std::string();
    return "--origin " + [&] {
      const Eigen::Vector3d o = t * Eigen::Vector3d::Zero();
      char b[96];
      std::snprintf(b, sizeof b, "%.6f,%.6f,%.6f", o.x(), o.y(), o.z());
      return std::string(b);
    }();
  };
  for (double dz : {1.5, -1.5}) {
    Eigen::Isometry3d t = Eigen::Translation3d(0, 0, dz) * id;
    variants.push_back({"z" + std::to_string(dz), "", t});
  }
  {
    Eigen::Isometry3d t = Eigen::Translation3d(0.3, -0.2, 0.0) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
    variants.push_back({"turned 90 deg", "", t});
  }
  {
    // Optical frame: x right, y down, z forward; the scan's up is the file's -y.
    Eigen::Matrix3d r;
    r << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    Eigen::Isometry3d t = id;
    t.linear() = r;
    variants.push_back({"optical frame", "--up -y", t});
  }
  {
    Eigen::Isometry3d t = Eigen::Translation3d(691000.0, 5335000.0, 0.0) * id;
    variants.push_back({"UTM", "", t});
  }
  int k = 0;
  for (const auto& v : variants) {
    SCOPED_TRACE(v.name);
    const std::string f = dir + "/v" + std::to_string(k++);
    WriteVariant(f + ".ply", scan.points, v.to_file);
    const auto got = Detect(f + ".ply", f, v.options + " " + with_origin(v.to_file), v.to_file.inverse());
    ExpectSame(ref, got, v.name + " on " + scan_path);
  }
  fs::remove_all(dir);
}

}  // namespace

TEST(FramesOnRealScans, ScanNetRoom) {
  const std::string data = furnihost::testing::SharedDataDir();
  ASSERT_FALSE(data.empty());
  CheckInvariance(data + "/scannet_votenet50k/scene0000_00.ply", "", 3);
}

TEST(FramesOnRealScans, SunRgbdView) {
  const std::string data = furnihost::testing::SharedDataDir();
  ASSERT_FALSE(data.empty());
  CheckInvariance(data + "/sunrgbd_dev/sun000005.ply", "--origin 0,0,0", 1);
}
