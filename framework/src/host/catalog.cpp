// CAD catalogs: catalog.json parsing, mesh import (LoadMeshFile, mesh_file.cpp: assimp in
// libfurnihost_meshio, loaded on the first mesh parsed), normalisation to the project frame
// (metres, z up, bounding-box bottom centre at the origin).
//
// Units and axes: the catalog's `up` and scale fields are defined relative to assimp's DEFAULT
// import (the "frame" text of ../shared/data/cad_catalog/catalog.json). For most formats that
// is the file's own axes and units, but the Collada importer of assimp 5.2 bakes the file's
// <unit meter="..."> into the root node (-> metres) and turns <up_axis>Z_UP</up_axis> files
// y up. We therefore pin the importer properties that change axes or units to their default
// values and never request aiProcess_GlobalScale, so an assimp configuration elsewhere in the
// process cannot silently change what a catalog entry means.
#include "furnihost/host/catalog.hpp"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <optional>
#include <stdexcept>
#include <string>

#include "furnihost/hash.hpp"
#include "furnihost/host/io.hpp"

namespace fs = std::filesystem;

namespace furnihost {

namespace {

// Hashes a whole file; returns false when it cannot be read.
bool HashFile(uint64_t& h, const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;  // opening a FIFO would block forever
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  char buf[1 << 16];
  while (in) {
    in.read(buf, sizeof(buf));
    h = Fnv1a(buf, static_cast<size_t>(in.gcount()), h);
  }
  return true;
}

std::string Hex64(uint64_t v) {
  char s[17];
  std::snprintf(s, sizeof(s), "%016llx", static_cast<unsigned long long>(v));
  return s;
}

std::string Fmt3(const Eigen::Vector3f& v) {
  std::ostringstream o;
  o.precision(4);
  o << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return o.str();
}

// Rotation turning the named mesh axis into +z. Mesh x stays the width and y the depth
// wherever the up axis allows it (for +y: (x, y, z) -> (x, -z, y), as the catalog's frame says).
std::optional<Eigen::Matrix3f> UpRotation(const std::string& up) {
  Eigen::Matrix3f r;
  if (up == "+z") {
    r.setIdentity();
  } else if (up == "-z") {
    r << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  } else if (up == "+y") {
    r << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  } else if (up == "-y") {
    r << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  } else if (up == "+x") {
    r << 0, 0, -1, 0, 1, 0, 1, 0, 0;
  } else if (up == "-x") {
    r << 0, 0, 1, 0, 1, 0, -1, 0, 0;
  } else {
    return std::nullopt;
  }
  return r;
}

const std::set<std::string>& KnownKeys() {
  static const std::set<std::string> keys = {
      "id", "class", "subclass", "mesh", "up", "scale", "height_m", "size_m", "front",
      // descriptive metadata carried by catalogs from the web; not interpreted
      "license", "source", "creator", "notes", "description", "url"};
  return keys;
}

// An entry checked and its mesh loaded and normalised; `reason` set when invalid.
struct EntryResult {
  std::string id;
  std::string reason;
  CatalogModel model;
  ModelFront front;
};

// Positive and small enough to stay finite as a float (1e300 would become inf).
bool PositiveFinite(const nlohmann::json& v) {
  return v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() > 0.0 && v.get<double>() < 1e30;
}

// ---- parsed-mesh cache -------------------------------------------------------------------
// assimp's parsing is most of a catalog's load (38 web models: ~60 ms of a ~0.4 s detection on a
// ScanNet room), so the parsed mesh (LoadMeshFile's result, file units and axes) is kept on disk
// by the file's content in CacheFolder("meshes") (the fitter's model clouds sit beside it). Only
// formats that hold all their geometry in one file are cached (a .gltf's buffers may live
// elsewhere; an .obj's .mtl and a COLLADA file's images are materials, which a Mesh does not
// keep, and assimp reads a COLLADA file's geometry from that file only). The key hashes the
// bytes, the extension (assimp picks the reader by it), the assimp version and this format's
// version; a cached mesh is the parsed one bit for bit. A
// missing, truncated or otherwise odd cache file is ignored and rewritten; a cache that cannot be
// written only costs the parsing.
constexpr char kMeshCacheMagic[8] = {'F', 'H', 'M', 'E', 'S', 'H', '1', '\0'};

std::optional<Mesh> ReadMeshCache(const std::string& file, uint64_t key) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return std::nullopt;
  const uintmax_t bytes = fs::file_size(file, ec);
  std::ifstream in(file, std::ios::binary);
  char magic[8];
  uint64_t k = 0, nv = 0, nt = 0;
  if (ec || !in || !in.read(magic, 8) || !in.read(reinterpret_cast<char*>(&k), 8) ||
      !in.read(reinterpret_cast<char*>(&nv), 8) || !in.read(reinterpret_cast<char*>(&nt), 8))
    return std::nullopt;
  if (std::memcmp(magic, kMeshCacheMagic, 8) != 0 || k != key || nv == 0 || nt == 0 || nv > (1ull << 31) ||
      nt > (1ull << 31) || bytes != 32 + 12 * nv + 12 * nt)
    return std::nullopt;
  Mesh m;
  m.vertices.resize(nv);
  m.triangles.resize(nt);
  std::vector<float> v(3 * nv);
  std::vector<int32_t> t(3 * nt);
  if (!in.read(reinterpret_cast<char*>(v.data()), std::streamsize(4 * v.size())) ||
      !in.read(reinterpret_cast<char*>(t.data()), std::streamsize(4 * t.size())))
    return std::nullopt;
  for (size_t i = 0; i < nv; ++i) {
    m.vertices[i] = Eigen::Vector3f(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    if (!m.vertices[i].allFinite()) return std::nullopt;
  }
  for (size_t i = 0; i < nt; ++i) {
    m.triangles[i] = Eigen::Vector3i(t[3 * i], t[3 * i + 1], t[3 * i + 2]);
    if ((m.triangles[i].array() < 0).any() || (m.triangles[i].array() >= int64_t(nv)).any()) return std::nullopt;
  }
  return m;
}

void WriteMeshCache(const std::string& dir, const std::string& file, uint64_t key, const Mesh& m) {
  try {
    fs::create_directories(dir);
    std::vector<float> v;
    v.reserve(3 * m.vertices.size());
    for (const auto& p : m.vertices) v.insert(v.end(), {p.x(), p.y(), p.z()});
    std::vector<int32_t> t;
    t.reserve(3 * m.triangles.size());
    for (const auto& f : m.triangles) t.insert(t.end(), {f.x(), f.y(), f.z()});
    const uint64_t nv = m.vertices.size(), nt = m.triangles.size();
    AtomicWrite(file, [&](const std::string& tmp) {
      std::ofstream out(tmp, std::ios::binary);
      out.write(kMeshCacheMagic, 8);
      out.write(reinterpret_cast<const char*>(&key), 8);
      out.write(reinterpret_cast<const char*>(&nv), 8);
      out.write(reinterpret_cast<const char*>(&nt), 8);
      out.write(reinterpret_cast<const char*>(v.data()), std::streamsize(4 * v.size()));
      out.write(reinterpret_cast<const char*>(t.data()), std::streamsize(4 * t.size()));
      out.close();
      if (!out) throw InputError(tmp + ": cannot write");
    });
  } catch (const std::exception& e) {
    spdlog::debug("mesh cache: {} not written ({})", file, e.what());
  }
}

// LoadMeshFile through the cache; `content` is the file's hash (HashFile from kFnvOffset), none
// when it cannot be read.
Mesh LoadMeshCached(const std::string& path, std::optional<uint64_t> content) {
  const std::string dir = CacheFolder("meshes");
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  static const std::set<std::string> kSelfContained{".obj", ".ply", ".off", ".stl", ".glb", ".dae"};
  std::error_code ec;
  if (dir.empty() || !kSelfContained.count(ext) || !fs::is_regular_file(path, ec)) return LoadMeshFile(path);
  if (!content) return LoadMeshFile(path);
  const uint64_t key = Fnv1a(ext + "|assimp " + FURNIHOST_ASSIMP_VERSION + "|" + std::string(kMeshCacheMagic, 7), *content);
  const std::string file = dir + "/" + Hex64(key) + ".fhmesh";
  if (auto cached = ReadMeshCache(file, key)) return std::move(*cached);
  Mesh m = LoadMeshFile(path);
  WriteMeshCache(dir, file, key, m);
  return m;
}

// The distinct mesh files a catalog's entries name (a grown catalog names one file from many
// entries: variants of a model differ in size only): each file is hashed once and parsed once
// (through the cache), on first use by any thread; each entry naming it takes a copy of the
// parsed mesh to normalise, the last one the mesh itself.
class MeshFiles {
 public:
  // The normalised path of an entry's "mesh" (relative to the catalog's folder `dir`).
  static std::string PathOf(const std::string& mesh, const fs::path& dir) {
    fs::path p(mesh);
    if (p.is_relative()) p = dir / p;
    return p.lexically_normal().string();
  }
  // Counts one more entry naming `path`.
  void Add(const std::string& path) { ++files_[path].users; }
  // The file's hash (HashFile from kFnvOffset); none when it cannot be read.
  std::optional<uint64_t> Hash(const std::string& path) {
    File& f = files_.at(path);
    std::call_once(f.hashed, [&] {
      uint64_t h = kFnvOffset;
      if (HashFile(h, path)) f.hash = h;
    });
    return f.hash;
  }
  // The parsed mesh (file units and axes) for one of the entries counted by Add; the parsing's
  // InputError for each of them when the file cannot be parsed.
  Mesh Take(const std::string& path) {
    File& f = files_.at(path);
    std::call_once(f.parsed, [&] {
      try {
        f.mesh = LoadMeshCached(path, Hash(path));
      } catch (const InputError& e) {
        f.error = e.what();
      }
    });
    if (!f.error.empty()) throw InputError(f.error);
    std::lock_guard<std::mutex> lock(f.taking);
    return --f.users == 0 ? std::move(f.mesh) : f.mesh;
  }
  // Every file's path.
  std::vector<std::string> Paths() const {
    std::vector<std::string> out;
    for (const auto& [p, f] : files_) out.push_back(p);
    return out;
  }

 private:
  struct File {
    size_t users = 0;
    std::once_flag hashed, parsed;
    std::optional<uint64_t> hash;
    Mesh mesh;
    std::string error;
    std::mutex taking;
  };
  std::map<std::string, File> files_;  // filled before the entries load; only its values change then
};

EntryResult LoadEntry(const nlohmann::json& e, size_t index, const fs::path& dir, MeshFiles& files) {
  EntryResult r;
  r.id = "#" + std::to_string(index);
  if (!e.is_object()) {
    r.reason = "entry is not a JSON object";
    return r;
  }
  if (e.contains("id") && e["id"].is_string() && !e["id"].get<std::string>().empty()) {
    r.id = e["id"].get<std::string>();
  } else {
    r.reason = "missing or empty \"id\"";
    return r;
  }
  auto fail = [&](std::string why) {
    r.reason = std::move(why);
    return r;
  };
  if (!e.contains("class") || !e["class"].is_string() || e["class"].get<std::string>().empty())
    return fail("missing or empty \"class\"");
  if (e.contains("subclass") && !e["subclass"].is_string())
    return fail("\"subclass\" must be a string");
  if (!e.contains("mesh") || !e["mesh"].is_string() || e["mesh"].get<std::string>().empty())
    return fail("missing or empty \"mesh\"");
  if (!e.contains("up") || !e["up"].is_string())
    return fail("missing \"up\" (one of +x, -x, +y, -y, +z, -z)");
  const std::string up = e["up"].get<std::string>();
  const auto rot = UpRotation(up);
  if (!rot) return fail("bad \"up\" \"" + up + "\" (expected one of +x, -x, +y, -y, +z, -z)");

  // "front": a mesh axis (as "up") or a vector in the mesh's axes, turned z up with the mesh; its
  // horizontal part is the front (scaled with the mesh below).
  std::optional<Eigen::Vector3f> front_file;
  if (e.contains("front")) {
    const auto& f = e["front"];
    const char* expected = " (expected one of +x, -x, +y, -y, +z, -z, or [x, y, z])";
    if (f.is_string()) {
      const std::string name = f.get<std::string>();
      if (!UpRotation(name)) return fail("bad \"front\" \"" + name + "\"" + expected);
      front_file = Eigen::Vector3f::Zero();
      (*front_file)[name[1] - 'x'] = name[0] == '+' ? 1.f : -1.f;
    } else if (f.is_array() && f.size() == 3 && std::all_of(f.begin(), f.end(), [](const auto& v) {
                 return v.is_number() && std::isfinite(v.template get<double>()) && std::abs(v.template get<double>()) < 1e6;
               })) {
      front_file = Eigen::Vector3f(f[0].get<float>(), f[1].get<float>(), f[2].get<float>());
    } else {
      return fail("bad \"front\" " + f.dump().substr(0, 40) + expected);
    }
    const Eigen::Vector3f turned = (*rot) * (*front_file);
    if (!(turned.head<2>().norm() > 0.5f * turned.norm()))
      return fail("\"front\" " + f.dump().substr(0, 40) + " points (nearly) along \"up\" " + up +
                  "; it names the horizontal way the model faces");
  }

  std::vector<std::string> scale_keys;
  for (const char* k : {"scale", "height_m", "size_m"})
    if (e.contains(k)) scale_keys.push_back(k);
  if (scale_keys.empty()) return fail("needs exactly one of \"scale\", \"height_m\", \"size_m\"");
  if (scale_keys.size() > 1)
    return fail("has both \"" + scale_keys[0] + "\" and \"" + scale_keys[1] +
                "\" (give exactly one of \"scale\", \"height_m\", \"size_m\")");
  const std::string& sk = scale_keys[0];
  if (sk == "size_m") {
    const auto& s = e["size_m"];
    if (!s.is_array() || s.size() != 3 || !PositiveFinite(s[0]) || !PositiveFinite(s[1]) ||
        !PositiveFinite(s[2]))
      return fail("\"size_m\" must be [width, depth, height] of three positive numbers (m)");
  } else if (!PositiveFinite(e[sk])) {
    return fail("\"" + sk + "\" must be a positive number, got " + e[sk].dump());
  }

  fs::path mesh = fs::path(e["mesh"].get<std::string>());
  if (mesh.is_relative()) mesh = dir / mesh;
  mesh = mesh.lexically_normal();
  std::error_code ec;
  if (!fs::exists(mesh, ec)) return fail("mesh file not found: " + mesh.string());
  if (!fs::is_regular_file(mesh, ec)) return fail("mesh is not a regular file: " + mesh.string());

  Mesh m;
  try {
    m = files.Take(mesh.string());
  } catch (const InputError& err) {
    return fail(std::string("unreadable mesh: ") + err.what());
  }

  // Turn z up; bounds in the rotated (still unscaled) frame.
  Eigen::AlignedBox3f box;
  for (auto& v : m.vertices) {
    v = (*rot) * v;
    box.extend(v);
  }
  const Eigen::Vector3f ext = box.sizes();
  Eigen::Vector3f scale = Eigen::Vector3f::Ones();
  if (sk == "scale") {
    scale.setConstant(e["scale"].get<float>());
  } else if (sk == "height_m") {
    if (!(ext.z() > 0.f)) return fail("zero-size model: height 0 in mesh units, cannot fit \"height_m\"");
    scale.setConstant(e["height_m"].get<float>() / ext.z());
  } else {
    for (int a = 0; a < 3; ++a) {
      if (!(ext[a] > 0.f))
        return fail("zero-size model: extents " + Fmt3(ext) +
                    " in mesh units (z up), cannot fit \"size_m\"");
      scale[a] = e["size_m"][a].get<float>() / ext[a];
    }
  }
  const Eigen::Vector3f size = ext.cwiseProduct(scale);
  // A model needs a height and some footprint to be scanned; 1 mm is far below any furniture.
  constexpr float kMinExtent = 1e-3f;
  if (!(size.z() > kMinExtent) || !(std::max(size.x(), size.y()) > kMinExtent))
    return fail("zero-size model: extents " + Fmt3(size) + " m after scaling");
  // And 100 m far above: such a size is a wrong "scale" (mm read as m), and scanning it from
  // a few metres would give no useful view.
  constexpr float kMaxExtent = 100.f;
  if (!(size.maxCoeff() <= kMaxExtent))
    return fail("implausible size " + Fmt3(size) + " m after scaling (over " + std::to_string(static_cast<int>(kMaxExtent)) +
                " m; check \"" + sk + "\")");

  const Eigen::Vector3f lo = box.min().cwiseProduct(scale);
  const Eigen::Vector3f hi = box.max().cwiseProduct(scale);
  const Eigen::Vector3f bottom_centre(0.5f * (lo.x() + hi.x()), 0.5f * (lo.y() + hi.y()), lo.z());
  for (auto& v : m.vertices) v = v.cwiseProduct(scale) - bottom_centre;
  // Zero-area triangles have no normal (consumers would divide by zero) and no surface to
  // scan: drop them, and refuse a mesh that has nothing else.
  const size_t before = m.triangles.size();
  m.triangles.erase(std::remove_if(m.triangles.begin(), m.triangles.end(),
                                   [&](const Eigen::Vector3i& t) {
                                     // sin(angle at a) <= 1e-6: zero area up to float rounding.
                                     const Eigen::Vector3f e1 = m.vertices[t[1]] - m.vertices[t[0]];
                                     const Eigen::Vector3f e2 = m.vertices[t[2]] - m.vertices[t[0]];
                                     return !(e1.cross(e2).norm() > 1e-6f * e1.norm() * e2.norm());
                                   }),
                    m.triangles.end());
  if (m.triangles.empty())
    return fail("degenerate mesh: all " + std::to_string(before) + " triangles have zero area");
  if (m.triangles.size() < before)
    spdlog::debug("{}: dropped {} zero-area triangles of {}", mesh.string(), before - m.triangles.size(), before);

  r.model.id = r.id;
  r.model.cls = e["class"].get<std::string>();
  r.model.subclass = e.value("subclass", std::string());
  r.model.mesh_path = fs::absolute(mesh).string();
  if (front_file) {
    const Eigen::Vector3f f = ((*rot) * (*front_file)).cwiseProduct(scale);
    r.front.front = Eigen::Vector3f(f.x(), f.y(), 0.f).normalized();
    r.front.source = "catalog";
  } else {
    FrontEstimate fe = EstimateFront(m);
    r.front.front = fe.front;
    r.front.source = std::move(fe.how);
  }
  r.model.mesh = std::move(m);
  r.model.size = size;
  return r;
}

}  // namespace

FURNIHOST_API const CatalogModel* Catalog::Find(const std::string& id) const {
  for (const auto& m : models)
    if (m.id == id) return &m;
  return nullptr;
}

FURNIHOST_API const ModelFront* Catalog::FrontOf(const std::string& id) const {
  const auto it = fronts.find(id);
  return it == fronts.end() ? nullptr : &it->second;
}

FURNIHOST_API std::vector<std::string> Catalog::Classes() const {
  std::set<std::string> s;
  for (const auto& m : models) s.insert(m.cls);
  return {s.begin(), s.end()};
}

Catalog LoadCatalog(const std::string& path, bool strict) {
  Catalog cat;
  cat.path = fs::absolute(path).lexically_normal().string();
  const nlohmann::json j = ReadJson(path);
  if (!j.is_object() || !j.contains("models") || !j["models"].is_array())
    throw InputError(path + ": not a catalog (expected an object with a \"models\" array)");
  if (j.contains("furnihost_catalog") &&
      !(j["furnihost_catalog"].is_number_integer() && j["furnihost_catalog"].get<int>() == 1))
    throw InputError(path + ": unsupported \"furnihost_catalog\" version " +
                     j["furnihost_catalog"].dump() + " (this build reads version 1)");
  const fs::path dir = fs::path(cat.path).parent_path();
  const auto& entries = j["models"];

  // Each distinct mesh file, hashed and parsed once, however many entries name it.
  MeshFiles files;
  for (const auto& e : entries)
    if (e.is_object() && e.contains("mesh") && e["mesh"].is_string())
      files.Add(MeshFiles::PathOf(e["mesh"].get<std::string>(), dir));
  std::vector<EntryResult> results(entries.size());
  tbb::parallel_for(size_t(0), entries.size(),
                    [&](size_t i) { results[i] = LoadEntry(entries[i], i, dir, files); });
  // The files of entries that failed before their mesh: hashed too, so fixing one changes the key.
  const std::vector<std::string> paths = files.Paths();
  tbb::parallel_for(size_t(0), paths.size(), [&](size_t k) { files.Hash(paths[k]); });
  // The catalog's hash: one chain over catalog.json and, per entry in order, the hash of its mesh
  // file (every mesh that exists, valid or not).
  uint64_t h = kFnvOffsetTruncated;
  const bool catalog_read = HashFile(h, path);
  for (const auto& e : entries)
    if (e.is_object() && e.contains("mesh") && e["mesh"].is_string())
      if (const auto fh = files.Hash(MeshFiles::PathOf(e["mesh"].get<std::string>(), dir))) h = Fnv1a(&*fh, sizeof(*fh), h);
  if (!catalog_read) throw InputError(path + ": cannot read the file");

  std::map<std::string, size_t> first_index;
  for (size_t i = 0; i < results.size(); ++i) {
    auto& r = results[i];
    if (r.reason.empty()) {
      auto [it, fresh] = first_index.emplace(r.id, i);
      if (!fresh) r.reason = "duplicate id (first defined at entry #" + std::to_string(it->second) + ")";
    }
    if (!r.reason.empty()) {
      if (strict) throw InputError(path + ": model " + r.id + ": " + r.reason);
      spdlog::warn("{}: model {}: {} (skipped)", path, r.id, r.reason);
      cat.skipped.push_back({r.id, r.reason});
      continue;
    }
    for (const auto& [k, v] : entries[i].items())
      if (!KnownKeys().count(k)) spdlog::warn("{}: model {}: unknown key \"{}\" ignored", path, r.id, k);
    cat.fronts[r.id] = std::move(r.front);
    cat.models.push_back(std::move(r.model));
  }
  cat.hash = Hex64(h);
  // Which models face the way their mesh suggests: one line naming each with its estimate, and
  // (at debug level) the depths each was chosen on.
  std::string estimated;
  size_t n_estimated = 0;
  for (const auto& m : cat.models)
    if (const ModelFront& f = cat.fronts.at(m.id); f.source != "catalog") {
      const std::string way = f.source.substr(0, f.source.find(" ("));
      estimated += (n_estimated++ ? ", " : "") + m.id + " " + way;
      spdlog::debug("{}: model {}: no \"front\", {}", path, m.id, f.source);
    }
  if (n_estimated)
    spdlog::info("{}: {} of {} model(s) have no \"front\", the way each faces is estimated from its mesh: {}", path,
                 n_estimated, cat.models.size(), estimated);
  if (!cat.skipped.empty())
    spdlog::warn("{}: {} model(s) loaded, {} skipped", path, cat.models.size(), cat.skipped.size());
  else
    spdlog::info("{}: {} model(s) loaded", path, cat.models.size());
  return cat;
}

std::map<std::string, Eigen::Vector3f> TypicalClassSizes(const Catalog& catalog) {
  std::map<std::string, std::vector<Eigen::Vector3f>> by_class;
  for (const auto& m : catalog.models) by_class[m.cls].push_back(m.size);
  std::map<std::string, Eigen::Vector3f> out;
  for (auto& [cls, sizes] : by_class) {
    Eigen::Vector3f med;
    for (int k = 0; k < 3; ++k) {
      std::vector<float> v;
      for (const auto& s : sizes) v.push_back(s[k]);
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      med[k] = v[v.size() / 2];
    }
    out[cls] = med;
  }
  return out;
}

}  // namespace furnihost
