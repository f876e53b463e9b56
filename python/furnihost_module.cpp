// furnihost._furnihost: the native part of the Python module. A graph runs through
// furnihost::Detector, the engine `furnihost detect` and `eval` run, and a detection's record is
// DetectionToJson's, so Python and the command line give the same detections of the same scan.
// Arrays come in as numpy (N, 3) float32 / float64 and are checked here; errors of the input
// (InputError, a stage's input error) raise ValueError with the command line's one-line message,
// everything else RuntimeError. The GIL is released while a graph loads, trains, detects and
// evaluates. furnihost/__init__.py wraps this module (Detection, Open3D interop).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "furnihost/geometry.hpp"
#include "furnihost/host/detections.hpp"
#include "furnihost/host/detector.hpp"
#include "furnihost/host/frame.hpp"
#include "furnihost/host/io.hpp"
#include "furnihost/log.hpp"
#include "furnihost/scan_reader.hpp"

namespace py = pybind11;
using nlohmann::json;

namespace furnihost {
namespace {

// JSON as Python objects. Non-finite numbers become None, as in the JSON files the command line
// writes (nlohmann writes them as null), so a record equals its detections.json entry.
py::object ToPython(const json& j) {
  switch (j.type()) {
    case json::value_t::null: return py::none();
    case json::value_t::boolean: return py::bool_(j.get<bool>());
    case json::value_t::number_integer: return py::int_(j.get<int64_t>());
    case json::value_t::number_unsigned: return py::int_(j.get<uint64_t>());
    case json::value_t::number_float: {
      const double v = j.get<double>();
      return std::isfinite(v) ? py::object(py::float_(v)) : py::object(py::none());
    }
    case json::value_t::string: return py::str(j.get_ref<const std::string&>());
    case json::value_t::array: {
      py::list l(j.size());
      for (size_t i = 0; i < j.size(); ++i) l[i] = ToPython(j[i]);
      return std::move(l);
    }
    case json::value_t::object: {
      py::dict d;
      for (auto it = j.begin(); it != j.end(); ++it) d[py::str(it.key())] = ToPython(it.value());
      return std::move(d);
    }
    default: return py::none();
  }
}

std::string TypeName(const py::handle& h) { return py::str(py::type::handle_of(h).attr("__name__")); }

std::string DtypeName(const py::dtype& dt) { return py::str(dt.attr("name")); }

std::string Shape(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k) s += (k ? ", " : "") + std::to_string(a.shape(k));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

// A number as text that parses back to the same double.
std::string Exact(double v) {
  std::ostringstream o;
  o.precision(17);
  o << v;
  return o.str();
}

// points: a numpy (N, 3) float32 / float64 array, checked, as 3 N doubles.
std::vector<double> PointsOf(const py::handle& points) {
  if (!py::isinstance<py::array>(points))
    throw InputError("points: expected a numpy array of shape (N, 3), float32 or float64 (or an "
                     "open3d.geometry.PointCloud, or a scan file's path), got " + TypeName(points));
  const py::array a = py::reinterpret_borrow<py::array>(points);
  const py::dtype dt = a.dtype();
  if (dt.kind() != 'f' || (dt.itemsize() != 4 && dt.itemsize() != 8))
    throw InputError("points: expected a float32 or float64 array, got " + DtypeName(dt) +
                     " (convert with points.astype(numpy.float64))");
  if (a.ndim() != 2 || a.shape(1) != 3) throw InputError("points: expected shape (N, 3), got " + Shape(a));
  const size_t n = static_cast<size_t>(a.shape(0));
  if (n == 0) throw InputError("points: the array is empty (shape (0, 3)): there is nothing to detect in");
  std::vector<double> xyz(3 * n);
  auto fill = [&](auto view) {
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) xyz[3 * i + size_t(k)] = static_cast<double>(view(py::ssize_t(i), k));
  };
  if (dt.itemsize() == 4) fill(py::array_t<float>(a).unchecked<2>());
  else fill(py::array_t<double>(a).unchecked<2>());
  size_t bad = 0, first = n;
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(xyz[3 * i]) || !std::isfinite(xyz[3 * i + 1]) || !std::isfinite(xyz[3 * i + 2])) {
      if (!bad++) first = i;
    }
  if (bad)
    throw InputError("points: row " + std::to_string(first) + " is not finite (" + Exact(xyz[3 * first]) + ", " +
                     Exact(xyz[3 * first + 1]) + ", " + Exact(xyz[3 * first + 2]) + "), " + std::to_string(bad) +
                     " of " + std::to_string(n) +
                     " rows are: drop them first (points[numpy.isfinite(points).all(axis=1)])");
  return xyz;
}

// colors: None, or (N, 3) uint8 (0-255) or float (0-1, Open3D's), as 3 N bytes.
std::vector<uint8_t> ColorsOf(const py::handle& colors, size_t n) {
  if (colors.is_none()) return {};
  if (!py::isinstance<py::array>(colors))
    throw InputError("colors: expected a numpy array of shape (N, 3), uint8 or float in [0, 1], got " + TypeName(colors));
  const py::array a = py::reinterpret_borrow<py::array>(colors);
  if (a.ndim() != 2 || a.shape(1) != 3 || static_cast<size_t>(a.shape(0)) != n)
    throw InputError("colors: expected shape (" + std::to_string(n) + ", 3), one row per point, got " + Shape(a));
  std::vector<uint8_t> rgb(3 * n);
  const py::dtype dt = a.dtype();
  if (dt.kind() == 'u' && dt.itemsize() == 1) {
    const auto v = py::array_t<uint8_t>(a).unchecked<2>();
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) rgb[3 * i + size_t(k)] = v(py::ssize_t(i), k);
  } else if (dt.kind() == 'f') {
    const auto v = py::array_t<double>(a).unchecked<2>();
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        const double c = v(py::ssize_t(i), k);
        if (!(c >= 0.0 && c <= 1.0))
          throw InputError("colors: row " + std::to_string(i) + " holds " + Exact(c) + ": float colours lie in [0, 1]");
        rgb[3 * i + size_t(k)] = static_cast<uint8_t>(std::lround(c * 255.0));
      }
  } else {
    throw InputError("colors: expected uint8 (0-255) or float (0-1), got " + DtypeName(dt));
  }
  return rgb;
}

// A sequence of numbers (or a numpy array of any shape) flattened, each finite.
std::vector<double> Numbers(const py::handle& h, const std::string& what) {
  py::array a;
  try {
    a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(h);
  } catch (const py::error_already_set&) {
  }
  if (!a) throw InputError(what + ": expected numbers, got " + TypeName(h));
  std::vector<double> v(static_cast<size_t>(a.size()));
  const double* p = static_cast<const double*>(a.data());
  for (size_t i = 0; i < v.size(); ++i) {
    v[i] = p[i];
    if (!std::isfinite(v[i])) throw InputError(what + ": value " + std::to_string(i) + " is not finite");
  }
  return v;
}

std::optional<Eigen::Vector3f> OriginOf(const py::handle& origin) {
  if (origin.is_none()) return std::nullopt;
  const std::vector<double> v = Numbers(origin, "origin");
  if (v.size() != 3) throw InputError("origin: expected 3 numbers (x, y, z), got " + std::to_string(v.size()));
  return Eigen::Vector3f(float(v[0]), float(v[1]), float(v[2]));
}

// up / transform as the command line's --up / --transform.
FrameOptions FrameOf(const std::string& up, const py::handle& transform) {
  FrameOptions f;
  f.up = up;
  if (up != "auto") UpAxisRotation(up, "up");  // validates
  if (transform.is_none()) return f;
  if (up != "+z") throw InputError("transform: give either up or transform, not both");
  std::string text;
  if (py::isinstance<py::str>(transform)) {
    text = transform.cast<std::string>();
  } else {
    for (double x : Numbers(transform, "transform")) text += (text.empty() ? "" : ",") + Exact(x);
  }
  f.transform = ParseTransform(text, "transform");
  return f;
}

// A graph loaded once, run many times. One call at a time per graph (Pipeline::Detect is not
// reentrant): the lock is taken without the GIL, so other Python threads go on meanwhile.
class Graph {
 public:
  Graph(const std::string& path, const std::vector<std::string>& sets, const std::vector<std::string>& plugin_paths,
        std::optional<uint64_t> seed, bool strict, bool retrain) {
    py::gil_scoped_release release;
    auto registry = std::make_shared<const Registry>(Registry::DefaultSearchPath(plugin_paths));
    GraphConfig g = LoadGraph(path, *registry, sets);
    RunContext ctx;
    ctx.seed = seed.value_or(g.seed);
    DetectorOptions options;
    options.strict_catalog = strict;
    options.retrain = retrain;
    detector_ = std::make_unique<Detector>(std::move(g), std::move(registry), ctx, options);
    // The catalog and the model load on a worker from now on, while the caller reads its scan
    // (the command line overlaps them with reading the scan too); their errors come with the
    // first train, detect or evaluate.
    detector_->StartLoading();
  }

  py::object Config() const { return ToPython(detector_->Graph().resolved); }
  std::string Path() const { return detector_->Graph().path; }
  uint64_t Seed() const { return detector_->Context().seed; }

  py::object Train() {
    json summary;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mu_);
      summary = detector_->Train().summary;
    }
    return ToPython(summary);
  }

  // The detections.json document of a detection in `points` (an array, or a scan file's path).
  py::object Detect(const py::object& points, const py::object& colors, const py::object& origin, const std::string& up,
                    const py::object& transform) {
    Pipeline::SceneInput in;
    in.origin = OriginOf(origin);
    in.frame = FrameOf(up, transform);
    std::vector<double> xyz;
    std::vector<uint8_t> rgb;
    if (py::isinstance<py::str>(points)) {
      in.path = points.cast<std::string>();
      RequireRegularFile(in.path, "scan file");
      if (!colors.is_none()) throw InputError("colors: given with a scan file, which has its own");
    } else {
      xyz = PointsOf(points);
      rgb = ColorsOf(colors, xyz.size() / 3);
      in.path = "points";
    }
    json doc;
    {
      py::gil_scoped_release release;
      if (!xyz.empty())
        in.scan = std::make_shared<const Scan>(
            ScanFromPoints(in.path, xyz.data(), xyz.size() / 3, rgb.empty() ? nullptr : rgb.data(), nullptr, in.frame.shift));
      std::lock_guard<std::mutex> lock(mu_);
      Stopwatch total;
      const std::vector<Pipeline::SceneInput> scenes{in};
      const Pipeline::Result r = detector_->Detect(scenes);
      doc = DetectionsDocument(r, scenes, detector_->Graph().path, detector_->Context().seed,
                               detector_->MissingStages(), total.Ms());
    }
    return ToPython(doc);
  }

  // What summary.json of `furnihost eval --graph <this> --dataset <dataset>` holds (without the
  // git and machine records).
  py::object Evaluate(const std::string& dataset_path, int seeds, const std::string& width, int jobs, double jitter,
                      const std::string& name) {
    const std::optional<WidthConvention> w = ParseWidthConvention(width);
    if (!w) throw InputError("width: expected \"max\" or \"min\", got '" + width + "'");
    if (seeds < 1 || seeds > 1000) throw InputError("seeds: expected 1 to 1000, got " + std::to_string(seeds));
    if (!(jitter >= 0.0 && jitter <= 0.05)) throw InputError("jitter: expected 0 to 0.05 m, got " + Exact(jitter));
    if (jobs < 0) throw InputError("jobs: expected 0 (as cores allow) or more, got " + std::to_string(jobs));
    json summary;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mu_);
      const Dataset dataset = LoadDataset(dataset_path);
      std::vector<std::vector<GroundTruthObject>> truth;
      for (const auto& s : dataset.scenes) truth.push_back(ReadGroundTruth(s.gt));
      const std::string hash = HashDataset(dataset);
      EvalRunInput in;
      in.dataset = &dataset;
      in.truth = &truth;
      in.width = *w;
      in.jobs = jobs;
      in.jitter_m = jitter;
      ConfigSummary config;
      config.name = in.name = name.empty() ? std::filesystem::path(detector_->Graph().path).stem().string() : name;
      config.graph = detector_->Graph().path;
      Stopwatch model_clock;
      detector_->WaitLoaded();
      const double model_ms = model_clock.Ms();
      for (int k = 0; k < seeds; ++k) {
        config.runs.push_back(detector_->Evaluate(in, detector_->Context().seed + uint64_t(k)));
        config.runs.back().model_ms = model_ms;
      }
      summary = EvalSummaryJson(dataset, hash, *w, {config});
    }
    return ToPython(summary);
  }

 private:
  std::unique_ptr<Detector> detector_;
  std::mutex mu_;
};

// (points in the file's coordinates, float64 (N, 3); colours uint8 (N, 3) or None; the sensor
// origin or None), read with the command line's readers.
py::tuple ReadScanArrays(const std::string& path) {
  Scan scan;
  {
    py::gil_scoped_release release;
    scan = ReadScan(path);
  }
  const size_t n = scan.points.size();
  py::array_t<double> points({py::ssize_t(n), py::ssize_t(3)});
  auto p = points.mutable_unchecked<2>();
  const Eigen::Vector3d& shift = scan.frame.shift;
  for (size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) p(py::ssize_t(i), k) = double(scan.points[i][k]) + shift[k];
  py::object colors = py::none();
  if (scan.colors.size() == n) {
    py::array_t<uint8_t> c({py::ssize_t(n), py::ssize_t(3)});
    auto cv = c.mutable_unchecked<2>();
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) cv(py::ssize_t(i), k) = scan.colors[i][size_t(k)];
    colors = std::move(c);
  }
  py::object origin = py::none();
  if (scan.origin) {
    py::array_t<double> o(3);
    for (int k = 0; k < 3; ++k) o.mutable_at(k) = double((*scan.origin)[k]) + shift[k];
    origin = std::move(o);
  }
  return py::make_tuple(std::move(points), std::move(colors), std::move(origin));
}

}  // namespace
}  // namespace furnihost

PYBIND11_MODULE(_furnihost, m) {
  using namespace furnihost;
  m.doc() = "furnihost's native part: graphs run through the engine of the furnihost command line";
  // Warnings and errors only: a library keeps quiet unless asked (set_log_level).
  SetupLogging(0);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      PyErr_SetString(PyExc_ValueError, OneLine(e.what()).c_str());
    } catch (const StageError& e) {
      PyErr_SetString(e.IsInputError() ? PyExc_ValueError : PyExc_RuntimeError, OneLine(e.what()).c_str());
    } catch (const std::filesystem::filesystem_error& e) {
      PyErr_SetString(PyExc_OSError, OneLine(e.what()).c_str());
    }
  });
  m.attr("__version__") = FURNIHOST_PYTHON_VERSION;
  m.def("set_log_level", &SetupLogging, py::arg("verbosity"),
        "Log to stderr: 0 warnings and errors (the default), 1 progress (the command line's), 2 debug.");
  m.def("read_scan", &ReadScanArrays, py::arg("path"));
  m.def("class_color", &ClassColor, py::arg("name"));
  m.def("share_dir", &ShareDir);
  m.def("default_graph", &DefaultGraph, py::arg("has_origin"));
  py::class_<Graph>(m, "Graph")
      .def(py::init<const std::string&, const std::vector<std::string>&, const std::vector<std::string>&,
                    std::optional<uint64_t>, bool, bool>(),
           py::arg("path"), py::arg("sets"), py::arg("plugin_paths"), py::arg("seed"), py::arg("strict"),
           py::arg("retrain"))
      .def_property_readonly("config", &Graph::Config)
      .def_property_readonly("path", &Graph::Path)
      .def_property_readonly("seed", &Graph::Seed)
      .def("train", &Graph::Train)
      .def("detect", &Graph::Detect, py::arg("points"), py::arg("colors"), py::arg("origin"), py::arg("up"),
           py::arg("transform"))
      .def("evaluate", &Graph::Evaluate, py::arg("dataset"), py::arg("seeds"), py::arg("width"), py::arg("jobs"),
           py::arg("jitter"), py::arg("name"));
}
