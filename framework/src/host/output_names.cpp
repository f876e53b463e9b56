// Names of output files and folders made from input names (scan stems, eval --name labels):
// every path the program writes stays inside its output folder and no two inputs share one.
#include <cctype>
#include <set>
#include <string>
#include <vector>

#include "furnihost/host/io.hpp"

namespace furnihost {

std::string SafeName(const std::string& name) {
  constexpr size_t kMaxBytes = 100;
  std::string s;
  for (char c : name) {
    if (s.size() >= kMaxBytes) break;
    const auto u = static_cast<unsigned char>(c);
    s += (std::isalnum(u) || c == '.' || c == '-' || c == '_') ? c : '_';
  }
  // "", "." and ".." name no file of their own; a leading dot hides one.
  for (char& c : s) {
    if (c != '.') break;
    c = '_';
  }
  return s.empty() ? "_" : s;
}

std::vector<std::string> UniqueSafeNames(const std::vector<std::string>& names) {
  // Compared without case: "Room" and "room" are one file on a case-insensitive file system.
  auto folded = [](std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  std::set<std::string> taken;
  std::vector<std::string> out;
  out.reserve(names.size());
  for (const auto& n : names) {
    const std::string base = SafeName(n);
    std::string name = base;
    for (int k = 2; taken.count(folded(name)); ++k) name = base + "_" + std::to_string(k);
    taken.insert(folded(name));
    out.push_back(name);
  }
  return out;
}

}  // namespace furnihost
