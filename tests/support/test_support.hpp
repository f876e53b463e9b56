// Helpers shared by every test: where the sources, plugins and shared data are.
#pragma once
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "furnihost/host/registry.hpp"

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

// A shell command's result: exit status (128 + the signal when killed), stdout, stderr.
struct CommandRun {
  int code = -1;
  std::string out, err;
};

// Runs `command` through the shell with stdin from /dev/null, capturing stdout and stderr (the
// latter through a file in this process's temporary folder).
inline CommandRun RunCommand(const std::string& command) {
  const std::string err_file = TempDir("command") + "/stderr.txt";
  CommandRun r;
  FILE* p = popen((command + " 2>" + err_file + " </dev/null").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  std::ifstream e(err_file);
  r.err.assign(std::istreambuf_iterator<char>(e), std::istreambuf_iterator<char>());
  return r;
}

#ifdef FURNIHOST_TEST_BINARY
// The furnihost binary of this build with `args`.
inline CommandRun RunFurnihost(const std::string& args) {
  return RunCommand(std::string(FURNIHOST_TEST_BINARY) + " " + args);
}
#endif

}  // namespace furnihost::testing
