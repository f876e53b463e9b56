#include "furnihost/hash.hpp"

#include <cstdlib>

namespace furnihost {

uint64_t Fnv1a(const void* data, size_t size, uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

std::string CacheFolder(const std::string& sub) {
  auto env = [](const char* name) {
    const char* e = std::getenv(name);
    return std::string(e && *e ? e : "");
  };
  std::string base = env("FURNIHOST_CACHE_DIR");
  if (base.empty() && !env("XDG_CACHE_HOME").empty()) base = env("XDG_CACHE_HOME") + "/furnihost";
  if (base.empty() && !env("HOME").empty()) base = env("HOME") + "/.cache/furnihost";
  return base.empty() ? base : base + "/" + sub;
}

}  // namespace furnihost
