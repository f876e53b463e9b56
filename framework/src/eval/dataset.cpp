// Dataset manifests (LoadDataset), their class map and their content hash.
#include "furnihost/host/evaluation.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>

#include "furnihost/host/io.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace furnihost {

namespace {

[[noreturn]] void Bad(const std::string& file, const std::string& pointer, const std::string& what) {
  throw InputError(file + ":" + pointer + ": " + what);
}

void CheckKeys(const json& o, const std::set<std::string>& known, const std::string& file,
               const std::string& pointer) {
  if (!o.is_object()) Bad(file, pointer.empty() ? "/" : pointer, "expected an object");
  for (const auto& item : o.items()) {
    if (known.count(item.key())) continue;
    std::string list;
    for (const auto& n : known) list += (list.empty() ? "" : ", ") + n;
    Bad(file, pointer + "/" + item.key(), "unknown key (known: " + list + ")");
  }
}

std::string ResolvePath(const fs::path& base, const json& v, const std::string& file, const std::string& pointer,
                        const std::string& what) {
  if (!v.is_string() || v.get<std::string>().empty()) Bad(file, pointer, "expected a path (string), got " + v.dump());
  fs::path p(v.get<std::string>());
  if (p.is_relative()) p = base / p;
  const std::string abs = p.lexically_normal().string();
  try {
    RequireRegularFile(abs, what);
  } catch (const InputError& e) {
    Bad(file, pointer, e.what());
  }
  return abs;
}

}  // namespace

std::optional<std::string> ClassMap::Map(const std::string& cls) const {
  std::optional<std::string> to = cls;
  auto it = map.find(cls);
  if (it != map.end()) to = it->second;
  if (!to || std::find(classes.begin(), classes.end(), *to) == classes.end()) return std::nullopt;
  return to;
}

Dataset LoadDataset(const std::string& path) {
  RequireRegularFile(path, "dataset manifest");
  const json j = ReadJson(path);
  if (!j.is_object()) throw InputError(path + ": expected a JSON object with \"scenes\" and \"classes\"");
  CheckKeys(j, {"description", "scenes", "class_map", "classes", "yaw_symmetry"}, path, "");
  Dataset d;
  d.path = path;
  const fs::path base = fs::absolute(fs::path(path)).parent_path();
  if (j.contains("description")) {
    if (!j["description"].is_string()) Bad(path, "/description", "expected a string");
    d.description = j["description"].get<std::string>();
  }

  if (!j.contains("classes")) Bad(path, "/classes", "missing (the evaluated classes, e.g. [\"chair\", \"table\"])");
  const json& cl = j["classes"];
  if (!cl.is_array() || cl.empty()) Bad(path, "/classes", "expected a non-empty list of class names");
  for (size_t i = 0; i < cl.size(); ++i) {
    if (!cl[i].is_string() || cl[i].get<std::string>().empty())
      Bad(path, "/classes/" + std::to_string(i), "expected a class name (string), got " + cl[i].dump());
    const std::string c = cl[i].get<std::string>();
    if (std::find(d.classes.classes.begin(), d.classes.classes.end(), c) != d.classes.classes.end())
      Bad(path, "/classes/" + std::to_string(i), "duplicate class \"" + c + "\"");
    d.classes.classes.push_back(c);
  }

  if (j.contains("class_map")) {
    const json& cm = j["class_map"];
    if (!cm.is_object()) Bad(path, "/class_map", "expected an object {\"name\": \"evaluated class\" or null}");
    for (const auto& item : cm.items()) {
      const std::string ptr = "/class_map/" + item.key();
      if (item.value().is_null()) {
        d.classes.map[item.key()] = std::nullopt;
        continue;
      }
      if (!item.value().is_string()) Bad(path, ptr, "expected a class name or null, got " + item.value().dump());
      const std::string to = item.value().get<std::string>();
      if (std::find(d.classes.classes.begin(), d.classes.classes.end(), to) == d.classes.classes.end()) {
        std::string list;
        for (const auto& c : d.classes.classes) list += (list.empty() ? "" : ", ") + c;
        Bad(path, ptr, "\"" + to + "\" is not one of the evaluated classes (" + list + "); use null to ignore a class");
      }
      d.classes.map[item.key()] = to;
    }
  }

  if (j.contains("yaw_symmetry")) {
    const json& ys = j["yaw_symmetry"];
    if (!ys.is_object()) Bad(path, "/yaw_symmetry", "expected an object {\"evaluated class\": n} (0 = any turn, n = n-fold)");
    for (const auto& item : ys.items()) {
      const std::string ptr = "/yaw_symmetry/" + item.key();
      const auto& cl = d.classes.classes;
      if (std::find(cl.begin(), cl.end(), item.key()) == cl.end()) Bad(path, ptr, "not one of the evaluated classes");
      const json& v = item.value();
      if (!v.is_number_integer() || v.get<long long>() < 0 || v.get<long long>() > 360)
        Bad(path, ptr, "expected an integer 0..360 (0 = any turn, n = n-fold), got " + v.dump().substr(0, 40));
      d.classes.yaw_symmetry[item.key()] = v.get<int>();
    }
  }

  if (!j.contains("scenes")) Bad(path, "/scenes", "missing (a list of {\"scan\", \"gt\"})");
  const json& sc = j["scenes"];
  if (!sc.is_array() || sc.empty()) Bad(path, "/scenes", "expected a non-empty list of {\"scan\", \"gt\"}");
  for (size_t i = 0; i < sc.size(); ++i) {
    const std::string ptr = "/scenes/" + std::to_string(i);
    CheckKeys(sc[i], {"scan", "gt", "origin", "up", "transform", "shift"}, path, ptr);
    if (!sc[i].contains("scan")) Bad(path, ptr + "/scan", "missing (path of the scan file)");
    if (!sc[i].contains("gt")) Bad(path, ptr + "/gt", "missing (path of the *.gt.json file)");
    DatasetScene s;
    s.scan = ResolvePath(base, sc[i]["scan"], path, ptr + "/scan", "scan file");
    s.gt = ResolvePath(base, sc[i]["gt"], path, ptr + "/gt", "ground-truth file");
    if (sc[i].contains("origin")) {
      const json& o = sc[i]["origin"];
      if (!o.is_array() || o.size() != 3 ||
          !std::all_of(o.begin(), o.end(), [](const json& v) { return v.is_number() && std::isfinite(v.get<double>()); }))
        Bad(path, ptr + "/origin", "expected [x, y, z] (3 finite numbers, metres), got " + o.dump());
      if (!std::all_of(o.begin(), o.end(), [](const json& v) { return std::abs(v.get<double>()) <= kMaxGlobalShift + kMaxScanCoordinate; }))
        Bad(path, ptr + "/origin", "lies beyond 1e8 m of the file's origin: " + o.dump());
      s.origin = Eigen::Vector3f(o[0].get<float>(), o[1].get<float>(), o[2].get<float>());
    }
    {
      if (sc[i].contains("up")) {
        if (!sc[i]["up"].is_string()) Bad(path, ptr + "/up", "expected an axis such as \"-y\"");
        s.frame.up = sc[i]["up"].get<std::string>();
        if (s.frame.up != "auto") UpAxisRotation(s.frame.up, path + ":" + ptr + "/up");
      }
      if (sc[i].contains("transform")) {
        if (!sc[i]["transform"].is_string()) Bad(path, ptr + "/transform", "expected a string of 16 or 6 numbers");
        if (sc[i].contains("up")) Bad(path, ptr + "/transform", "give either up or transform, not both");
        s.frame.transform = ParseTransform(sc[i]["transform"].get<std::string>(), path + ":" + ptr + "/transform");
      }
    }
    if (sc[i].contains("shift")) {
      const json& o = sc[i]["shift"];
      if (!o.is_array() || o.size() != 3 ||
          !std::all_of(o.begin(), o.end(), [](const json& v) { return v.is_number() && std::isfinite(v.get<double>()); }))
        Bad(path, ptr + "/shift", "expected [x, y, z] (3 finite numbers), got " + o.dump());
      s.frame.shift.shift = Eigen::Vector3d(o[0].get<double>(), o[1].get<double>(), o[2].get<double>());
      CheckShift(*s.frame.shift.shift, path + ":" + ptr + "/shift");
    }
    d.scenes.push_back(s);
  }
  return d;
}

std::string HashDataset(const Dataset& d) {
  uint64_t h = kFnvOffset;
  auto add = [&](const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw InputError(file + ": cannot read (for the dataset hash)");
    std::vector<char> buf(1 << 20);
    while (in) {
      in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
      h = Fnv1a(buf.data(), static_cast<size_t>(in.gcount()), h);
    }
  };
  add(d.path);
  for (const auto& s : d.scenes) {
    add(s.scan);
    add(s.gt);
  }
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(h));
  return std::string("fnv1a64:") + hex;
}

}  // namespace furnihost
