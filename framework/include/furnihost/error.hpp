// Error types shared by host and plugins. They live in the SDK library (libfurnihost_sdk.so) so
// that their type_info and vtables outlive any plugin that throws them.
#pragma once
#include <stdexcept>
#include <string>

#define FURNIHOST_API __attribute__((visibility("default")))

namespace furnihost {

namespace detail {
// A message quoting a file's bytes may hold NUL (a UTF-16 text): what() is a C string and
// would end there, so NUL bytes are shown as '?'.
inline std::string WithoutNul(std::string s) {
  for (auto& c : s)
    if (c == '\0') c = '?';
  return s;
}
}  // namespace detail

// Bad user input: file, config, parameter, data. The CLI maps it to exit code 2.
class FURNIHOST_API InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& what) : std::runtime_error(detail::WithoutNul(what)) {}
  ~InputError() override;
};

// Raised by a stage (plugin). The host prefixes the stage tag and type when it catches it.
// `input` says whether the failure is the user's data (exit 2) or a defect (exit 1).
class FURNIHOST_API StageError : public std::runtime_error {
 public:
  explicit StageError(const std::string& what, bool input = true)
      : std::runtime_error(detail::WithoutNul(what)), input_(input) {}
  ~StageError() override;
  bool IsInputError() const { return input_; }

 private:
  bool input_;
};

}  // namespace furnihost
