#include "wire.hpp"

namespace furnihost::app::wire {

namespace {

// Eigen's fixed-size objects are plain arrays of their scalars (no padding): copied as such.
template <class M>
void Fixed(Writer& w, const M& m) {
  for (int i = 0; i < int(m.size()); ++i) w.Pod(m.data()[i]);
}
template <class M>
M GetFixed(Reader& r) {
  M m;
  for (int i = 0; i < int(m.size()); ++i) m.data()[i] = r.Pod<typename M::Scalar>();
  return m;
}
template <class T>
void Iso(Writer& w, const Eigen::Transform<T, 3, Eigen::Isometry>& t) {
  Fixed(w, t.matrix());
}
template <class T>
Eigen::Transform<T, 3, Eigen::Isometry> GetIso(Reader& r) {
  Eigen::Transform<T, 3, Eigen::Isometry> t;
  t.matrix() = GetFixed<Eigen::Matrix<T, 4, 4>>(r);
  return t;
}

void PutPoints(Writer& w, const Points& p) {
  w.Pod(uint64_t(p.size()));
  for (const auto& v : p) Fixed(w, v);
}
Points GetPoints(Reader& r) {
  Points p(r.Count(3 * sizeof(float)));
  for (auto& v : p) v = GetFixed<Eigen::Vector3f>(r);
  return p;
}

template <class T>
void Opt(Writer& w, const std::optional<T>& v) {
  w.Pod(uint8_t(v.has_value()));
  if (v) w.Pod(*v);
}
template <class T>
std::optional<T> GetOpt(Reader& r) {
  if (!r.Pod<uint8_t>()) return std::nullopt;
  return r.Pod<T>();
}

void PutStrings(Writer& w, const std::vector<std::string>& v) {
  w.Pod(uint64_t(v.size()));
  for (const auto& s : v) w.Str(s);
}
std::vector<std::string> GetStrings(Reader& r) {
  std::vector<std::string> v(r.Count(sizeof(uint64_t)));
  for (auto& s : v) s = r.Str();
  return v;
}

void Put(Writer& w, const OrientedBox& b) {
  Fixed(w, b.center);
  Fixed(w, b.size);
  w.Pod(b.yaw);
}
OrientedBox GetBox(Reader& r) {
  OrientedBox b;
  b.center = GetFixed<Eigen::Vector3f>(r);
  b.size = GetFixed<Eigen::Vector3f>(r);
  b.yaw = r.Pod<float>();
  return b;
}

}  // namespace

void Put(Writer& w, const Detection& d) {
  w.Str(d.cls);
  Fixed(w, d.center);
  w.Pod(d.yaw);
  w.Pod(d.score);
  Opt(w, d.confidence);
  w.Str(d.model);
  Opt(w, d.verified);
  Opt(w, d.coverage);
  Opt(w, d.free_space_ratio);
  Opt(w, d.rms);
  w.Pod(d.iterations);
  w.Pod(uint64_t(d.checks.size()));
  for (const Check& c : d.checks) {
    w.Str(c.name);
    w.Pod(c.value);
    w.Pod(c.limit);
    w.Pod(c.at_least);
    w.Pod(c.passed);
  }
  PutStrings(w, d.notes);
  w.PodVec(d.support);
  Iso(w, d.model_pose);
  w.Pod(uint8_t(d.box.has_value()));
  if (d.box) Put(w, *d.box);
  w.Str(d.box_source);
  w.Pod(d.proposal);
  w.Pod(d.proposal_scene);
  w.Pod(uint64_t(d.evidence.size()));
  for (const auto& [k, v] : d.evidence) w.Str(k), w.Pod(v);
  w.Str(d.chain);
}

Detection GetDetection(Reader& r) {
  Detection d;
  d.cls = r.Str();
  d.center = GetFixed<Eigen::Vector3f>(r);
  d.yaw = r.Pod<float>();
  d.score = r.Pod<float>();
  d.confidence = GetOpt<float>(r);
  d.model = r.Str();
  d.verified = GetOpt<bool>(r);
  d.coverage = GetOpt<float>(r);
  d.free_space_ratio = GetOpt<float>(r);
  d.rms = GetOpt<float>(r);
  d.iterations = r.Pod<int>();
  d.checks.resize(r.Count(sizeof(uint64_t)));
  for (Check& c : d.checks) {
    c.name = r.Str();
    c.value = r.Pod<double>();
    c.limit = r.Pod<double>();
    c.at_least = r.Pod<bool>();
    c.passed = r.Pod<bool>();
  }
  d.notes = GetStrings(r);
  d.support = r.PodVec<Support>();
  d.model_pose = GetIso<float>(r);
  if (r.Pod<uint8_t>()) d.box = GetBox(r);
  d.box_source = r.Str();
  d.proposal = r.Pod<int>();
  d.proposal_scene = r.Pod<int>();
  for (uint64_t n = r.Count(sizeof(uint64_t)), i = 0; i < n; ++i) {
    std::string k = r.Str();
    d.evidence[k] = r.Pod<float>();
  }
  d.chain = r.Str();
  return d;
}

void Put(Writer& w, const std::vector<Detection>& v) {
  w.Pod(uint64_t(v.size()));
  for (const auto& d : v) Put(w, d);
}
std::vector<Detection> GetDetections(Reader& r) {
  std::vector<Detection> v(r.Count(sizeof(uint64_t)));
  for (auto& d : v) d = GetDetection(r);
  return v;
}

void Put(Writer& w, const GroundTruthObject& g) {
  w.Str(g.cls);
  Fixed(w, g.center);
  Fixed(w, g.size);
  Opt(w, g.yaw);
  w.Str(g.model);
  Opt(w, g.yaw_symmetry);
}
GroundTruthObject GetGroundTruthObject(Reader& r) {
  GroundTruthObject g;
  g.cls = r.Str();
  g.center = GetFixed<Eigen::Vector3f>(r);
  g.size = GetFixed<Eigen::Vector3f>(r);
  g.yaw = GetOpt<float>(r);
  g.model = r.Str();
  g.yaw_symmetry = GetOpt<int>(r);
  return g;
}

void Put(Writer& w, const GroundModel& g) {
  w.Pod(g.kind);
  w.Str(g.source);
  w.Pod(g.plane);
  Fixed(w, g.origin);
  w.Pod(g.cell);
  w.Pod(g.width);
  w.Pod(g.height);
  w.PodVec(g.heights);
  w.PodVec(g.observed);
  w.Pod(g.observed_area_m2);
}
GroundModel GetGroundModel(Reader& r) {
  GroundModel g;
  g.kind = r.Pod<GroundKind>();
  g.source = r.Str();
  g.plane = r.Pod<FloorPlane>();
  g.origin = GetFixed<Eigen::Vector2f>(r);
  g.cell = r.Pod<float>();
  g.width = r.Pod<int>();
  g.height = r.Pod<int>();
  g.heights = r.PodVec<float>();
  g.observed = r.PodVec<uint8_t>();
  g.observed_area_m2 = r.Pod<float>();
  return g;
}

void Put(Writer& w, const ScanFrame& f) {
  Fixed(w, f.shift);
  Iso(w, f.to_upright);
  Iso(w, f.canonical);
  w.Str(f.up);
}
ScanFrame GetScanFrame(Reader& r) {
  ScanFrame f;
  f.shift = GetFixed<Eigen::Vector3d>(r);
  f.to_upright = GetIso<double>(r);
  f.canonical = GetIso<double>(r);
  f.up = r.Str();
  return f;
}

void Put(Writer& w, const Scan& s) {
  w.Str(s.source);
  PutPoints(w, s.points);
  w.Pod(uint8_t(s.origin.has_value()));
  if (s.origin) Fixed(w, *s.origin);
  Iso(w, s.pose);
  Put(w, s.frame);
  w.Pod(uint8_t(s.ground.has_value()));
  if (s.ground) Put(w, *s.ground);
  w.Pod(uint64_t(s.truth.size()));
  for (const auto& g : s.truth) Put(w, g);
  w.Pod(uint64_t(s.attributes.size()));
  for (const auto& [k, v] : s.attributes) w.Str(k), w.PodVec(v);
  w.PodVec(s.colors);
}
Scan GetScan(Reader& r) {
  Scan s;
  s.source = r.Str();
  s.points = GetPoints(r);
  if (r.Pod<uint8_t>()) s.origin = GetFixed<Eigen::Vector3f>(r);
  s.pose = GetIso<float>(r);
  s.frame = GetScanFrame(r);
  if (r.Pod<uint8_t>()) s.ground = GetGroundModel(r);
  s.truth.resize(r.Count(sizeof(uint64_t)));
  for (auto& g : s.truth) g = GetGroundTruthObject(r);
  for (uint64_t n = r.Count(sizeof(uint64_t)), i = 0; i < n; ++i) {
    std::string k = r.Str();
    s.attributes[k] = r.PodVec<int32_t>();
  }
  s.colors = r.PodVec<std::array<uint8_t, 3>>();
  return s;
}

void Put(Writer& w, const Segmentation& s) {
  PutPoints(w, s.normals);
  w.PodVec(s.curvature);
  w.Pod(uint64_t(s.parts.size()));
  for (const Part& p : s.parts) {
    w.PodVec(p.indices);
    Fixed(w, p.centroid);
  }
  w.Pod(s.discarded_points);
}
Segmentation GetSegmentation(Reader& r) {
  Segmentation s;
  s.normals = GetPoints(r);
  s.curvature = r.PodVec<float>();
  s.parts.resize(r.Count(sizeof(uint64_t)));
  for (Part& p : s.parts) {
    p.indices = r.PodVec<int>();
    p.centroid = GetFixed<Eigen::Vector3f>(r);
  }
  s.discarded_points = r.Pod<int>();
  return s;
}

void Put(Writer& w, const FeatureMatrix& f) {
  w.Pod(int64_t(f.values.rows()));
  w.Pod(int64_t(f.values.cols()));
  for (Eigen::Index i = 0; i < f.values.size(); ++i) w.Pod(f.values.data()[i]);
  PutStrings(w, f.names);
  w.Pod(int64_t(f.excess.size()));
  for (Eigen::Index i = 0; i < f.excess.size(); ++i) w.Pod(f.excess[i]);
}
FeatureMatrix GetFeatureMatrix(Reader& r) {
  FeatureMatrix f;
  const int64_t rows = r.Pod<int64_t>(), cols = r.Pod<int64_t>();
  if (rows < 0 || cols < 0 || (cols > 0 && uint64_t(rows) > r.Remaining() / sizeof(float) / uint64_t(cols)))
    throw InputError("feature matrix: corrupt shape");
  f.values.resize(rows, cols);
  for (Eigen::Index i = 0; i < f.values.size(); ++i) f.values.data()[i] = r.Pod<float>();
  f.names = GetStrings(r);
  const int64_t n = r.Pod<int64_t>();
  if (n < 0 || uint64_t(n) > r.Remaining() / sizeof(float)) throw InputError("feature matrix: corrupt excess");
  f.excess.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) f.excess[i] = r.Pod<float>();
  return f;
}

void Put(Writer& w, const TrainingView& v) {
  w.Str(v.cls);
  w.Str(v.model_id);
  w.Pod(v.view);
  Fixed(w, v.object_centroid);
  Fixed(w, v.object_size);
  Put(w, v.scan);
  Put(w, v.segmentation);
  Put(w, v.features);
}
TrainingView GetTrainingView(Reader& r) {
  TrainingView v;
  v.cls = r.Str();
  v.model_id = r.Str();
  v.view = r.Pod<int>();
  v.object_centroid = GetFixed<Eigen::Vector3f>(r);
  v.object_size = GetFixed<Eigen::Vector3f>(r);
  v.scan = GetScan(r);
  v.segmentation = GetSegmentation(r);
  v.features = GetFeatureMatrix(r);
  return v;
}

}  // namespace furnihost::app::wire
