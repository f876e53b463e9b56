// libfurnihost_meshio: the assimp side of furnihost::LoadMeshFile, in a library of its own that
// the host loads (dlopen) on the first mesh it has to parse: a catalog whose meshes are all in
// the mesh cache, and every command that reads no catalog, never load assimp. Loading assimp and
// its dependencies (draco, minizip, ...) with the host cost every process ~6 ms of relocations
// and page faults before main(), 2 % of a 50k-point detection.
//
// Units and axes are pinned to assimp's defaults here (see the top of catalog.cpp: the catalog's
// `up` and scale fields are defined relative to the default import).
//
// Two guards stand between a file from the web and assimp's code:
// - Every file assimp opens goes through RegularFilesOnly (an IOSystem): the mesh itself and
//   whatever it names (an OBJ's mtllib, a glTF's buffer uri, a COLLADA image). A FIFO, a device,
//   a folder or an empty file (/proc's files claim size 0) is never opened: a FIFO would block
//   the process forever.
// - The file is imported without post-processing first, and the raw scene is checked (every
//   face index, bone weight and node mesh reference in range, vertices finite, the node tree of
//   bounded depth) before assimp's post-processing steps run: they follow face indices into the
//   vertex arrays unchecked (a PLY face index 0xFFFFFFF0 crashed inside JoinIdenticalVertices),
//   and they walk the node tree recursively.
#include <assimp/DefaultIOSystem.h>
#include <assimp/Importer.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <sys/stat.h>

#include <cmath>
#include <exception>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "furnihost/types.hpp"

#define FURNIHOST_MESHIO_EXPORT __attribute__((visibility("default")))

// Debian's assimp is built with ASSIMP_BUILD_DEBUG: an internal consistency check that fails
// on a malformed file (e.g. a broken OFF face list) calls this function, which aborts the
// whole process. This definition interposes the library's (this library comes before assimp in
// the search list assimp's own references use once it is loaded through this one) and turns the
// abort into an exception that the import reports as an unreadable mesh. Without a debug assimp
// it is never called.
namespace Assimp {
FURNIHOST_MESHIO_EXPORT void aiAssertViolation(const char* expression, const char* file, int line) {
  throw std::runtime_error(std::string("assimp internal check failed: ") + expression + " (" + file + ":" +
                           std::to_string(line) + ")");
}
}  // namespace Assimp

namespace {

// assimp's file access for one import: the default one, for regular, non-empty files only, and
// read only (an importer may not create, delete or change folders). The first file refused is
// remembered for the error message.
class RegularFilesOnly : public Assimp::DefaultIOSystem {
 public:
  bool Exists(const char* file) const override { return Readable(file); }
  Assimp::IOStream* Open(const char* file, const char* mode) override {
    if (!mode || mode[0] != 'r' || !Readable(file)) {
      Refuse(file);
      return nullptr;
    }
    return Assimp::DefaultIOSystem::Open(file, mode);
  }
  bool CreateDirectory(const std::string&) override { return false; }
  bool ChangeDirectory(const std::string&) override { return false; }
  bool DeleteFile(const std::string&) override { return false; }
  const std::string& refused() const { return refused_; }

 private:
  static bool Readable(const char* file) {
    struct stat st {};
    return file && ::stat(file, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0;
  }
  void Refuse(const char* file) {
    if (!refused_.empty() || !file) return;
    struct stat st {};
    const std::string name(file);
    if (::stat(file, &st) != 0) refused_ = name + " does not exist";
    else if (S_ISDIR(st.st_mode)) refused_ = name + " is a folder";
    else if (!S_ISREG(st.st_mode)) refused_ = name + " is not a regular file (FIFO, device or socket)";
    else if (st.st_size == 0) refused_ = name + " is empty";
  }
  std::string refused_;
};

// Deeper node trees than this are refused: assimp's post-processing recurses once per level,
// and no CAD model nests its parts this deep.
constexpr unsigned kMaxNodeDepth = 1000;

// The raw scene against itself: returns what is wrong, or "" when post-processing may run.
std::string CheckScene(const aiScene& scene) {
  if (scene.mNumMeshes > 0 && !scene.mMeshes) return "mesh list missing";
  for (unsigned mi = 0; mi < scene.mNumMeshes; ++mi) {
    const aiMesh* m = scene.mMeshes[mi];
    const std::string at = "mesh " + std::to_string(mi);
    if (!m) return at + " is missing";
    if (m->mNumVertices > 0 && !m->mVertices) return at + " has no vertex array";
    if (m->mNumFaces > 0 && !m->mFaces) return at + " has no face array";
    // Every vertex a face uses exists and is finite (post-processing sorts them by position:
    // a NaN breaks the sort); unused ones are dropped by it.
    for (unsigned f = 0; f < m->mNumFaces; ++f) {
      const aiFace& face = m->mFaces[f];
      if (face.mNumIndices > 0 && !face.mIndices) return "face " + std::to_string(f) + " of " + at + " has no indices";
      for (unsigned k = 0; k < face.mNumIndices; ++k) {
        if (face.mIndices[k] >= m->mNumVertices)
          return "face " + std::to_string(f) + " of " + at + " uses vertex " + std::to_string(face.mIndices[k]) +
                 " of " + std::to_string(m->mNumVertices);
        const aiVector3D& p = m->mVertices[face.mIndices[k]];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
          return "non-finite vertex coordinate in " + at;
      }
    }
    if (m->mNumBones > 0 && !m->mBones) return at + " has no bone list";
    for (unsigned b = 0; b < m->mNumBones; ++b) {
      const aiBone* bone = m->mBones[b];
      if (!bone || (bone->mNumWeights > 0 && !bone->mWeights)) return "bone " + std::to_string(b) + " of " + at + " is broken";
      for (unsigned w = 0; w < bone->mNumWeights; ++w)
        if (bone->mWeights[w].mVertexId >= m->mNumVertices)
          return "bone " + std::to_string(b) + " of " + at + " weighs vertex " +
                 std::to_string(bone->mWeights[w].mVertexId) + " of " + std::to_string(m->mNumVertices);
    }
    if (m->mNumAnimMeshes > 0 && !m->mAnimMeshes) return at + " has no morph target list";
    for (unsigned a = 0; a < m->mNumAnimMeshes; ++a) {
      const aiAnimMesh* am = m->mAnimMeshes[a];
      if (!am || am->mNumVertices != m->mNumVertices)
        return "morph target " + std::to_string(a) + " of " + at + " does not match its vertices";
    }
  }
  if (!scene.mRootNode) return "no root node";
  // Depth first without recursion: every node's mesh references in range, a bounded depth,
  // and no node met twice (a cycle would never end).
  std::vector<std::pair<const aiNode*, unsigned>> stack{{scene.mRootNode, 0u}};
  size_t visited = 0;
  while (!stack.empty()) {
    const auto [node, depth] = stack.back();
    stack.pop_back();
    if (!node) return "a node is missing";
    if (depth > kMaxNodeDepth) return "nodes nested deeper than " + std::to_string(kMaxNodeDepth) + " levels";
    if (++visited > (size_t(1) << 24)) return "more than 2^24 nodes (or a cycle)";
    if (node->mNumMeshes > 0 && !node->mMeshes) return "a node has no mesh list";
    for (unsigned k = 0; k < node->mNumMeshes; ++k)
      if (node->mMeshes[k] >= scene.mNumMeshes)
        return "a node uses mesh " + std::to_string(node->mMeshes[k]) + " of " + std::to_string(scene.mNumMeshes);
    if (node->mNumChildren > 0 && !node->mChildren) return "a node has no child list";
    for (unsigned c = 0; c < node->mNumChildren; ++c) stack.emplace_back(node->mChildren[c], depth + 1);
  }
  return "";
}

}  // namespace

// Reads `path` into `out` (triangles only; vertices as the file gives them). Returns false with
// the reason in `error` (without the path) when the file cannot be read as a mesh. Never throws.
extern "C" FURNIHOST_MESHIO_EXPORT bool furnihost_meshio_import(const char* path, furnihost::Mesh* out,
                                                              std::string* error) {
  try {
    Assimp::Importer importer;
    auto* io = new RegularFilesOnly;  // owned by the importer
    importer.SetIOHandler(io);
    // Pinned to assimp's defaults on purpose: catalogs are written against the default import.
    importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, false);
    importer.SetPropertyBool(AI_CONFIG_FBX_CONVERT_TO_M, false);
    importer.SetPropertyFloat(AI_CONFIG_GLOBAL_SCALE_FACTOR_KEY, 1.0f);
    // Points and lines carry no surface for a ray to hit.
    importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    const aiScene* scene = importer.ReadFile(path, 0);  // the importer alone: checked below
    auto failed = [&](const aiScene* s) { return !s || (s->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || !s->mRootNode; };
    if (failed(scene)) {
      *error = !io->refused().empty()          ? io->refused()
               : importer.GetErrorString()[0] ? importer.GetErrorString()
                                               : "assimp could not read it";
      return false;
    }
    if (const std::string why = CheckScene(*scene); !why.empty()) {
      *error = why;
      return false;
    }
    const unsigned flags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                           aiProcess_PreTransformVertices | aiProcess_SortByPType;
    scene = importer.ApplyPostProcessing(flags);
    if (failed(scene)) {
      *error = importer.GetErrorString()[0] ? importer.GetErrorString() : "assimp could not process it";
      return false;
    }
    furnihost::Mesh m;
    for (unsigned mi = 0; mi < scene->mNumMeshes; ++mi) {
      const aiMesh* am = scene->mMeshes[mi];
      if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
      const int base = static_cast<int>(m.vertices.size());
      m.vertices.reserve(m.vertices.size() + am->mNumVertices);
      for (unsigned v = 0; v < am->mNumVertices; ++v) {
        const aiVector3D& p = am->mVertices[v];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
          *error = "non-finite vertex coordinate in mesh " + std::to_string(mi);
          return false;
        }
        m.vertices.emplace_back(p.x, p.y, p.z);
      }
      for (unsigned f = 0; f < am->mNumFaces; ++f) {
        const aiFace& face = am->mFaces[f];
        if (face.mNumIndices != 3) continue;
        for (unsigned k = 0; k < 3; ++k)
          if (face.mIndices[k] >= am->mNumVertices) {
            *error = "face " + std::to_string(f) + " of mesh " + std::to_string(mi) + " uses vertex " +
                     std::to_string(face.mIndices[k]) + " of " + std::to_string(am->mNumVertices);
            return false;
          }
        m.triangles.emplace_back(base + static_cast<int>(face.mIndices[0]), base + static_cast<int>(face.mIndices[1]),
                                 base + static_cast<int>(face.mIndices[2]));
      }
    }
    *out = std::move(m);
    return true;
  } catch (const std::bad_alloc&) {
    *error = "out of memory: the file declares more data than fits in memory";
    return false;
  } catch (const std::length_error&) {
    *error = "the file declares more elements than a mesh can hold";
    return false;
  } catch (const std::exception& e) {  // see aiAssertViolation above; assimp's own errors too
    *error = e.what();
    return false;
  } catch (...) {
    *error = "assimp failed";
    return false;
  }
}
