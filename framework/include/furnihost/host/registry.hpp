// The plugin host: finds plugin libraries, checks them, and creates stages by type name.
// Only registry.cpp includes Boost.DLL's loader.
#pragma once
#include <deque>
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

// The folder of the host library (libfurnihost_host.so) this process loaded: <prefix>/lib when
// installed, the build tree's lib/ in a build; "" when it cannot be found.
FURNIHOST_API std::string HostLibraryDir();

class FURNIHOST_API Registry {
 public:
  // Search order: `extra_dirs` (--plugin-path), $FURNIHOST_PLUGIN_PATH (':'-separated),
  // <HostLibraryDir()>/furnihost/plugins of an installed host or the build tree's plugin folder
  // of a built one, the configured install prefix's. A type found twice keeps the first
  // and refuses the later one. The user's folders load at construction; the project's own
  // folders at the end of the path load when first needed (each costs ~0.15 s per process,
  // more than a detection on a 50k-point scan): Find/Create try the files named
  // libfurnihost_<kind>_<name>.so for the type first, then every library; Plugins, Refusals
  // and TypeNames load them all.
  static std::vector<std::string> DefaultSearchPath(const std::vector<std::string>& extra_dirs);
  explicit Registry(const std::vector<std::string>& search_dirs);
  ~Registry();
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  // Loads a single library file (used by tests and by the scan of each folder).
  // Returns false and records a refusal if the file is not an acceptable plugin.
  bool LoadFile(const std::string& path);

  const std::deque<PluginEntry>& Plugins() const;  // every library of the search path loaded
  const std::vector<PluginRefusal>& Refusals() const;
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
  bool Load(const std::string& path) const;            // the caller holds the lock
  const PluginEntry* FindLoaded(const std::string& type) const;  // among the loaded ones
  void LoadAll() const;

  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::vector<std::string> dirs_;
  // Filled as libraries load (from const look-ups); a deque keeps earlier entries in place.
  mutable std::deque<PluginEntry> plugins_;
  mutable std::vector<PluginRefusal> refusals_;
};

}  // namespace furnihost
