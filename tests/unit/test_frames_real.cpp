// Issue 18: detection on a real dev scan (ScanNet room, SUN RGB-D view) gives the same
// detections, up to the transform, when the scan is shifted in z by +-1.5 m, turned about z
// (a quarter turn and an arbitrary angle, each with a shift),
// put into a camera optical frame (read with --up -y), or moved to UTM-sized coordinates
// (automatic global shift). Each variant is written as a double-precision PLY, detected by the
// furnihost binary with the shipped ScanNet config, and its detections.json (written in the
// variant's own frame) mapped back and matched against the original's.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "furnihost/host/io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

struct Det {
  std::string cls;
  Eigen::Vector3d center;
  double score;
  Eigen::Vector3d box_size;
  bool accepted = false;
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

// Runs detection; returns every detection (accepted or not) mapped by `to_original`.
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
    const auto& c = e.at("center");
    Det x{e.at("class").get<std::string>(), to_original * Eigen::Vector3d(c[0], c[1], c[2]),
          e.at("score").get<double>(), Eigen::Vector3d::Zero(),
          e.contains("verified") && e["verified"].is_boolean() && e["verified"].get<bool>()};
    if (e.contains("box")) {
      const auto& s = e["box"]["size"];
      // Length and width as the longer and shorter side: a quarter turn of the frame swaps them.
      x.box_size = Eigen::Vector3d(std::max(s[0].get<double>(), s[1].get<double>()),
                                   std::min(s[0].get<double>(), s[1].get<double>()), s[2].get<double>());
    }
    d.push_back(x);
  }
  return d;
}

// Every detection of `a` accepted or scoring at least 0.03 has one of `b` of its class within
// 5 cm, with a score within 10 % and a box size within 5 % (and the other way round, for those
// of `b` accepted or at least 0.035, so a candidate scoring right at the floor is not counted
// against either): the same detections, and the same candidates but for the faintest, whose
// scores move by more than that with rounding (a variant of another class in their cluster).
void ExpectSame(const std::vector<Det>& a, const std::vector<Det>& b, const std::string& what) {
  auto covered = [](const std::vector<Det>& x, const std::vector<Det>& y, double floor) {
    int n = 0, need = 0;
    for (const auto& p : x) {
      if (p.score < floor && !p.accepted) continue;
      ++need;
      for (const auto& q : y)
        if (p.cls == q.cls && (p.center - q.center).norm() < 0.05 &&
            std::abs(p.score - q.score) <= 0.1 * std::max(std::abs(p.score), 1e-3) + 1e-4 &&
            (p.box_size - q.box_size).cwiseAbs().maxCoeff() <= 0.05 * p.box_size.maxCoeff() + 1e-4) {
          ++n;
          break;
        }
    }
    return n == need;
  };
  auto list = [](const std::vector<Det>& x) {
    std::string s;
    char b[160];
    for (const auto& d : x) {
      if (d.score < 0.03 && !d.accepted) continue;
      std::snprintf(b, sizeof b, "\n  %s (%.3f %.3f %.3f) score %.4f size %.2f x %.2f x %.2f", d.cls.c_str(), d.center.x(),
                    d.center.y(), d.center.z(), d.score, d.box_size.x(), d.box_size.y(), d.box_size.z());
      s += b;
    }
    return s;
  };
  const bool same = covered(a, b, 0.03) && covered(b, a, 0.035);
  EXPECT_TRUE(same) << what << "\noriginal:" << list(a) << "\nvariant, mapped back:" << list(b);
}

void CheckInvariance(const std::string& scan_path, const std::string& origin_opt, size_t min_detections) {
  const std::string dir = furnihost::testing::TempDir("frames_" + fs::path(scan_path).stem().string());
  const furnihost::Scan scan = furnihost::ReadScan(scan_path);
  const Eigen::Isometry3d id = Eigen::Isometry3d::Identity();
  WriteVariant(dir + "/orig.ply", scan.points, id);
  const auto ref = Detect(dir + "/orig.ply", dir + "/orig", origin_opt, id);
  const size_t strong = std::count_if(ref.begin(), ref.end(), [](const Det& d) { return d.score >= 0.03 || d.accepted; });
  ASSERT_GE(strong, min_detections) << "too few detections on " << scan_path << " to compare";

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
    Eigen::Isometry3d t = Eigen::Translation3d(-1.234, 2.345, 0.0) * Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitZ());
    variants.push_back({"turned 34.4 deg", "", t});
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
  CheckInvariance(data + "/scannet_votenet50k/scene0000_00.ply", "", 6);
}

TEST(FramesOnRealScans, SunRgbdView) {
  const std::string data = furnihost::testing::SharedDataDir();
  ASSERT_FALSE(data.empty());
  CheckInvariance(data + "/sunrgbd_dev/sun000005.ply", "--origin 0,0,0", 2);
}
