// Catalog loading: up-axis / unit normalisation of every shared model, and the documented
// errors for broken entries.
#include <sys/stat.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>

#include "furnihost/host/catalog.hpp"
#include "furnihost/geometry.hpp"
#include "furnihost/host/io.hpp"
#include "test_support.hpp"

namespace furnihost {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Plausible real-world heights per class [m] (ranges, not tuned to any one file):
// chairs 0.7-1.3 (dining to high-back office), tables 0.3-0.9 (coffee to dining), stools
// 0.4-0.9 (low to bar stool), armchairs and sofas 0.6-1.1, desks 0.6-2.0 (with hutch),
// cabinets 0.4-2.4 (nightstand to wardrobe / tall bookshelf).
const std::map<std::string, std::pair<float, float>> kHeight = {
    {"chair", {0.7f, 1.3f}},    {"table", {0.3f, 0.9f}}, {"stool", {0.4f, 0.9f}},
    {"armchair", {0.6f, 1.1f}}, {"sofa", {0.6f, 1.1f}},  {"desk", {0.6f, 2.0f}},
    {"cabinet", {0.4f, 2.4f}}};

TEST(Catalog, EverySharedModelLoadsWithAPlausibleSize) {
  const std::string data = testing::SharedDataDir();
  ASSERT_FALSE(data.empty());
  const std::string path = data + "/cad_catalog/catalog.json";
  const json raw = json::parse(std::ifstream(path));
  const Catalog cat = LoadCatalog(path, /*strict=*/true);
  EXPECT_TRUE(cat.skipped.empty());
  ASSERT_EQ(cat.models.size(), raw["models"].size());
  EXPECT_EQ(cat.hash.size(), 16u);
  for (const auto& m : cat.models) {
    SCOPED_TRACE(m.id);
    ASSERT_TRUE(kHeight.count(m.cls)) << "class without a stated range: " << m.cls;
    const auto [lo, hi] = kHeight.at(m.cls);
    EXPECT_GE(m.size.z(), lo);
    EXPECT_LE(m.size.z(), hi);
    // Footprint: nothing in a room is under 20 cm or over 3 m wide/deep.
    EXPECT_GE(m.size.x(), 0.2f);
    EXPECT_GE(m.size.y(), 0.2f);
    EXPECT_LE(m.size.x(), 3.0f);
    EXPECT_LE(m.size.y(), 3.0f);
    // Standing with its bounding-box bottom centre at the origin, size = its bounds.
    Eigen::AlignedBox3f b;
    for (const auto& v : m.mesh.vertices) b.extend(v);
    EXPECT_NEAR(b.min().z(), 0.f, 1e-4f);
    EXPECT_NEAR(b.center().x(), 0.f, 1e-4f);
    EXPECT_NEAR(b.center().y(), 0.f, 1e-4f);
    EXPECT_LT((b.sizes() - m.size).norm(), 1e-4f);
    EXPECT_FALSE(m.mesh.triangles.empty());
    EXPECT_TRUE(fs::exists(m.mesh_path));
  }
  // size_m entries fit all three axes exactly: width = x, depth = y, height = z.
  const CatalogModel* chair = cat.Find("sh3d_chair");
  ASSERT_NE(chair, nullptr);
  EXPECT_LT((chair->size - Eigen::Vector3f(0.4f, 0.42f, 0.9f)).norm(), 1e-4f);
  EXPECT_EQ(cat.Find("no_such_model"), nullptr);
  const auto classes = cat.Classes();
  EXPECT_TRUE(std::is_sorted(classes.begin(), classes.end()));
  EXPECT_EQ(classes.size(), kHeight.size());
}

// Turn symmetries of the shared models (what `furnihost simulate` writes into the ground truth):
// nothing one sits on looks the same turned round; a rectangular table does by half turns, a
// square one by quarter turns.
TEST(Catalog, SharedModelsTurnSymmetries) {
  const std::string data = furnihost::testing::SharedDataDir();
  ASSERT_FALSE(data.empty());
  const Catalog cat = LoadCatalog(data + "/cad_catalog/catalog.json", true);
  for (const auto& m : cat.models)
    if (m.cls == "chair" || m.cls == "armchair" || m.cls == "sofa") {
      EXPECT_EQ(YawSymmetry(m.mesh), 1) << m.id;
    }
  EXPECT_EQ(YawSymmetry(cat.Find("sh3d_table")->mesh), 2);
  EXPECT_EQ(YawSymmetry(cat.Find("sh3d_squareTable")->mesh), 4);
}

// A tiny temporary catalog folder.
struct TempCatalog {
  fs::path dir;
  explicit TempCatalog(const std::string& name) : dir(testing::TempDir("catalog_" + name)) {}
  ~TempCatalog() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  void Write(const std::string& rel, const std::string& text) const {
    fs::create_directories((dir / rel).parent_path());
    std::ofstream(dir / rel, std::ios::binary) << text;
  }
  std::string Catalog(const json& models) const {
    Write("catalog.json", json{{"furnihost_catalog", 1}, {"models", models}}.dump(1));
    return (dir / "catalog.json").string();
  }
};

// An OBJ box [0, w] x [0, h] x [0, d] (y up, file units).
std::string ObjBox(float w, float h, float d) {
  std::string s = "# box\n";
  for (int i = 0; i < 8; ++i)
    s += "v " + std::to_string(i & 1 ? w : 0.f) + " " + std::to_string(i & 2 ? h : 0.f) + " " +
         std::to_string(i & 4 ? d : 0.f) + "\n";
  s += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
  return s;
}

TEST(Catalog, UnitsAndUpAxesAreNormalised) {
  TempCatalog t("units");
  t.Write("mm.obj", ObjBox(500.f, 900.f, 400.f));  // millimetres, y up
  t.Write("zup.obj", ObjBox(2.f, 1.f, 3.f));       // z up: height 3
  // Collada in centimetres, Z_UP: assimp's default import gives metres, y up; the catalog
  // (like ../shared/data/cad_catalog) therefore says up "+y", scale 1.
  t.Write("cm.dae", R"(<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit meter="0.01" name="centimeter"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries><geometry id="g"><mesh>
    <source id="p"><float_array id="pa" count="12">0 0 0 100 0 0 100 50 0 0 50 200</float_array>
      <technique_common><accessor source="#pa" count="4" stride="3">
        <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
      </accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
    <triangles count="2"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2 0 2 3</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n">
    <instance_geometry url="#g"/></node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
)");
  const std::string path = t.Catalog(json::array({
      {{"id", "mm"}, {"class", "chair"}, {"mesh", "mm.obj"}, {"up", "+y"}, {"scale", 0.001}},
      {{"id", "zup"}, {"class", "table"}, {"mesh", "zup.obj"}, {"up", "+z"}, {"height_m", 0.75}},
      {{"id", "fit"}, {"class", "table"}, {"mesh", "mm.obj"}, {"up", "+y"}, {"size_m", {1.2, 0.8, 0.7}}},
      {{"id", "cm"}, {"class", "cabinet"}, {"mesh", "cm.dae"}, {"up", "+y"}, {"scale", 1.0}},
  }));
  const Catalog cat = LoadCatalog(path, true);
  ASSERT_EQ(cat.models.size(), 4u);
  auto size = [&](const char* id) { return cat.Find(id)->size; };
  EXPECT_LT((size("mm") - Eigen::Vector3f(0.5f, 0.4f, 0.9f)).norm(), 1e-4f);
  EXPECT_LT((size("zup") - Eigen::Vector3f(0.5f, 0.25f, 0.75f)).norm(), 1e-4f);
  EXPECT_LT((size("fit") - Eigen::Vector3f(1.2f, 0.8f, 0.7f)).norm(), 1e-4f);
  EXPECT_LT((size("cm") - Eigen::Vector3f(1.0f, 0.5f, 2.0f)).norm(), 1e-4f)
      << "assimp's Collada unit / up-axis handling changed: " << size("cm").transpose();
  // y up turned z up keeps handedness: the OBJ's +z (depth) becomes -y.
  const auto& mm = cat.Find("mm")->mesh;
  Eigen::AlignedBox3f b;
  for (const auto& v : mm.vertices) b.extend(v);
  EXPECT_NEAR(b.min().z(), 0.f, 1e-6f);
  EXPECT_NEAR(b.center().x(), 0.f, 1e-6f);
}

TEST(Catalog, BrokenEntriesAreReportedWithTheirId) {
  TempCatalog t("broken");
  t.Write("ok.obj", ObjBox(1.f, 1.f, 1.f));
  t.Write("garbage.obj", "this is not a mesh\n\x01\x02\x03");
  t.Write("flat.obj", ObjBox(1.f, 0.f, 1.f));  // no height
  const std::vector<std::pair<json, std::string>> broken = {
      {{{"id", "missing"}, {"class", "chair"}, {"mesh", "nope.obj"}, {"up", "+y"}, {"scale", 1}},
       "mesh file not found"},
      {{{"id", "garbage"}, {"class", "chair"}, {"mesh", "garbage.obj"}, {"up", "+y"}, {"scale", 1}},
       "unreadable mesh"},
      {{{"id", "flat"}, {"class", "chair"}, {"mesh", "flat.obj"}, {"up", "+y"}, {"scale", 1}},
       "zero-size model"},
      {{{"id", "two"}, {"class", "chair"}, {"mesh", "ok.obj"}, {"up", "+y"}, {"scale", 1}, {"height_m", 0.8}},
       "has both \"scale\" and \"height_m\""},
      {{{"id", "badup"}, {"class", "chair"}, {"mesh", "ok.obj"}, {"up", "y"}, {"scale", 1}},
       "bad \"up\" \"y\""},
      {{{"id", "noscale"}, {"class", "chair"}, {"mesh", "ok.obj"}, {"up", "+y"}}, "needs exactly one of"},
      {{{"id", "negative"}, {"class", "chair"}, {"mesh", "ok.obj"}, {"up", "+y"}, {"scale", -2}},
       "\"scale\" must be a positive number"},
  };
  const json good = {{"id", "good"}, {"class", "chair"}, {"mesh", "ok.obj"}, {"up", "+y"}, {"height_m", 0.8}};
  for (const auto& [entry, reason] : broken) {
    SCOPED_TRACE(entry.dump());
    const std::string path = t.Catalog(json::array({good, entry}));
    // Lenient: skipped with id and reason, the good model still loads.
    const Catalog cat = LoadCatalog(path, false);
    ASSERT_EQ(cat.models.size(), 1u);
    EXPECT_EQ(cat.models[0].id, "good");
    ASSERT_EQ(cat.skipped.size(), 1u);
    EXPECT_EQ(cat.skipped[0].id, entry["id"].get<std::string>());
    EXPECT_NE(cat.skipped[0].reason.find(reason), std::string::npos) << cat.skipped[0].reason;
    // Strict: InputError "<catalog path>: model <id>: <reason>".
    try {
      LoadCatalog(path, true);
      ADD_FAILURE() << "strict load accepted a broken entry";
    } catch (const InputError& e) {
      const std::string prefix = path + ": model " + entry["id"].get<std::string>() + ": ";
      EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
      EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
  }
  // Duplicate ids: the second is skipped.
  const Catalog dup = LoadCatalog(t.Catalog(json::array({good, good})), false);
  EXPECT_EQ(dup.models.size(), 1u);
  ASSERT_EQ(dup.skipped.size(), 1u);
  EXPECT_NE(dup.skipped[0].reason.find("duplicate id"), std::string::npos);
  // Not a catalog at all.
  t.Write("other.json", R"({"objects": []})");
  EXPECT_THROW(LoadCatalog((t.dir / "other.json").string()), InputError);
  EXPECT_THROW(LoadMeshFile((t.dir / "nope.obj").string()), InputError);
}

// Face indices past the vertices, in layouts assimp's post-processing followed unchecked (a
// binary PLY index 0xFFFFFFF0: SIGSEGV), refused with the face named; files a mesh names that
// are FIFOs or folders are never opened (they blocked forever): an OBJ's material is skipped, a
// glTF's buffer makes the mesh unreadable.
TEST(Catalog, BadFaceIndicesAndNamedFilesThatAreNotRegular) {
  TempCatalog t("hostile_meshes");
  auto error_of = [&](const std::string& mesh) {
    try {
      LoadMeshFile((t.dir / mesh).string());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 2\nproperty list uchar uint vertex_indices\nend_header\n";
  const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 1};
  ply.append(reinterpret_cast<const char*>(v), sizeof v);
  for (uint32_t far : {2u, 0xFFFFFFF0u}) {
    const uint8_t three = 3;
    const uint32_t f[3] = {0, 1, far};
    ply.append(reinterpret_cast<const char*>(&three), 1);
    ply.append(reinterpret_cast<const char*>(f), sizeof f);
  }
  t.Write("bad.ply", ply);
  EXPECT_NE(error_of("bad.ply").find("face 1 of mesh 0 uses vertex 4294967280 of 3"), std::string::npos) << error_of("bad.ply");
  t.Write("faces_later.ply",  // the face element not the one right after the vertices
          "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
          "element edge 1\nproperty int vertex1\nproperty int vertex2\nelement face 1\n"
          "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 1\n0 1\n3 0 1 7\n");
  EXPECT_NE(error_of("faces_later.ply").find("uses vertex 7 of 3"), std::string::npos) << error_of("faces_later.ply");
  t.Write("huge.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                      "element face 2000000000\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 1\n3 0 1 2\n");
  EXPECT_NE(error_of("huge.ply").find("declares 2000000000 items"), std::string::npos) << error_of("huge.ply");

  t.Write("m.obj", "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 1\nf 1 2 3\n");
  ASSERT_EQ(::mkfifo((t.dir / "m.mtl").c_str(), 0644), 0);
  EXPECT_EQ(LoadMeshFile((t.dir / "m.obj").string()).triangles.size(), 1u);
  const std::string gltf =
      R"({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
          "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "buffers": [{"byteLength": 36, "uri": "m.bin"}],
          "bufferViews": [{"buffer": 0, "byteLength": 36}],
          "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1]}]})";
  t.Write("m.gltf", gltf);
  ASSERT_EQ(::mkfifo((t.dir / "m.bin").c_str(), 0644), 0);
  EXPECT_NE(error_of("m.gltf").find("m.bin is not a regular file"), std::string::npos) << error_of("m.gltf");
  fs::remove(t.dir / "m.bin");
  t.Write("m.bin", std::string(reinterpret_cast<const char*>(v), sizeof v));
  EXPECT_EQ(LoadMeshFile((t.dir / "m.gltf").string()).triangles.size(), 1u);
}

TEST(Catalog, HashCoversTheCatalogAndEveryMesh) {
  TempCatalog t("hash");
  t.Write("a.obj", ObjBox(1.f, 1.f, 1.f));
  const json models = json::array(
      {{{"id", "a"}, {"class", "chair"}, {"mesh", "a.obj"}, {"up", "+y"}, {"height_m", 0.8}}});
  const std::string path = t.Catalog(models);
  const std::string h1 = LoadCatalog(path).hash;
  EXPECT_EQ(LoadCatalog(path).hash, h1);
  t.Write("a.obj", ObjBox(1.f, 1.f, 1.5f));  // the mesh changes, catalog.json does not
  const std::string h2 = LoadCatalog(path).hash;
  EXPECT_NE(h2, h1);
  t.Catalog(json::array({{{"id", "a"}, {"class", "chair"}, {"mesh", "a.obj"}, {"up", "+y"}, {"height_m", 0.9}}}));
  EXPECT_NE(LoadCatalog(path).hash, h2);
}

// Entries naming one mesh file (a grown catalog's variants) share its parsing, each normalised
// by its own "up" and scale: every model is the one a catalog of that entry alone gives, bit for
// bit; an unparsable shared file skips each entry naming it; the hash follows the shared file.
TEST(Catalog, EntriesNamingOneMeshFileLoadAsEachAlone) {
  TempCatalog t("shared_mesh");
  t.Write("a.obj", ObjBox(1.f, 2.f, 3.f));
  t.Write("b.obj", ObjBox(4.f, 1.f, 1.f));
  t.Write("bad.obj", "# no geometry\n");
  const json entries = json::array(
      {{{"id", "a1"}, {"class", "chair"}, {"mesh", "a.obj"}, {"up", "+y"}, {"size_m", {0.5, 0.4, 0.8}}},
       {{"id", "b1"}, {"class", "table"}, {"mesh", "b.obj"}, {"up", "+y"}, {"scale", 0.2}},
       {{"id", "a2"}, {"class", "chair"}, {"mesh", "./sub/../a.obj"}, {"up", "+z"}, {"height_m", 1.2}},
       {{"id", "x1"}, {"class", "chair"}, {"mesh", "bad.obj"}, {"up", "+y"}, {"scale", 1.0}},
       {{"id", "a3"}, {"class", "chair"}, {"mesh", "a.obj"}, {"up", "-x"}, {"scale", 0.3}, {"front", "+z"}},
       {{"id", "x2"}, {"class", "chair"}, {"mesh", "bad.obj"}, {"up", "+y"}, {"scale", 2.0}},
       {{"id", "a4"}, {"class", "chair"}, {"mesh", "a.obj"}, {"up", "sideways"}, {"scale", 1.0}}});
  const std::string path = t.Catalog(entries);
  const Catalog all = LoadCatalog(path);
  ASSERT_EQ(all.models.size(), 4u);
  ASSERT_EQ(all.skipped.size(), 3u);
  EXPECT_EQ(all.skipped[0].id, "x1");
  EXPECT_EQ(all.skipped[1].id, "x2");
  EXPECT_EQ(all.skipped[0].reason.substr(0, 16), "unreadable mesh:");
  EXPECT_EQ(all.skipped[1].reason.substr(0, 16), "unreadable mesh:");
  EXPECT_EQ(all.skipped[2].id, "a4");
  for (const auto& m : all.models) {
    SCOPED_TRACE(m.id);
    json one = json::array();
    for (const auto& e : entries)
      if (e["id"] == m.id) one.push_back(e);
    TempCatalog alone("shared_mesh_" + m.id);
    alone.Write("a.obj", ObjBox(1.f, 2.f, 3.f));
    alone.Write("b.obj", ObjBox(4.f, 1.f, 1.f));
    const Catalog c = LoadCatalog(alone.Catalog(one));
    ASSERT_EQ(c.models.size(), 1u);
    const CatalogModel& x = c.models[0];
    EXPECT_EQ(x.size, m.size);
    ASSERT_EQ(x.mesh.vertices.size(), m.mesh.vertices.size());
    ASSERT_EQ(x.mesh.triangles.size(), m.mesh.triangles.size());
    EXPECT_EQ(std::memcmp(x.mesh.vertices.data(), m.mesh.vertices.data(), 12 * x.mesh.vertices.size()), 0);
    EXPECT_EQ(std::memcmp(x.mesh.triangles.data(), m.mesh.triangles.data(), 12 * x.mesh.triangles.size()), 0);
    EXPECT_EQ(c.FrontOf(x.id)->front, all.FrontOf(m.id)->front);
  }
  EXPECT_NEAR(all.Find("a2")->size.z(), 1.2f, 1e-5f);
  EXPECT_NEAR(all.Find("a1")->size.z(), 0.8f, 1e-5f);
  EXPECT_EQ(LoadCatalog(path).hash, all.hash);
  t.Write("a.obj", ObjBox(1.f, 2.f, 3.5f));  // the shared file changes
  EXPECT_NE(LoadCatalog(path).hash, all.hash);
  t.Write("a.obj", ObjBox(1.f, 2.f, 3.f));
  EXPECT_EQ(LoadCatalog(path).hash, all.hash);
  t.Write("bad.obj", ObjBox(1.f, 1.f, 1.f));  // a skipped entry's file counts too
  EXPECT_NE(LoadCatalog(path).hash, all.hash);
}

// Parsed meshes are cached by content ($FURNIHOST_CACHE_DIR/meshes): a second load reads the
// cache and gives the same catalog bit for bit; a truncated or forged cache file is ignored and
// rewritten; a changed mesh gets its own entry.
TEST(Catalog, ParsedMeshesAreCachedByContent) {
  TempCatalog t("mesh_cache");
  const std::string cache = (t.dir / "cache").string();
  const char* old = std::getenv("FURNIHOST_CACHE_DIR");
  const std::string restore = old ? old : "";
  ::setenv("FURNIHOST_CACHE_DIR", cache.c_str(), 1);
  t.Write("a.obj", ObjBox(500.f, 900.f, 400.f));
  const json models = json::array(
      {{{"id", "a"}, {"class", "chair"}, {"mesh", "a.obj"}, {"up", "+y"}, {"scale", 0.001}}});
  const std::string path = t.Catalog(models);
  auto same = [](const Catalog& x, const Catalog& y) {
    if (x.models.size() != y.models.size()) return false;
    for (size_t i = 0; i < x.models.size(); ++i) {
      const Mesh &a = x.models[i].mesh, &b = y.models[i].mesh;
      if (a.vertices.size() != b.vertices.size() || a.triangles.size() != b.triangles.size()) return false;
      if (std::memcmp(a.vertices.data(), b.vertices.data(), 12 * a.vertices.size()) ||
          std::memcmp(a.triangles.data(), b.triangles.data(), 12 * a.triangles.size()) ||
          x.models[i].size != y.models[i].size)
        return false;
    }
    return x.hash == y.hash;
  };
  auto entries = [&] {
    std::vector<fs::path> files;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(fs::path(cache) / "meshes", ec))
      if (e.path().extension() == ".fhmesh") files.push_back(e.path());
    return files;
  };
  const Catalog first = LoadCatalog(path);  // parsed, then written to the cache
  ASSERT_EQ(entries().size(), 1u);
  const fs::path entry = entries()[0];
  const Catalog second = LoadCatalog(path);  // from the cache
  EXPECT_TRUE(same(first, second));
  const auto good = fs::file_size(entry);
  for (const std::string& garbage : {std::string("FHMESH1"), std::string(size_t(good), 'x')}) {
    std::ofstream(entry, std::ios::binary | std::ios::trunc) << garbage;
    EXPECT_TRUE(same(first, LoadCatalog(path)));
    EXPECT_EQ(fs::file_size(entry), good);  // rewritten
  }
  {  // the right header, a face index out of range
    std::fstream f(entry, std::ios::binary | std::ios::in | std::ios::out);
    f.seekp(std::streamoff(good) - 4);
    const int32_t bad = 1000;
    f.write(reinterpret_cast<const char*>(&bad), 4);
  }
  EXPECT_TRUE(same(first, LoadCatalog(path)));
  t.Write("a.obj", ObjBox(500.f, 900.f, 600.f));  // the mesh changes
  const Catalog changed = LoadCatalog(path);
  EXPECT_NEAR(changed.models.at(0).size.y(), 0.6f, 1e-6f);  // z up after the turn: depth is y
  EXPECT_EQ(entries().size(), 2u);
  if (old)
    ::setenv("FURNIHOST_CACHE_DIR", restore.c_str(), 1);
  else
    ::unsetenv("FURNIHOST_CACHE_DIR");
}

// data/: the bundled catalogs load, hold only redistributable models, and the demo scene
// uses models the training catalog does not contain.
TEST(Catalog, BundledDataIsRedistributableAndTheDemoIsHeldOut) {
  const std::string root = testing::SourceDir() + "/data";
  const Catalog train = LoadCatalog(root + "/catalog/catalog.json", true);
  const Catalog demo = LoadCatalog(root + "/demo/catalog.json", true);
  for (const char* cls : {"chair", "table", "cabinet", "armchair"}) {
    const auto c = train.Classes();
    EXPECT_TRUE(std::count(c.begin(), c.end(), cls)) << "training catalog lacks " << cls;
  }
  for (const std::string file : {"/catalog/catalog.json", "/demo/catalog.json"}) {
    const json parsed = json::parse(std::ifstream(root + file));  // must outlive the loop
    for (const auto& e : parsed["models"]) {
      const std::string lic = e.value("license", "");
      EXPECT_TRUE(lic.rfind("MIT-0", 0) == 0 || lic.rfind("CC-BY-3.0", 0) == 0)
          << file << ": " << e["id"] << " has licence \"" << lic << "\"";
    }
  }
  for (const auto& m : demo.models) EXPECT_EQ(train.Find(m.id), nullptr) << m.id << " is in both";
  const auto truth = ReadGroundTruth(root + "/demo/room.gt.json");
  ASSERT_FALSE(truth.empty());
  for (const auto& t : truth) {
    const CatalogModel* m = demo.Find(t.model);
    ASSERT_NE(m, nullptr) << t.model;
    EXPECT_EQ(t.cls, m->cls);
    EXPECT_EQ(train.Find(t.model), nullptr);
  }
  const Scan scan = ReadScan(root + "/demo/room.pcd");
  EXPECT_GT(scan.points.size(), 50000u);
  ASSERT_TRUE(scan.origin.has_value());
  EXPECT_LT((*scan.origin - Eigen::Vector3f(3.f, 2.5f, 1.5f)).norm(), 1e-5f);
}

}  // namespace
}  // namespace furnihost
