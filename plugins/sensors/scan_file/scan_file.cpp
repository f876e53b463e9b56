// sensors.scan_file — reads a scan from a file (PCD, PLY, XYZ), or takes one a program holds in
// memory (SensorRequest::scan), for detection, with optional voxel downsampling so real scans
// can be matched to the training views' density. With a sensor origin, returns at the origin
// itself are dropped: a depth camera's driver writes its invalid pixels as (0, 0, 0), the
// camera's own position, where no surface can be (left in, they move the scan's bounding box,
// its canonical frame and every score).
#include <spdlog/spdlog.h>

#include "furnihost/geometry.hpp"
#include "furnihost/plugin.hpp"
#include "furnihost/scan_reader.hpp"

namespace furnihost {

namespace {

struct ScanFileOptions {
  float voxel_m = 0.f;             // voxel-grid edge [m]; 0 keeps every point
  size_t max_points = 20000000;    // memory guard
  std::vector<double> origin;      // sensor origin [x, y, z] when the file has none; empty = unknown
};

// Each parameter declared once; its default is ScanFileOptions{}'s.
const ParamBinding<ScanFileOptions>& Binding() {
  using O = ScanFileOptions;
  static const auto b =
      ParamBinding<O>()
          .Number("voxel_m", &O::voxel_m, 0.0, 1.0, "m", "voxel-grid downsampling edge [m]; 0 keeps every point")
          .Int("max_points", &O::max_points, 1, 2e9, "count", "refuse scans with more points than this (memory guard)")
          .NumberList("origin", &O::origin, -1e6, 1e6, "m",
                      "sensor origin [x, y, z] in the scan frame when the file has none (empty = unknown)")
          .Rule([](const O& o) {
            return o.origin.empty() || o.origin.size() == 3
                       ? std::string()
                       : "origin: expected 3 numbers, got " + std::to_string(o.origin.size());
          });
  return b;
}

}  // namespace

class ScanFile : public Sensor {
 public:
  static ParamSchema Schema() { return Binding().Schema(); }
  explicit ScanFile(const nlohmann::json& p) {
    const ScanFileOptions o = Binding().Parse(p);
    voxel_ = o.voxel_m;
    max_points_ = o.max_points;
    if (o.origin.size() == 3) origin_ = Eigen::Vector3f(o.origin[0], o.origin[1], o.origin[2]);
  }

  std::vector<Scan> Acquire(const SensorRequest& req, const RunContext&) override {
    if (req.path.empty() && !req.scan) throw InputError("sensors.scan_file reads files: no path given");
    // A scan in memory (a program's points) is taken as if read from its file.
    if (req.scan && req.scan->points.size() > max_points_)
      throw InputError(req.scan->source + ": " + std::to_string(req.scan->points.size()) +
                       " points exceed the limit of " + std::to_string(max_points_) + " (the sensor's max_points)");
    Scan scan = req.scan ? *req.scan : ReadScan(req.path, nullptr, max_points_, req.shift);
    // Origins are given in the file's coordinates: shifted like its points. The command line
    // wins over the file.
    auto shifted = [&](const Eigen::Vector3f& o) { return Eigen::Vector3f((o.cast<double>() - scan.frame.shift).cast<float>()); };
    if (req.origin) scan.origin = shifted(*req.origin);
    else if (!scan.origin && origin_) scan.origin = shifted(*origin_);
    if (scan.origin) {
      std::vector<int> kept;
      kept.reserve(scan.points.size());
      for (size_t i = 0; i < scan.points.size(); ++i)
        if (!((scan.points[i] - *scan.origin).squaredNorm() < kAtOrigin * kAtOrigin)) kept.push_back(int(i));
      if (kept.size() < scan.points.size()) {
        spdlog::info("{}: {} returns at the sensor origin dropped (a depth camera's invalid pixels)", scan.source,
                     scan.points.size() - kept.size());
        Points p(kept.size());
        for (size_t i = 0; i < kept.size(); ++i) p[i] = scan.points[size_t(kept[i])];
        scan.points.swap(p);
        KeepAttributes(scan, kept);
      }
    }
    if (voxel_ > 0) {
      std::vector<int> kept;
      const size_t before = scan.points.size();
      scan.points = VoxelDownsample(scan.points, voxel_, &kept);
      KeepAttributes(scan, kept);  // per-point attributes follow the first point of each voxel
      spdlog::info("{}: voxel {} m: {} -> {} points", scan.source, voxel_, before, scan.points.size());
    }
    return {std::move(scan)};
  }

 private:
  static constexpr float kAtOrigin = 1e-4f;  // [m]: a return this close to the sensor is its own position

  // Keeps the per-point attributes and colours of the points at `kept`, in that order.
  static void KeepAttributes(Scan& scan, const std::vector<int>& kept) {
    for (auto& [name, values] : scan.attributes) {
      std::vector<int32_t> v(kept.size());
      for (size_t i = 0; i < kept.size(); ++i) v[i] = values[size_t(kept[i])];
      values.swap(v);
    }
    if (!scan.colors.empty()) {
      std::vector<std::array<uint8_t, 3>> c(kept.size());
      for (size_t i = 0; i < kept.size(); ++i) c[i] = scan.colors[size_t(kept[i])];
      scan.colors.swap(c);
    }
  }

  float voxel_;
  size_t max_points_;
  std::optional<Eigen::Vector3f> origin_;
};

}  // namespace furnihost

FURNIHOST_PLUGIN(furnihost::ScanFile, "sensors.scan_file", "1.0.0",
                 "reads a scan from a .pcd/.ply/.xyz file (VIEWPOINT = sensor origin), optional voxel downsampling")
