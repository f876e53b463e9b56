// voters.pcl_ism: PCL's ISM model to and from text, through a temporary file.
#include "model_io.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "furnihost/error.hpp"

namespace furnihost::voters {

namespace {

// A unique temp file, removed when this goes out of scope.
class TempFile {
 public:
  TempFile() {
    std::string pattern = (std::filesystem::temp_directory_path() / "furnihost_pcl_ism_XXXXXX").string();
    const int fd = ::mkstemp(pattern.data());
    if (fd < 0) throw StageError("cannot create a temporary file in " + pattern, false);
    ::close(fd);
    path_ = pattern;
  }
  ~TempFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  std::string& path() { return path_; }

 private:
  std::string path_;
};

}  // namespace

// PCL writes and reads its model only through files.
std::string ModelToText(IsmModel& model) {
  TempFile f;
  if (!model.saveModelToFile(f.path())) throw StageError("ISM: cannot write " + f.path(), false);
  std::ifstream in(f.path());
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::shared_ptr<IsmModel> ModelFromText(const std::string& text) {
  TempFile f;
  {
    std::ofstream out(f.path());
    out << text;
    if (!out) throw StageError("ISM: cannot write " + f.path(), false);
  }
  auto model = std::make_shared<IsmModel>();
  if (!model->loadModelFromfile(f.path())) throw StageError("ISM: cannot read " + f.path(), false);
  return model;
}

// Zeroes what would not survive PCL's text format (NaN, inf); returns how many values changed.
size_t Sanitize(IsmModel& m) {
  size_t fixed = 0;
  for (unsigned w = 0; w < m.number_of_visual_words_; ++w) {
    const bool ok = std::isfinite(m.learned_weights_[w]) && m.directions_to_center_.row(w).allFinite();
    if (ok) continue;
    // A word without a defined direction must not vote: ISM drops votes of weight ~0.
    m.learned_weights_[w] = 0.f;
    m.directions_to_center_.row(w).setZero();
    ++fixed;
  }
  for (auto& per_class : m.statistical_weights_)
    for (float& s : per_class)
      if (!std::isfinite(s)) s = 0.f, ++fixed;
  for (float& s : m.sigmas_)
    if (!std::isfinite(s)) s = 0.f, ++fixed;
  for (Eigen::Index i = 0; i < m.clusters_centers_.size(); ++i)
    if (!std::isfinite(m.clusters_centers_.data()[i])) m.clusters_centers_.data()[i] = 0.f, ++fixed;
  return fixed;
}

}  // namespace furnihost::voters
