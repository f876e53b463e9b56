#include <cstdio>
#include <stdexcept>

#include "furnihost/error.hpp"
#include "furnihost/stage.hpp"
#include "furnihost/types.hpp"

namespace furnihost {

// Out-of-line destructors anchor vtables and type_info in the SDK library, so dynamic_cast
// and catch clauses agree between the host and every plugin.
InputError::~InputError() = default;
StageError::~StageError() = default;
Stage::~Stage() = default;
Sensor::~Sensor() = default;
Segmenter::~Segmenter() = default;
Proposer::~Proposer() = default;
Features::~Features() = default;
Voter::~Voter() = default;
Fitter::~Fitter() = default;

nlohmann::json Voter::Merge(const std::vector<nlohmann::json>&) {
  throw std::logic_error("this voter does not merge models trained apart (StageNeeds::training_merges)");
}

Check Check::AtLeast(std::string name, double value, double limit) {
  return Check{std::move(name), value, limit, true, value >= limit};
}

Check Check::AtMost(std::string name, double value, double limit) {
  return Check{std::move(name), value, limit, false, value <= limit};
}

std::string Check::Text() const {
  const char* op = at_least ? (passed ? ">=" : "<") : (passed ? "<=" : ">");
  char buf[160];
  std::snprintf(buf, sizeof buf, "%s %.4g %s %.4g", name.c_str(), value, op, limit);
  return buf;
}

std::string FirstFailure(const std::vector<Check>& checks) {
  for (const auto& c : checks)
    if (!c.passed) return c.Text();
  return "";
}

Eigen::AlignedBox3f Mesh::Bounds() const {
  Eigen::AlignedBox3f b;
  for (const auto& v : vertices) b.extend(v);
  return b;
}

}  // namespace furnihost
