// The model cache's rule for the path it writes: a graph's model_cache (or `train --out`) may
// name a model file or nothing yet. A graph from elsewhere that names ~/.bashrc as its cache
// gets an error, never that file replaced by a model.
#include <sys/stat.h>

#include <cstring>
#include <fstream>

#include "furnihost/pipeline.hpp"

namespace furnihost {

void CheckModelCacheTarget(const std::string& path, const std::string& where) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return;  // nothing there (or unreachable: the write says so)
  const std::string refuse = "; a model cache replaces only a furnihost model file (delete it, or name another path)";
  if (S_ISDIR(st.st_mode)) throw InputError(where + path + ": is a directory, cannot write a file there");
  if (!S_ISREG(st.st_mode))
    throw InputError(where + path + ": is not a regular file (FIFO, device or socket)" + refuse);
  const size_t n = sizeof(kModelMagic) - 1;
  char head[sizeof(kModelMagic)] = {};
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(where + path + ": exists and cannot be read" + refuse);
  in.read(head, static_cast<std::streamsize>(n));
  if (static_cast<size_t>(in.gcount()) != n || std::memcmp(head, kModelMagic, n) != 0)
    throw InputError(where + path + ": exists and is not a furnihost model file" + refuse);
}

}  // namespace furnihost
