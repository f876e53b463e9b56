// Bytes of the values that MPI ranks hand each other (framework/app/mpi_jobs.hpp): a scene's
// detections and records in `furnihost eval`, a catalog model's training views in training.
//
// Exact: floats and doubles travel as their bytes, so what rank 0 gathers is what the rank that
// computed it held, bit for bit (a detection, a normal, a feature), and the gathered run writes
// what one process writes. Every field of each type is written, in declaration order; Reader
// throws InputError("... truncated" / "... corrupt") on bytes that do not parse. Both ends are
// the same build (one binary on every rank), so there is no versioning.
#pragma once
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "furnihost/error.hpp"
#include "furnihost/types.hpp"

namespace furnihost::app::wire {

class Writer {
 public:
  template <class T>
  void Pod(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>, "Pod: trivially copyable types only");
    out_.append(reinterpret_cast<const char*>(&v), sizeof v);
  }
  void Str(const std::string& s) {
    Pod(uint64_t(s.size()));
    out_.append(s);
  }
  template <class T>
  void PodVec(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>, "PodVec: trivially copyable types only");
    Pod(uint64_t(v.size()));
    if (!v.empty()) out_.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  std::string Take() { return std::move(out_); }

 private:
  std::string out_;
};

class Reader {
 public:
  explicit Reader(const std::string& in, std::string what) : in_(in), what_(std::move(what)) {}
  template <class T>
  T Pod() {
    static_assert(std::is_trivially_copyable_v<T>, "Pod: trivially copyable types only");
    T v;
    Need(sizeof v);
    std::memcpy(&v, in_.data() + at_, sizeof v);
    at_ += sizeof v;
    return v;
  }
  std::string Str() {
    const uint64_t n = Count(1);
    std::string s = in_.substr(at_, n);
    at_ += n;
    return s;
  }
  template <class T>
  std::vector<T> PodVec() {
    const uint64_t n = Count(sizeof(T));
    std::vector<T> v(n);
    if (n) std::memcpy(v.data(), in_.data() + at_, n * sizeof(T));
    at_ += n * sizeof(T);
    return v;
  }
  // A count of items of `size` bytes each that the remaining bytes can hold.
  uint64_t Count(size_t size) {
    const uint64_t n = Pod<uint64_t>();
    if (size > 0 && n > (in_.size() - at_) / size) throw InputError(what_ + ": corrupt (a count beyond the data)");
    return n;
  }
  bool Done() const { return at_ == in_.size(); }
  size_t Remaining() const { return in_.size() - at_; }
  // Throws unless every byte was read.
  void End() const {
    if (!Done()) throw InputError(what_ + ": corrupt (" + std::to_string(in_.size() - at_) + " bytes left over)");
  }

 private:
  void Need(size_t n) const {
    if (in_.size() - at_ < n) throw InputError(what_ + ": truncated");
  }
  const std::string& in_;
  std::string what_;
  size_t at_ = 0;
};

// Every field, in declaration order.
void Put(Writer& w, const Detection& d);
Detection GetDetection(Reader& r);
void Put(Writer& w, const std::vector<Detection>& v);
std::vector<Detection> GetDetections(Reader& r);
void Put(Writer& w, const GroundTruthObject& g);
GroundTruthObject GetGroundTruthObject(Reader& r);
void Put(Writer& w, const GroundModel& g);
GroundModel GetGroundModel(Reader& r);
void Put(Writer& w, const ScanFrame& f);
ScanFrame GetScanFrame(Reader& r);
// A scan without its ScanNeighbours (the pipeline finds them per detection; training views
// have none).
void Put(Writer& w, const Scan& s);
Scan GetScan(Reader& r);
void Put(Writer& w, const Segmentation& s);
Segmentation GetSegmentation(Reader& r);
void Put(Writer& w, const FeatureMatrix& f);
FeatureMatrix GetFeatureMatrix(Reader& r);
// A training view without its catalog model pointer (the receiver points it at its own copy).
void Put(Writer& w, const TrainingView& v);
TrainingView GetTrainingView(Reader& r);

}  // namespace furnihost::app::wire
