// The plugin host: finds plugin libraries, checks them, and creates stages by type name.
// Only registry.cpp includes Boost.DLL's loader.
#pragma once
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "furnihost/params.hpp"
#include "furnihost/stage.hpp"

namespace furnihost {

struct PluginEntry {
  std::string type, version, description, path;
  StageKind kind;
  ParamSchema params;
};

struct PluginRefusal {
  std::string path, reason;
};

class FURNIHOST_API Registry {
 public:
  // Search order: `extra_dirs` (--plugin-path), $FURNIHOST_PLUGIN_PATH (':'-separated),
  // the build tree's plugin folder, the install prefix's. A type found twice keeps the first
  // and refuses the later one.
  static std::vector<std::string> DefaultSearchPath(const std::vector<std::string>& extra_dirs);
  explicit Registry(const std::vector<std::string>& search_dirs);
  ~Registry();
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  // Loads a single library file (used by tests and by the scan of each folder).
  // Returns false and records a refusal if the file is not an acceptable plugin.
  bool LoadFile(const std::string& path);

  const std::vector<PluginEntry>& Plugins() const { return plugins_; }
  const std::vector<PluginRefusal>& Refusals() const { return refusals_; }
  const std::vector<std::string>& SearchDirs() const { return dirs_; }
  const PluginEntry* Find(const std::string& type) const;
  std::vector<std::string> TypeNames() const;

  // Creates a stage from validated params. The returned object keeps its library loaded.
  std::shared_ptr<Stage> Create(const std::string& type, const nlohmann::json& params) const;

  template <class T>
  std::shared_ptr<T> CreateAs(const std::string& type, const nlohmann::json& params) const {
    auto s = Create(type, params);
    auto t = std::dynamic_pointer_cast<T>(s);
    if (!t) throw InputError("plugin " + type + " does not implement the expected stage kind");
    return t;
  }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<std::string> dirs_;
  std::vector<PluginEntry> plugins_;
  std::vector<PluginRefusal> refusals_;
};

}  // namespace furnihost
