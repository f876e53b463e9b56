// Declared parameters: each plugin publishes a schema; the host validates JSON against it
// before anything runs, fills defaults, and prints it in `furnihost plugins`.
//
// A plugin declares each parameter once, bound to a member of its options struct
// (ParamBinding below): the schema, the default (read from the struct), parsing and the
// cross-field rules all come from that one declaration.
#pragma once
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "furnihost/error.hpp"

namespace furnihost {

// NumberMap: an object of name -> number, each number range-checked (e.g. per-class thresholds).
enum class ParamType { Bool, Int, Number, String, Enum, NumberList, NumberMap, Object };

FURNIHOST_API const char* ToString(ParamType t);

struct ParamSpec {
  std::string name;
  ParamType type = ParamType::Number;
  nlohmann::json default_value;
  std::optional<double> min, max;     // inclusive range for Int/Number (NumberList/NumberMap items)
  std::vector<std::string> choices;   // for Enum
  std::string help;
  // False for parameters that only matter at detection time (e.g. a voter's thresholds): they
  // are left out of the model cache key, so changing them does not retrain the model.
  bool training = true;
  std::string unit;  // "m", "deg", "px"...; empty = none (a count, a ratio)
};

// " in [min, max]" of a numeric spec: whole numbers in full ("2147483647"), others as a stream
// prints them ("0.5", "1e-06"); "-inf" / "inf" for a missing bound; "" when it has neither.
FURNIHOST_API std::string RangeText(const ParamSpec& s);

class FURNIHOST_API ParamSchema {
 public:
  ParamSchema& Bool(const std::string& name, bool def, const std::string& help);
  ParamSchema& Int(const std::string& name, long long def, std::optional<double> min,
                   std::optional<double> max, const std::string& help);
  ParamSchema& Number(const std::string& name, double def, std::optional<double> min,
                      std::optional<double> max, const std::string& help);
  ParamSchema& String(const std::string& name, const std::string& def, const std::string& help);
  ParamSchema& Enum(const std::string& name, const std::string& def,
                    std::vector<std::string> choices, const std::string& help);
  ParamSchema& NumberList(const std::string& name, std::vector<double> def,
                          std::optional<double> min, std::optional<double> max,
                          const std::string& help);
  ParamSchema& NumberMap(const std::string& name, std::map<std::string, double> def,
                         std::optional<double> min, std::optional<double> max,
                         const std::string& help);
  ParamSchema& Object(const std::string& name, nlohmann::json def, const std::string& help);
  // Marks the parameter declared last as detection-only (ParamSpec::training = false).
  ParamSchema& DetectionOnly();
  // Sets the unit of the parameter declared last.
  ParamSchema& Unit(const std::string& unit);
  // `resolved` without its detection-only parameters: what a trained model depends on.
  nlohmann::json TrainingParams(const nlohmann::json& resolved) const;

  const std::vector<ParamSpec>& Specs() const { return specs_; }
  const ParamSpec* Find(const std::string& name) const;

  // Validates `given` (an object or null) and returns it with every default filled.
  // `where` is a "file:/json/pointer" prefix used in error messages.
  // Throws InputError such as "x.json:/stages/seg/params/angle_deg: expected a number in
  // [0, 180], got \"forty\"". An empty `where` names the bare parameter ("angle_deg: ...").
  // A schema with a String parameter "preset" and an Object "presets" ({name: {parameter:
  // value}}) fills the parameters `given` leaves out from the preset `given` names first.
  nlohmann::json Resolve(const nlohmann::json& given, const std::string& where) const;

  nlohmann::json ToJson() const;

 private:
  std::vector<ParamSpec> specs_;
};

namespace param_detail {

// A float default as the shortest decimal that reads back to the same float (0.04f -> 0.04,
// not 0.03999999910593033), so the schema prints what the source says.
inline double FloatAsDecimal(float f) {
  char buf[32];
  for (int digits = 1; digits <= 9; ++digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, static_cast<double>(f));
    const double d = std::strtod(buf, nullptr);
    if (static_cast<float>(d) == f) return d;
  }
  return f;
}

template <class T>
double NumberDefault(T v) {
  if constexpr (std::is_same_v<T, float>) return FloatAsDecimal(v);
  else return static_cast<double>(v);
}

// The member a binding names: a pointer to a data member (&O::x), or a callable returning a
// reference into O for nested members ([](O& o) -> float& { return o.base.x; }).
template <class O, class M>
decltype(auto) Field(O& o, const M& m) {
  if constexpr (std::is_member_object_pointer_v<M>) return (o.*m);
  else return m(o);
}

template <class O, class M>
using FieldType = std::remove_reference_t<decltype(Field(std::declval<O&>(), std::declval<const M&>()))>;

// "a, b,c" -> {"a", "b", "c"}: items trimmed of spaces and tabs, empty items dropped.
inline std::vector<std::string> SplitCommaList(const std::string& list) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= list.size()) {
    const size_t comma = std::min(list.find(',', start), list.size());
    const std::string item = list.substr(start, comma - start);
    const size_t b = item.find_first_not_of(" \t");
    if (b != std::string::npos) out.push_back(item.substr(b, item.find_last_not_of(" \t") - b + 1));
    start = comma + 1;
  }
  return out;
}

template <class T>
struct IsVector : std::false_type {};
template <class T, class A>
struct IsVector<std::vector<T, A>> : std::true_type {};
template <class T>
struct IsStringMap : std::false_type {};
template <class T, class C, class A>
struct IsStringMap<std::map<std::string, T, C, A>> : std::true_type {};

}  // namespace param_detail

// One declaration per parameter, bound to a member of the options struct O:
//
//   struct MyOptions {
//     double angle_deg = 40;  // default: the struct's, so schema and struct cannot disagree
//     int min_points = 10;
//   };
//   const ParamBinding<MyOptions>& Binding() {
//     static const auto b = ParamBinding<MyOptions>()
//         .Number("angle_deg", &MyOptions::angle_deg, 0, 180, "deg", "normal angle threshold")
//         .Int("min_points", &MyOptions::min_points, 1, 1e6, "", "smallest region kept")
//         .Rule([](const MyOptions& o) {
//           return o.min_points < 100 || o.angle_deg < 90 ? "" : "min_points >= 100 needs angle_deg < 90";
//         });
//     return b;
//   }
//   static ParamSchema Schema() { return Binding().Schema(); }
//   explicit MyStage(const nlohmann::json& p) : o_(Binding().Parse(p)) {}
//
// The default of each parameter is read from a default-constructed O{} (float members print as
// their shortest decimal: 0.04f as 0.04). Parse() validates like ParamSchema::Resolve (type,
// range, unknown names: InputError naming the parameter), fills the struct in declaration
// order, then runs Object parsers (which may read the typed fields) and the rules; a rule
// returns "" when satisfied, else a message naming the parameters, thrown as
// StageError(message) (an input error: `furnihost validate` exits 2).
template <class O>
class ParamBinding {
 public:
  using RuleFn = std::function<std::string(const O&)>;
  using ObjectFn = std::function<void(O&, const nlohmann::json&)>;

  template <class M>
  ParamBinding& Bool(const std::string& name, M m, const std::string& help) {
    static_assert(std::is_same_v<param_detail::FieldType<O, M>, bool>, "Bool binds a bool member");
    schema_.Bool(name, Default(m), help);
    return Add(name, m);
  }
  template <class M>
  ParamBinding& Int(const std::string& name, M m, std::optional<double> min, std::optional<double> max,
                    const std::string& unit, const std::string& help) {
    using T = param_detail::FieldType<O, M>;
    static_assert(std::is_integral_v<T> && !std::is_same_v<T, bool>, "Int binds an integer member");
    schema_.Int(name, static_cast<long long>(Default(m)), min, max, help).Unit(unit);
    return Add(name, m);
  }
  template <class M>
  ParamBinding& Number(const std::string& name, M m, std::optional<double> min, std::optional<double> max,
                       const std::string& unit, const std::string& help) {
    static_assert(std::is_floating_point_v<param_detail::FieldType<O, M>>, "Number binds a float or double member");
    schema_.Number(name, param_detail::NumberDefault(Default(m)), min, max, help).Unit(unit);
    return Add(name, m);
  }
  template <class M>
  ParamBinding& String(const std::string& name, M m, const std::string& help) {
    static_assert(std::is_same_v<param_detail::FieldType<O, M>, std::string>, "String binds a std::string member");
    schema_.String(name, Default(m), help);
    return Add(name, m);
  }
  // A comma-separated list of names in one JSON string ("chair, table"; "" = none), split into
  // a std::vector<std::string> member (items trimmed, empty items dropped). The schema default
  // is the member's default joined with ", ".
  template <class M>
  ParamBinding& StringList(const std::string& name, M m, const std::string& help) {
    static_assert(std::is_same_v<param_detail::FieldType<O, M>, std::vector<std::string>>,
                  "StringList binds a std::vector<std::string> member");
    std::string def;
    for (const auto& item : Default(m)) def += (def.empty() ? "" : ", ") + item;
    schema_.String(name, def, help);
    parsers_.push_back([m](O& o, const nlohmann::json& v) {
      param_detail::Field(o, m) = param_detail::SplitCommaList(v.get<std::string>());
    });
    return *this;
  }
  // A std::string member holds the choice; an enum or integer member holds its index in `choices`.
  template <class M>
  ParamBinding& Enum(const std::string& name, M m, std::vector<std::string> choices, const std::string& help) {
    using T = param_detail::FieldType<O, M>;
    std::string def;
    if constexpr (std::is_same_v<T, std::string>) {
      def = Default(m);
    } else {
      static_assert(std::is_enum_v<T> || std::is_integral_v<T>, "Enum binds a std::string, enum or integer member");
      def = choices.at(static_cast<size_t>(Default(m)));
    }
    schema_.Enum(name, def, choices, help);
    parsers_.push_back([name, m, choices](O& o, const nlohmann::json& v) {
      const std::string c = v.get<std::string>();
      if constexpr (std::is_same_v<T, std::string>) {
        param_detail::Field(o, m) = c;
      } else {
        size_t i = 0;
        while (i < choices.size() && choices[i] != c) ++i;
        param_detail::Field(o, m) = static_cast<T>(i);
      }
    });
    return *this;
  }
  template <class M>
  ParamBinding& NumberList(const std::string& name, M m, std::optional<double> min, std::optional<double> max,
                           const std::string& unit, const std::string& help) {
    using T = param_detail::FieldType<O, M>;
    static_assert(param_detail::IsVector<T>::value && std::is_arithmetic_v<typename T::value_type>,
                  "NumberList binds a std::vector of numbers");
    std::vector<double> def;
    for (const auto& x : Default(m)) def.push_back(param_detail::NumberDefault(x));
    schema_.NumberList(name, def, min, max, help).Unit(unit);
    return Add(name, m);
  }
  template <class M>
  ParamBinding& NumberMap(const std::string& name, M m, std::optional<double> min, std::optional<double> max,
                          const std::string& unit, const std::string& help) {
    using T = param_detail::FieldType<O, M>;
    static_assert(param_detail::IsStringMap<T>::value && std::is_arithmetic_v<typename T::mapped_type>,
                  "NumberMap binds a std::map<std::string, number>");
    std::map<std::string, double> def;
    for (const auto& [k, x] : Default(m)) def[k] = param_detail::NumberDefault(x);
    schema_.NumberMap(name, def, min, max, help).Unit(unit);
    return Add(name, m);
  }
  // A free-form object (checked only to be an object); `parse` fills O from it after every
  // typed parameter is set.
  ParamBinding& Object(const std::string& name, nlohmann::json def, const std::string& help, ObjectFn parse) {
    schema_.Object(name, std::move(def), help);
    parsers_.push_back(nullptr);
    objects_.emplace_back(name, std::move(parse));
    return *this;
  }
  ParamBinding& DetectionOnly() {
    schema_.DetectionOnly();
    return *this;
  }
  // A rule between parameters: "" when `o` satisfies it, else a message naming them.
  ParamBinding& Rule(RuleFn rule) {
    rules_.push_back(std::move(rule));
    return *this;
  }

  const ParamSchema& Schema() const { return schema_; }

  // `params`: the stage's resolved parameters (missing ones take their defaults).
  O Parse(const nlohmann::json& params) const { return Parse(params, "", false); }
  // The same for a section of a file: errors are InputErrors that start with `where` (a
  // "file:/json/pointer"), "where/<parameter>: ..." or, for a rule, "where: <message>".
  O Parse(const nlohmann::json& params, const std::string& where) const { return Parse(params, where, true); }

 private:
  O Parse(const nlohmann::json& params, const std::string& where, bool located) const {
    const nlohmann::json r = schema_.Resolve(params, where);
    O o{};
    const auto& specs = schema_.Specs();
    for (size_t i = 0; i < specs.size(); ++i)
      if (parsers_[i]) parsers_[i](o, r.at(specs[i].name));
    for (const auto& [name, parse] : objects_) parse(o, r.at(name));
    for (const auto& rule : rules_) {
      const std::string message = rule(o);
      if (message.empty()) continue;
      if (located) throw InputError(where + ": " + message);
      throw StageError(message);
    }
    return o;
  }

  template <class M>
  param_detail::FieldType<O, M> Default(const M& m) const {
    O d{};
    return param_detail::Field(d, m);
  }
  template <class M>
  ParamBinding& Add(const std::string&, M m) {
    parsers_.push_back([m](O& o, const nlohmann::json& v) {
      using T = param_detail::FieldType<O, M>;
      param_detail::Field(o, m) = v.get<T>();
    });
    return *this;
  }

  ParamSchema schema_;
  std::vector<ObjectFn> parsers_;  // one per spec, in order (null for Object parameters)
  std::vector<std::pair<std::string, ObjectFn>> objects_;
  std::vector<RuleFn> rules_;
};

}  // namespace furnihost
