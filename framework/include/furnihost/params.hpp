// Declared parameters: each plugin publishes a schema; the host validates JSON against it
// before anything runs, fills defaults, and prints it in `furnihost plugins`.
#pragma once
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "furnihost/error.hpp"

namespace furnihost {

enum class ParamType { Bool, Int, Number, String, Enum, NumberList, Object };

FURNIHOST_API const char* ToString(ParamType t);

struct ParamSpec {
  std::string name;
  ParamType type = ParamType::Number;
  nlohmann::json default_value;
  std::optional<double> min, max;     // inclusive range for Int/Number (and NumberList items)
  std::vector<std::string> choices;   // for Enum
  std::string help;
  // False for parameters that only matter at detection time (e.g. a voter's thresholds): they
  // are left out of the model cache key, so changing them does not retrain the model.
  bool training = true;
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
  ParamSchema& Object(const std::string& name, nlohmann::json def, const std::string& help);
  // Marks the parameter declared last as detection-only (ParamSpec::training = false).
  ParamSchema& DetectionOnly();
  // `resolved` without its detection-only parameters: what a trained model depends on.
  nlohmann::json TrainingParams(const nlohmann::json& resolved) const;

  const std::vector<ParamSpec>& Specs() const { return specs_; }
  const ParamSpec* Find(const std::string& name) const;

  // Validates `given` (an object or null) and returns it with every default filled.
  // `where` is a "file:/json/pointer" prefix used in error messages.
  // Throws InputError such as "x.json:/stages/seg/params/angle_deg: expected a number in
  // [0, 180], got \"forty\"".
  nlohmann::json Resolve(const nlohmann::json& given, const std::string& where) const;

  nlohmann::json ToJson() const;

 private:
  std::vector<ParamSpec> specs_;
};

}  // namespace furnihost
