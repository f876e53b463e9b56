// Mesh files: LoadMeshFile checks a file's format where assimp 5.2 would loop, allocate without
// bound or read out of bounds on a malformed file (PLY headers, COLLADA index lists, OFF files),
// then imports it through libfurnihost_meshio (assimp), which the host loads on the first mesh
// it parses.
#include <dlfcn.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "furnihost/host/catalog.hpp"
#include "furnihost/host/io.hpp"

namespace fs = std::filesystem;

namespace furnihost {
namespace {
// assimp 5.2's PLY importer loops forever on a header without end_header (a truncated
// download) or with a malformed line (fuzz_catalog): the header must follow the PLY grammar
// before assimp sees the file. Its element counts must fit the file too: assimp allocates what a
// header declares before reading a byte of data (2e9 faces: std::bad_alloc). Face indices are
// checked on the imported scene (meshio/mesh_import.cpp), whatever the layout and encoding.
void CheckPlyHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  if (!std::getline(in, line)) return;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  // assimp takes a file for PLY by its "ply" token, not by a whole first line (fuzz_catalog:
  // "ply" and garbage on the first line hung it too), so such a file is checked as well.
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool ply_name = ext == ".ply";
  if (line.rfind("ply", 0) != 0 && !ply_name) return;
  if (line != "ply")
    throw InputError(path + ": malformed PLY file (the first line is not 'ply')");
  static const std::map<std::string, int> kTypes = {
      {"char", 1},  {"uchar", 1},  {"int8", 1},  {"uint8", 1},  {"short", 2},   {"ushort", 2},
      {"int16", 2}, {"uint16", 2}, {"int", 4},   {"uint", 4},   {"int32", 4},   {"uint32", 4},
      {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  auto bad = [&](const std::string& why) { return InputError(path + ": malformed PLY file (" + why + ")"); };
  size_t read = line.size() + 1;
  bool format = false, ascii = false;
  struct Element {
    std::string name;
    unsigned long long count = 0;
    unsigned long long min_bytes = 0;  // the fewest bytes one item of it takes in the file
  };
  std::vector<Element> elements;
  while (read < (1u << 16) && std::getline(in, line)) {
    read += line.size() + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    for (char c : line)
      if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7F) throw bad("control character");
    std::istringstream ls(line);
    std::vector<std::string> t;
    for (std::string w; ls >> w;) t.push_back(w);
    if (t.empty() || t[0] == "comment" || t[0] == "obj_info") continue;
    if (t[0] == "end_header") {
      if (!format || elements.empty()) throw bad("no format or no element before end_header");
      break;
    }
    if (t[0] == "format") {
      if (t.size() != 3 || (t[1] != "ascii" && t[1] != "binary_little_endian" && t[1] != "binary_big_endian"))
        throw bad("bad format line");
      format = true;
      ascii = t[1] == "ascii";
    } else if (t[0] == "element") {
      if (t.size() != 3 || t[2].find_first_not_of("0123456789") != std::string::npos || t[2].size() > 10)
        throw bad("bad element line '" + line.substr(0, 40) + "'");
      elements.push_back({t[1], std::stoull(t[2]), 0});
    } else if (t[0] == "property") {
      const bool list = t.size() == 5 && t[1] == "list" && kTypes.count(t[2]) && kTypes.count(t[3]);
      if (elements.empty() || !(list || (t.size() == 3 && kTypes.count(t[1]))))
        throw bad("bad property line '" + line.substr(0, 40) + "'");
      // ascii: a value and its separator; binary: a scalar, or a list's count alone (it may be 0).
      elements.back().min_bytes += ascii ? 2 : static_cast<unsigned long long>(kTypes.at(list ? t[2] : t[1]));
    } else {
      throw bad("unknown line '" + line.substr(0, 40) + "'");
    }
  }
  if (line.rfind("end_header", 0) != 0) throw InputError(path + ": PLY header has no end_header in its first 64 KB (truncated file?)");
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  const std::streamoff at = in.tellg();
  if (ec || at < 0) return;
  const unsigned long long left = size > uintmax_t(at) ? size - uintmax_t(at) : 0;
  // The last ascii value needs no separator after it.
  unsigned long long need = 0;
  for (const auto& e : elements) {
    const unsigned long long per = std::max<unsigned long long>(e.min_bytes, 1);
    if (e.count > (left + 1) / per || need + e.count * per > left + 1)
      throw bad("element '" + e.name.substr(0, 40) + "' declares " + std::to_string(e.count) + " items, the file holds " +
                std::to_string(left) + " bytes of data");
    need += e.count * per;
  }
}

// assimp 5.2's COLLADA importer reads the index lists (<p>, <v>, <vcount>, <h>) and integer
// arrays number by number and stops only at the end of the text: a character that is neither a
// digit nor a blank is never consumed, so one stray byte in a list appends zeros forever
// (fuzz_mesh: 12 GB and four minutes, then std::bad_alloc). A COLLADA file is imported only if
// those lists hold integers and blanks. Linear in the file.
void CheckColladaLists(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char head[512] = {};
  in.read(head, sizeof(head) - 1);
  std::string start(head, static_cast<size_t>(in.gcount()));
  for (char& c : start) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".dae" && ext != ".xml" && start.find("<collada") == std::string::npos) return;
  in.clear();
  in.seekg(0);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  static const std::set<std::string> kLists{"p", "v", "vcount", "h", "int_array"};
  for (size_t i = text.find('<'); i != std::string::npos; i = text.find('<', i + 1)) {
    size_t e = i + 1;
    while (e < text.size() && (std::isalnum(static_cast<unsigned char>(text[e])) || text[e] == '_')) ++e;
    if (!kLists.count(text.substr(i + 1, e - i - 1))) continue;
    const size_t open_end = text.find('>', e);
    if (open_end == std::string::npos) return;  // assimp's XML parser refuses it
    if (text[open_end - 1] == '/') continue;    // <p/>: empty
    const bool signed_values = text.compare(i + 1, 9, "int_array") == 0;
    for (size_t k = open_end + 1; k < text.size() && text[k] != '<'; ++k) {
      const unsigned char c = static_cast<unsigned char>(text[k]);
      if (std::isdigit(c) || c == ' ' || c == '\t' || c == '\n' || c == '\r' || (signed_values && c == '-')) continue;
      const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(k), '\n');
      throw InputError(path + ":" + std::to_string(line) + ": <" + text.substr(i + 1, e - i - 1) +
                       "> holds a character that is not part of an integer list (byte " + std::to_string(int(c)) + ")");
    }
  }
}

// assimp 5.2's OFF importer reads vertices by unchecked face indices and splits lines at
// control characters (fuzz_catalog: a heap overflow, then a crash). An OFF file is imported
// only if it is plain: header, counts, nV vertex lines of >= 3 numbers, nF face lines of
// 3..9 indices below nV (then optional colour values).
void CheckOff(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  auto bad = [&](const std::string& why) { return InputError(path + ": malformed OFF file (" + why + ")"); };
  auto next = [&](std::vector<std::string>& tok) {
    while (std::getline(in, line)) {
      if (!line.empty() && line.back() == '\r') line.pop_back();
      for (char c : line)
        if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7F) throw bad("control character");
      std::istringstream ls(line);
      tok.clear();
      for (std::string t; ls >> t;) tok.push_back(t);
      if (!tok.empty() && tok[0][0] != '#') return true;
    }
    return false;
  };
  auto number = [](const std::string& t, double& v) {
    char* end = nullptr;
    v = std::strtod(t.c_str(), &end);
    return end == t.c_str() + t.size() && std::isfinite(v);
  };
  std::vector<std::string> tok;
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (!next(tok)) return;
  std::string head = tok[0];
  for (auto& c : head) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  if (ext != ".off" && head.find("OFF") == std::string::npos) return;  // another format
  // assimp also reads "OFF<digits>", "4OFF", "STOFF"...: only the plain headers are imported.
  if (tok[0] != "OFF" && tok[0] != "COFF" && tok[0] != "NOFF" && tok[0] != "CNOFF")
    throw bad("unsupported header '" + tok[0].substr(0, 20) + "'");
  tok.erase(tok.begin());
  if (tok.empty() && !next(tok)) throw bad("no counts");
  double nv = 0, nf = 0;
  if (tok.size() < 2 || !number(tok[0], nv) || !number(tok[1], nf) || nv < 0 || nf < 0 || nv > 1e8 || nf > 1e8 ||
      nv != std::floor(nv) || nf != std::floor(nf))
    throw bad("bad vertex/face counts");
  for (double i = 0; i < nv; ++i) {
    double v;
    if (!next(tok) || tok.size() < 3 || !number(tok[0], v) || !number(tok[1], v) || !number(tok[2], v))
      throw bad("vertex " + std::to_string(static_cast<long long>(i)) + " is not 3 numbers");
  }
  for (double f = 0; f < nf; ++f) {
    double k, idx;
    if (!next(tok) || !number(tok[0], k) || k < 3 || k > 9 || k != std::floor(k) || tok.size() < 1 + k)
      throw bad("face " + std::to_string(static_cast<long long>(f)) + " is not 3 to 9 vertex indices");
    for (size_t m = 1; m <= static_cast<size_t>(k); ++m)
      if (!number(tok[m], idx) || idx < 0 || idx >= nv || idx != std::floor(idx))
        throw bad("face " + std::to_string(static_cast<long long>(f)) + " uses vertex " + tok[m] + " of " +
                  std::to_string(static_cast<long long>(nv)));
  }
}
}  // namespace

namespace {
// libfurnihost_meshio's import function, the library loaded once (beside the host library, else
// by the dynamic linker's search: RUNPATH, LD_LIBRARY_PATH); an InputError when it cannot be.
using ImportFn = bool (*)(const char*, Mesh*, std::string*);
ImportFn MeshImporter() {
  static const std::pair<ImportFn, std::string> loaded = []() -> std::pair<ImportFn, std::string> {
    const char* kName = "libfurnihost_meshio.so";
    std::vector<std::string> tried;
    Dl_info self{};
    if (dladdr(reinterpret_cast<void*>(&LoadMeshFile), &self) && self.dli_fname)
      tried.push_back((fs::path(self.dli_fname).parent_path() / kName).string());
    tried.push_back(kName);
    std::string errors;
    for (const auto& name : tried) {
      // Never closed: the mesh importer stays for the process (as the plugins' libraries do).
      if (void* lib = dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL)) {
        if (auto* fn = reinterpret_cast<ImportFn>(dlsym(lib, "furnihost_meshio_import"))) return {fn, ""};
        errors += (errors.empty() ? "" : "; ") + name + ": no furnihost_meshio_import";
        continue;
      }
      const char* e = dlerror();
      errors += (errors.empty() ? "" : "; ") + std::string(e ? e : name);
    }
    return {nullptr, errors};
  }();
  if (!loaded.first) throw InputError("cannot load the mesh importer (" + loaded.second + ")");
  return loaded.first;
}
}  // namespace

Mesh LoadMeshFile(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError(path + ": no such mesh file");
  CheckPlyHeader(path);
  CheckOff(path);
  CheckColladaLists(path);
  Mesh out;
  std::string why;
  if (!MeshImporter()(path.c_str(), &out, &why)) throw InputError(path + ": " + why);
  if (out.triangles.empty()) throw InputError(path + ": no triangles in the file");
  return out;
}

}  // namespace furnihost
