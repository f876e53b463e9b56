// Shared helpers of the libFuzzer targets: a private temp folder, splitting one fuzz input
// into several files, and silencing the logs (a fuzzer runs millions of inputs).
#pragma once
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "furnihost/host/catalog.hpp"

namespace furnihost::fuzz {

// One folder per process, so parallel fuzzers (-jobs) never share files.
inline const std::string& Dir() {
  static const std::string dir = [] {
    auto p = std::filesystem::temp_directory_path() / ("furnihost_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(p);
    spdlog::set_level(spdlog::level::off);
    return p.string();
  }();
  return dir;
}

inline std::string Write(const std::string& name, const char* data, size_t size) {
  const std::string path = Dir() + "/" + name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(data, static_cast<std::streamsize>(size));
  return path;
}

// Splits at each "\n---\n" line; seeds use it to hold a config and its base, or a catalog
// and its meshes, in one input.
inline std::vector<std::string> Split(const uint8_t* data, size_t size) {
  const std::string s(reinterpret_cast<const char*>(data), size);
  const std::string sep = "\n---\n";
  std::vector<std::string> parts;
  size_t start = 0;
  while (true) {
    size_t at = s.find(sep, start);
    if (at == std::string::npos) {
      parts.push_back(s.substr(start));
      return parts;
    }
    parts.push_back(s.substr(start, at - start));
    start = at + sep.size();
  }
}

// What every consumer of a catalog relies on: indices in range, finite metres, a height.
// Traps (a finding) otherwise.
inline void TrapUnlessUsable(const Catalog& c) {
  for (const auto& m : c.models) {
    for (const auto& t : m.mesh.triangles)
      for (int k = 0; k < 3; ++k)
        if (t[k] < 0 || t[k] >= static_cast<int>(m.mesh.vertices.size())) __builtin_trap();
    for (const auto& v : m.mesh.vertices)
      if (!v.allFinite()) __builtin_trap();
    if (!m.size.allFinite() || !(m.size.z() > 0.f)) __builtin_trap();
  }
}

}  // namespace furnihost::fuzz
