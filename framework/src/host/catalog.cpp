// CAD catalogs: catalog.json parsing, mesh import with assimp (in libfurnihost_meshio, loaded on
// the first mesh parsed: meshio/mesh_import.cpp), normalisation to the project frame (metres,
// z up, bounding-box bottom centre at the origin).
//
// Units and axes: the catalog's `up` and scale fields are defined relative to assimp's DEFAULT
// import (the "frame" text of ../shared/data/cad_catalog/catalog.json). For most formats that
// is the file's own axes and units, but the Collada importer of assimp 5.2 bakes the file's
// <unit meter="..."> into the root node (-> metres) and turns <up_axis>Z_UP</up_axis> files
// y up. We therefore pin the importer properties that change axes or units to their default
// values and never request aiProcess_GlobalScale, so an assimp configuration elsewhere in the
// process cannot silently change what a catalog entry means.
#include "furnihost/host/catalog.hpp"

#include <dlfcn.h>
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

namespace {
// assimp 5.2's PLY importer loops forever on a header without end_header (a truncated
// download) or with a malformed line (fuzz_catalog): the header must follow the PLY grammar
// before assimp sees the file. Its element counts must fit the file too: assimp allocates what a
// header declares before reading a byte of data (2e9 faces: std::bad_alloc). Face indices are
// checked on the imported scene (meshio/mesh_import.cpp), whatever the layout and encoding.
void CheckPlyHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  if (!std::getline(in, line)) return;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  // assimp takes a file for PLY by its "ply" token, not by a whole first line (fuzz_catalog:
  // "ply" and garbage on the first line hung it too), so such a file is checked as well.
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool ply_name = ext == ".ply";
  if (line.rfind("ply", 0) != 0 && !ply_name) return;
  if (line != "ply")
    throw InputError(path + ": malformed PLY file (the first line is not 'ply')");
  static const std::map<std::string, int> kTypes = {
      {"char", 1},  {"uchar", 1},  {"int8", 1},  {"uint8", 1},  {"short", 2},   {"ushort", 2},
      {"int16", 2}, {"uint16", 2}, {"int", 4},   {"uint", 4},   {"int32", 4},   {"uint32", 4},
      {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  auto bad = [&](const std::string& why) { return InputError(path + ": malformed PLY file (" + why + ")"); };
  size_t read = line.size() + 1;
  bool format = false, ascii = false;
  struct Element {
    std::string name;
    unsigned long long count = 0;
    unsigned long long min_bytes = 0;  // the fewest bytes one item of it takes in the file
  };
  std::vector<Element> elements;
  while (read < (1u << 16) && std::getline(in, line)) {
    read += line.size() + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    for (char c : line)
      if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7F) throw bad("control character");
    std::istringstream ls(line);
    std::vector<std::string> t;
    for (std::string w; ls >> w;) t.push_back(w);
    if (t.empty() || t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "end_header") {
      if (!format || elements.empty()) throw bad("no format or no element before end_header");
      break;
    }
    if (t[0] == "format") {
      if (t.size() != 3 || (t[1] != "ascii" && t[1] != "binary_little_endian" && t[1] != "binary_big_endian"))
        throw bad("bad format line");
      format = true;
      ascii = t[1] == "ascii";
    } else if (t[0] == "element") {
      if (t.size() != 3 || t[2].find_first_not_of("0123456789") != std::string::npos || t[2].size() > 10)
        throw bad("bad element line '" + line.substr(0, 40) + "'");
      elements.push_back({t[1], std::stoull(t[2]), 0});
    } else if (t[0] == "property") {
      const bool list = t.size() == 5 && t[1] == "list" && kTypes.count(t[2]) && kTypes.count(t[3]);
      if (elements.empty() || !(list || (t.size() == 3 && kTypes.count(t[1]))))
        throw bad("bad property line '" + line.substr(0, 40) + "'");
      // ascii: a value and its separator; binary: a scalar, or a list's count alone (it may be 0).
      elements.back().min_bytes += ascii ? 2 : static_cast<unsigned long long>(kTypes.at(list ? t[2] : t[1]));
    } else {
      throw bad("unknown line '" + line.substr(0, 40) + "'");
    }
  }
  if (line.rfind("end_header", 0) != 0) throw InputError(path + ": PLY header has no end_header in its first 64 KB (truncated file?)");
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  const std::streamoff at = in.tellg();
  if (ec || at < 0) return;
  const unsigned long long left = size > uintmax_t(at) ? size - uintmax_t(at) : 0;
  // The last ascii value needs no separator after it.
  unsigned long long need = 0;
  for (const auto& e : elements) {
    const unsigned long long per = std::max<unsigned long long>(e.min_bytes, 1);
    if (e.count > (left + 1) / per || need + e.count * per > left + 1)
      throw bad("element '" + e.name.substr(0, 40) + "' declares " + std::to_string(e.count) + " items, the file holds " +
                std::to_string(left) + " bytes of data");
    need += e.count * per;
  }
}

// assimp 5.2's COLLADA importer reads the index lists (<p>, <v>, <vcount>, <h>) and integer
// arrays number by number and stops only at the end of the text: a character that is neither a
// digit nor a blank is never consumed, so one stray byte in a list appends zeros forever
// (fuzz_mesh: 12 GB and four minutes, then std::bad_alloc). A COLLADA file is imported only if
// those lists hold integers and blanks. Linear in the file.
void CheckColladaLists(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char head[512] = {};
  in.read(head, sizeof(head) - 1);
  std::string start(head, static_cast<size_t>(in.gcount()));
  for (char& c : start) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".dae" && ext != ".xml" && start.find("<collada") == std::string::npos) return;
  in.clear();
  in.seekg(0);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  static const std::set<std::string> kLists{"p", "v", "vcount", "h", "int_array"};
  for (size_t i = text.find('<'); i != std::string::npos; i = text.find('<', i + 1)) {
    size_t e = i + 1;
    while (e < text.size() && (std::isalnum(static_cast<unsigned char>(text[e])) || text[e] == '_')) ++e;
    if (!kLists.count(text.substr(i + 1, e - i - 1))) continue;
    const size_t open_end = text.find('>', e);
    if (open_end == std::string::npos) return;  // assimp's XML parser refuses it
    if (text[open_end - 1] == '/') continue;    // <p/>: empty
    const bool signed_values = text.compare(i + 1, 9, "int_array") == 0;
    for (size_t k = open_end + 1; k < text.size() && text[k] != '<'; ++k) {
      const unsigned char c = static_cast<unsigned char>(text[k]);
      if (std::isdigit(c) || c == ' ' || c == '\t' || c == '\n' || c == '\r' || (signed_values && c == '-')) continue;
      const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(k), '\n');
      throw InputError(path + ":" + std::to_string(line) + ": <" + text.substr(i + 1, e - i - 1) +
                       "> holds a character that is not part of an integer list (byte " + std::to_string(int(c)) + ")");
    }
  }
}

// assimp 5.2's OFF importer reads vertices by unchecked face indices and splits lines at
// control characters (fuzz_catalog: a heap overflow, then a crash). An OFF file is imported
// only if it is plain: header, counts, nV vertex lines of >= 3 numbers, nF face lines of
// 3..9 indices below nV (then optional colour values).
void CheckOff(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  auto bad = [&](const std::string& why) { return InputError(path + ": malformed OFF file (" + why + ")"); };
  auto next = [&](std::vector<std::string>& tok) {
    while (std::getline(in, line)) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      for (char c : line)
        if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7F) throw bad("control character");
      std::istringstream ls(line);
      tok.clear();
      for (std::string t; ls >> t;) tok.push_back(t);
      if (!tok.empty() && tok[0][0] != '#') return true;
    }
    return false;
  };
  auto number = [](const std::string& t, double& v) {
    char* end = nullptr;
    v = std::strtod(t.c_str(), &end);
    return end == t.c_str() + t.size() && std::isfinite(v);
  };
  std::vector<std::string> tok;
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (!next(tok)) return;
  std::string head = tok[0];
  for (auto& c : head) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (ext != ".off" && head.find("OFF") == std::string::npos) return;  // another format
  // assimp also reads "OFF<digits>", "4OFF", "STOFF"...: only the plain headers are imported.
  if (tok[0] != "OFF" && tok[0] != "COFF" && tok[0] != "NOFF" && tok[0] != "CNOFF")
    throw bad("unsupported header '" + tok[0].substr(0, 20) + "'");
  tok.erase(tok.begin());
  if (tok.empty() && !next(tok)) throw bad("no counts");
  double nv = 0, nf = 0;
  if (tok.size() < 2 || !number(tok[0], nv) || !number(tok[1], nf) || nv < 0 || nf < 0 || nv > 1e8 || nf > 1e8 ||
      nv != std::floor(nv) || nf != std::floor(nf))
    throw bad("bad vertex/face counts");
  for (double i = 0; i < nv; ++i) {
    double v;
    if (!next(tok) || tok.size() < 3 || !number(tok[0], v) || !number(tok[1], v) || !number(tok[2], v))
      throw bad("vertex " + std::to_string(static_cast<long long>(i)) + " is not 3 numbers");
  }
  for (double f = 0; f < nf; ++f) {
    double k, idx;
    if (!next(tok) || !number(tok[0], k) || k < 3 || k > 9 || k != std::floor(k) || tok.size() < 1 + k)
      throw bad("face " + std::to_string(static_cast<long long>(f)) + " is not 3 to 9 vertex indices");
    for (size_t m = 1; m <= static_cast<size_t>(k); ++m)
      if (!number(tok[m], idx) || idx < 0 || idx >= nv || idx != std::floor(idx))
        throw bad("face " + std::to_string(static_cast<long long>(f)) + " uses vertex " + tok[m] + " of " +
                  std::to_string(static_cast<long long>(nv)));
  }
}
}  // namespace

namespace {
// libfurnihost_meshio's import function, the library loaded once (beside the host library, else
// by the dynamic linker's search: RUNPATH, LD_LIBRARY_PATH); an InputError when it cannot be.
using ImportFn = bool (*)(const char*, Mesh*, std::string*);
ImportFn MeshImporter() {
  static const std::pair<ImportFn, std::string> loaded = []() -> std::pair<ImportFn, std::string> {
    const char* kName = "libfurnihost_meshio.so";
    std::vector<std::string> tried;
    Dl_info self{};
    if (dladdr(reinterpret_cast<void*>(&LoadMeshFile), &self) && self.dli_fname)
      tried.push_back((fs::path(self.dli_fname).parent_path() / kName).string());
    tried.push_back(kName);
    std::string errors;
    for (const auto& name : tried) {
      // Never closed: the mesh importer stays for the process (as the plugins' libraries do).
      if (void* lib = dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL)) {
        if (auto* fn = reinterpret_cast<ImportFn>(dlsym(lib, "furnihost_meshio_import"))) return {fn, ""};
        errors += (errors.empty() ? "" : "; ") + name + ": no furnihost_meshio_import";
        continue;
      }
      const char* e = dlerror();
      errors += (errors.empty() ? "" : "; ") + std::string(e ? e : name);
    }
    return {nullptr, errors};
  }();
  if (!loaded.first) throw InputError("cannot load the mesh importer (" + loaded.second + ")");
  return loaded.first;
}
}  // namespace

Mesh LoadMeshFile(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path + ": no such mesh file");
  CheckPlyHeader(path);
  CheckOff(path);
  CheckColladaLists(path);
  Mesh out;
  std::string why;
  if (!MeshImporter()(path.c_str(), &out, &why)) throw InputError(path + ": " + why);
  if (out.triangles.empty()) throw InputError(path + ": no triangles in the file");
  return out;
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
