// Helpers shared by every test: where the sources, plugins and shared data are.
#pragma once
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "furnihost/registry.hpp"

namespace furnihost::testing {

// The project source folder (FURNIHOST_SOURCE_DIR, set by ctest).
inline std::string SourceDir() {
  const char* s = std::getenv("FURNIHOST_SOURCE_DIR");
  return s ? s : FURNIHOST_TEST_SOURCE_DIR;
}

// ../shared/data beside the checkout. Tests that need it fail loudly (never skip) when absent.
inline std::string SharedDataDir() {
  std::filesystem::path p = std::filesystem::path(SourceDir()) / ".." / "shared" / "data";
  if (!std::filesystem::is_directory(p)) {
    ADD_FAILURE() << "shared data folder missing: " << p << " (CI must have ../shared beside the clone)";
    return "";
  }
  return std::filesystem::weakly_canonical(p).string();
}

inline std::string PluginDir() {
  const char* s = std::getenv("FURNIHOST_PLUGIN_PATH");
  return s ? s : FURNIHOST_TEST_PLUGIN_DIR;
}

inline std::string TempDir(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() /
           ("furnihost_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(p);
  return p.string();
}

// A registry over the build tree's plugins only.
inline std::unique_ptr<Registry> MakeRegistry() {
  return std::make_unique<Registry>(std::vector<std::string>{PluginDir()});
}

// The lines of a command's stderr that are not log lines (spdlog's start with '['): the
// one-line errors the CLI promises.
inline std::vector<std::string> ErrorLines(const std::string& err) {
  std::vector<std::string> lines;
  std::istringstream in(err);
  std::string l;
  while (std::getline(in, l))
    if (!l.empty() && l[0] != '[') lines.push_back(l);
  return lines;
}

}  // namespace furnihost::testing
