// libFuzzer target: catalogs. The input is split at "\n---\n" lines into catalog.json and
// four mesh files (a.obj, b.off, c.ply, d.stl) that its entries may name; LoadCatalog parses,
// imports (assimp), normalises and hashes them, strict and lenient. Anything but InputError
// is a finding. The parsed-mesh cache lives in the fuzzer's own folder and is emptied after
// each input: the lenient load writes it, the strict one reads it back, and a long run does not
// fill ~/.cache with one file per mesh it made up.
#include <cstdlib>
#include <filesystem>

#include "fuzz_common.hpp"
#include "furnihost/host/catalog.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto parts = furnihost::fuzz::Split(data, size);
  static const char* const kNames[] = {"catalog.json", "a.obj", "b.off", "c.ply", "d.stl"};
  for (size_t i = 0; i < 5; ++i) {
    const std::string& text = i < parts.size() ? parts[i] : std::string();
    furnihost::fuzz::Write(kNames[i], text.data(), text.size());
  }
  static const std::string cache = [] {
    const std::string c = furnihost::fuzz::Dir() + "/mesh_cache";
    ::setenv("FURNIHOST_CACHE_DIR", c.c_str(), 1);
    return c;
  }();
  const std::string path = furnihost::fuzz::Dir() + "/catalog.json";
  for (bool strict : {false, true}) {
    try {
      furnihost::fuzz::TrapUnlessUsable(furnihost::LoadCatalog(path, strict));
    } catch (const furnihost::InputError&) {
    }
  }
  std::error_code ec;
  std::filesystem::remove_all(cache, ec);
  return 0;
}
