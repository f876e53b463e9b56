// Right ABI and info, but no factory symbol: must be refused.
#include "furnihost/plugin.hpp"
extern "C" BOOST_SYMBOL_EXPORT int furnihost_abi_version() { return FURNIHOST_ABI_VERSION; }
namespace {
const furnihost::PluginInfo& Info() {
  static const furnihost::PluginInfo info{FURNIHOST_ABI_VERSION, "features.no_factory", "0.1.0", "no factory", {}};
  return info;
}
}  // namespace
BOOST_DLL_ALIAS(Info, furnihost_plugin_info)
