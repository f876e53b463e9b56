#include "furnihost/params.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "shown.hpp"

namespace furnihost {

using detail::Shown;

std::string detail::Clipped(const std::string& s, std::size_t max) {
  std::string out = s.size() > max ? s.substr(0, max >= 3 ? max - 3 : 0) : s;
  for (char& c : out)
    if (c < 32 || c >= 127) c = '?';  // char may be signed: bytes >= 128 are negative
  return s.size() > max ? out + "..." : out;
}

std::string detail::Shown(const nlohmann::json& v, std::size_t max) {
  return Clipped(v.dump(-1, ' ', true, nlohmann::json::error_handler_t::replace), max);
}

const char* ToString(ParamType t) {
  switch (t) {
    case ParamType::Bool: return "bool";
    case ParamType::Int: return "int";
    case ParamType::Number: return "number";
    case ParamType::String: return "string";
    case ParamType::Enum: return "enum";
    case ParamType::NumberList: return "number[]";
    case ParamType::NumberMap: return "{name: number}";
    case ParamType::Object: return "object";
  }
  return "?";
}

namespace {

std::string FormatNumber(double v) {
  std::ostringstream s;
  if (std::abs(v) < 1e15 && v == std::floor(v)) s << static_cast<long long>(v);  // 2147483647, not 2.14748e+09
  else s << v;
  return s.str();
}

bool InRange(const ParamSpec& s, double v) {
  return std::isfinite(v) && (!s.min || v >= *s.min) && (!s.max || v <= *s.max);
}

}  // namespace

std::string RangeText(const ParamSpec& s) {
  if (!s.min && !s.max) return "";
  return " in [" + (s.min ? FormatNumber(*s.min) : std::string("-inf")) + ", " +
         (s.max ? FormatNumber(*s.max) : std::string("inf")) + "]";
}

ParamSchema& ParamSchema::Bool(const std::string& name, bool def, const std::string& help) {
  specs_.push_back({name, ParamType::Bool, def, {}, {}, {}, help, true, ""});
  return *this;
}
ParamSchema& ParamSchema::Int(const std::string& name, long long def, std::optional<double> min,
                              std::optional<double> max, const std::string& help) {
  specs_.push_back({name, ParamType::Int, def, min, max, {}, help, true, ""});
  return *this;
}
ParamSchema& ParamSchema::Number(const std::string& name, double def, std::optional<double> min,
                                 std::optional<double> max, const std::string& help) {
  specs_.push_back({name, ParamType::Number, def, min, max, {}, help, true, ""});
  return *this;
}
ParamSchema& ParamSchema::String(const std::string& name, const std::string& def,
                                 const std::string& help) {
  specs_.push_back({name, ParamType::String, def, {}, {}, {}, help, true, ""});
  return *this;
}
ParamSchema& ParamSchema::Enum(const std::string& name, const std::string& def,
                               std::vector<std::string> choices, const std::string& help) {
  specs_.push_back({name, ParamType::Enum, def, {}, {}, std::move(choices), help, true, ""});
  return *this;
}
ParamSchema& ParamSchema::NumberList(const std::string& name, std::vector<double> def,
                                     std::optional<double> min, std::optional<double> max,
                                     const std::string& help) {
  specs_.push_back({name, ParamType::NumberList, def, min, max, {}, help, true, ""});
  return *this;
}
ParamSchema& ParamSchema::NumberMap(const std::string& name, std::map<std::string, double> def,
                                    std::optional<double> min, std::optional<double> max,
                                    const std::string& help) {
  specs_.push_back({name, ParamType::NumberMap, def, min, max, {}, help, true, ""});
  return *this;
}
ParamSchema& ParamSchema::Object(const std::string& name, nlohmann::json def,
                                 const std::string& help) {
  specs_.push_back({name, ParamType::Object, std::move(def), {}, {}, {}, help, true, ""});
  return *this;
}

const ParamSpec* ParamSchema::Find(const std::string& name) const {
  for (const auto& s : specs_)
    if (s.name == name) return &s;
  return nullptr;
}

// Presets: a schema declaring a String "preset" and an Object "presets" ({name: {param: value}})
// takes the named preset's values for every parameter `given` does not set ("none": no preset);
// a given "presets" adds presets or redefines declared ones.
// The preset's entries are validated below as if given, so a bad one names its parameter.
namespace {
nlohmann::json WithPreset(const ParamSchema& schema, const nlohmann::json& given, const std::string& prefix) {
  nlohmann::json merged = given.is_object() ? given : nlohmann::json::object();
  const ParamSpec* preset = schema.Find("preset");
  const ParamSpec* presets = schema.Find("presets");
  if (!preset || !presets || preset->type != ParamType::String || presets->type != ParamType::Object ||
      !merged.contains("preset"))
    return merged;
  const nlohmann::json& name = merged.at("preset");
  if (!name.is_string()) throw InputError(prefix + "preset: expected a preset's name, got " + Shown(name));
  const std::string n = name.get<std::string>();
  if (n == "none") return merged;
  // The declared presets, and those the config adds or redefines.
  nlohmann::json table = presets->default_value.is_object() ? presets->default_value : nlohmann::json::object();
  if (merged.contains("presets")) {
    const nlohmann::json& own = merged.at("presets");
    if (!own.is_object()) throw InputError(prefix + "presets: expected an object of name: {parameter: value}, got " + Shown(own));
    for (auto it = own.begin(); it != own.end(); ++it) table[it.key()] = it.value();
  }
  if (!table.contains(n) || !table.at(n).is_object()) {
    std::string valid = "none";
    for (auto it = table.begin(); it != table.end(); ++it) valid += ", " + it.key();
    throw InputError(prefix + "preset: unknown preset \"" + n + "\"; valid: " + valid);
  }
  for (auto it = table.at(n).begin(); it != table.at(n).end(); ++it) {
    if (!schema.Find(it.key()) || it.key() == "preset" || it.key() == "presets")
      throw InputError(prefix + "presets/" + n + "/" + it.key() + ": not a parameter a preset can set");
    if (!merged.contains(it.key())) merged[it.key()] = it.value();
  }
  return merged;
}
}  // namespace

nlohmann::json ParamSchema::Resolve(const nlohmann::json& given, const std::string& where) const {
  const std::string prefix = where.empty() ? "" : where + "/";
  if (!given.is_null() && !given.is_object())
    throw InputError((where.empty() ? std::string("params") : where) + ": expected an object of parameters, got " + Shown(given));
  nlohmann::json out = nlohmann::json::object();
  if (given.is_object()) {
    for (auto it = given.begin(); it != given.end(); ++it) {
      if (Find(it.key())) continue;
      std::string valid;
      for (const auto& s : specs_) valid += (valid.empty() ? "" : ", ") + s.name;
      throw InputError(prefix + it.key() + ": unknown parameter; valid: " +
                       (valid.empty() ? "(none)" : valid));
    }
  }
  const nlohmann::json merged = WithPreset(*this, given, prefix);
  for (const auto& s : specs_) {
    const std::string at = prefix + s.name;
    if (!merged.contains(s.name)) {
      out[s.name] = s.default_value;
      continue;
    }
    const nlohmann::json& v = merged.at(s.name);
    switch (s.type) {
      case ParamType::Bool:
        if (!v.is_boolean()) throw InputError(at + ": expected true or false, got " + Shown(v));
        break;
      case ParamType::Int:
        if (!v.is_number_integer() || !InRange(s, v.get<double>()))
          throw InputError(at + ": expected an integer" + RangeText(s) + ", got " + Shown(v));
        break;
      case ParamType::Number:
        if (!v.is_number() || !InRange(s, v.get<double>()))
          throw InputError(at + ": expected a number" + RangeText(s) + ", got " + Shown(v));
        break;
      case ParamType::String:
        if (!v.is_string()) throw InputError(at + ": expected a string, got " + Shown(v));
        break;
      case ParamType::Enum: {
        bool ok = v.is_string();
        if (ok) {
          ok = false;
          for (const auto& c : s.choices) ok = ok || v.get<std::string>() == c;
        }
        if (!ok) {
          std::string list;
          for (const auto& c : s.choices) list += (list.empty() ? "" : ", ") + c;
          throw InputError(at + ": expected one of " + list + ", got " + Shown(v));
        }
        break;
      }
      case ParamType::NumberList: {
        bool ok = v.is_array();
        if (ok)
          for (const auto& x : v) ok = ok && x.is_number() && InRange(s, x.get<double>());
        if (!ok)
          throw InputError(at + ": expected a list of numbers" + RangeText(s) + ", got " + Shown(v));
        break;
      }
      case ParamType::NumberMap: {
        if (!v.is_object())
          throw InputError(at + ": expected an object of name: number" + RangeText(s) + ", got " + Shown(v));
        for (auto it = v.begin(); it != v.end(); ++it)
          if (!it->is_number() || !InRange(s, it->get<double>()))
            throw InputError(at + "/" + it.key() + ": expected a number" + RangeText(s) + ", got " + Shown(*it));
        break;
      }
      case ParamType::Object:
        if (!v.is_object()) throw InputError(at + ": expected an object, got " + Shown(v));
        break;
    }
    out[s.name] = v;
  }
  return out;
}

ParamSchema& ParamSchema::DetectionOnly() {
  if (specs_.empty()) throw std::logic_error("ParamSchema::DetectionOnly() before any parameter");
  specs_.back().training = false;
  return *this;
}

ParamSchema& ParamSchema::Unit(const std::string& unit) {
  if (specs_.empty()) throw std::logic_error("ParamSchema::Unit() before any parameter");
  specs_.back().unit = unit;
  return *this;
}

nlohmann::json ParamSchema::TrainingParams(const nlohmann::json& resolved) const {
  nlohmann::json out = resolved;
  if (!out.is_object()) return out;
  for (const auto& s : specs_)
    if (!s.training) out.erase(s.name);
  return out;
}

nlohmann::json ParamSchema::ToJson() const {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& s : specs_) {
    nlohmann::json p = {{"name", s.name}, {"type", ToString(s.type)}, {"default", s.default_value},
                        {"help", s.help}};
    if (s.min) p["min"] = *s.min;
    if (s.max) p["max"] = *s.max;
    if (!s.choices.empty()) p["choices"] = s.choices;
    if (!s.training) p["detection_only"] = true;
    if (!s.unit.empty()) p["unit"] = s.unit;
    a.push_back(p);
  }
  return a;
}

}  // namespace furnihost
