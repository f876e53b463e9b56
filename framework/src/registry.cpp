// The only file of the host that includes Boost.DLL's loader.
#include "furnihost/registry.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <boost/dll/runtime_symbol_info.hpp>
#include <boost/dll/shared_library.hpp>
#include <cstdlib>
#include <dlfcn.h>
#include <filesystem>
#include <map>
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
};

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
  dirs.push_back(FURNIHOST_PLUGIN_BUILD_DIR);
  boost::system::error_code ec;
  auto exe = boost::dll::program_location(ec);
  if (!ec) dirs.push_back((fs::path(exe.string()).parent_path() / ".." / "lib" / "furnihost" / "plugins").string());
  dirs.push_back(FURNIHOST_PLUGIN_INSTALL_DIR);
  return dirs;
}

Registry::Registry(const std::vector<std::string>& search_dirs) : impl_(new Impl), dirs_(search_dirs) {
  for (const auto& d : dirs_) {
    std::error_code ec;
    if (!fs::is_directory(d, ec)) continue;
    std::vector<std::string> files;
    for (const auto& e : fs::directory_iterator(d, ec)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("libfurnihost_", 0) == 0 && e.path().extension() == ".so") files.push_back(e.path().string());
    }
    std::sort(files.begin(), files.end());
    for (const auto& f : files) LoadFile(f);
  }
}

Registry::~Registry() {
  // Entries hold ParamSchema copies made by plugin code, but copies live in host memory and
  // use the SDK library's code; clearing them before the library handles close is still tidy
  // (accepted plugins stay mapped anyway: see LoadFile).
  plugins_.clear();
}

bool Registry::LoadFile(const std::string& path) {
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
      return refuse("type name '" + info.type +
                    "' does not start with sensors., segmenters., features., voters. or fitters.");
    if (auto* other = Find(info.type))
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

const PluginEntry* Registry::Find(const std::string& type) const {
  for (const auto& p : plugins_)
    if (p.type == type) return &p;
  return nullptr;
}

std::vector<std::string> Registry::TypeNames() const {
  std::vector<std::string> names;
  for (const auto& p : plugins_) names.push_back(p.type);
  std::sort(names.begin(), names.end());
  return names;
}

std::shared_ptr<Stage> Registry::Create(const std::string& type, const nlohmann::json& params) const {
  auto it = impl_->by_type.find(type);
  if (it == impl_->by_type.end()) {
    std::string known;
    for (const auto& n : TypeNames()) known += (known.empty() ? "" : ", ") + n;
    throw InputError("unknown plugin " + type + "; known: " + (known.empty() ? "(none found)" : known));
  }
  const auto lib = it->second.lib;
  Stage* raw = nullptr;
  try {
    raw = it->second.create(params);
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
