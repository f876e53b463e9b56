// The only file of the host that includes Boost.DLL's loader.
#include "furnihost/host/registry.hpp"

#include "furnihost/host/config.hpp"  // the kinds' names

#include <spdlog/spdlog.h>

#include <algorithm>
#include <boost/dll/shared_library.hpp>
#include <cstdlib>
#include <dlfcn.h>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>

#include "furnihost/plugin.hpp"

namespace fs = std::filesystem;

namespace furnihost {

struct Registry::Impl {
  struct Loaded {
    std::shared_ptr<boost::dll::shared_library> lib;
    PluginCreateFn* create = nullptr;
  };
  std::map<std::string, Loaded> by_type;
  std::set<std::string> seen_files;
  std::vector<std::string> files;  // every candidate library of the search path, in search order
  bool all_loaded = false;
  std::recursive_mutex mu;  // libraries are loaded on first use, possibly from several threads
};

namespace {
// True when a library's file name follows the convention libfurnihost_<kind>_<name>.so for
// `type` = "<kinds>.<name>" (e.g. libfurnihost_segmenter_region_growing.so for
// segmenters.region_growing): <kind> is one word, the rest must equal the name.
bool NamedFor(const std::string& path, const std::string& type) {
  const std::string file = fs::path(path).filename().string(), prefix = "libfurnihost_", ext = ".so";
  const size_t dot = type.find('.');
  if (dot == std::string::npos || file.size() <= prefix.size() + ext.size()) return false;
  const std::string stem = file.substr(prefix.size(), file.size() - prefix.size() - ext.size());
  const size_t us = stem.find('_');
  return us != std::string::npos && stem.substr(us + 1) == type.substr(dot + 1);
}

std::string Canonical(const std::string& path) {
  std::error_code ec;
  return fs::weakly_canonical(path, ec).string();
}

// The folders the project's own plugins are built and installed to, found from where this host
// library lies, so the binary, a program linking the host (the Python module) and a prefix moved
// after installing all find them: <lib>/furnihost/plugins beside an installed host library; the
// build tree's plugin folder only when this host is the build tree's (an installed host never
// loads plugins of a newer build); then the configured install prefix's.
std::vector<std::string> ShippedDirs() {
  std::vector<std::string> dirs;
  auto add = [&](const std::string& d) {
    for (const auto& have : dirs)
      if (Canonical(have) == Canonical(d)) return;
    dirs.push_back(d);
  };
  const std::string lib = HostLibraryDir();
  if (lib.empty() || Canonical(lib) == Canonical(FURNIHOST_LIBRARY_BUILD_DIR)) add(FURNIHOST_PLUGIN_BUILD_DIR);
  if (!lib.empty()) add((fs::path(lib) / "furnihost" / "plugins").string());
  add(FURNIHOST_PLUGIN_INSTALL_DIR);
  return dirs;
}
}  // namespace

std::string HostLibraryDir() {
  Dl_info self{};
  if (!dladdr(reinterpret_cast<void*>(&HostLibraryDir), &self) || !self.dli_fname) return "";
  std::error_code ec;
  const fs::path lib = fs::weakly_canonical(self.dli_fname, ec);
  return ec ? std::string() : lib.parent_path().string();
}

std::vector<std::string> Registry::DefaultSearchPath(const std::vector<std::string>& extra_dirs) {
  std::vector<std::string> dirs = extra_dirs;
  if (const char* env = std::getenv("FURNIHOST_PLUGIN_PATH")) {
    std::string s = env;
    size_t start = 0;
    while (start <= s.size()) {
      size_t end = s.find(':', start);
      if (end == std::string::npos) end = s.size();
      if (end > start) dirs.push_back(s.substr(start, end - start));
      start = end + 1;
    }
  }
  for (const auto& d : ShippedDirs()) dirs.push_back(d);
  return dirs;
}

Registry::Registry(const std::vector<std::string>& search_dirs) : impl_(new Impl), dirs_(search_dirs) {
  // The user's folders (--plugin-path, $FURNIHOST_PLUGIN_PATH, or any not the project's own) are
  // loaded now, so each bad library there is reported at once and their types take precedence;
  // the project's own folders after the last of them load on demand (see Find).
  std::set<std::string> shipped;
  for (const auto& d : ShippedDirs()) shipped.insert(Canonical(d));
  size_t eager = 0;  // dirs_[0, eager) load now
  for (size_t i = 0; i < dirs_.size(); ++i)
    if (!shipped.count(Canonical(dirs_[i]))) eager = i + 1;
  for (size_t i = 0; i < dirs_.size(); ++i) {
    const std::string& d = dirs_[i];
    std::error_code ec;
    if (!fs::is_directory(d, ec)) continue;
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(d, ec)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("libfurnihost_", 0) == 0 && e.path().extension() == ".so") files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    impl_->files.insert(impl_->files.end(), files.begin(), files.end());
    if (i < eager)
      for (const auto& f : files) Load(f);
  }
}

void Registry::LoadAll() const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mu);
  if (impl_->all_loaded) return;
  for (const auto& f : impl_->files) Load(f);
  impl_->all_loaded = true;
}

const std::deque<PluginEntry>& Registry::Plugins() const {
  LoadAll();
  return plugins_;
}

const std::vector<PluginRefusal>& Registry::Refusals() const {
  LoadAll();
  return refusals_;
}

Registry::~Registry() {
  // Entries hold ParamSchema copies made by plugin code, but copies live in host memory and
  // use the SDK library's code; clearing them before the library handles close is still tidy
  // (accepted plugins stay mapped anyway: see LoadFile).
  plugins_.clear();
}

bool Registry::LoadFile(const std::string& path) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mu);
  return Load(path);
}

bool Registry::Load(const std::string& path) const {
  std::error_code ec;
  const std::string canonical = fs::weakly_canonical(path, ec).string();
  if (impl_->seen_files.count(canonical)) return false;  // the same file found twice
  impl_->seen_files.insert(canonical);
  auto refuse = [&](const std::string& why) {
    refusals_.push_back({path, why});
    spdlog::warn("plugin {} refused: {}", path, why);
    return false;
  };
  // dlopen() of a FIFO blocks forever, and of a folder fails obscurely: refuse both first.
  if (!fs::is_regular_file(path, ec)) return refuse("not a regular file");
  auto lib = std::make_shared<boost::dll::shared_library>();
  boost::system::error_code lec;
  lib->load(path, boost::dll::load_mode::rtld_lazy | boost::dll::load_mode::rtld_local, lec);
  if (lec) return refuse("not a loadable shared library (" + lec.message() + ")");
  try {
    if (!lib->has("furnihost_abi_version")) return refuse("missing symbol furnihost_abi_version");
    const int abi = lib->get<PluginAbiFn>("furnihost_abi_version")();
    if (abi != FURNIHOST_ABI_VERSION)
      return refuse("ABI version " + std::to_string(abi) + ", the host needs " +
                    std::to_string(FURNIHOST_ABI_VERSION) + " (rebuild the plugin)");
    if (!lib->has("furnihost_plugin_info")) return refuse("missing symbol furnihost_plugin_info");
    if (!lib->has("furnihost_plugin_create")) return refuse("missing symbol furnihost_plugin_create (no factory)");
    const PluginInfo& info = lib->get_alias<PluginInfoFn>("furnihost_plugin_info")();
    auto* create = &lib->get_alias<PluginCreateFn>("furnihost_plugin_create");
    auto kind = KindFromTypeName(info.type);
    if (!kind)
      return refuse("type name '" + info.type + "' does not start with one of " + KindTypePrefixes());
    if (auto* other = FindLoaded(info.type))
      return refuse("duplicate type " + info.type + " (already loaded from " + other->path + ")");
    // Accepted plugins stay mapped until the process ends (RTLD_NODELETE, set on the already
    // loaded library; the extra reference is never dropped). TBB worker threads can still be
    // returning through a plugin's task code (oneTBB's templates are instantiated in the plugin)
    // after its parallel_for has returned, and they outlive every registry: unmapping the code
    // under them crashed ~2 % of test processes at exit under load (worker thread PC in the
    // unmapped fitter plugin, main thread in exit handlers).
    if (!dlopen(path.c_str(), RTLD_LAZY | RTLD_LOCAL | RTLD_NOLOAD | RTLD_NODELETE))
      spdlog::debug("plugin {}: could not pin it in memory ({})", path, dlerror());
    PluginEntry e{info.type, info.version, info.description, path, *kind, info.params};
    plugins_.push_back(std::move(e));
    impl_->by_type[info.type] = {lib, create};
    return true;
  } catch (const std::exception& ex) {
    return refuse(std::string("error while reading its info: ") + ex.what());
  } catch (...) {
    return refuse("unknown exception while reading its info");
  }
}

const PluginEntry* Registry::FindLoaded(const std::string& type) const {
  for (const auto& p : plugins_)
    if (p.type == type) return &p;
  return nullptr;
}

const PluginEntry* Registry::Find(const std::string& type) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mu);
  if (const PluginEntry* e = FindLoaded(type)) return e;
  if (impl_->all_loaded) return nullptr;
  // Loading every library costs ~0.15 s per process (PCL's and VTK's relocations alone ~0.1 s),
  // more than a whole detection on a 50k-point scan: the libraries named for the type are tried
  // first, in search order, and the others only when none of them declares it.
  for (const auto& f : impl_->files)
    if (NamedFor(f, type)) {
      Load(f);
      if (const PluginEntry* e = FindLoaded(type)) return e;
    }
  LoadAll();
  return FindLoaded(type);
}

std::vector<std::string> Registry::TypeNames() const {
  LoadAll();
  std::vector<std::string> names;
  for (const auto& p : plugins_) names.push_back(p.type);
  std::sort(names.begin(), names.end());
  return names;
}

std::shared_ptr<Stage> Registry::Create(const std::string& type, const nlohmann::json& params) const {
  std::unique_lock<std::recursive_mutex> lock(impl_->mu);
  Find(type);
  auto it = impl_->by_type.find(type);
  if (it == impl_->by_type.end()) {
    std::string known;
    for (const auto& n : TypeNames()) known += (known.empty() ? "" : ", ") + n;
    throw InputError("unknown plugin " + type + "; known: " + (known.empty() ? "(none found)" : known));
  }
  const auto lib = it->second.lib;
  const auto create = it->second.create;
  lock.unlock();  // the factory runs unlocked: stages may be created in parallel
  Stage* raw = nullptr;
  try {
    raw = create(params);
  } catch (const InputError& e) {
    throw InputError(type + ": " + e.what());
  } catch (const StageError& e) {
    throw StageError(type + ": " + e.what(), e.IsInputError());
  } catch (const std::exception& e) {
    throw StageError(type + ": " + e.what(), false);
  } catch (...) {
    throw StageError(type + ": unknown exception from the plugin factory", false);
  }
  if (!raw) throw StageError(type + ": the plugin factory returned nothing", false);
  const auto want = KindFromTypeName(type);
  if (!want || raw->Kind() != *want) {
    delete raw;
    throw StageError(type + ": the object it created is not a " +
                     std::string(want ? ToString(*want) : "?"), false);
  }
  // The deleter owns a reference to the library: the code of the object's destructor stays
  // mapped until the object is gone (Boost.DLL missuses: never outlive the library).
  return std::shared_ptr<Stage>(raw, [lib](Stage* p) { delete p; });
}

}  // namespace furnihost
