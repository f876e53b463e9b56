// libFuzzer target: one catalog mesh through the loader with assimp (LoadCatalog -> LoadMeshFile
// -> libfurnihost_meshio: the header checks, assimp's import, the raw-scene check, its
// post-processing, normalisation). The first byte picks the format (m.ply, m.obj, m.gltf,
// m.dae, m.glb); the rest is split at "\n---\n" lines into the mesh and the files it may name:
// m.mtl (an OBJ's mtllib) and m.bin (a glTF buffer). No parsed-mesh cache: every input is
// imported. Anything but InputError, a crash, a hang (> 25 s) or a sanitizer report is a finding.
#include <cstdlib>

#include "fuzz_common.hpp"
#include "furnihost/host/catalog.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool no_cache = [] {  // CacheFolder: none of the three set -> nothing cached
    ::unsetenv("FURNIHOST_CACHE_DIR");
    ::unsetenv("XDG_CACHE_HOME");
    ::unsetenv("HOME");
    return true;
  }();
  (void)no_cache;
  if (size == 0) return 0;
  static const char* const kExt[] = {"ply", "obj", "gltf", "dae", "glb"};
  const std::string ext = kExt[data[0] % 5];
  const auto parts = furnihost::fuzz::Split(data + 1, size - 1);
  static const char* const kSide[] = {"m.mtl", "m.bin"};
  furnihost::fuzz::Write("m." + ext, parts[0].data(), parts[0].size());
  for (size_t i = 0; i < 2; ++i) {
    const std::string& text = i + 1 < parts.size() ? parts[i + 1] : std::string();
    furnihost::fuzz::Write(kSide[i], text.data(), text.size());
  }
  const std::string catalog = R"({"models": [{"id": "m", "class": "chair", "mesh": "m.)" + ext +
                              R"(", "up": "+z", "size_m": [0.5, 0.5, 0.8]}]})";
  const std::string path = furnihost::fuzz::Write("catalog.json", catalog.data(), catalog.size());
  try {
    furnihost::fuzz::TrapUnlessUsable(furnihost::LoadCatalog(path, true));
  } catch (const furnihost::InputError&) {
  }
  return 0;
}
