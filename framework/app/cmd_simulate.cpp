// furnihost simulate: builds a synthetic room from a scene file and catalog models, scans it
// with sensors.simulated_laser and writes the scan plus its ground truth (<stem>.gt.json).
//
// Scene file (world frame: room corner at the origin, x/y on the floor [m], z up):
//   {"room": {"size_m": [6, 5], "height_m": 2.7, "walls": true, "ceiling": false},
//    "objects": [{"model": "sh3d_chair", "x": 1.0, "y": 2.0, "yaw_deg": 90}],
//    "sensors": [{"position": [0.5, 0.5, 1.5], "yaw_deg": 45, "pitch_deg": 0}],
//    "sensor_params": {"voxel_m": 0.03}}
// x, y = where the model's bounding-box bottom centre stands; yaw about +z, counter-clockwise.
// Objects may not overlap on the floor plan, except one marked "under": true (a chair pushed
// under a table, whose seat passes below the top): the scene's author vouches that its mesh
// clears the others.
// Sensor pitch_deg turns about the sensor's y (left) axis, positive looks down. Without
// "sensors": one pan-tilt scan from sensor_height_m at the room centre with a 360 deg sweep.
//
// Ground truth: every placed object, with the number of the scan's returns that hit it
// ("n_points"). One scan per sensor (--per-sensor, or a single sensor) can leave the objects it
// barely sees out of its ground truth (--min-visible) and be written in its sensor's upright
// frame (--sensor-frame: a single RGB-D view as SUN RGB-D gives it, or a robot's level camera).
#include <CLI/CLI.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <unordered_map>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/host/catalog.hpp"
#include "furnihost/geometry.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/log.hpp"
#include "furnihost/host/registry.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace furnihost::app {
namespace {

constexpr const char* kSensorType = "sensors.simulated_laser";
constexpr double kPi = 3.14159265358979323846;
// Footprints may touch; they overlap when they interpenetrate by more than this [m].
constexpr float kOverlapTolerance = 0.005f;

struct SceneObject {
  std::string model;
  float x = 0, y = 0, z = 0, yaw_deg = 0;
  bool under = false;  // may overlap the others on the floor plan
};
struct SceneSensor {
  Eigen::Vector3f position = Eigen::Vector3f::Zero();
  bool has_z = false;
  float yaw_deg = 0, pitch_deg = 0;
};
struct SceneSpec {
  float width = 0, depth = 0, height = 2.7f;
  bool walls = true, ceiling = false;
  std::vector<SceneObject> objects;
  std::vector<SceneSensor> sensors;
  json sensor_params = json::object();
};

std::string Ptr(const std::string& file, const std::string& pointer) { return file + ":" + pointer; }

void CheckKeys(const json& o, const std::set<std::string>& known, const std::string& file,
               const std::string& pointer) {
  if (!o.is_object()) throw InputError(Ptr(file, pointer) + ": expected an object");
  for (const auto& [k, v] : o.items()) {
    if (known.count(k)) continue;
    std::string list;
    for (const auto& n : known) list += (list.empty() ? "" : ", ") + n;
    throw InputError(Ptr(file, pointer + "/" + k) + ": unknown key (known: " + list + ")");
  }
}

float Number(const json& o, const std::string& key, const std::string& file,
             const std::string& pointer, std::optional<float> def, float lo, float hi) {
  if (!o.contains(key)) {
    if (def) return *def;
    throw InputError(Ptr(file, pointer + "/" + key) + ": missing (a number)");
  }
  const json& v = o[key];
  if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo || v.get<double>() > hi) {
    std::ostringstream m;
    m << Ptr(file, pointer + "/" + key) << ": expected a number in [" << lo << ", " << hi
      << "], got " << v.dump();
    throw InputError(m.str());
  }
  return v.get<float>();
}

// Item `i` of a numeric array (the caller checked the array's size).
float NumberAt(const json& a, size_t i, const std::string& file, const std::string& pointer,
               float lo, float hi) {
  const json& v = a[i];
  if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo || v.get<double>() > hi) {
    std::ostringstream m;
    m << Ptr(file, pointer + "/" + std::to_string(i)) << ": expected a number in [" << lo << ", "
      << hi << "], got " << v.dump();
    throw InputError(m.str());
  }
  return v.get<float>();
}

SceneSpec ParseScene(const json& j, const std::string& file) {
  SceneSpec s;
  CheckKeys(j, {"room", "objects", "sensors", "sensor_params", "description"}, file, "");
  if (!j.contains("room")) throw InputError(file + ": missing \"room\"");
  const json& room = j["room"];
  CheckKeys(room, {"size_m", "height_m", "walls", "ceiling"}, file, "/room");
  if (!room.contains("size_m") || !room["size_m"].is_array() || room["size_m"].size() != 2)
    throw InputError(Ptr(file, "/room/size_m") + ": expected [width_x, depth_y] in metres");
  s.width = NumberAt(room["size_m"], 0, file, "/room/size_m", 0.5f, 1000.f);
  s.depth = NumberAt(room["size_m"], 1, file, "/room/size_m", 0.5f, 1000.f);
  s.height = Number(room, "height_m", file, "/room", 2.7f, 0.5f, 100.f);
  for (const char* k : {"walls", "ceiling"})
    if (room.contains(k) && !room[k].is_boolean())
      throw InputError(Ptr(file, std::string("/room/") + k) + ": expected true or false");
  s.walls = room.value("walls", true);
  s.ceiling = room.value("ceiling", false);

  if (j.contains("objects")) {
    if (!j["objects"].is_array()) throw InputError(Ptr(file, "/objects") + ": expected an array");
    for (size_t i = 0; i < j["objects"].size(); ++i) {
      const json& o = j["objects"][i];
      const std::string p = "/objects/" + std::to_string(i);
      CheckKeys(o, {"model", "x", "y", "z", "yaw_deg", "under"}, file, p);
      SceneObject so;
      if (!o.contains("model") || !o["model"].is_string())
        throw InputError(Ptr(file, p + "/model") + ": missing model id (a string)");
      so.model = o["model"].get<std::string>();
      so.x = Number(o, "x", file, p, std::nullopt, -1e4f, 1e4f);
      so.y = Number(o, "y", file, p, std::nullopt, -1e4f, 1e4f);
      so.z = Number(o, "z", file, p, 0.f, -1e4f, 1e4f);
      so.yaw_deg = Number(o, "yaw_deg", file, p, 0.f, -3600.f, 3600.f);
      if (o.contains("under")) {
        if (!o["under"].is_boolean()) throw InputError(Ptr(file, p + "/under") + ": expected true or false");
        so.under = o["under"].get<bool>();
      }
      s.objects.push_back(so);
    }
  }
  if (j.contains("sensors")) {
    if (!j["sensors"].is_array()) throw InputError(Ptr(file, "/sensors") + ": expected an array");
    for (size_t i = 0; i < j["sensors"].size(); ++i) {
      const json& o = j["sensors"][i];
      const std::string p = "/sensors/" + std::to_string(i);
      CheckKeys(o, {"position", "yaw_deg", "pitch_deg"}, file, p);
      SceneSensor ss;
      if (!o.contains("position") || !o["position"].is_array() ||
          (o["position"].size() != 2 && o["position"].size() != 3))
        throw InputError(Ptr(file, p + "/position") + ": expected [x, y] or [x, y, z] in metres");
      for (size_t a = 0; a < o["position"].size(); ++a)
        ss.position[a] = NumberAt(o["position"], a, file, p + "/position", -1e4f, 1e4f);
      ss.has_z = o["position"].size() == 3;
      ss.yaw_deg = Number(o, "yaw_deg", file, p, 0.f, -3600.f, 3600.f);
      ss.pitch_deg = Number(o, "pitch_deg", file, p, 0.f, -90.f, 90.f);
      s.sensors.push_back(ss);
    }
  }
  if (j.contains("sensor_params")) {
    if (!j["sensor_params"].is_object())
      throw InputError(Ptr(file, "/sensor_params") + ": expected an object");
    s.sensor_params = j["sensor_params"];
  }
  return s;
}

// Footprint of a placed model: its bounding rectangle (x width, y depth) turned by yaw.
struct Footprint {
  Eigen::Vector2f c;
  Eigen::Vector2f axis[2];  // unit axes
  Eigen::Vector2f half;     // half extents along the axes
  std::array<Eigen::Vector2f, 4> Corners() const {
    std::array<Eigen::Vector2f, 4> out;
    int k = 0;
    for (int sx : {-1, 1})
      for (int sy : {-1, 1}) out[k++] = c + sx * half.x() * axis[0] + sy * half.y() * axis[1];
    return out;
  }
  bool Contains(const Eigen::Vector2f& p) const {
    const Eigen::Vector2f d = p - c;
    return std::abs(d.dot(axis[0])) < half.x() && std::abs(d.dot(axis[1])) < half.y();
  }
};

// Separating-axis test; returns the smallest interpenetration depth (<= 0: apart/touching).
float Penetration(const Footprint& a, const Footprint& b) {
  float depth = std::numeric_limits<float>::max();
  for (const Footprint* f : {&a, &b})
    for (const auto& ax : f->axis) {
      auto range = [&](const Footprint& g) {
        float lo = std::numeric_limits<float>::max(), hi = -lo;
        for (const auto& c : g.Corners()) {
          lo = std::min(lo, c.dot(ax));
          hi = std::max(hi, c.dot(ax));
        }
        return std::make_pair(lo, hi);
      };
      const auto [alo, ahi] = range(a);
      const auto [blo, bhi] = range(b);
      depth = std::min(depth, std::min(ahi, bhi) - std::max(alo, blo));
    }
  return depth;
}

// The overlapping pair (k, i), k < i, with the smallest i (then k) that interpenetrates by more
// than `tolerance`, as a loop over all pairs in order would report first; none when no two do.
// Footprints are filed by the centre of their bounding square in a hierarchy of square grids
// (cells doubling in size; each footprint on the finest level whose cells are at least its
// size), and each is tested against those on its own and the coarser levels in the cells around
// it: n log n for any layout (rows along x or y, grids, a few large among many small), where
// all pairs took 106 s for 78,400 objects. Pairs with an object marked `under` are skipped.
std::optional<std::pair<size_t, size_t>> FirstOverlap(const std::vector<Footprint>& feet, const std::vector<bool>& under,
                                                     float tolerance) {
  const size_t n = feet.size();
  if (n < 2) return std::nullopt;
  std::vector<Eigen::AlignedBox2f> box(n);
  float smallest = std::numeric_limits<float>::max();
  for (size_t i = 0; i < n; ++i) {
    for (const auto& c : feet[i].Corners()) box[i].extend(c);
    smallest = std::min(smallest, box[i].sizes().maxCoeff());
  }
  const double base = std::max(double(smallest), 1e-3);
  auto level_of = [&](size_t i) {
    int l = 0;
    while (base * std::ldexp(1.0, l) < double(box[i].sizes().maxCoeff()) && l < 60) ++l;
    return l;
  };
  auto key = [](int64_t x, int64_t y) { return (uint64_t(x) << 32) ^ (uint64_t(y) & 0xffffffffu); };
  std::vector<int> level(n);
  std::map<int, std::unordered_map<uint64_t, std::vector<size_t>>> grid;  // level -> cell -> footprints
  for (size_t i = 0; i < n; ++i) {
    level[i] = level_of(i);
    const double cell = base * std::ldexp(1.0, level[i]);
    const Eigen::Vector2f c = box[i].center();
    grid[level[i]][key(int64_t(std::floor(c.x() / cell)), int64_t(std::floor(c.y() / cell)))].push_back(i);
  }
  std::optional<std::pair<size_t, size_t>> best;
  auto consider = [&](size_t a, size_t b) {
    const size_t lo = std::min(a, b), hi = std::max(a, b);
    if (best && (hi > best->second || (hi == best->second && lo >= best->first))) return;
    if (under[a] || under[b]) return;  // an object marked "under" may overlap the others
    Eigen::AlignedBox2f grown = box[a];
    grown.min().array() -= tolerance;
    grown.max().array() += tolerance;
    if (!grown.intersects(box[b]) || !(Penetration(feet[a], feet[b]) > tolerance)) return;
    best = std::make_pair(lo, hi);
  };
  for (size_t i = 0; i < n; ++i)
    for (auto it = grid.find(level[i]); it != grid.end(); ++it) {
      // A footprint filed at this level lies within half a cell of its cell's square.
      const double cell = base * std::ldexp(1.0, it->first);
      const double reach = 0.5 * cell + tolerance;
      const int64_t x0 = int64_t(std::floor((box[i].min().x() - reach) / cell)),
                    x1 = int64_t(std::floor((box[i].max().x() + reach) / cell)),
                    y0 = int64_t(std::floor((box[i].min().y() - reach) / cell)),
                    y1 = int64_t(std::floor((box[i].max().y() + reach) / cell));
      for (int64_t x = x0; x <= x1; ++x)
        for (int64_t y = y0; y <= y1; ++y) {
          const auto cell_it = it->second.find(key(x, y));
          if (cell_it == it->second.end()) continue;
          for (size_t j : cell_it->second)
            if (j != i && (level[j] != level[i] || j > i)) consider(i, j);
        }
    }
  return best;
}

// Floor (z = 0), optional walls and ceiling of the room [0, w] x [0, d] x [0, h].
Mesh RoomMesh(const SceneSpec& s) {
  Mesh m;
  auto quad = [&](Eigen::Vector3f a, Eigen::Vector3f b, Eigen::Vector3f c, Eigen::Vector3f d) {
    const int i = static_cast<int>(m.vertices.size());
    m.vertices.insert(m.vertices.end(), {a, b, c, d});
    m.triangles.emplace_back(i, i + 1, i + 2);
    m.triangles.emplace_back(i, i + 2, i + 3);
  };
  const float w = s.width, d = s.depth, h = s.height;
  quad({0, 0, 0}, {w, 0, 0}, {w, d, 0}, {0, d, 0});
  if (s.walls) {
    quad({0, 0, 0}, {0, 0, h}, {w, 0, h}, {w, 0, 0});
    quad({w, 0, 0}, {w, 0, h}, {w, d, h}, {w, d, 0});
    quad({w, d, 0}, {w, d, h}, {0, d, h}, {0, d, 0});
    quad({0, d, 0}, {0, d, h}, {0, 0, h}, {0, 0, 0});
  }
  if (s.ceiling) quad({0, 0, h}, {0, d, h}, {w, d, h}, {w, 0, h});
  return m;
}

std::string Fmt(float v) {
  std::ostringstream o;
  o.precision(3);
  o << v;
  return o.str();
}

std::string ObjectName(size_t i, const SceneObject& o) {
  return "#" + std::to_string(i) + " (" + o.model + ")";
}

Scan Merge(std::vector<Scan>& scans, const std::string& source) {
  Scan m;
  m.source = source;
  m.origin = scans.front().origin;
  m.truth = scans.front().truth;
  const bool inst = std::all_of(scans.begin(), scans.end(),
                                [](const Scan& s) { return s.attributes.count("instance") > 0; });
  for (auto& s : scans) {
    m.points.insert(m.points.end(), s.points.begin(), s.points.end());
    if (inst) {
      auto& dst = m.attributes["instance"];
      const auto& src = s.attributes.at("instance");
      dst.insert(dst.end(), src.begin(), src.end());
    }
  }
  return m;
}

}  // namespace

int RunSimulate(const std::vector<std::string>& args) {
  CLI::App app{"Scan a synthetic room built from catalog models with the simulated laser and "
               "write the scan and its ground truth (<scan stem>.gt.json)", "simulate"};
  std::string catalog_path, scene_path, out_path, sensor_params_text;
  bool strict = false, per_sensor = false, sensor_frame = false;
  int min_visible = 0;
  CommonOptions common;  // --plugin-path, -v/-q, --threads, --seed (default 42)
  common.Add(app);
  app.add_option("--catalog", catalog_path, "catalog.json with the models the scene names")->required();
  app.add_option("--scene", scene_path, "scene file (room, objects, sensors)")->required();
  app.add_option("--out", out_path, "output scan: .pcd (with VIEWPOINT), .ply or .xyz")->required();
  app.add_option("--sensor-params", sensor_params_text,
                 "JSON object of sensors.simulated_laser parameters (over the scene's sensor_params)");
  app.add_flag("--strict", strict, "a broken catalog entry is an error instead of being skipped");
  app.add_flag("--per-sensor", per_sensor, "write one scan per sensor (<stem>_<i>.<ext>) instead of merging");
  app.add_option("--min-visible", min_visible,
                 "one scan per sensor: objects with fewer returns in a sensor's scan are left out of its ground "
                 "truth (0 = every object; objects out of view would count as missed)")
      ->check(CLI::Range(0, 100000000));
  app.add_flag("--sensor-frame", sensor_frame,
               "one scan per sensor: write each scan and its ground truth in its sensor's upright frame (sensor at "
               "the origin, x along its heading, z up, the floor at minus its height), as SUN RGB-D's views");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  const RunContext ctx = common.Context(42);
  if ((min_visible > 0 || sensor_frame) && !per_sensor)
    throw InputError(std::string(sensor_frame ? "--sensor-frame" : "--min-visible") +
                     ": applies to one scan per sensor: add --per-sensor");
  const Stopwatch clock;

  const std::string ext = fs::path(out_path).extension().string();
  if (ext != ".pcd" && ext != ".ply" && ext != ".xyz" && ext != ".txt")
    throw InputError("--out " + out_path + ": unknown scan format (use .pcd, .ply or .xyz)");
  json user_params = json::object();
  if (!sensor_params_text.empty()) {
    user_params = ParseCliJson(sensor_params_text, "--sensor-params");
    if (!user_params.is_object()) throw InputError("--sensor-params: expected a JSON object");
  }

  const SceneSpec scene = ParseScene(ReadJson(scene_path), scene_path);

  const Catalog catalog = LoadCatalog(catalog_path, strict);

  // Place the objects and check them against the room and each other.
  std::vector<PlacedObject> placed;
  std::vector<Footprint> feet;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const SceneObject& o = scene.objects[i];
    const CatalogModel* m = catalog.Find(o.model);
    if (!m) {
      for (const auto& sk : catalog.skipped)
        if (sk.id == o.model)
          throw InputError(Ptr(scene_path, "/objects/" + std::to_string(i) + "/model") + ": model " +
                           o.model + " was skipped by the catalog: " + sk.reason);
      std::string known;
      for (const auto& cm : catalog.models) known += (known.empty() ? "" : ", ") + cm.id;
      throw InputError(Ptr(scene_path, "/objects/" + std::to_string(i) + "/model") +
                       ": unknown model \"" + o.model + "\" in " + catalog_path + " (known: " + known + ")");
    }
    const float yaw = static_cast<float>(o.yaw_deg * kPi / 180.0);
    Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
    pose.translate(Eigen::Vector3f(o.x, o.y, o.z));
    pose.rotate(Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()));
    placed.push_back({m, pose});
    Footprint f;
    f.c = {o.x, o.y};
    f.axis[0] = {std::cos(yaw), std::sin(yaw)};
    f.axis[1] = {-std::sin(yaw), std::cos(yaw)};
    f.half = 0.5f * m->size.head<2>();
    for (const auto& c : f.Corners())
      if (c.x() < -kOverlapTolerance || c.y() < -kOverlapTolerance ||
          c.x() > scene.width + kOverlapTolerance || c.y() > scene.depth + kOverlapTolerance)
        throw InputError(scene_path + ": object " + ObjectName(i, o) + " leaves the room [0, " +
                         Fmt(scene.width) + "] x [0, " + Fmt(scene.depth) + "] (footprint corner at " +
                         Fmt(c.x()) + ", " + Fmt(c.y()) + ")");
    if (o.z < 0.f || o.z + m->size.z() > scene.height + kOverlapTolerance)
      throw InputError(scene_path + ": object " + ObjectName(i, o) + " (" + Fmt(m->size.z()) +
                       " m tall at z = " + Fmt(o.z) + ") does not fit between floor and ceiling (" +
                       Fmt(scene.height) + " m)");
    feet.push_back(f);
  }
  std::vector<bool> under;
  for (const auto& o : scene.objects) under.push_back(o.under);
  if (const auto pair = FirstOverlap(feet, under, kOverlapTolerance)) {
    const auto [k, i] = *pair;
    throw InputError(scene_path + ": objects " + ObjectName(k, scene.objects[k]) + " and " +
                     ObjectName(i, scene.objects[i]) + " overlap (footprints intersect by " +
                     Fmt(Penetration(feet[i], feet[k])) + " m)");
  }

  // Sensor parameters: scene's sensor_params, then --sensor-params; the default room-centre
  // scan sweeps all around unless the user chose a field of view.
  json params = scene.sensor_params;
  params.update(user_params);
  if (scene.sensors.empty() && !params.contains("horizontal_fov_deg")) params["horizontal_fov_deg"] = 360.0;

  Registry registry(Registry::DefaultSearchPath(common.plugin_paths));
  const PluginEntry* entry = registry.Find(kSensorType);
  if (!entry) {
    std::string dirs;
    for (const auto& d : registry.SearchDirs()) dirs += (dirs.empty() ? "" : ", ") + d;
    throw InputError(std::string("plugin ") + kSensorType + " not found (searched: " + dirs +
                     "; add --plugin-path DIR)");
  }
  // The scene's own block first, so an error there names the scene file.
  entry->params.Resolve(scene.sensor_params, scene_path + ":/sensor_params");
  const json resolved = entry->params.Resolve(params, "--sensor-params");
  const float sensor_height = resolved.at("sensor_height_m").get<float>();

  std::vector<SceneSensor> sensors = scene.sensors;
  if (sensors.empty()) {
    SceneSensor c;
    c.position = {0.5f * scene.width, 0.5f * scene.depth, sensor_height};
    c.has_z = true;
    sensors.push_back(c);
  }
  SensorRequest request;
  std::vector<Eigen::Isometry3f> upright;  // each sensor's position and heading (no pitch)
  request.objects = placed;
  request.extra = RoomMesh(scene);
  for (size_t i = 0; i < sensors.size(); ++i) {
    SceneSensor s = sensors[i];
    if (!s.has_z) s.position.z() = sensor_height;
    const Eigen::Vector3f& p = s.position;
    const std::string name = scene.sensors.empty() ? "the default sensor at the room centre"
                                                   : "sensor #" + std::to_string(i);
    if (p.x() <= 0.f || p.y() <= 0.f || p.x() >= scene.width || p.y() >= scene.depth || p.z() <= 0.f ||
        p.z() >= scene.height)
      throw InputError(scene_path + ": " + name + " at (" + Fmt(p.x()) + ", " + Fmt(p.y()) + ", " +
                       Fmt(p.z()) + ") is outside the room");
    for (size_t k = 0; k < feet.size(); ++k)
      if (feet[k].Contains(p.head<2>()) && p.z() < scene.objects[k].z + placed[k].model->size.z())
        throw InputError(scene_path + ": " + name + " is inside object " +
                         ObjectName(k, scene.objects[k]) +
                         (scene.sensors.empty() ? " (add a \"sensors\" entry)" : ""));
    Eigen::Isometry3f pose = Eigen::Isometry3f::Identity();
    pose.translate(p);
    pose.rotate(Eigen::AngleAxisf(static_cast<float>(s.yaw_deg * kPi / 180.0), Eigen::Vector3f::UnitZ()));
    upright.push_back(pose);
    pose.rotate(Eigen::AngleAxisf(static_cast<float>(s.pitch_deg * kPi / 180.0), Eigen::Vector3f::UnitY()));
    request.poses.push_back(pose);
  }

  std::vector<Scan> scans;
  {
    auto sensor = registry.CreateAs<Sensor>(kSensorType, resolved);
    try {
      scans = sensor->Acquire(request, ctx);
    } catch (const StageError& e) {
      // Re-thrown from host code while the plugin is still loaded.
      throw StageError(std::string(kSensorType) + ": " + e.what(), e.IsInputError());
    } catch (const InputError& e) {
      throw InputError(std::string(kSensorType) + ": " + e.what());
    } catch (const std::exception& e) {
      // Any other type may have its code in the plugin: copy the message before unloading.
      throw StageError(std::string(kSensorType) + ": " + e.what(), false);
    } catch (...) {
      throw StageError(std::string(kSensorType) + ": unknown exception", false);
    }
  }
  if (scans.size() != request.poses.size())
    throw StageError(std::string(kSensorType) + " returned " + std::to_string(scans.size()) +
                         " scans for " + std::to_string(request.poses.size()) + " poses",
                     false);

  const std::string description = "furnihost simulate --scene " + scene_path + " --catalog " +
                                   catalog_path + " --seed " + std::to_string(ctx.seed);
  // Each placed model's yaw symmetry, so that evaluation folds yaw errors by it (a table
  // turned by 180 degrees is the same table; a chair is not).
  std::map<std::string, int> symmetry;
  for (const auto& s : scans)
    for (const auto& g : s.truth)
      if (!symmetry.count(g.model))
        if (const CatalogModel* m = catalog.Find(g.model)) symmetry[g.model] = YawSymmetry(m->mesh);
  // Returns per object: "instance" holds the 1-based index of the placed object each point hit.
  auto returns_of = [&](const Scan& s) {
    std::vector<size_t> hits(placed.size(), 0);
    const auto it = s.attributes.find("instance");
    if (it != s.attributes.end())
      for (const auto v : it->second)
        if (v >= 1 && size_t(v) <= hits.size()) ++hits[size_t(v) - 1];
    return hits;
  };
  auto gt_json = [&](const Scan& s) {
    std::vector<GroundTruthObject> truth = s.truth;
    for (auto& t : truth) {
      if (symmetry.count(t.model)) t.yaw_symmetry = symmetry.at(t.model);
      // The way the object faces: its model's front turned by the model's yaw.
      if (const ModelFront* f = catalog.FrontOf(t.model); f && t.yaw)
        t.yaw = std::remainder(*t.yaw + std::atan2(f->front.y(), f->front.x()), 2.f * float(kPi));
    }
    json g = GroundTruthToJson(truth);
    if (g.is_array()) g = json{{"units", "m"}, {"up", "z"}, {"objects", g}};
    // The simulated sensor lists every placed object, in order.
    const std::vector<size_t> hits = returns_of(s);
    if (g["objects"].size() == hits.size()) {
      json kept = json::array();
      for (size_t k = 0; k < hits.size(); ++k) {
        g["objects"][k]["n_points"] = hits[k];
        if (hits[k] >= size_t(min_visible)) kept.push_back(g["objects"][k]);
      }
      g["objects"] = kept;
      if (min_visible > 0) g["min_visible"] = min_visible;
    }
    if (sensor_frame) g["frame"] = "the sensor's upright frame: sensor at the origin, x along its heading, z up";
    g["scene"] = fs::path(scene_path).filename().string();
    g["size_convention"] =
        std::string("[dx, dy, dz] = axis-aligned extents of the placed model in the ") +
        (sensor_frame ? "sensor's" : "world") + " frame; center = "
        "their centre; yaw = the way the object faces [rad, counter-clockwise about +z from +x]: its catalog "
        "model's front turned by the model's rotation; yaw_symmetry = turns about +z that map the "
        "model onto itself (0 = any, n = n-fold, 1 = none; 95 % of its surface within 2 cm); n_points = the scan's "
        "returns on it";
    g["generator"] = {{"command", description},
                      {"catalog_hash", catalog.hash},
                      {"sensor", kSensorType},
                      {"sensor_params", resolved}};
    return g;
  };
  auto write = [&](const std::string& path, const Scan& s) {
    WriteScan(path, s);
    const fs::path p(path);
    const std::string gt = (p.parent_path() / (p.stem().string() + ".gt.json")).string();
    WriteJson(gt, gt_json(s));
    return gt;
  };

  if (sensor_frame) {
    // Each scan and its ground truth in its sensor's upright frame.
    for (size_t i = 0; i < scans.size(); ++i) {
      Scan& s = scans[i];
      const Eigen::Isometry3f to = upright[i].inverse();
      for (auto& p : s.points) p = to * p;
      if (s.origin) s.origin = to * *s.origin;
      const float turn = std::atan2(to.linear()(1, 0), to.linear()(0, 0));
      for (size_t k = 0; k < s.truth.size() && k < placed.size(); ++k) {
        GroundTruthObject& t = s.truth[k];
        Eigen::AlignedBox3f b;
        for (const auto& v : placed[k].model->mesh.vertices) b.extend(to * (placed[k].pose * v));
        t.center = b.center();
        t.size = b.sizes();
        if (t.yaw) t.yaw = std::remainder(*t.yaw + turn, 2.f * float(kPi));
      }
    }
  }
  size_t total = 0;
  std::string written;
  if (per_sensor && scans.size() > 1) {
    const fs::path p(out_path);
    for (size_t i = 0; i < scans.size(); ++i) {
      const std::string path =
          (p.parent_path() / (p.stem().string() + "_" + std::to_string(i) + ext)).string();
      scans[i].source = description + " (sensor " + std::to_string(i) + ")";
      write(path, scans[i]);
      total += scans[i].points.size();
      written += (written.empty() ? "" : ", ") + path;
    }
    written += " (+ .gt.json each)";
  } else {
    Scan merged = Merge(scans, description);
    total = merged.points.size();
    written = out_path + ", " + write(out_path, merged);
  }
  std::cout << "simulate: " << placed.size() << " objects, " << sensors.size()
            << (sensors.size() == 1 ? " sensor, " : " sensors, ") << total << " points -> "
            << written << " (" << Fmt(static_cast<float>(clock.Ms() / 1000.0)) << " s)" << std::endl;
  return 0;
}

}  // namespace furnihost::app
