// How an offending value is shown in a one-line error message: the config and parameter checks
// and the scan readers' header checks show values the same way. Internal to the framework (SDK
// and host); plugins report values through the parameter schema, which uses these.
#pragma once
#include <cstddef>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "furnihost/error.hpp"  // FURNIHOST_API

// In namespace detail: exported from the SDK library (the host's config checks call them across
// the library boundary) but no part of the plugin API.
namespace furnihost::detail {

// `s` as printable ASCII on one line: every other byte (control characters, a binary file's
// bytes, UTF-8) as '?'; longer than `max`: its first max - 3 characters and "...".
FURNIHOST_API std::string Clipped(const std::string& s, std::size_t max = 60);

// A JSON value as Clipped shows its dump, non-ASCII characters escaped as JSON does (\u00fc),
// so a name in another script stays readable and is not replaced by '?'.
FURNIHOST_API std::string Shown(const nlohmann::json& v, std::size_t max = 60);

}  // namespace furnihost::detail
