#include "furnihost/frame.hpp"

#include <spdlog/spdlog.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unordered_map>

#include "furnihost/geometry.hpp"

namespace furnihost {

Eigen::Matrix3d UpAxisRotation(const std::string& axis, const std::string& option) {
  // Rows: the working x, y, z axes in file coordinates.
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(), Z = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d up, fwd;
  if (axis == "+z" || axis == "z") up = Z, fwd = X;
  else if (axis == "-z") up = -Z, fwd = X;
  else if (axis == "+y" || axis == "y") up = Y, fwd = X;
  else if (axis == "-y") up = -Y, fwd = Z;
  else if (axis == "+x" || axis == "x") up = X, fwd = Y;
  else if (axis == "-x") up = -X, fwd = Y;
  else
    throw InputError(option + ": '" + axis + "' is not an axis (expected +x, -x, +y, -y, +z, -z or auto)");
  Eigen::Matrix3d r;
  r.row(0) = fwd.transpose();
  r.row(1) = up.cross(fwd).transpose();
  r.row(2) = up.transpose();
  return r;
}

Eigen::Isometry3d ParseTransform(const std::string& text, const std::string& option) {
  std::vector<double> v;
  std::string t = text;
  for (auto& c : t)
    if (c == ',') c = ' ';
  std::istringstream in(t);
  double x;
  while (in >> x) v.push_back(x);
  const bool finite = std::all_of(v.begin(), v.end(), [](double d) { return std::isfinite(d); });
  if (!in.eof() || !finite || (v.size() != 16 && v.size() != 6))
    throw InputError(option + ": expected 16 numbers (a 4x4 matrix, row-major) or 6 (x,y,z,roll,pitch,yaw in metres "
                     "and radians), got '" + text.substr(0, 80) + "'");
  Eigen::Isometry3d iso = Eigen::Isometry3d::Identity();
  if (v.size() == 6) {
    iso.linear() = (Eigen::AngleAxisd(v[5], Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(v[4], Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(v[3], Eigen::Vector3d::UnitX()))
                       .toRotationMatrix();
    iso.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    return iso;
  }
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = v[size_t(r) * 4 + size_t(c)];
  const Eigen::Matrix3d rot = m.topLeftCorner<3, 3>();
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    throw InputError(option + ": the last row of the matrix must be 0 0 0 1");
  const double det = rot.determinant();
  if (std::abs(det) < 1e-9) throw InputError(option + ": the matrix is singular");
  if ((rot * rot.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-4 || det < 0)
    throw InputError(option + ": the rotation part is not a rotation (orthonormal, determinant +1); scale and "
                     "mirroring are not supported");
  // Re-orthonormalise what was accepted, so rounding in the text does not skew every point.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(rot, Eigen::ComputeFullU | Eigen::ComputeFullV);
  iso.linear() = svd.matrixU() * svd.matrixV().transpose();
  iso.translation() = m.topRightCorner<3, 1>();
  return iso;
}

std::optional<Eigen::Vector3d> EstimateUpAxis(const Points& points) {
  // Surface normals of a 5 cm voxel sample (PCA over each voxel's 3x3x3 neighbourhood).
  const float voxel = 0.05f;
  const Points v = VoxelDownsample(points, voxel);
  if (v.size() < 50) return std::nullopt;
  auto key = [&](const Eigen::Vector3f& p, int dx, int dy, int dz) {
    auto q = [&](float c, int d) { return uint64_t((int64_t(std::floor(c / voxel)) + d) & 0x1FFFFF); };
    return q(p.x(), dx) | (q(p.y(), dy) << 21) | (q(p.z(), dz) << 42);
  };
  std::unordered_map<uint64_t, int> cell;
  cell.reserve(v.size() * 2);
  for (size_t i = 0; i < v.size(); ++i) cell.emplace(key(v[i], 0, 0, 0), int(i));
  std::vector<Eigen::Vector3f> normal(v.size(), Eigen::Vector3f::Zero());
  std::vector<uint8_t> planar(v.size(), 0);
  for (size_t i = 0; i < v.size(); ++i) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    int n = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          auto it = cell.find(key(v[i], dx, dy, dz));
          if (it == cell.end()) continue;
          const Eigen::Vector3d p = v[it->second].cast<double>();
          mean += p;
          cov += p * p.transpose();
          ++n;
        }
    if (n < 5) continue;
    mean /= n;
    cov = cov / n - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    const Eigen::Vector3d ev = es.eigenvalues();
    if (!(ev[0] < 0.05 * ev[1])) continue;  // not flat enough to have a direction
    normal[i] = es.eigenvectors().col(0).cast<float>();
    planar[i] = 1;
  }
  // Dominant plane directions: planar samples binned on the half sphere (about 5 degrees),
  // the densest bin taken, its members removed (within 15 degrees), three times.
  std::vector<std::pair<Eigen::Vector3f, int>> dirs;
  std::vector<uint8_t> used(v.size(), 0);
  for (int round = 0; round < 3; ++round) {
    std::unordered_map<int, int> bins;
    auto bin = [](Eigen::Vector3f n) {
      if (n.z() < 0 || (n.z() == 0 && n.y() < 0)) n = -n;
      const float theta = std::acos(std::clamp(n.z(), -1.f, 1.f)), phi = std::atan2(n.y(), n.x());
      return int(theta / 0.09f) * 1000 + int((phi + 3.2f) / 0.09f);
    };
    for (size_t i = 0; i < v.size(); ++i)
      if (planar[i] && !used[i]) ++bins[bin(normal[i])];
    if (bins.empty()) break;
    const auto best = std::max_element(bins.begin(), bins.end(), [](auto& a, auto& b) {
      return a.second != b.second ? a.second < b.second : a.first > b.first;
    });
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < v.size(); ++i)
      if (planar[i] && !used[i] && bin(normal[i]) == best->first) {
        Eigen::Vector3f n = normal[i];
        if (sum.dot(n.cast<double>()) < 0) n = -n;
        sum += n.cast<double>();
      }
    const Eigen::Vector3f d = sum.normalized().cast<float>();
    int members = 0;
    for (size_t i = 0; i < v.size(); ++i)
      if (planar[i] && !used[i] && std::abs(normal[i].dot(d)) > std::cos(15.f * 3.14159265f / 180.f)) {
        used[i] = 1;
        ++members;
      }
    dirs.push_back({d, members});
  }
  // For each direction and sign: the extreme plane (the lowest 3 cm slice along it that holds
  // members of the direction) must have nearly every sample on its positive side; the one with
  // the most members in that slice is the floor.
  std::optional<Eigen::Vector3d> up;
  int best_support = 0;
  for (const auto& [d, members] : dirs) {
    if (members < 20) continue;
    for (float sign : {1.f, -1.f}) {
      const Eigen::Vector3f u = sign * d;
      std::vector<float> s(v.size());
      for (size_t i = 0; i < v.size(); ++i) s[i] = u.dot(v[i]);
      std::vector<float> sorted = s;
      const size_t k = sorted.size() / 100;  // 1st percentile: outliers below the floor
      std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
      const float lo = sorted[k];
      int support = 0;
      for (size_t i = 0; i < v.size(); ++i)
        if (planar[i] && std::abs(normal[i].dot(u)) > 0.96f && s[i] >= lo - 0.03f && s[i] <= lo + 0.06f) ++support;
      if (support > best_support) {
        best_support = support;
        up = u.cast<double>();
      }
    }
  }
  if (!up || best_support < 20) return std::nullopt;
  return up;
}

void ToWorkingFrame(Scan& scan, const FrameOptions& o) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  std::string how = o.up;
  if (o.transform) {
    t = *o.transform;
    how = "transform";
  } else if (o.up == "auto") {
    const auto up = EstimateUpAxis(scan.points);
    if (!up) throw InputError(scan.source + ": --up auto: no dominant plane with the scene above it; give --up AXIS");
    // The file axis nearest to it decides the forward direction (as UpAxisRotation does), then
    // the exact plane normal is up.
    const Eigen::Vector3d z = up->normalized();
    Eigen::Vector3d fwd = std::abs(z.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    if (std::abs(z.y()) > 0.7) fwd = Eigen::Vector3d::UnitZ();
    fwd = (fwd - fwd.dot(z) * z).normalized();
    t.linear().row(0) = fwd.transpose();
    t.linear().row(1) = z.cross(fwd).transpose();
    t.linear().row(2) = z.transpose();
    std::ostringstream s;
    s.precision(3);
    s << "auto: (" << z.x() << ", " << z.y() << ", " << z.z() << ")";
    how = s.str();
    spdlog::info("{}: --up auto: up is ({:.3f}, {:.3f}, {:.3f}) in the file's axes", scan.source, z.x(), z.y(), z.z());
  } else {
    t.linear() = UpAxisRotation(o.up, "--up");
  }
  scan.frame.to_working = t;
  scan.frame.up = how;
  if (t.matrix().isIdentity()) return;
  const Eigen::Isometry3f tf = t.cast<float>();
  for (auto& p : scan.points) p = tf * p;
  if (scan.origin) scan.origin = tf * *scan.origin;
}

nlohmann::json ToJson(const ScanFrame& f) {
  nlohmann::json m = nlohmann::json::array();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m.push_back(f.to_working.matrix()(r, c));
  return {{"shift", {f.shift.x(), f.shift.y(), f.shift.z()}}, {"file_to_working", m}, {"up", f.up}};
}

}  // namespace furnihost
