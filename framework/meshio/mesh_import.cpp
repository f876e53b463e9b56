// libfurnihost_meshio: the assimp side of furnihost::LoadMeshFile, in a library of its own that
// the host loads (dlopen) on the first mesh it has to parse: a catalog whose meshes are all in
// the mesh cache, and every command that reads no catalog, never load assimp. Loading assimp and
// its dependencies (draco, minizip, ...) with the host cost every process ~6 ms of relocations
// and page faults before main(), 2 % of a 50k-point detection.
//
// Units and axes are pinned to assimp's defaults here (see the top of catalog.cpp: the catalog's
// `up` and scale fields are defined relative to the default import).
#include <assimp/Importer.hpp>
#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cmath>
#include <exception>
#include <stdexcept>
#include <string>

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

// Reads `path` into `out` (triangles only; vertices as the file gives them). Returns false with
// the reason in `error` (without the path) when the file cannot be read as a mesh. Never throws.
extern "C" FURNIHOST_MESHIO_EXPORT bool furnihost_meshio_import(const char* path, furnihost::Mesh* out,
                                                              std::string* error) {
  try {
    Assimp::Importer importer;
    // Pinned to assimp's defaults on purpose: catalogs are written against the default import.
    importer.SetPropertyBool(AI_CONFIG_IMPORT_COLLADA_IGNORE_UP_DIRECTION, false);
    importer.SetPropertyBool(AI_CONFIG_FBX_CONVERT_TO_M, false);
    importer.SetPropertyFloat(AI_CONFIG_GLOBAL_SCALE_FACTOR_KEY, 1.0f);
    // Points and lines carry no surface for a ray to hit.
    importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    const unsigned flags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                           aiProcess_PreTransformVertices | aiProcess_SortByPType;
    const aiScene* scene = importer.ReadFile(path, flags);
    if (!scene || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) || !scene->mRootNode) {
      *error = importer.GetErrorString()[0] ? importer.GetErrorString() : "assimp could not read it";
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
        // assimp's PLY importer passes out-of-range indices through unchecked.
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
  } catch (const std::exception& e) {  // see aiAssertViolation above; assimp's own errors and bad_alloc too
    *error = e.what();
    return false;
  } catch (...) {
    *error = "assimp failed";
    return false;
  }
}
