// What a plugin exports. Include this in exactly one source file of a plugin and use
// FURNIHOST_PLUGIN once:
//
//   class MySegmenter : public furnihost::Segmenter {
//    public:
//     static furnihost::ParamSchema Schema();           // declared parameters
//     explicit MySegmenter(const nlohmann::json& p);    // p: validated, defaults filled
//     furnihost::Segmentation Segment(const furnihost::Scan&, const furnihost::RunContext&) override;
//   };
//   FURNIHOST_PLUGIN(MySegmenter, "segmenters.mine", "1.0.0", "what it does")
//
// ABI policy: plugins are built with the host's compiler and standard library (in-tree or
// against an installed furnihost of the same version) and link only the SDK library
// (furnihost::sdk, libfurnihost_sdk.so). The host reads the plain C symbol
// `furnihost_abi_version` first and refuses a mismatch before touching anything else.
#pragma once
#include <boost/config.hpp>
#include <boost/dll/alias.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "furnihost/params.hpp"
#include "furnihost/stage.hpp"

// Covers the SDK alone: the headers of include/furnihost/ (not those of include/furnihost/host/)
// and the functions libfurnihost_sdk.so defines for them. It changes whenever one of their types
// changes layout or one of their exported functions its signature; the host's headers
// (furnihost/host/: pipeline, config, registry, io, evaluation, ...) change freely, since no
// plugin includes them.
#define FURNIHOST_ABI_VERSION 12

namespace furnihost {

struct PluginInfo {
  int abi_version = FURNIHOST_ABI_VERSION;
  std::string type;         // "<kind>s.<name>"
  std::string version;      // plugin's own semantic version
  std::string description;  // one line
  ParamSchema params;
};

using PluginInfoFn = const PluginInfo&();
using PluginCreateFn = Stage*(const nlohmann::json& params);
using PluginAbiFn = int();

}  // namespace furnihost

#define FURNIHOST_PLUGIN(CLASS, TYPE, VERSION, DESCRIPTION)                                 \
  extern "C" BOOST_SYMBOL_EXPORT int furnihost_abi_version() { return FURNIHOST_ABI_VERSION; } \
  namespace furnihost_plugin_exports {                                                     \
  const ::furnihost::PluginInfo& Info() {                                                  \
    static const ::furnihost::PluginInfo info{FURNIHOST_ABI_VERSION, TYPE, VERSION,        \
                                              DESCRIPTION, CLASS::Schema()};               \
    return info;                                                                           \
  }                                                                                        \
  ::furnihost::Stage* Create(const nlohmann::json& params) { return new CLASS(params); }   \
  }                                                                                        \
  BOOST_DLL_ALIAS(furnihost_plugin_exports::Info, furnihost_plugin_info)                   \
  BOOST_DLL_ALIAS(furnihost_plugin_exports::Create, furnihost_plugin_create)
