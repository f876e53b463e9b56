#include "furnihost/host/io.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace furnihost {

namespace {
std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}
}  // namespace

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

std::string DumpJson(const nlohmann::json& j, int indent) {
  // Strings may hold what the file system or the command line gave (a file name that is not
  // UTF-8): shown with U+FFFD, where the default dump throws (an internal error, exit 1).
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

void WriteJson(const std::string& path, const nlohmann::json& j) { AtomicWriteText(path, DumpJson(j, 2) + "\n"); }

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

size_t JsonDepth(const std::string& text) {
  // Brackets outside strings; enough to refuse absurd nesting before any parser recurses.
  size_t depth = 0, max_depth = 0;
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
    else if ((c == ']' || c == '}') && depth > 0) --depth;
  }
  return max_depth;
}

namespace {
bool IsUtf8(const std::string& s) {
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    const size_t len = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (len == 0 || i + len > s.size()) return false;
    for (size_t k = 1; k < len; ++k)
      if ((static_cast<unsigned char>(s[i + k]) & 0xC0) != 0x80) return false;
    i += len;
  }
  return true;
}
}  // namespace

void RequireUtf8(const std::string& text, const std::string& what) {
  if (text.find('\0') != std::string::npos || !IsUtf8(text))
    throw InputError(what + ": not UTF-8 text (a NUL byte or an invalid byte sequence)");
}

nlohmann::json ParseJsonText(const std::string& text, const std::string& where) {
  // nlohmann's parser takes a NUL byte for the end of the text: "0\0junk" would be 0.
  if (const size_t nul = text.find('\0'); nul != std::string::npos)
    throw InputError(where + ": not valid JSON: a NUL byte at offset " + std::to_string(nul));
  // The parser builds iteratively, but the serializer (every message that quotes a value),
  // comparisons and copies recurse once per level: 10^4 levels overflow the stack.
  if (JsonDepth(text) > kMaxJsonDepth)
    throw InputError(where + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    // parse_error, and out_of_range for numbers beyond double ("1e400").
    std::string what = e.what();
    auto pos = what.find("] ");
    throw InputError(where + ": not valid JSON: " + (pos == std::string::npos ? what : what.substr(pos + 2)));
  }
}

nlohmann::json ParseCliJson(const std::string& text, const std::string& option, bool bare_words) {
  RequireUtf8(text, option);  // JSON is UTF-8 text; the value ends up in run records
  if (JsonDepth(text) > kMaxJsonDepth)
    throw InputError(option + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  if (bare_words) {
    nlohmann::json value = nlohmann::json::parse(text, nullptr, false);
    return value.is_discarded() ? nlohmann::json(text) : value;
  }
  return ParseJsonText(text, option);
}

nlohmann::json ReadJson(const std::string& path) {
  RequireRegularFile(path, "JSON file");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot be opened");
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseJsonText(ss.str(), path);
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
    // A box of no size matches nothing (its width is the match radius): the AP would drop
    // silently.
    if (!(g.size.array() > 0.f).all())
      throw InputError(at + "/size: expected three positive extents [m], got " + o["size"].dump());
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
