#include "furnihost/io.hpp"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace furnihost {

void RequireRegularFile(const std::string& path, const std::string& what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw InputError(path + ": no such " + what);
  if (S_ISDIR(st.st_mode)) throw InputError(path + ": is a directory, expected a " + what);
  if (!S_ISREG(st.st_mode)) throw InputError(path + ": is not a regular file (FIFO, device or socket), expected a " + what);
  if (::access(path.c_str(), R_OK) != 0) throw InputError(path + ": cannot be read (permission denied)");
  if (st.st_size == 0) throw InputError(path + ": is empty");
}

namespace {

std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

void CheckCap(const std::string& path, size_t n, size_t max_points) {
  if (max_points && n > max_points)
    throw InputError(path + ": " + std::to_string(n) + " points exceed the limit of " + std::to_string(max_points) +
                     " (raise the graph's limits.max_points or the sensor's max_points)");
}

// Scans are in metres in a local frame. Farther points are dropped like NaNs: they are no
// furniture, and grid keys (voxels, vote cells) computed from them would overflow.
constexpr float kMaxCoordinate = 1e6f;
// A file whose first finite point lies this far from the origin [m] is shifted automatically
// (as CloudCompare offers): no room scan in a local frame reaches 10 km.
constexpr double kAutoShiftFrom = 1e4;
// ... and no farther than this: ECEF and every map projection stay below 1e8 m; beyond is
// garbage (1e30 from a broken driver), dropped as far points, never a shift.
constexpr double kAutoShiftUpTo = 1e8;
// The shift for a first point `d`: each far coordinate rounded down to 100 m, so the local
// coordinates keep their decimals and the shift reads well in a log.
Eigen::Vector3d AutoShift(const Eigen::Vector3d& d) {
  Eigen::Vector3d s = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k)
    if (std::abs(d[k]) >= kAutoShiftFrom) s[k] = std::floor(d[k] / 100.0) * 100.0;
  return s;
}

// What the readers drop besides keeping ReadStats, and the global shift (in double, before
// anything is rounded to float): files in georeferenced coordinates (UTM: x ~ 7e5, y ~ 5e6)
// would lose centimetres to float rounding, and grid keys computed from them would overflow.
struct Tally {
  ReadStats stats;
  size_t far = 0;  // finite points beyond kMaxCoordinate after the shift
  std::optional<Eigen::Vector3d> shift;  // subtracted from every point; set by the first far point when automatic
  bool auto_shift = true;
  // True when `d` is kept (then `v` holds it, shifted); counts it otherwise.
  bool Keep(const Eigen::Vector3d& d, Eigen::Vector3f& v) {
    if (!d.allFinite()) {
      ++stats.non_finite;
      return false;
    }
    if (!shift && auto_shift && d.cwiseAbs().maxCoeff() >= kAutoShiftFrom && d.cwiseAbs().maxCoeff() <= kAutoShiftUpTo)
      shift = AutoShift(d);
    const Eigen::Vector3d local = shift ? Eigen::Vector3d(d - *shift) : d;
    if (local.cwiseAbs().maxCoeff() > kMaxCoordinate) {
      ++far;
      return false;
    }
    v = local.cast<float>();
    return true;
  }
};

// PCL trusts a PCD header's sizes: it allocates WIDTH x HEIGHT x point size before reading
// anything, and unpacks binary_compressed data for the header's point count even when the
// stored uncompressed size is smaller (a crash on a 20-byte file). The sizes are checked
// against the file first; a header this parser cannot read is left to PCL to refuse.
void PrecheckPcd(const std::string& path, size_t max_points) {
  std::ifstream in(path, std::ios::binary);
  std::string line, data;
  std::vector<long long> sizes, counts;
  long long width = -1, height = -1, points = -1;
  size_t header_bytes = 0;
  while (data.empty() && std::getline(in, line)) {
    header_bytes += line.size() + 1;
    if (header_bytes > (1u << 16)) return;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    long long v;
    if (key == "SIZE") while (ls >> v) sizes.push_back(v);
    else if (key == "COUNT") while (ls >> v) counts.push_back(v);
    else if (key == "WIDTH") ls >> width;
    else if (key == "HEIGHT") ls >> height;
    else if (key == "POINTS") ls >> points;
    else if (key == "DATA") ls >> data;
  }
  // PCL's defaults for a missing HEIGHT / WIDTH.
  if (height < 0) height = 1;
  if (width < 0) width = points;
  if (data.empty() || width < 0 || sizes.empty()) return;
  unsigned __int128 step = 0, values = 0;  // bytes and values per point
  for (size_t i = 0; i < sizes.size(); ++i) {
    const long long c = i < counts.size() ? counts[i] : 1;
    if (sizes[i] <= 0 || c <= 0) return;
    step += static_cast<unsigned __int128>(sizes[i]) * static_cast<unsigned __int128>(c);
    values += static_cast<unsigned __int128>(c);
  }
  const unsigned __int128 n = static_cast<unsigned __int128>(width) * static_cast<unsigned __int128>(height);
  const unsigned __int128 most = std::max<unsigned __int128>(n, points > 0 ? points : 0);
  const size_t shown = most > std::numeric_limits<size_t>::max() ? std::numeric_limits<size_t>::max()
                                                                  : static_cast<size_t>(most);
  CheckCap(path, shown, max_points);
  std::error_code ec;
  const auto file_size = fs::file_size(path, ec);
  if (ec || file_size < header_bytes) return;
  const unsigned __int128 left = file_size - header_bytes;
  const std::string declared = std::to_string(shown) + " points";
  if (data == "binary" && n * step > left)
    throw InputError(path + ": PCD data shorter than its header says (" + declared + ", " +
                     std::to_string(static_cast<size_t>(left)) + " bytes of data)");
  // Each ascii value takes at least one byte.
  if (data == "ascii" && most * values > left)
    throw InputError(path + ": PCD declares " + declared + " but holds " + std::to_string(static_cast<size_t>(left)) +
                     " bytes of data");
  if (data == "binary_compressed") {
    uint32_t sz[2] = {0, 0};
    in.read(reinterpret_cast<char*>(sz), sizeof sz);
    if (!in || left < 8) throw InputError(path + ": binary_compressed PCD data truncated (no size words)");
    if (sz[0] > left - 8)
      throw InputError(path + ": binary_compressed PCD data truncated (" + std::to_string(sz[0]) +
                       " compressed bytes declared, " + std::to_string(static_cast<size_t>(left - 8)) + " present)");
    // LZF expands at most ~88x (a 3-byte back reference copies up to 264 bytes).
    if (sz[1] != n * step || (n > 0 && sz[0] == 0) || sz[1] > 100ull * sz[0] + 64)
      throw InputError(path + ": corrupt binary_compressed PCD (uncompressed size " + std::to_string(sz[1]) +
                       " bytes, the header's " + declared + " need " +
                       std::to_string(static_cast<unsigned long long>(std::min<unsigned __int128>(n * step, ~0ull))) + ")");
  }
}

// ---- PCD (PCL) -------------------------------------------------------------------------------
Scan ReadPcd(const std::string& path, Tally& tally, size_t max_points) {
  ReadStats& stats = tally.stats;
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);  // our message replaces PCL's
  PrecheckPcd(path, max_points);
  pcl::PCDReader reader;
  pcl::PCLPointCloud2 blob;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int version = 0;
  // Read the header first so a huge declared size is refused before allocating.
  int data_type = 0;
  unsigned int data_idx = 0;
  int header_rc = -1;
  try {  // PCL's header parser throws std::out_of_range on some malformed lines
    header_rc = reader.readHeader(path, blob, origin, orientation, version, data_type, data_idx);
  } catch (const std::exception& e) {
    throw InputError(path + ": not a valid PCD file (bad header: " + e.what() + ")");
  }
  if (header_rc < 0) throw InputError(path + ": not a valid PCD file (bad header)");
  const size_t declared = static_cast<size_t>(blob.width) * blob.height;
  CheckCap(path, declared, max_points);
  bool has_x = false, has_y = false, has_z = false;
  for (const auto& f : blob.fields) {
    has_x |= f.name == "x";
    has_y |= f.name == "y";
    has_z |= f.name == "z";
  }
  if (!has_x || !has_y || !has_z) throw InputError(path + ": PCD has no x, y, z fields");
  blob = pcl::PCLPointCloud2();
  int rc = -1;
  try {
    rc = reader.read(path, blob, origin, orientation, version);
  } catch (const std::exception& e) {
    throw InputError(path + ": corrupt PCD data (" + e.what() + ")");
  }
  if (rc < 0) throw InputError(path + ": corrupt or truncated PCD data");
  const size_t n = static_cast<size_t>(blob.width) * blob.height;
  if (n * blob.point_step > blob.data.size()) throw InputError(path + ": PCD data shorter than its header says");
  int off[3] = {-1, -1, -1};
  for (const auto& f : blob.fields) {
    int k = f.name == "x" ? 0 : f.name == "y" ? 1 : f.name == "z" ? 2 : -1;
    if (k < 0) continue;
    if (f.datatype != pcl::PCLPointField::FLOAT32 && f.datatype != pcl::PCLPointField::FLOAT64)
      throw InputError(path + ": PCD field " + f.name + " is not float");
    off[k] = static_cast<int>(f.offset) | (f.datatype == pcl::PCLPointField::FLOAT64 ? 1 << 30 : 0);
  }
  Scan scan;
  scan.source = path;
  scan.points.reserve(n);
  stats.read = n;
  for (size_t i = 0; i < n; ++i) {
    const uint8_t* p = blob.data.data() + i * blob.point_step;
    Eigen::Vector3d d;
    for (int k = 0; k < 3; ++k) {
      const bool dbl = off[k] & (1 << 30);
      const size_t o = off[k] & ~(1 << 30);
      if (o + (dbl ? 8 : 4) > blob.point_step) throw InputError(path + ": PCD field offsets exceed the point size");
      if (dbl) {
        std::memcpy(&d[k], p + o, 8);
      } else {
        float f;
        std::memcpy(&f, p + o, 4);
        d[k] = f;
      }
    }
    Eigen::Vector3f v;
    if (!tally.Keep(d, v)) continue;
    scan.points.push_back(v);
  }
  const bool default_view = origin.head<3>().isZero() && orientation.coeffs().isApprox(Eigen::Quaternionf::Identity().coeffs());
  if (!default_view && origin.head<3>().allFinite()) {
    const Eigen::Vector3d o = origin.head<3>().cast<double>() - tally.shift.value_or(Eigen::Vector3d::Zero());
    scan.origin = o.cast<float>();
  }
  return scan;
}

// ---- PLY (own reader: keeps label/instance/colour, refuses inconsistent sizes) -----------
struct PlyProp {
  std::string name, type;
  int size = 0;
};

int PlyTypeSize(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "int32" || t == "uint32" || t == "float" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

double PlyDecode(const uint8_t* p, const std::string& t, bool swap) {
  uint8_t b[8];
  const int n = PlyTypeSize(t);
  for (int i = 0; i < n; ++i) b[i] = swap ? p[n - 1 - i] : p[i];
  if (t == "char" || t == "int8") return static_cast<int8_t>(b[0]);
  if (t == "uchar" || t == "uint8") return b[0];
  if (t == "short" || t == "int16") { int16_t v; std::memcpy(&v, b, 2); return v; }
  if (t == "ushort" || t == "uint16") { uint16_t v; std::memcpy(&v, b, 2); return v; }
  if (t == "int" || t == "int32") { int32_t v; std::memcpy(&v, b, 4); return v; }
  if (t == "uint" || t == "uint32") { uint32_t v; std::memcpy(&v, b, 4); return v; }
  if (t == "float" || t == "float32") { float v; std::memcpy(&v, b, 4); return v; }
  double v;
  std::memcpy(&v, b, 8);
  return v;
}

Scan ReadPly(const std::string& path, Tally& tally, size_t max_points) {
  ReadStats& stats = tally.stats;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot be opened");
  std::string line;
  if (!std::getline(in, line) || line.rfind("ply", 0) != 0) throw InputError(path + ": not a PLY file (no 'ply' magic)");
  std::string format;
  size_t n_vertex = 0;
  bool in_vertex = false, seen_vertex = false, vertex_first = true;
  std::vector<PlyProp> props;
  int header_lines = 0;
  while (std::getline(in, line)) {
    if (++header_lines > 10000) throw InputError(path + ": PLY header too long");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "format") {
      ls >> format;
    } else if (word == "element") {
      std::string name;
      long long count = -1;
      ls >> name >> count;
      if (count < 0 || ls.fail()) throw InputError(path + ": PLY element '" + name + "' has a bad count");
      in_vertex = name == "vertex";
      if (in_vertex) {
        n_vertex = static_cast<size_t>(count);
        seen_vertex = true;
      } else if (!seen_vertex && count > 0) {
        vertex_first = false;
      }
    } else if (word == "property" && in_vertex) {
      std::string type, name;
      ls >> type;
      if (type == "list") throw InputError(path + ": PLY vertex list properties are not supported");
      ls >> name;
      int sz = PlyTypeSize(type);
      if (!sz) throw InputError(path + ": PLY property '" + name + "' has unknown type '" + type + "'");
      props.push_back({name, type, sz});
    } else if (word == "end_header") {
      break;
    }
  }
  if (line.rfind("end_header", 0) != 0) throw InputError(path + ": PLY header has no end_header");
  if (!seen_vertex) throw InputError(path + ": PLY has no vertex element");
  if (!vertex_first) throw InputError(path + ": PLY elements before 'vertex' are not supported");
  int ix = -1, iy = -1, iz = -1, ir = -1, ig = -1, ib = -1;
  for (size_t i = 0; i < props.size(); ++i) {
    const auto& nm = props[i].name;
    if (nm == "x") ix = i;
    if (nm == "y") iy = i;
    if (nm == "z") iz = i;
    if (nm == "red" || nm == "r" || nm == "diffuse_red") ir = i;
    if (nm == "green" || nm == "g" || nm == "diffuse_green") ig = i;
    if (nm == "blue" || nm == "b" || nm == "diffuse_blue") ib = i;
  }
  if (ix < 0 || iy < 0 || iz < 0) throw InputError(path + ": PLY vertex has no x, y, z properties");
  CheckCap(path, n_vertex, max_points);
  const bool colour = ir >= 0 && ig >= 0 && ib >= 0;
  std::vector<int> attr_props;
  for (size_t i = 0; i < props.size(); ++i) {
    const auto& t = props[i].type;
    const bool integer = t != "float" && t != "float32" && t != "double" && t != "float64";
    if (integer && (int)i != ir && (int)i != ig && (int)i != ib) attr_props.push_back(i);
  }
  Scan scan;
  scan.source = path;
  stats.read = n_vertex;
  std::vector<double> vals(props.size());
  auto keep = [&](size_t) {
    Eigen::Vector3f v;
    if (!tally.Keep(Eigen::Vector3d(vals[ix], vals[iy], vals[iz]), v)) return;
    scan.points.push_back(v);
    if (colour)
      scan.colors.push_back({static_cast<uint8_t>(std::clamp(vals[ir], 0.0, 255.0)),
                             static_cast<uint8_t>(std::clamp(vals[ig], 0.0, 255.0)),
                             static_cast<uint8_t>(std::clamp(vals[ib], 0.0, 255.0))});
    // Integer attributes may be uint32 (or ascii text of any size): clamp to int32 (UB otherwise).
    for (int a : attr_props)
      scan.attributes[props[a].name].push_back(
          std::isfinite(vals[a]) ? static_cast<int32_t>(std::clamp(vals[a], -2147483648.0, 2147483647.0)) : 0);
  };
  if (format == "ascii") {
    for (size_t i = 0; i < n_vertex; ++i) {
      if (!std::getline(in, line)) throw InputError(path + ": PLY ends after " + std::to_string(i) + " of " + std::to_string(n_vertex) + " vertices");
      std::istringstream ls(line);
      for (size_t k = 0; k < props.size(); ++k) {
        std::string tok;
        if (!(ls >> tok)) throw InputError(path + ": PLY vertex " + std::to_string(i) + " has too few values");
        char* end = nullptr;
        vals[k] = std::strtod(tok.c_str(), &end);
        if (end == tok.c_str()) throw InputError(path + ": PLY vertex " + std::to_string(i) + " has a non-numeric value '" + tok + "'");
      }
      keep(i);
    }
  } else if (format == "binary_little_endian" || format == "binary_big_endian") {
    const bool swap = format == "binary_big_endian";
    size_t stride = 0;
    std::vector<size_t> offs;
    for (const auto& p : props) {
      offs.push_back(stride);
      stride += p.size;
    }
    const auto data_start = in.tellg();
    in.seekg(0, std::ios::end);
    const auto file_end = in.tellg();
    in.seekg(data_start);
    if (data_start < 0 || file_end < data_start ||
        static_cast<size_t>(file_end - data_start) / std::max<size_t>(stride, 1) < n_vertex)
      throw InputError(path + ": PLY declares " + std::to_string(n_vertex) + " vertices but the file holds fewer");
    std::vector<uint8_t> buf(stride * std::min<size_t>(n_vertex, 65536));
    size_t done = 0;
    while (done < n_vertex) {
      const size_t chunk = std::min<size_t>(n_vertex - done, 65536);
      in.read(reinterpret_cast<char*>(buf.data()), chunk * stride);
      if (static_cast<size_t>(in.gcount()) != chunk * stride) throw InputError(path + ": PLY data truncated");
      for (size_t i = 0; i < chunk; ++i) {
        for (size_t k = 0; k < props.size(); ++k) vals[k] = PlyDecode(buf.data() + i * stride + offs[k], props[k].type, swap);
        keep(done + i);
      }
      done += chunk;
    }
  } else {
    throw InputError(path + ": unknown PLY format '" + format + "'");
  }
  return scan;
}

// ---- XYZ -------------------------------------------------------------------------------
Scan ReadXyz(const std::string& path, Tally& tally, size_t max_points) {
  ReadStats& stats = tally.stats;
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot be opened");
  Scan scan;
  scan.source = path;
  std::string line;
  size_t lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#' || line[first] == '/') continue;
    for (auto& c : line)
      if (c == ',' || c == ';') c = ' ';
    const char* s = line.c_str();
    double v[3];
    for (int k = 0; k < 3; ++k) {
      char* end = nullptr;
      v[k] = std::strtod(s, &end);
      if (end == s) throw InputError(path + ":" + std::to_string(lineno) + ": expected x y z, got '" + line.substr(0, 40) + "'");
      s = end;
    }
    ++stats.read;
    CheckCap(path, stats.read, max_points);
    Eigen::Vector3f p;
    if (!tally.Keep(Eigen::Vector3d(v[0], v[1], v[2]), p)) continue;
    scan.points.push_back(p);
  }
  return scan;
}

}  // namespace

Scan ReadScan(const std::string& path, ReadStats* stats_out, size_t max_points, const ShiftOption& shift) {
  RequireRegularFile(path, "scan file");
  Tally tally;
  tally.shift = shift.shift;
  tally.auto_shift = shift.automatic;
  const ReadStats& stats = tally.stats;
  const std::string ext = Lower(fs::path(path).extension().string());
  Scan scan;
  if (ext == ".pcd") scan = ReadPcd(path, tally, max_points);
  else if (ext == ".ply") scan = ReadPly(path, tally, max_points);
  else if (ext == ".xyz" || ext == ".txt" || ext == ".pts" || ext == ".asc") scan = ReadXyz(path, tally, max_points);
  else throw InputError(path + ": unknown scan format '" + ext + "' (expected .pcd, .ply, .xyz or .txt)");
  if (scan.points.empty() && tally.far)
    throw InputError(path + ": holds no points within " + std::to_string(static_cast<int>(kMaxCoordinate)) +
                     " m of the " + (tally.shift ? "shifted origin" : "origin") + " (" + std::to_string(tally.far) +
                     " farther; give the global shift with --shift x,y,z)");
  scan.frame.shift = tally.shift.value_or(Eigen::Vector3d::Zero());
  if (tally.shift && !shift.shift)
    spdlog::info("{}: coordinates far from the origin: global shift ({:.1f}, {:.1f}, {:.1f}) subtracted (outputs are "
                 "written back in the file's coordinates)", path, scan.frame.shift.x(), scan.frame.shift.y(),
                 scan.frame.shift.z());
  if (scan.points.empty()) throw InputError(path + ": holds no finite points");
  if (stats.non_finite) spdlog::info("{}: dropped {} NaN/inf points of {}", path, stats.non_finite, stats.read);
  if (tally.far)
    spdlog::warn("{}: dropped {} of {} points farther than {} m from the origin (scans are metres in a local frame)",
                 path, tally.far, stats.read, static_cast<int>(kMaxCoordinate));
  if (stats_out) *stats_out = stats;
  return scan;
}

void AtomicWrite(const std::string& path, const std::function<void(const std::string&)>& fill) {
  fs::path p(path);
  std::error_code ec;
  if (p.has_parent_path()) fs::create_directories(p.parent_path(), ec);
  if (fs::is_directory(p)) throw InputError(path + ": is a directory, cannot write a file there");
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  try {
    fill(tmp);
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  fs::rename(tmp, p, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw InputError(path + ": cannot write (" + ec.message() + ")");
  }
}

namespace {
std::ofstream OpenOut(const std::string& tmp, bool binary) {
  std::ofstream out(tmp, binary ? std::ios::binary : std::ios::out);
  if (!out) throw InputError(tmp + ": cannot open for writing");
  return out;
}
void Finish(std::ofstream& out, const std::string& tmp) {
  out.flush();
  if (!out) throw InputError(tmp + ": write failed (disk full?)");
}
}  // namespace

void AtomicWriteText(const std::string& path, const std::string& text) {
  AtomicWrite(path, [&](const std::string& tmp) {
    auto out = OpenOut(tmp, true);
    out << text;
    Finish(out, tmp);
  });
}

void WriteJson(const std::string& path, const nlohmann::json& j) { AtomicWriteText(path, j.dump(2) + "\n"); }

void WritePcd(const std::string& path, const Scan& scan) {
  AtomicWrite(path, [&](const std::string& tmp) {
    auto out = OpenOut(tmp, true);
    const Eigen::Vector3f o = scan.origin.value_or(Eigen::Vector3f::Zero());
    out << "# .PCD v0.7 - Point Cloud Data file format (written by furnihost)\nVERSION 0.7\n"
        << "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " << scan.points.size()
        << "\nHEIGHT 1\nVIEWPOINT " << o.x() << " " << o.y() << " " << o.z() << " 1 0 0 0\nPOINTS "
        << scan.points.size() << "\nDATA binary\n";
    out.write(reinterpret_cast<const char*>(scan.points.data()), scan.points.size() * sizeof(Eigen::Vector3f));
    Finish(out, tmp);
  });
}

void WritePly(const std::string& path, const Points& points, const std::vector<std::array<uint8_t, 3>>* colors) {
  const bool rgb = colors && colors->size() == points.size();
  AtomicWrite(path, [&](const std::string& tmp) {
    auto out = OpenOut(tmp, true);
    out << "ply\nformat binary_little_endian 1.0\ncomment written by furnihost\nelement vertex " << points.size()
        << "\nproperty float x\nproperty float y\nproperty float z\n";
    if (rgb) out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    out << "end_header\n";
    std::vector<char> buf;
    buf.reserve(points.size() * 15);
    for (size_t i = 0; i < points.size(); ++i) {
      const char* p = reinterpret_cast<const char*>(points[i].data());
      buf.insert(buf.end(), p, p + 12);
      if (rgb) buf.insert(buf.end(), (*colors)[i].begin(), (*colors)[i].end());
    }
    out.write(buf.data(), buf.size());
    Finish(out, tmp);
  });
}

void WritePlyInFrame(const std::string& path, const Points& working, const ScanFrame& frame,
                     const std::vector<std::array<uint8_t, 3>>* colors) {
  if (frame.IsIdentity()) return WritePly(path, working, colors);
  if (frame.shift.isZero()) {
    const Eigen::Isometry3f back = frame.ToWorking().inverse().cast<float>();
    Points p(working.size());
    for (size_t i = 0; i < working.size(); ++i) p[i] = back * working[i];
    return WritePly(path, p, colors);
  }
  const bool rgb = colors && colors->size() == working.size();
  AtomicWrite(path, [&](const std::string& tmp) {
    auto out = OpenOut(tmp, true);
    out << "ply\nformat binary_little_endian 1.0\ncomment written by furnihost (global shift " << std::fixed
        << frame.shift.x() << " " << frame.shift.y() << " " << frame.shift.z() << " added back)\nelement vertex "
        << working.size() << "\nproperty double x\nproperty double y\nproperty double z\n";
    if (rgb) out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    out << "end_header\n";
    std::vector<char> buf;
    buf.reserve(working.size() * 27);
    for (size_t i = 0; i < working.size(); ++i) {
      const Eigen::Vector3d q = frame.ToFile(working[i]);
      const char* p = reinterpret_cast<const char*>(q.data());
      buf.insert(buf.end(), p, p + 24);
      if (rgb) buf.insert(buf.end(), (*colors)[i].begin(), (*colors)[i].end());
    }
    out.write(buf.data(), buf.size());
    Finish(out, tmp);
  });
}

void WriteXyz(const std::string& path, const Points& points) {
  AtomicWrite(path, [&](const std::string& tmp) {
    auto out = OpenOut(tmp, false);
    char line[96];
    for (const auto& p : points) {
      std::snprintf(line, sizeof line, "%.6g %.6g %.6g\n", p.x(), p.y(), p.z());
      out << line;
    }
    Finish(out, tmp);
  });
}

void WriteScan(const std::string& path, const Scan& scan) {
  const std::string ext = Lower(fs::path(path).extension().string());
  if (ext == ".pcd") WritePcd(path, scan);
  else if (ext == ".ply") WritePly(path, scan.points, scan.colors.empty() ? nullptr : &scan.colors);
  else if (ext == ".xyz" || ext == ".txt") WriteXyz(path, scan.points);
  else throw InputError(path + ": unknown output format '" + ext + "' (use .pcd, .ply or .xyz)");
}

nlohmann::json ReadJson(const std::string& path) {
  RequireRegularFile(path, "JSON file");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  // Refuse absurd nesting before parsing (the parser and destructor would recurse deeply).
  int depth = 0, max_depth = 0;
  bool in_str = false, esc = false;
  for (char c : text) {
    if (in_str) {
      if (esc) esc = false;
      else if (c == '\\') esc = true;
      else if (c == '"') in_str = false;
      continue;
    }
    if (c == '"') in_str = true;
    else if (c == '[' || c == '{') max_depth = std::max(max_depth, ++depth);
    else if (c == ']' || c == '}') --depth;
  }
  if (max_depth > 256) throw InputError(path + ": JSON nested deeper than 256 levels");
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    // parse_error, and out_of_range for numbers beyond double ("1e400").
    std::string what = e.what();
    auto pos = what.find("] ");
    throw InputError(path + ": not valid JSON: " + (pos == std::string::npos ? what : what.substr(pos + 2)));
  }
}

namespace {
Eigen::Vector3f Vec3(const nlohmann::json& j, const std::string& where) {
  if (!j.is_array() || j.size() != 3) throw InputError(where + ": expected [x, y, z]");
  Eigen::Vector3f v;
  for (int k = 0; k < 3; ++k) {
    if (!j[k].is_number()) throw InputError(where + ": expected numbers");
    v[k] = j[k].get<float>();
  }
  if (!v.allFinite()) throw InputError(where + ": non-finite value");
  return v;
}
}  // namespace

std::vector<GroundTruthObject> ReadGroundTruth(const std::string& path) {
  nlohmann::json j = ReadJson(path);
  if (!j.is_object() || !j.contains("objects") || !j["objects"].is_array())
    throw InputError(path + ":/objects: expected a list of objects");
  if (j.contains("units") && j["units"] != "m") throw InputError(path + ":/units: only \"m\" is supported");
  if (j.contains("up") && j["up"] != "z") throw InputError(path + ":/up: only \"z\" is supported");
  std::vector<GroundTruthObject> out;
  for (size_t i = 0; i < j["objects"].size(); ++i) {
    const auto& o = j["objects"][i];
    const std::string at = path + ":/objects/" + std::to_string(i);
    if (!o.is_object() || !o.contains("class") || !o["class"].is_string()) throw InputError(at + "/class: expected a string");
    GroundTruthObject g;
    g.cls = o["class"].get<std::string>();
    g.center = Vec3(o.value("center", nlohmann::json()), at + "/center");
    g.size = Vec3(o.value("size", nlohmann::json()), at + "/size");
    if (o.contains("yaw") && o["yaw"].is_number()) g.yaw = o["yaw"].get<float>();
    if (o.contains("model") && o["model"].is_string()) g.model = o["model"].get<std::string>();
    if (o.contains("yaw_symmetry")) {
      const auto& y = o["yaw_symmetry"];
      if (!y.is_number_integer() || y.get<long long>() < 0 || y.get<long long>() > 360)
        throw InputError(at + "/yaw_symmetry: expected an integer 0..360 (0 = any turn, n = n-fold)");
      g.yaw_symmetry = y.get<int>();
    }
    out.push_back(g);
  }
  return out;
}

nlohmann::json GroundTruthToJson(const std::vector<GroundTruthObject>& objects) {
  // Round to 0.1 mm / 1e-6 rad so floats print as 1.55, not 1.5499999523.
  auto r = [](float v, double q) { return std::round(static_cast<double>(v) / q) * q; };
  nlohmann::json arr = nlohmann::json::array();
  for (const auto& g : objects) {
    nlohmann::json o = {{"class", g.cls},
                        {"center", {r(g.center.x(), 1e-4), r(g.center.y(), 1e-4), r(g.center.z(), 1e-4)}},
                        {"size", {r(g.size.x(), 1e-4), r(g.size.y(), 1e-4), r(g.size.z(), 1e-4)}}};
    if (g.yaw) o["yaw"] = r(*g.yaw, 1e-6);
    if (!g.model.empty()) o["model"] = g.model;
    if (g.yaw_symmetry) o["yaw_symmetry"] = *g.yaw_symmetry;
    arr.push_back(o);
  }
  return {{"units", "m"}, {"up", "z"}, {"objects", arr}};
}

}  // namespace furnihost
