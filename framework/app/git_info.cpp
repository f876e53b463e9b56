#include "git_info.hpp"

#include <sys/stat.h>

#include <cctype>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <fstream>
#include <iterator>
#include <sstream>

namespace fs = std::filesystem;

namespace furnihost::app {

namespace {

// A small text file of a .git folder (HEAD, a ref, commondir), at most 64 KiB; "" when it is not
// a regular file.
std::string Small(const fs::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size > (1 << 16)) return "";
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string Trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  size_t b = 0;
  while (b < s.size() && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  return s.substr(b);
}

bool IsSha(const std::string& s) {
  if (s.size() != 40) return false;
  for (char c : s)
    if (!std::isxdigit(static_cast<unsigned char>(c))) return false;
  return true;
}

// A ref name as git writes them: no "..", no absolute path, no control bytes.
bool SafeRef(const std::string& r) {
  if (r.empty() || r[0] == '/' || r.find("..") != std::string::npos) return false;
  for (char c : r)
    if (static_cast<unsigned char>(c) < 0x20 || c == '\\') return false;
  return true;
}

struct Repo {
  fs::path worktree, gitdir, common;
};

// The repository holding `dir`: its .git folder, or a worktree's .git file ("gitdir: ...") and
// that folder's commondir.
std::optional<Repo> FindRepo(fs::path dir) {
  std::error_code ec;
  dir = fs::absolute(dir, ec);
  for (int up = 0; up < 64 && !dir.empty(); ++up) {
    const fs::path dot = dir / ".git";
    struct stat st {};
    if (::stat(dot.c_str(), &st) == 0) {
      Repo r;
      r.worktree = dir;
      if (S_ISDIR(st.st_mode)) {
        r.gitdir = dot;
      } else if (S_ISREG(st.st_mode)) {
        const std::string t = Trim(Small(dot));
        if (t.rfind("gitdir:", 0) != 0) return std::nullopt;
        fs::path g = Trim(t.substr(7));
        r.gitdir = g.is_relative() ? dir / g : g;
      } else {
        return std::nullopt;
      }
      const std::string common = Trim(Small(r.gitdir / "commondir"));
      r.common = common.empty() ? r.gitdir : (fs::path(common).is_relative() ? r.gitdir / common : fs::path(common));
      return r;
    }
    if (dir == dir.root_path()) break;
    dir = dir.parent_path();
  }
  return std::nullopt;
}

// `ref` ("refs/heads/main") to its commit: the loose ref file (the worktree's, then the common
// one's), else packed-refs; symbolic refs followed a few steps.
std::optional<std::string> Resolve(const Repo& r, std::string ref) {
  for (int hop = 0; hop < 5; ++hop) {
    if (!SafeRef(ref)) return std::nullopt;
    std::string t = Trim(Small(r.gitdir / ref));
    if (t.empty()) t = Trim(Small(r.common / ref));
    if (t.empty()) {
      std::istringstream packed(Small(r.common / "packed-refs"));
      for (std::string line; std::getline(packed, line);)
        if (line.size() > 41 && line[40] == ' ' && Trim(line.substr(41)) == ref && IsSha(line.substr(0, 40)))
          return line.substr(0, 40);
      return std::nullopt;
    }
    if (IsSha(t)) return t;
    if (t.rfind("ref:", 0) != 0) return std::nullopt;
    ref = Trim(t.substr(4));
  }
  return std::nullopt;
}

uint32_t Be32(const unsigned char* p) { return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | p[3]; }

// Whether a tracked file's size or modification time differs from the index's record (git
// status would then compare contents; a touched but unchanged file counts as changed here).
// nullopt when the index cannot be read (missing, unknown version, truncated).
std::optional<bool> Dirty(const Repo& r) {
  const fs::path index = r.gitdir / "index";
  struct stat st {};
  if (::stat(index.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size > (int64_t(1) << 30)) return std::nullopt;
  std::ifstream in(index, std::ios::binary);
  const std::string data((std::istreambuf_iterator<char>(in)), {});
  const auto* d = reinterpret_cast<const unsigned char*>(data.data());
  const size_t n = data.size();
  if (n < 12 + 20 || data.compare(0, 4, "DIRC") != 0) return std::nullopt;
  const uint32_t version = Be32(d + 4), entries = Be32(d + 8);
  if (version < 2 || version > 4) return std::nullopt;
  size_t at = 12;
  std::string path;
  for (uint32_t e = 0; e < entries; ++e) {
    const size_t start = at;
    if (at + 62 > n) return std::nullopt;
    const uint32_t mtime_s = Be32(d + start + 8), mtime_ns = Be32(d + start + 12);
    const uint32_t mode = Be32(d + start + 24), size = Be32(d + start + 36);
    const unsigned flags = unsigned(d[start + 60]) << 8 | d[start + 61];
    at += 62;
    if (version >= 3 && (flags & 0x4000)) {
      if (at + 2 > n) return std::nullopt;
      at += 2;
    }
    if (version == 4) {  // the path: strip N bytes of the previous one, then a NUL-ended suffix
      uint64_t strip = 0;
      for (int k = 0;; ++k) {
        if (at >= n || k > 9) return std::nullopt;
        const unsigned char c = d[at++];
        strip = (strip << 7) | (c & 0x7F);
        if (!(c & 0x80)) break;
        ++strip;
      }
      if (strip > path.size()) return std::nullopt;
      path.resize(path.size() - strip);
      const size_t end = data.find('\0', at);
      if (end == std::string::npos) return std::nullopt;
      path += data.substr(at, end - at);
      at = end + 1;
    } else {
      const size_t end = data.find('\0', at);
      if (end == std::string::npos) return std::nullopt;
      path = data.substr(at, end - at);
      at = start + ((end + 1 - start + 7) / 8) * 8;  // NUL-padded to a multiple of 8 bytes
    }
    const unsigned stage = (flags >> 12) & 3;
    const bool assume_unchanged = flags & 0x8000;
    if (stage != 0 || assume_unchanged || (mode >> 12) == 0xE) continue;  // conflicts, skipped files, submodules
    struct stat f {};
    if (::lstat((r.worktree / path).c_str(), &f) != 0) return true;
    // A git built without nanosecond times records 0 there.
    if (uint32_t(f.st_size) != size || uint32_t(f.st_mtim.tv_sec) != mtime_s ||
        (mtime_ns != 0 && uint32_t(f.st_mtim.tv_nsec) != mtime_ns))
      return true;
  }
  return false;
}

}  // namespace

nlohmann::json GitInfo(const std::vector<std::string>& dirs) {
  for (const auto& d : dirs) {
    const auto repo = FindRepo(d);
    if (!repo) continue;
    const std::string head = Trim(Small(repo->gitdir / "HEAD"));
    std::optional<std::string> rev;
    if (IsSha(head)) rev = head;  // a detached HEAD
    else if (head.rfind("ref:", 0) == 0) rev = Resolve(*repo, Trim(head.substr(4)));
    if (!rev) continue;
    const std::optional<bool> dirty = Dirty(*repo);
    return {{"revision", *rev}, {"dirty", dirty ? nlohmann::json(*dirty) : nlohmann::json(nullptr)}, {"dir", d}};
  }
  return {{"revision", "unknown"}, {"dirty", nullptr}};
}

}  // namespace furnihost::app
