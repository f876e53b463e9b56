#include "furnihost/host/frame.hpp"

#include <spdlog/spdlog.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nanoflann.hpp>
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
  // A subnormal entry (1e-310) is no angle's sine or cosine and no length: a corrupted value.
  for (size_t k = 0; k < v.size(); ++k)
    if (std::fpclassify(v[k]) == FP_SUBNORMAL)
      throw InputError(option + ": number " + std::to_string(k + 1) + " is subnormal (below 2.2e-308): not a transform");
  // The translation moves the scan's points, which lie within kMaxScanCoordinate of the file's
  // (shifted) origin: as far again puts them beyond float's metre resolution, and 1e300 at
  // infinity. Georeferenced coordinates take a global shift (--shift), not a translation.
  const Eigen::Vector3d move = v.size() == 6 ? Eigen::Vector3d(v[0], v[1], v[2]) : Eigen::Vector3d(v[3], v[7], v[11]);
  if (!(move.cwiseAbs().maxCoeff() <= kMaxScanCoordinate))
    throw InputError(option + ": the translation (" + text.substr(0, 80) + ") reaches beyond " +
                     std::to_string(static_cast<long long>(kMaxScanCoordinate)) +
                     " m; georeferenced coordinates take a global shift (--shift x,y,z)");
  if (v.size() == 6 && !(Eigen::Vector3d(v[3], v[4], v[5]).cwiseAbs().maxCoeff() <= 1e3))
    throw InputError(option + ": roll, pitch and yaw are radians; got (" + text.substr(0, 80) + ")");
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

void CheckShift(const Eigen::Vector3d& shift, const std::string& option) {
  if (!(shift.cwiseAbs().maxCoeff() <= kMaxGlobalShift))
    throw InputError(option + ": a global shift is at most " + std::to_string(static_cast<long long>(kMaxGlobalShift)) +
                     " m per axis (ECEF and map projections stay below), got (" + std::to_string(shift.x()) + ", " +
                     std::to_string(shift.y()) + ", " + std::to_string(shift.z()) + ")");
}

void CheckSensorOrigin(const Scan& scan, const std::string& given_as) {
  if (!scan.origin) return;
  std::string ext = std::filesystem::path(scan.source).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const std::string name = !given_as.empty() ? given_as
                           : ext == ".pcd"    ? std::string("its VIEWPOINT")
                                              : std::string("the sensor's \"origin\" parameter");
  const Eigen::Vector3d o = scan.origin->cast<double>();
  const Eigen::Vector3d file = o + scan.frame.shift;
  auto where = [&] {
    char b[160];
    std::snprintf(b, sizeof b, "(%.6g, %.6g, %.6g)", file.x(), file.y(), file.z());
    return std::string(b);
  };
  if (!o.allFinite() || !(o.cwiseAbs().maxCoeff() <= kMaxScanCoordinate))
    throw InputError(scan.source + ": the sensor origin given by " + name + " " + where() + " lies beyond " +
                     std::to_string(static_cast<long long>(kMaxScanCoordinate)) + " m of the scan's origin");
  Eigen::AlignedBox3d box;
  for (const auto& p : scan.points)
    if (p.allFinite()) box.extend(p.cast<double>());
  if (box.isEmpty()) return;
  const double d = (o - o.cwiseMax(box.min()).cwiseMin(box.max())).norm();
  if (!(d <= kMaxSensorRange))
    throw InputError(scan.source + ": the sensor origin given by " + name + " " + where() + " lies " +
                     std::to_string(static_cast<long long>(std::llround(d))) + " m from the scan's points (no sensor sees " +
                     "farther than " + std::to_string(static_cast<long long>(kMaxSensorRange)) +
                     " m; a sensor origin in other coordinates than the points?)");
}

std::optional<Eigen::Vector3d> EstimateUpAxis(const Points& points, const std::optional<Eigen::Vector3d>& near,
                                              double max_deg) {
  const Eigen::Vector3f hint = near ? Eigen::Vector3f(near->normalized().cast<float>()) : Eigen::Vector3f::Zero();
  const float min_cos = near ? float(std::cos(max_deg * M_PI / 180.0)) : -2.f;
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
    planar[i] = !near || std::abs(normal[i].dot(hint)) >= min_cos;
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
      if (near && u.dot(hint) < min_cos) continue;
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

namespace {
struct CloudAdaptor {
  const Points& pts;
  size_t kdtree_get_point_count() const { return pts.size(); }
  float kdtree_get_pt(size_t i, size_t d) const { return pts[i][int(d)]; }
  template <class B>
  bool kdtree_get_bbox(B&) const { return false; }
};
using CloudTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>, CloudAdaptor, 3, uint32_t>;
}  // namespace

Eigen::Isometry3d EstimateCanonicalFrame(const Points& upright) { return EstimateCanonicalFrame(upright, nullptr, 0); }

Eigen::Isometry3d EstimateCanonicalFrame(const Points& upright, ScanNeighbours* neighbours, int keep_k) {
  if (neighbours) *neighbours = ScanNeighbours();
  std::vector<uint32_t> finite;
  finite.reserve(upright.size());
  for (size_t i = 0; i < upright.size(); ++i)
    if (upright[i].allFinite()) finite.push_back(uint32_t(i));
  if (finite.size() < 10) return Eigen::Isometry3d::Identity();
  // A sample by index (every s-th finite point), exact duplicates once: the same points in
  // whatever frame the cloud is given.
  const size_t stride = std::max<size_t>(1, finite.size() / 30000);
  Points sample;
  for (size_t k = 0; k < finite.size(); k += stride) sample.push_back(upright[finite[k]]);
  std::vector<uint32_t> which;  // the distinct position of each sampled point
  sample = GroupEqualPoints(sample, &which);  // the first of equal points kept
  // Every point sampled: its neighbours are the scan's, kept for the stages (ScanNeighbours).
  const bool keep = neighbours && keep_k > 0 && keep_k <= kMaxScanNeighbours && stride == 1 &&
                    finite.size() == upright.size() && sample.size() >= 20;
  // Azimuths of the vertical surfaces' normals (plane fits over 12 neighbours), as 4 x angle.
  double C = 0, S = 0, W = 0;
  if (sample.size() >= 20) {
    CloudAdaptor ad{sample};
    CloudTree tree(3, ad, nanoflann::KDTreeSingleIndexAdaptorParams(16));  // built by its constructor
    const size_t k = 12;
    // With `keep`, max(keep_k, 12) are searched: a k-d tree's search for more neighbours visits
    // the same leaves in the same order and more, so its first 12 are the 12 (ties included).
    const size_t searched = keep ? std::max(size_t(keep_k), k) : k;
    if (keep) {
      neighbours->k = int(searched);
      neighbours->nearest.assign(sample.size() * searched, 0);
      neighbours->count.assign(sample.size(), 0);
    }
    std::vector<Eigen::Vector3d> acc(sample.size(), Eigen::Vector3d::Zero());  // (cos, sin, weight)
    // Queries in the tree's leaf order (each point's result is its own, summed below in point
    // order): neighbouring queries walk the same branches, which a scan's file order (random
    // for ScanNet's sampled vertices) does not.
    const auto& leaf_order = tree.vAcc;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, sample.size(), 2048), [&](const tbb::blocked_range<size_t>& r) {
      std::vector<uint32_t> idx(searched);
      std::vector<float> d2(searched);
      for (size_t t = r.begin(); t != r.end(); ++t) {
        const size_t i = leaf_order[t];
        nanoflann::KNNResultSet<float, uint32_t> rs(searched);
        rs.init(idx.data(), d2.data());
        tree.findNeighbors(rs, sample[i].data(), nanoflann::SearchParams());
        if (keep) {
          std::copy(idx.begin(), idx.begin() + long(rs.size()), neighbours->nearest.begin() + long(i * searched));
          neighbours->count[i] = uint8_t(rs.size());
        }
        const size_t n = std::min(rs.size(), k);
        if (n < 6) continue;
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (size_t j = 0; j < n; ++j) mean += sample[idx[j]].cast<double>();
        mean /= double(n);
        Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
        for (size_t j = 0; j < n; ++j) {
          const Eigen::Vector3d d = sample[idx[j]].cast<double>() - mean;
          cov += d * d.transpose();
        }
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
        es.computeDirect(cov);
        const Eigen::Vector3d ev = es.eigenvalues();
        if (!(ev[0] < 0.1 * ev[1])) continue;  // not flat
        const Eigen::Vector3d nrm = es.eigenvectors().col(0);
        if (!nrm.allFinite() || std::abs(nrm.z()) > 0.3) continue;  // not a vertical surface
        const double a = 4.0 * std::atan2(nrm.y(), nrm.x());
        acc[i] = Eigen::Vector3d(std::cos(a), std::sin(a), 1.0);
      }
    });
    for (const auto& a : acc) C += a.x(), S += a.y(), W += a.z();
    if (keep) {  // each point's position, and each position's points
      GroupMembers(which, sample.size(), neighbours->start, neighbours->members);
      neighbours->position = std::move(which);
    }
  }
  double yaw = 0;  // of the dominant directions, in (-45, 45] degrees
  // Walls decide when their directions agree beyond what chance gives noisy normals (a
  // resultant of 4 random-walk steps).
  if (W >= 50 && std::hypot(C, S) >= std::max(0.05 * W, 4.0 * std::sqrt(W))) {
    yaw = 0.25 * std::atan2(S, C);
  } else {
    // No walls to go by: the major axis of the points on the floor plane.
    Eigen::Vector2d m = Eigen::Vector2d::Zero();
    for (const auto& p : sample) m += p.head<2>().cast<double>();
    m /= double(sample.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const auto& p : sample) {
      const Eigen::Vector2d d = p.head<2>().cast<double>() - m;
      cov += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
    const Eigen::Vector2d ev = es.eigenvalues();
    if (ev[1] > 0 && ev[0] < 0.8 * ev[1]) {
      const Eigen::Vector2d ax = es.eigenvectors().col(1);
      yaw = 0.25 * std::atan2(std::sin(4 * std::atan2(ax.y(), ax.x())), std::cos(4 * std::atan2(ax.y(), ax.x())));
    }
  }
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::AlignedBox3d box;
  for (uint32_t i : finite) box.extend(t.linear() * upright[i].cast<double>());
  t.translation() = -box.center();
  return t;
}

namespace {
// EstimateUpAxis's normal is the mean of 5 cm voxel normals in a ~5 degree bin: a few degrees
// off. The plane fitted (PCA) to the points within 4 cm of the lowest percentile along it (the
// floor, or a band of it), twice, is the floor's own.
Eigen::Vector3d RefineFloorNormal(const Points& pts, Eigen::Vector3d u) {
  u.normalize();
  std::vector<double> h(pts.size());
  for (int round = 0; round < 2; ++round) {
    for (size_t i = 0; i < pts.size(); ++i) h[i] = u.dot(pts[i].cast<double>());
    std::vector<double> sorted = h;
    const size_t k = sorted.size() / 50;
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    const double lo = sorted[k];
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    size_t n = 0;
    for (size_t i = 0; i < pts.size(); ++i)
      if (std::abs(h[i] - lo) < 0.04) mean += pts[i].cast<double>(), ++n;
    if (n < 50) break;
    mean /= double(n);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (size_t i = 0; i < pts.size(); ++i)
      if (std::abs(h[i] - lo) < 0.04) {
        const Eigen::Vector3d d = pts[i].cast<double>() - mean;
        cov += d * d.transpose();
      }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    if (!(es.eigenvalues()(0) < 0.05 * es.eigenvalues()(1))) break;  // not a plane (a corner, a step)
    Eigen::Vector3d nv = es.eigenvectors().col(0);
    if (nv.dot(u) < 0) nv = -nv;
    if (!nv.allFinite() || nv.dot(u) < std::cos(10.0 * M_PI / 180.0)) break;
    u = nv.normalized();
  }
  return u;
}
}  // namespace

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
    if (o.level) {
      // The floor's normal in the axis-turned frame; turned onto +z by the smallest rotation.
      const Eigen::Matrix3f r = t.linear().cast<float>();
      Points upright(scan.points.size());
      for (size_t i = 0; i < upright.size(); ++i) upright[i] = r * scan.points[i];
      auto floor = EstimateUpAxis(upright, Eigen::Vector3d::UnitZ(), kLevelMaxDeg);
      if (floor) floor = RefineFloorNormal(upright, *floor);
      const double tilt = floor ? std::acos(std::clamp(floor->normalized().z(), -1.0, 1.0)) * 180.0 / M_PI : 0.0;
      if (floor && tilt > kLevelMinDeg) {
        t.linear() = Eigen::Quaterniond::FromTwoVectors(floor->normalized(), Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                     t.linear();
        std::ostringstream s;
        s.precision(3);
        s << o.up << ", levelled by " << tilt << " deg";
        how = s.str();
        spdlog::info("{}: the floor is tilted {:.1f} deg from --up {}: levelled", scan.source, tilt, o.up);
      } else {
        spdlog::debug("{}: level: {}", scan.source,
                      floor ? fmt::format("the floor is within {:.1f} deg of --up {}: kept", tilt, o.up)
                            : std::string("no floor plane found: the axis is kept"));
      }
    }
  }
  scan.frame.to_upright = t;
  scan.frame.up = how;
  if (o.canonical) {
    Points upright;
    const Points* u = &scan.points;
    if (!t.matrix().isIdentity()) {
      const Eigen::Isometry3f tf = t.cast<float>();
      upright.resize(scan.points.size());
      for (size_t i = 0; i < upright.size(); ++i) upright[i] = tf * scan.points[i];
      u = &upright;
    }
    auto nb = o.neighbours > 0 ? std::make_shared<ScanNeighbours>() : nullptr;
    scan.frame.canonical = EstimateCanonicalFrame(*u, nb.get(), o.neighbours);
    // The working frame is a turn and a shift of the z-up one: the same neighbours.
    scan.neighbours = nb && nb->k > 0 ? std::move(nb) : nullptr;
    const Eigen::Isometry3d& c = scan.frame.canonical;
    spdlog::debug("{}: canonical frame: turned {:.3f} deg about z, shifted by ({:.3f}, {:.3f}, {:.3f}) m", scan.source,
                  std::atan2(c.linear()(1, 0), c.linear()(0, 0)) * 180.0 / M_PI, c.translation().x(),
                  c.translation().y(), c.translation().z());
  } else {
    scan.frame.canonical = Eigen::Isometry3d::Identity();
  }
  // One rounding: the file's (shifted) coordinates straight into the working frame, in double.
  const Eigen::Isometry3d w = scan.frame.ToWorking();
  if (w.matrix().isIdentity()) return;
  for (auto& p : scan.points) p = (w * p.cast<double>()).cast<float>();
  if (scan.origin) scan.origin = (w * scan.origin->cast<double>()).cast<float>();
}

nlohmann::json ToJson(const ScanFrame& f) {
  auto rows = [](const Eigen::Isometry3d& t) {
    nlohmann::json m = nlohmann::json::array();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m.push_back(t.matrix()(r, c));
    return m;
  };
  return {{"shift", {f.shift.x(), f.shift.y(), f.shift.z()}},
          {"file_to_upright", rows(f.to_upright)},
          {"upright_to_working", rows(f.canonical)},
          {"file_to_working", rows(f.ToWorking())},
          {"up", f.up}};
}

}  // namespace furnihost
