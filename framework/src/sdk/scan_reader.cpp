// Scan file readers (.pcd, .ply, .xyz/.txt) and the file check they start with: the SDK part
// of the IO (sensor plugins read scans). The writers and the JSON / ground-truth files are
// host IO (io.cpp).
#include "furnihost/scan_reader.hpp"

#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

#include "shown.hpp"

namespace fs = std::filesystem;

namespace furnihost {

using detail::Clipped;

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
constexpr float kMaxCoordinate = float(kMaxScanCoordinate);
// A file whose first finite point other than (0, 0, 0) (a depth camera's invalid return) lies
// this far from the origin [m] is shifted automatically (as CloudCompare offers). 100 m, not
// more: the pipeline computes in float, whose spacing at 1 km (0.06 mm) already moves normals
// and fits of a room scanned at 1.4-3.3 cm; within 100 m it is 8 times finer.
constexpr double kAutoShiftFrom = 100.0;
// ... and no farther than this: ECEF and every map projection stay below 1e8 m; beyond is
// garbage (1e30 from a broken driver), dropped as far points, never a shift.
constexpr double kAutoShiftUpTo = kMaxGlobalShift;
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
  std::optional<Eigen::Vector3d> shift;  // subtracted from every point; when automatic, set by the first point
  bool auto_shift = true;
  bool decided = false;  // the automatic shift is decided, once, by the first finite point not (0, 0, 0) nor garbage
  // Every stride-th finite point (file coordinates), at most kSample of them, thinned as the
  // file goes on: where the bulk of the scan lies, whichever point came first (ReadScan checks
  // the automatic shift against it).
  static constexpr size_t kSample = 4096;
  std::vector<Eigen::Vector3d> sample;
  size_t stride = 1, countdown = 1;
  // True when `d` is kept (then `v` holds it, shifted); counts it otherwise.
  bool Keep(const Eigen::Vector3d& d, Eigen::Vector3f& v) {
    if (!d.allFinite()) {
      ++stats.non_finite;
      return false;
    }
    if (auto_shift && --countdown == 0) {
      countdown = stride;
      sample.push_back(d);
      if (sample.size() == kSample) {  // keep every other one, sample half as often
        for (size_t k = 0; 2 * k < kSample; ++k) sample[k] = sample[2 * k];
        sample.resize(kSample / 2);
        countdown = stride;  // the next kept position: every 2 x stride-th from the first
        stride *= 2;
      }
    }
    // One decision for the whole file: a room that straddles the threshold is shifted whole or
    // not at all, never torn in two.
    // Garbage beyond kAutoShiftUpTo decides nothing (it is dropped as far).
    if (!decided && !shift && auto_shift && !d.isZero(0.0) && d.cwiseAbs().maxCoeff() <= kAutoShiftUpTo) {
      decided = true;
      if (d.cwiseAbs().maxCoeff() >= kAutoShiftFrom) shift = AutoShift(d);
    }
    const Eigen::Vector3d local = shift ? Eigen::Vector3d(d - *shift) : d;
    if (local.cwiseAbs().maxCoeff() > kMaxCoordinate) {
      ++far;
      return false;
    }
    v = local.cast<float>();
    return true;
  }
};

// ---- PCD (own reader) ------------------------------------------------------------------
// PCL's reader trusts a header's sizes (it allocates and copies what they declare before
// looking at the file) and crashed on fuzzed files, so PCD is read here: the header is
// checked whole (every size, count and offset against the others and against the file) before
// a byte of data is touched.

// PCL writes ~200-byte headers; a header that has no DATA line by then is not one.
constexpr size_t kPcdHeaderMax = size_t(1) << 16;
// Bytes per point: descriptors (VFH: 308 floats) stay far below; more is a corrupt header.
constexpr uint64_t kPcdMaxPointStep = uint64_t(1) << 20;
// Binary data is decoded this many bytes at a time, so a 10^7-point file is never copied whole.
constexpr size_t kPcdChunkBytes = size_t(8) << 20;

struct PcdField {
  std::string name;
  int size = 0;        // bytes per value: 1, 2, 4 or 8
  char type = 0;       // I (signed), U (unsigned), F (float)
  uint64_t count = 1;  // values per point
  size_t offset = 0;   // from the start of a point in the binary layout
};

struct PcdHeader {
  std::vector<PcdField> fields;
  size_t n = 0;           // WIDTH x HEIGHT
  size_t point_step = 0;  // bytes per point
  size_t values = 0;      // values per point (tokens on an ascii line)
  std::string data;       // ascii, binary or binary_compressed
  size_t data_offset = 0; // first byte after the DATA line
  std::optional<Eigen::Vector3d> viewpoint;  // unset when it is PCL's default (no sensor origin)
};

// A header token as shown in a message: printable and short, so the error stays one line.
std::string Token(const std::string& s) { return Clipped(s, 27); }

[[noreturn]] void BadPcdHeader(const std::string& path, const std::string& what) {
  throw InputError(path + ": not a valid PCD file (bad header: " + what + ")");
}

// A decimal count (digits only) up to `max`.
bool ParseCount(const std::string& s, uint64_t max, uint64_t& v) {
  if (s.empty() || s.size() > 20) return false;
  unsigned __int128 acc = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    acc = acc * 10 + unsigned(c - '0');
  }
  if (acc > max) return false;
  v = static_cast<uint64_t>(acc);
  return true;
}

// The whole token is a number (strtod's syntax, so nan and inf too).
bool ParseReal(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size();
}

std::vector<std::string> Tokens(const std::string& line) {
  std::vector<std::string> t;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) t.push_back(line.substr(i, j - i));
    i = j;
  }
  return t;
}

PcdHeader ReadPcdHeader(const std::string& path, std::ifstream& in, uint64_t file_size, size_t max_points) {
  std::string head(static_cast<size_t>(std::min<uint64_t>(file_size, kPcdHeaderMax)), '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  if (static_cast<size_t>(in.gcount()) != head.size()) throw InputError(path + ": cannot be read");
  std::map<std::string, std::vector<std::string>> lines;  // keyword -> its values
  PcdHeader h;
  size_t pos = 0;
  while (h.data.empty()) {
    if (pos >= head.size())
      BadPcdHeader(path, file_size > head.size() ? "no DATA line in the first 64 KiB" : "no DATA line");
    size_t eol = head.find('\n', pos);
    if (eol == std::string::npos) {
      if (file_size > head.size()) BadPcdHeader(path, "no DATA line in the first 64 KiB");
      eol = head.size();
    }
    std::string line = head.substr(pos, eol - pos);
    pos = eol + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::vector<std::string> t = Tokens(line);
    if (t.empty() || t[0][0] == '#') continue;
    std::string key = t[0] == "COLUMNS" ? "FIELDS" : t[0];  // COLUMNS: PCD 0.5's name
    static const char* const kKeys[] = {"VERSION", "FIELDS", "SIZE", "TYPE", "COUNT",
                                        "WIDTH",   "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
    if (std::none_of(std::begin(kKeys), std::end(kKeys), [&](const char* k) { return key == k; }))
      BadPcdHeader(path, "unknown line '" + Token(line) + "'");
    // A keyword given twice is a second header inside the first (the fuzzer's crash).
    if (lines.count(key)) BadPcdHeader(path, key + " given twice");
    t.erase(t.begin());
    if (key == "DATA") {
      if (t.size() != 1 || (t[0] != "ascii" && t[0] != "binary" && t[0] != "binary_compressed"))
        BadPcdHeader(path, "DATA '" + Token(line.substr(std::min<size_t>(line.size(), 5))) +
                               "', expected ascii, binary or binary_compressed");
      h.data = t[0];
      h.data_offset = std::min<size_t>(pos, head.size());
    }
    lines[key] = std::move(t);
  }

  static const std::vector<std::string> kNone;
  auto values_of = [&](const char* key) -> const std::vector<std::string>& {
    const auto it = lines.find(key);
    return it == lines.end() ? kNone : it->second;
  };
  const auto& names = values_of("FIELDS");
  if (names.empty()) BadPcdHeader(path, "no FIELDS");
  for (const char* axis : {"x", "y", "z"})
    if (std::find(names.begin(), names.end(), axis) == names.end()) throw InputError(path + ": PCD has no x, y, z fields");
  const auto& sizes = values_of("SIZE");
  const auto& types = values_of("TYPE");
  const auto& counts = values_of("COUNT");
  auto same_length = [&](const char* key, const std::vector<std::string>& v) {
    if (v.size() != names.size())
      BadPcdHeader(path, std::string(key) + " has " + std::to_string(v.size()) + " entries for " +
                             std::to_string(names.size()) + " FIELDS");
  };
  same_length("SIZE", sizes);
  same_length("TYPE", types);
  if (lines.count("COUNT")) same_length("COUNT", counts);
  uint64_t step = 0, values = 0;
  for (size_t i = 0; i < names.size(); ++i) {
    PcdField f;
    f.name = names[i];
    if (f.name != "_")  // "_" pads; every other name must be unique
      for (size_t j = 0; j < i; ++j)
        if (names[j] == f.name) BadPcdHeader(path, "field '" + Token(f.name) + "' given twice");
    uint64_t v = 0;
    if (!ParseCount(sizes[i], 8, v) || (v != 1 && v != 2 && v != 4 && v != 8))
      BadPcdHeader(path, "SIZE '" + Token(sizes[i]) + "' of field '" + Token(f.name) + "', expected 1, 2, 4 or 8");
    f.size = int(v);
    if (types[i].size() != 1 || (types[i][0] != 'I' && types[i][0] != 'U' && types[i][0] != 'F'))
      BadPcdHeader(path, "TYPE '" + Token(types[i]) + "' of field '" + Token(f.name) + "', expected I, U or F");
    f.type = types[i][0];
    if (f.type == 'F' && f.size < 4) BadPcdHeader(path, "field '" + Token(f.name) + "' is a float of size " + sizes[i]);
    if (!counts.empty() && (!ParseCount(counts[i], kPcdMaxPointStep, f.count) || f.count == 0))
      BadPcdHeader(path, "COUNT '" + Token(counts[i]) + "' of field '" + Token(f.name) + "'");
    f.offset = static_cast<size_t>(step);
    step += uint64_t(f.size) * f.count;
    values += f.count;
    if (step > kPcdMaxPointStep) BadPcdHeader(path, "points of more than 1 MiB");
    h.fields.push_back(f);
  }
  h.point_step = static_cast<size_t>(step);
  h.values = static_cast<size_t>(values);
  for (const auto& f : h.fields)
    if (f.name == "x" || f.name == "y" || f.name == "z") {
      if (f.type != 'F') throw InputError(path + ": PCD field " + f.name + " is not float");
      if (f.count != 1) BadPcdHeader(path, "field " + f.name + " has COUNT " + std::to_string(f.count));
    }

  // PCL stores WIDTH and HEIGHT in 32 bits; so their product fits 64.
  auto count_of = [&](const char* key, uint64_t& v) {
    if (!lines.count(key)) return false;
    const auto& t = values_of(key);
    if (t.size() != 1 || !ParseCount(t[0], 0xFFFFFFFFull, v))
      BadPcdHeader(path, std::string(key) + " '" + Token(t.empty() ? "" : t[0]) + (t.size() > 1 ? " ..." : "") +
                             "' is not a count below 2^32");
    return true;
  };
  uint64_t width = 0, height = 1, points = 0;
  const bool has_width = count_of("WIDTH", width), has_points = count_of("POINTS", points);
  count_of("HEIGHT", height);
  if (!has_width && !has_points) BadPcdHeader(path, "no WIDTH");
  if (!has_width) width = points;  // PCD 0.5 gave only POINTS
  const uint64_t n = width * height;
  CheckCap(path, static_cast<size_t>(std::max(n, points)), max_points);
  if (has_points && points != n)
    BadPcdHeader(path, "POINTS " + std::to_string(points) + " but WIDTH x HEIGHT = " + std::to_string(n));
  h.n = static_cast<size_t>(n);

  if (lines.count("VIEWPOINT")) {
    const auto& t = values_of("VIEWPOINT");
    double vp[7];
    if (t.size() != 7) BadPcdHeader(path, "VIEWPOINT needs 7 numbers (tx ty tz qw qx qy qz)");
    for (int k = 0; k < 7; ++k)
      if (!ParseReal(t[k], vp[k])) BadPcdHeader(path, "VIEWPOINT value '" + Token(t[k]) + "' is not a number");
    // PCL writes 0 0 0 1 0 0 0 when nothing is known: that is no sensor origin.
    const bool default_view = vp[0] == 0 && vp[1] == 0 && vp[2] == 0 && std::abs(vp[3] - 1) < 1e-5 &&
                              std::abs(vp[4]) < 1e-5 && std::abs(vp[5]) < 1e-5 && std::abs(vp[6]) < 1e-5;
    const Eigen::Vector3d o(vp[0], vp[1], vp[2]);
    if (!default_view && o.allFinite()) h.viewpoint = o;
  }
  return h;
}

// LZF as PCL's binary_compressed writes it: a control byte below 32 starts a run of
// control + 1 literal bytes; above, its top 3 bits are a length - 2 (7: a further byte adds to
// it) and its low 5 bits with the next byte an offset - 1 back into the output. Every read is
// bounds-checked. The output is decoded into a window and handed to `emit(offset, bytes, n)` a
// piece at a time, in order: a reference reaches at most 8 KiB back, so the whole output is
// never held (a header may declare gigabytes). False when the stream is corrupt or does not
// give exactly `out_size` bytes.
template <class Emit>
bool LzfDecompress(const uint8_t* in, size_t in_size, uint64_t out_size, Emit&& emit) {
  constexpr size_t kReach = 8192, kWindow = size_t(1) << 18;
  std::vector<uint8_t> win(kWindow);
  size_t ip = 0, wp = 0;   // input position; window position
  uint64_t flushed = 0;    // output bytes emitted before win[0]
  uint64_t first = 0;      // the first output byte not emitted yet
  auto produced = [&] { return flushed + wp; };
  while (ip < in_size) {
    if (wp + 300 > kWindow) {  // room for the longest run (264 bytes): emit, keep the reach
      const size_t keep = std::min<size_t>(kReach, wp);
      if (produced() > first) emit(first, win.data() + (first - flushed), size_t(produced() - first));
      first = produced();
      std::memmove(win.data(), win.data() + (wp - keep), keep);
      flushed += wp - keep;
      wp = keep;
    }
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {
      const size_t len = ctrl + 1;
      if (len > in_size - ip || len > out_size - produced()) return false;
      std::memcpy(win.data() + wp, in + ip, len);
      ip += len;
      wp += len;
      continue;
    }
    size_t len = ctrl >> 5;
    if (len == 7) {
      if (ip >= in_size) return false;
      len += in[ip++];
    }
    len += 2;
    if (ip >= in_size) return false;
    const size_t back = ((size_t(ctrl & 31) << 8) | in[ip++]) + 1;
    if (back > wp || len > out_size - produced()) return false;
    // A reference may overlap the bytes it writes (a repeated run): copy forwards, bytewise.
    for (size_t k = 0; k < len; ++k, ++wp) win[wp] = win[wp - back];
  }
  if (produced() != out_size) return false;
  if (produced() > first) emit(first, win.data() + (first - flushed), size_t(produced() - first));
  return true;
}

double PcdValue(const uint8_t* p, const PcdField& f) {
  switch (f.type) {
    case 'F':
      if (f.size == 4) { float v; std::memcpy(&v, p, 4); return v; }
      else { double v; std::memcpy(&v, p, 8); return v; }
    case 'U':
      switch (f.size) {
        case 1: return *p;
        case 2: { uint16_t v; std::memcpy(&v, p, 2); return v; }
        case 4: { uint32_t v; std::memcpy(&v, p, 4); return v; }
        default: { uint64_t v; std::memcpy(&v, p, 8); return double(v); }
      }
    default:
      switch (f.size) {
        case 1: return static_cast<int8_t>(*p);
        case 2: { int16_t v; std::memcpy(&v, p, 2); return v; }
        case 4: { int32_t v; std::memcpy(&v, p, 4); return v; }
        default: { int64_t v; std::memcpy(&v, p, 8); return double(v); }
      }
  }
}

// Where each field of a point goes: coordinates, packed colour, integer attributes.
struct PcdRoles {
  int xyz[3] = {-1, -1, -1};
  int rgb = -1;  // "rgb" / "rgba": 4 bytes 0xAARRGGBB (PCL stores them as F or U)
  std::vector<int> attrs;  // integer fields of one value (label, instance, ...)
};

PcdRoles RolesOf(const PcdHeader& h) {
  PcdRoles r;
  for (int i = 0; i < int(h.fields.size()); ++i) {
    const auto& f = h.fields[i];
    if (f.name == "x") r.xyz[0] = i;
    else if (f.name == "y") r.xyz[1] = i;
    else if (f.name == "z") r.xyz[2] = i;
    else if ((f.name == "rgb" || f.name == "rgba") && f.size == 4 && f.count == 1 && r.rgb < 0) r.rgb = i;
    else if (f.type != 'F' && f.count == 1 && f.name != "_") r.attrs.push_back(i);
  }
  return r;
}

// Keeps the points of a PCD body, with their colours and attributes.
struct PcdSink {
  Scan& scan;
  Tally& tally;
  const PcdHeader& h;
  const PcdRoles& roles;
  std::vector<std::vector<int32_t>*> attrs;
  PcdSink(Scan& s, Tally& t, const PcdHeader& hd, const PcdRoles& r) : scan(s), tally(t), h(hd), roles(r) {
    for (int a : roles.attrs) attrs.push_back(&scan.attributes[h.fields[a].name]);
  }
  // `value(i)`: field i's value as a double; `bits`: the packed colour.
  template <class Value>
  void Add(const Value& value, uint32_t bits) {
    Eigen::Vector3f v;
    if (!tally.Keep(Eigen::Vector3d(value(roles.xyz[0]), value(roles.xyz[1]), value(roles.xyz[2])), v)) return;
    scan.points.push_back(v);
    if (roles.rgb >= 0)
      scan.colors.push_back({uint8_t(bits >> 16), uint8_t(bits >> 8), uint8_t(bits)});
    for (size_t k = 0; k < attrs.size(); ++k) {
      const double d = value(roles.attrs[k]);
      // Integer fields may be 64-bit or uint32: clamp to int32 (a cast would be UB).
      attrs[k]->push_back(std::isfinite(d) ? static_cast<int32_t>(std::clamp(d, -2147483648.0, 2147483647.0)) : 0);
    }
  }
};

void ReadPcdAscii(const std::string& path, std::ifstream& in, const PcdHeader& h, PcdSink& sink) {
  // Offsets of each field's first value on a line.
  std::vector<size_t> first(h.fields.size());
  for (size_t i = 0, at = 0; i < h.fields.size(); at += h.fields[i].count, ++i) first[i] = at;
  std::vector<double> vals(h.values);
  std::string line;
  size_t i = 0;
  uint32_t bits = 0;
  while (i < h.n) {
    if (!std::getline(in, line))
      throw InputError(path + ": PCD ends after " + std::to_string(i) + " of " + std::to_string(h.n) + " points");
    const std::vector<std::string> t = Tokens(line.size() && line.back() == '\r' ? line.substr(0, line.size() - 1) : line);
    if (t.empty()) continue;
    if (t.size() != h.values)
      throw InputError(path + ": PCD point " + std::to_string(i) + " has " + std::to_string(t.size()) +
                       " values, its header's fields need " + std::to_string(h.values));
    for (size_t k = 0; k < t.size(); ++k)
      if (!ParseReal(t[k], vals[k]))
        throw InputError(path + ": PCD point " + std::to_string(i) + ": '" + Token(t[k]) + "' is not a number");
    if (sink.roles.rgb >= 0) {
      // PCL writes a packed colour as its integer; other writers as the float of the same bits.
      const std::string& c = t[first[sink.roles.rgb]];
      uint64_t u = 0;
      if (ParseCount(c, 0xFFFFFFFFull, u)) {
        bits = uint32_t(u);
      } else {
        const float f = float(vals[first[sink.roles.rgb]]);
        std::memcpy(&bits, &f, 4);
      }
    }
    sink.Add([&](int f) { return vals[first[f]]; }, bits);
    ++i;
  }
}

Scan ReadPcd(const std::string& path, Tally& tally, size_t max_points) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot be opened");
  std::error_code ec;
  const uint64_t file_size = fs::file_size(path, ec);
  if (ec) throw InputError(path + ": cannot be read (" + ec.message() + ")");
  const PcdHeader h = ReadPcdHeader(path, in, file_size, max_points);
  const PcdRoles roles = RolesOf(h);
  const uint64_t left = file_size - h.data_offset;
  const std::string declared = std::to_string(h.n) + " points";
  const unsigned __int128 body = static_cast<unsigned __int128>(h.n) * h.point_step;
  // Sizes against the file before anything is allocated for them.
  if (h.data == "binary" && body > left)
    throw InputError(path + ": PCD data shorter than its header says (" + declared + " of " +
                     std::to_string(h.point_step) + " bytes, " + std::to_string(left) + " bytes of data)");
  if (h.data == "ascii" && static_cast<unsigned __int128>(h.n) * h.values > left)  // a value takes a byte at least
    throw InputError(path + ": PCD declares " + declared + " but holds " + std::to_string(left) + " bytes of data");
  uint32_t sz[2] = {0, 0};  // binary_compressed: compressed and uncompressed sizes
  if (h.data == "binary_compressed") {
    if (left < 8) throw InputError(path + ": binary_compressed PCD data truncated (no size words)");
    in.clear();
    in.seekg(static_cast<std::streamoff>(h.data_offset));
    in.read(reinterpret_cast<char*>(sz), sizeof sz);
    if (!in) throw InputError(path + ": binary_compressed PCD data truncated (no size words)");
    if (sz[0] > left - 8)
      throw InputError(path + ": binary_compressed PCD data truncated (" + std::to_string(sz[0]) +
                       " compressed bytes declared, " + std::to_string(left - 8) + " present)");
    // A 3-byte LZF back reference writes at most 264 bytes.
    if (sz[1] != body || (h.n > 0 && sz[0] == 0) || sz[1] > 100ull * sz[0] + 64)
      throw InputError(path + ": corrupt binary_compressed PCD (uncompressed size " + std::to_string(sz[1]) +
                       " bytes, the header's " + declared + " need " +
                       std::to_string(static_cast<unsigned long long>(std::min<unsigned __int128>(body, ~0ull))) + ")");
  }

  Scan scan;
  scan.source = path;
  tally.stats.read = h.n;
  scan.points.reserve(h.n);
  if (roles.rgb >= 0) scan.colors.reserve(h.n);
  PcdSink sink(scan, tally, h, roles);
  auto bits_at = [&](const uint8_t* p) {
    uint32_t b = 0;
    std::memcpy(&b, p, 4);
    return b;
  };
  if (h.data == "ascii") {
    in.clear();
    in.seekg(static_cast<std::streamoff>(h.data_offset));
    ReadPcdAscii(path, in, h, sink);
  } else if (h.data == "binary") {
    in.clear();
    in.seekg(static_cast<std::streamoff>(h.data_offset));
    const size_t per_chunk = std::max<size_t>(1, kPcdChunkBytes / h.point_step);
    std::vector<uint8_t> buf(std::min(per_chunk, h.n) * h.point_step);
    for (size_t done = 0; done < h.n;) {
      const size_t m = std::min(per_chunk, h.n - done);
      in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(m * h.point_step));
      if (static_cast<size_t>(in.gcount()) != m * h.point_step) throw InputError(path + ": PCD data truncated");
      for (size_t i = 0; i < m; ++i) {
        const uint8_t* p = buf.data() + i * h.point_step;
        sink.Add([&](int f) { return PcdValue(p + h.fields[f].offset, h.fields[f]); },
                 roles.rgb >= 0 ? bits_at(p + h.fields[roles.rgb].offset) : 0);
      }
      done += m;
    }
  } else {
    // The compressed bytes (no more than the file holds), decoded as a stream: stored field by
    // field (all points' x, then all y, ...; field f starts at n x its offset), of which only the
    // fields a point keeps (x, y, z, colour, attributes) are collected, one column each.
    std::vector<uint8_t> packed(sz[0]);
    in.read(reinterpret_cast<char*>(packed.data()), static_cast<std::streamsize>(packed.size()));
    if (static_cast<size_t>(in.gcount()) != packed.size()) throw InputError(path + ": binary_compressed PCD data truncated");
    std::vector<int> kept(roles.xyz, roles.xyz + 3);
    if (roles.rgb >= 0) kept.push_back(roles.rgb);
    kept.insert(kept.end(), roles.attrs.begin(), roles.attrs.end());
    std::vector<std::vector<uint8_t>> column(h.fields.size());
    for (int f : kept) column[size_t(f)].resize(h.n * size_t(h.fields[f].size));  // count 1: RolesOf
    const bool ok = LzfDecompress(packed.data(), packed.size(), sz[1], [&](uint64_t at, const uint8_t* b, size_t len) {
      for (int f : kept) {
        const uint64_t lo = uint64_t(h.n) * h.fields[f].offset, hi = lo + column[size_t(f)].size();
        const uint64_t from = std::max(lo, at), to = std::min<uint64_t>(hi, at + len);
        if (from < to) std::memcpy(column[size_t(f)].data() + (from - lo), b + (from - at), size_t(to - from));
      }
    });
    packed = {};
    if (!ok)
      throw InputError(path + ": corrupt or truncated PCD data (the binary_compressed stream does not decode to " +
                       std::to_string(sz[1]) + " bytes)");
    for (size_t i = 0; i < h.n; ++i) {
      auto at = [&](int f) { return column[size_t(f)].data() + i * size_t(h.fields[f].size); };
      sink.Add([&](int f) { return PcdValue(at(f), h.fields[f]); }, roles.rgb >= 0 ? bits_at(at(roles.rgb)) : 0);
    }
  }
  if (h.viewpoint) scan.origin = (*h.viewpoint - tally.shift.value_or(Eigen::Vector3d::Zero())).cast<float>();
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

// A property type as a code, resolved once per header (decoding compared the type's name
// for every value: a third of reading a 50k-point ScanNet room).
enum class PlyType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };
PlyType PlyTypeOf(const std::string& t) {
  if (t == "char" || t == "int8") return PlyType::kInt8;
  if (t == "uchar" || t == "uint8") return PlyType::kUint8;
  if (t == "short" || t == "int16") return PlyType::kInt16;
  if (t == "ushort" || t == "uint16") return PlyType::kUint16;
  if (t == "int" || t == "int32") return PlyType::kInt32;
  if (t == "uint" || t == "uint32") return PlyType::kUint32;
  if (t == "float" || t == "float32") return PlyType::kFloat32;
  return PlyType::kFloat64;
}

double PlyDecode(const uint8_t* p, PlyType t, int n, bool swap) {
  uint8_t b[8];
  for (int i = 0; i < n; ++i) b[i] = swap ? p[n - 1 - i] : p[i];
  switch (t) {
    case PlyType::kInt8: return static_cast<int8_t>(b[0]);
    case PlyType::kUint8: return b[0];
    case PlyType::kInt16: { int16_t v; std::memcpy(&v, b, 2); return v; }
    case PlyType::kUint16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
    case PlyType::kInt32: { int32_t v; std::memcpy(&v, b, 4); return v; }
    case PlyType::kUint32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
    case PlyType::kFloat32: { float v; std::memcpy(&v, b, 4); return v; }
    case PlyType::kFloat64: break;
  }
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
      if (in_vertex && seen_vertex)
        throw InputError(path + ": PLY has two 'vertex' elements (one point list per file is read)");
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
  // Each attribute's column, looked up at its first kept point (not once per point).
  std::vector<std::vector<int32_t>*> attr_column(attr_props.size(), nullptr);
  auto keep = [&](size_t) {
    Eigen::Vector3f v;
    if (!tally.Keep(Eigen::Vector3d(vals[ix], vals[iy], vals[iz]), v)) return;
    scan.points.push_back(v);
    // Colour channels may be float properties holding NaN: 0 then (casting NaN is UB).
    auto byte = [](double c) { return static_cast<uint8_t>(std::isfinite(c) ? std::clamp(c, 0.0, 255.0) : 0.0); };
    if (colour) scan.colors.push_back({byte(vals[ir]), byte(vals[ig]), byte(vals[ib])});
    // Integer attributes may be uint32 (or ascii text of any size): clamp to int32 (UB otherwise).
    for (size_t k = 0; k < attr_props.size(); ++k) {
      const int a = attr_props[k];
      if (!attr_column[k]) attr_column[k] = &scan.attributes[props[a].name];
      attr_column[k]->push_back(
          std::isfinite(vals[a]) ? static_cast<int32_t>(std::clamp(vals[a], -2147483648.0, 2147483647.0)) : 0);
    }
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
    std::vector<PlyType> types;
    for (const auto& p : props) {
      offs.push_back(stride);
      types.push_back(PlyTypeOf(p.type));
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
        for (size_t k = 0; k < props.size(); ++k) vals[k] = PlyDecode(buf.data() + i * stride + offs[k], types[k], props[k].size, swap);
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
// One point per line: x y z and optional further columns (intensity, colour, normals), the same
// number on every line. Values are separated by blanks, by commas (CSV) or by semicolons; with
// semicolons (or blanks) a decimal comma ("1,25;2,5;0,75", "1,25 2,5 0,75") is a decimal point,
// decided once, on the first data line, and held to on every line (a file that mixes the styles
// is refused rather than misread). A UTF-8 byte-order mark is skipped; UTF-16 text is refused
// with its name. Leica .pts files begin (each scan) with a line holding the point count alone.

constexpr size_t kXyzMaxLine = size_t(1) << 16;  // bytes; longer is not one point's line
constexpr size_t kXyzMaxColumns = 64;

enum class XyzStyle { kBlank, kComma, kSemicolon, kBlankDecimalComma };

// Blank-separated fields of `line` (blanks: space, tab, CR).
std::vector<std::string> BlankFields(const std::string& line) {
  std::vector<std::string> t;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
    if (j > i) t.push_back(line.substr(i, j - i));
    i = j;
  }
  return t;
}

// A comma between digits inside a field: "1,25".
bool InnerComma(const std::string& f) {
  const size_t c = f.find(',');
  return c != std::string::npos && c > 0 && c + 1 < f.size() && std::isdigit(static_cast<unsigned char>(f[c - 1])) &&
         std::isdigit(static_cast<unsigned char>(f[c + 1]));
}

// Semicolons: separators (commas are decimal). Otherwise commas inside blank-separated values
// ("1,25 2 0,75") are decimal commas, and commas between values ("1,2,3", "1, 2, 3") separate.
XyzStyle StyleOf(const std::string& line) {
  if (line.find(';') != std::string::npos) return XyzStyle::kSemicolon;
  if (line.find(',') == std::string::npos) return XyzStyle::kBlank;
  const auto f = BlankFields(line);
  const bool inner = std::any_of(f.begin(), f.end(), InnerComma);
  const bool trailing = std::any_of(f.begin(), f.end(), [](const std::string& v) { return v.back() == ','; });
  return f.size() >= 3 && inner && !trailing ? XyzStyle::kBlankDecimalComma : XyzStyle::kComma;
}

// The fields of a data line in `style`, decimal commas made points; "" in `why` when the line
// does not follow the style.
std::vector<std::string> XyzFields(const std::string& line, XyzStyle style, std::string& why) {
  std::string t = line;
  std::vector<std::string> f;
  switch (style) {
    case XyzStyle::kBlank:
      if (t.find(',') != std::string::npos || t.find(';') != std::string::npos)
        why = "separators change: ',' or ';' after blank-separated lines";
      return BlankFields(t);
    case XyzStyle::kComma:
      if (t.find(';') != std::string::npos) why = "separators change: ';' after comma-separated lines";
      for (auto& c : t)
        if (c == ',') c = ' ';
      return BlankFields(t);
    case XyzStyle::kSemicolon:
      for (auto& c : t)
        if (c == ';') c = ' ';
      f = BlankFields(t);
      break;
    case XyzStyle::kBlankDecimalComma:
      if (t.find(';') != std::string::npos) why = "separators change: ';' after blank-separated lines";
      f = BlankFields(t);
      break;
  }
  for (auto& v : f) {  // decimal commas
    const size_t c = v.find(',');
    if (c == std::string::npos) continue;
    if (v.find(',', c + 1) != std::string::npos || v.find('.') != std::string::npos) {
      why = "'" + Clipped(v, 30) + "' is no number with a decimal comma";
      return f;
    }
    v[c] = '.';
  }
  return f;
}

Scan ReadXyz(const std::string& path, Tally& tally, size_t max_points) {
  ReadStats& stats = tally.stats;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot be opened");
  const bool pts = Lower(fs::path(path).extension().string()) == ".pts";
  Scan scan;
  scan.source = path;
  std::optional<XyzStyle> style;
  size_t columns = 0, first_line = 0;
  std::vector<char> buf(size_t(1) << 16);
  std::string line;
  size_t lineno = 0;
  bool start = true, done = false;
  auto bad = [&](const std::string& why) { return InputError(path + ":" + std::to_string(lineno) + ": " + why); };
  auto take = [&]() {  // one whole line in `line`
    ++lineno;
    if (line.find('\0') != std::string::npos)
      throw bad("holds NUL bytes: UTF-16 text or binary data, not an XYZ text of one point per line");
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#' || line[first] == '/') return;
    if (!style) style = StyleOf(line), first_line = lineno;
    std::string why;
    const std::vector<std::string> f = XyzFields(line, *style, why);
    if (!why.empty()) throw bad(why + " (line " + std::to_string(first_line) + " set the style)");
    // A Leica .pts count line: the number of points of the scan that follows.
    if (pts && f.size() == 1 && f[0].find_first_not_of("0123456789") == std::string::npos) return;
    if (f.size() > kXyzMaxColumns)
      throw bad("holds " + std::to_string(f.size()) + " values: an XYZ file holds one point per line (x y z and at most " +
                std::to_string(kXyzMaxColumns - 3) + " more columns)");
    double v[3];
    for (size_t k = 0; k < f.size(); ++k) {
      const char* s = f[k].c_str();
      char* end = nullptr;
      const double d = std::strtod(s, &end);
      if (end == s || *end != '\0') throw bad("expected x y z, got '" + Clipped(line, 40) + "'");
      if (k < 3) v[k] = d;
    }
    if (f.size() < 3) throw bad("expected x y z, got '" + Clipped(line, 40) + "'");
    if (columns == 0) columns = f.size();
    if (f.size() != columns)
      throw bad("holds " + std::to_string(f.size()) + " values, line " + std::to_string(first_line) + " held " +
                std::to_string(columns) + " (one point per line, the same columns on every line)");
    ++stats.read;
    CheckCap(path, stats.read, max_points);
    Eigen::Vector3f p;
    if (!tally.Keep(Eigen::Vector3d(v[0], v[1], v[2]), p)) return;
    scan.points.push_back(p);
  };
  // Lines are cut from fixed-size reads: a line longer than kXyzMaxLine is refused when it
  // gets that long, never held whole (20 million points on one line).
  while (!done) {
    in.read(buf.data(), std::streamsize(buf.size()));
    const size_t got = size_t(in.gcount());
    if (got == 0) break;
    size_t i = 0;
    if (start) {  // byte-order marks: UTF-8's is skipped, UTF-16 (or 32) is refused by name
      start = false;
      const auto* u = reinterpret_cast<const uint8_t*>(buf.data());
      if (got >= 2 && ((u[0] == 0xFF && u[1] == 0xFE) || (u[0] == 0xFE && u[1] == 0xFF)))
        throw InputError(path + ": is UTF-16 text; save it as UTF-8 or ASCII (one point per line: x y z)");
      if (got >= 3 && u[0] == 0xEF && u[1] == 0xBB && u[2] == 0xBF) i = 3;
    }
    while (i < got) {
      const char* nl = static_cast<const char*>(std::memchr(buf.data() + i, '\n', got - i));
      const size_t end = nl ? size_t(nl - buf.data()) : got;
      line.append(buf.data() + i, end - i);
      if (line.size() > kXyzMaxLine) {
        ++lineno;
        throw bad("is longer than " + std::to_string(kXyzMaxLine / 1024) +
                  " KiB: an XYZ file holds one point per line (x y z [more columns])");
      }
      i = end;
      if (nl) {
        take();
        line.clear();
        ++i;
      }
    }
  }
  if (!line.empty()) take();
  return scan;
}

// The file read once with `tally`'s shift rules.
Scan ReadFormat(const std::string& path, const std::string& ext, Tally& tally, size_t max_points) {
  if (ext == ".pcd") return ReadPcd(path, tally, max_points);
  if (ext == ".ply") return ReadPly(path, tally, max_points);
  return ReadXyz(path, tally, max_points);
}

// The automatic shift is decided by the first point; when the bulk of the scan (the median of
// the sample) lies farther than this from where that shift put the origin, the first point was
// a stray return (or a stray return near the origin came before a georeferenced bulk), and the
// file is read again with the shift the bulk calls for. [m]
constexpr double kReshiftFrom = 1000.0;

std::optional<Eigen::Vector3d> BetterShift(Tally& t) {
  if (t.sample.empty()) return std::nullopt;
  Eigen::Vector3d m;
  for (int a = 0; a < 3; ++a) {
    std::vector<double> c(t.sample.size());
    for (size_t i = 0; i < c.size(); ++i) c[i] = t.sample[i][a];
    std::nth_element(c.begin(), c.begin() + long(c.size() / 2), c.end());
    m[a] = c[c.size() / 2];
  }
  if (!(m.cwiseAbs().maxCoeff() <= kAutoShiftUpTo)) return std::nullopt;  // a bulk of garbage: dropped as far
  const Eigen::Vector3d now = t.shift.value_or(Eigen::Vector3d::Zero());
  if ((m - now).cwiseAbs().maxCoeff() <= kReshiftFrom) return std::nullopt;
  const Eigen::Vector3d want = AutoShift(m);
  if (want == now) return std::nullopt;
  return want;
}

// Stray far returns (a driver's garbage, a reflection, a point of another scan): points that a
// gap of more than kStrayGap along some axis separates from the largest group of the scan. They
// are dropped, with a warning, in every graph alike, before any stage sees the scan: grids that
// span the scan (voxel indices, occupancy, the canonical frame's box) would otherwise span them.
constexpr float kStrayGap = 100.f;

size_t DropStrayReturns(Scan& scan) {
  const size_t n = scan.points.size();
  if (n < 2) return 0;
  Eigen::AlignedBox3f box;
  for (const auto& p : scan.points) box.extend(p);
  const Eigen::Vector3f extent = box.sizes();
  if (!(extent.maxCoeff() > kStrayGap)) return 0;  // no such gap can fit (every room scan)
  std::vector<char> stray(n, 0);
  std::vector<float> v(n);
  for (int a = 0; a < 3; ++a) {
    if (!(extent[a] > kStrayGap)) continue;
    for (size_t i = 0; i < n; ++i) v[i] = scan.points[i][a];
    std::sort(v.begin(), v.end());
    // The longest run of sorted values without a gap wider than kStrayGap (the first of equals).
    size_t best_b = 0, best_e = 1, b = 0;
    for (size_t i = 1; i <= n; ++i)
      if (i == n || v[i] - v[i - 1] > kStrayGap) {
        if (i - b > best_e - best_b) best_b = b, best_e = i;
        b = i;
      }
    const float lo = v[best_b], hi = v[best_e - 1];
    for (size_t i = 0; i < n; ++i)
      if (scan.points[i][a] < lo || scan.points[i][a] > hi) stray[i] = 1;
  }
  std::vector<size_t> kept;
  kept.reserve(n);
  for (size_t i = 0; i < n; ++i)
    if (!stray[i]) kept.push_back(i);
  if (kept.size() == n) return 0;
  auto keep = [&](auto& values) {
    if (values.size() != n) return;
    for (size_t k = 0; k < kept.size(); ++k) values[k] = values[kept[k]];
    values.resize(kept.size());
  };
  keep(scan.points);
  keep(scan.colors);
  for (auto& [name, values] : scan.attributes) keep(values);
  return n - kept.size();
}

// What every reader does once the points are in: refuses a scan left with no point, records the
// shift, logs what was dropped.
void FinishScan(const std::string& path, const Tally& tally, const ShiftOption& shift, Scan& scan, ReadStats* stats_out) {
  const ReadStats& stats = tally.stats;
  if (scan.points.empty() && tally.far)
    throw InputError(path + ": holds no points within " + std::to_string(static_cast<int>(kMaxCoordinate)) +
                     " m of the " + (tally.shift ? "shifted origin" : "origin") + " (" + std::to_string(tally.far) +
                     " farther; give the global shift with --shift x,y,z)");
  scan.frame.shift = tally.shift.value_or(Eigen::Vector3d::Zero());
  if (!shift.shift && !scan.frame.shift.isZero(0.0))
    spdlog::info("{}: coordinates far from the origin: global shift ({:.1f}, {:.1f}, {:.1f}) subtracted (outputs are "
                 "written back in the file's coordinates)", path, scan.frame.shift.x(), scan.frame.shift.y(),
                 scan.frame.shift.z());
  if (scan.points.empty()) throw InputError(path + ": holds no finite points");
  if (stats.non_finite) spdlog::info("{}: dropped {} NaN/inf points of {}", path, stats.non_finite, stats.read);
  if (tally.far)
    spdlog::warn("{}: dropped {} of {} points farther than {} m from the origin (scans are metres in a local frame)",
                 path, tally.far, stats.read, static_cast<int>(kMaxCoordinate));
  if (const size_t strays = DropStrayReturns(scan))
    spdlog::warn("{}: dropped {} stray returns of {} points, separated from the rest of the scan by more than {} m",
                 path, strays, stats.read, static_cast<int>(kStrayGap));
  if (stats_out) *stats_out = stats;
}

// The points taken by `take` (a file read, or points in memory) with the shift rules: the given
// shift, else the automatic one, taken again with the shift the bulk calls for when the first
// point was a stray return (BetterShift); then FinishScan.
template <class Take>
Scan TakeShifted(const std::string& name, const ShiftOption& shift, ReadStats* stats_out, Take take) {
  Tally tally;
  tally.shift = shift.shift;
  tally.auto_shift = shift.automatic && !shift.shift;
  Scan scan = take(tally);
  if (tally.auto_shift)
    if (const auto better = BetterShift(tally)) {
      Tally again;
      again.shift = *better;
      again.auto_shift = false;
      scan = take(again);
      tally = std::move(again);
    }
  FinishScan(name, tally, shift, scan, stats_out);
  return scan;
}
}  // namespace

Scan ReadScan(const std::string& path, ReadStats* stats_out, size_t max_points, const ShiftOption& shift) {
  RequireRegularFile(path, "scan file");
  const std::string ext = Lower(fs::path(path).extension().string());
  if (ext != ".pcd" && ext != ".ply" && ext != ".xyz" && ext != ".txt" && ext != ".pts" && ext != ".asc")
    throw InputError(path + ": unknown scan format '" + ext + "' (expected .pcd, .ply, .xyz or .txt)");
  return TakeShifted(path, shift, stats_out, [&](Tally& tally) { return ReadFormat(path, ext, tally, max_points); });
}

std::optional<Eigen::Vector3d> ScanFileOrigin(const std::string& path) {
  RequireRegularFile(path, "scan file");
  if (Lower(fs::path(path).extension().string()) != ".pcd") return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot be opened");
  std::error_code ec;
  const uint64_t file_size = fs::file_size(path, ec);
  if (ec) throw InputError(path + ": cannot be read (" + ec.message() + ")");
  return ReadPcdHeader(path, in, file_size, 0).viewpoint;
}

Scan ScanFromPoints(const std::string& name, const double* xyz, size_t n, const uint8_t* rgb, ReadStats* stats_out,
                    const ShiftOption& shift) {
  return TakeShifted(name, shift, stats_out, [&](Tally& tally) {
    Scan scan;
    scan.source = name;
    scan.points.reserve(n);
    if (rgb) scan.colors.reserve(n);
    Eigen::Vector3f v;
    for (size_t i = 0; i < n; ++i) {
      ++tally.stats.read;
      if (!tally.Keep(Eigen::Vector3d(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]), v)) continue;
      scan.points.push_back(v);
      if (rgb) scan.colors.push_back({rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]});
    }
    return scan;
  });
}

}  // namespace furnihost
