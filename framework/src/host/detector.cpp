#include "furnihost/host/detector.hpp"

#include <spdlog/spdlog.h>

#include <filesystem>
#include <optional>

#include "furnihost/host/detections.hpp"
#include "furnihost/host/frame.hpp"
#include "furnihost/host/model_cache.hpp"

namespace fs = std::filesystem;

namespace furnihost {

Detector::Detector(GraphConfig graph, std::shared_ptr<const Registry> registry, const RunContext& ctx,
                   const DetectorOptions& options)
    : graph_(std::move(graph)), registry_(std::move(registry)), ctx_(ctx), options_(options), pipeline_(graph_, *registry_) {
  if (!pipeline_.HasDetectionChain()) return;
  if (const auto& c = graph_.calibration_map)
    spdlog::info("calibration: {} ({} classes); detections accepted at confidence >= {}", c->Path(),
                 c->Classes().size(), graph_.calibration.min_confidence);
  else
    spdlog::info("no calibration in {}: detections carry no confidence and the stages' thresholds decide "
                 "(docs/calibration.md)",
                 graph_.path);
}

Detector::~Detector() {
  try {
    loading_group_.wait();
  } catch (...) {  // the loading's own error: Load keeps it, but nothing may escape here
  }
}

TrainedModel Detector::Ensure(const RunContext& train, bool force) {
  return options_.ensure_model ? options_.ensure_model(pipeline_, catalog_, train, force)
                               : EnsureModel(pipeline_, catalog_, train, force);
}

void Detector::Load() {
  catalog_ = LoadCatalog(graph_.catalog, options_.strict_catalog);
  const std::string& cache = graph_.model_cache;
  std::error_code ec;
  std::optional<fs::file_time_type> before;
  if (!cache.empty() && fs::exists(cache, ec)) before = fs::last_write_time(cache, ec);
  // The model is the graph's: trained with the graph's seed (its cache is keyed by it), whatever
  // seed the detections use.
  RunContext train = ctx_;
  train.seed = graph_.seed;
  model_ = Ensure(train, options_.retrain);
  model_source_ = before && fs::exists(cache, ec) && fs::last_write_time(cache, ec) == *before ? "cache" : "trained";
}

void Detector::StartLoading() {
  if (loaded_ || loading_ || !HasDetectionChain()) return;
  loading_ = true;
  load_error_ = nullptr;
  loading_group_.run([this] {
    try {
      Load();
    } catch (...) {
      load_error_ = std::current_exception();
    }
  });
}

void Detector::WaitLoaded() {
  if (loaded_ || !HasDetectionChain()) return;
  StartLoading();
  loading_group_.wait();
  loading_ = false;
  if (load_error_) std::rethrow_exception(std::exchange(load_error_, nullptr));
  loaded_ = true;
}

const Catalog& Detector::GetCatalog() {
  WaitLoaded();
  return catalog_;
}

const TrainedModel& Detector::GetModel() {
  WaitLoaded();
  return model_;
}

const TrainedModel& Detector::Train() {
  if (!HasDetectionChain()) throw InputError(graph_.path + ": training needs a voter stage");
  if (loading_) WaitLoaded();  // a loading under way ends first (its error is thrown)
  // A model this detector's loading has just trained (no valid cache) is the one training again
  // would give: training is deterministic for the graph's seed.
  if (loaded_ && model_source_ == "trained") return model_;
  if (!loaded_) catalog_ = LoadCatalog(graph_.catalog, options_.strict_catalog);
  RunContext train = ctx_;
  train.seed = graph_.seed;
  model_ = Ensure(train, true);
  model_source_ = "trained";
  loaded_ = true;
  return model_;
}

Pipeline::Result Detector::Detect(const std::vector<Pipeline::SceneInput>& scenes) {
  const bool chain = HasDetectionChain();
  StartLoading();
  Pipeline::Result r = pipeline_.Detect(scenes, chain ? &model_ : nullptr, chain ? &catalog_ : nullptr, ctx_,
                                        [this] { WaitLoaded(); });
  WaitLoaded();  // Detect returns before its stages on a scan with no points
  return r;
}

nlohmann::json DetectionsDocument(const Pipeline::Result& r, const std::vector<Pipeline::SceneInput>& scenes,
                                  const std::string& graph, uint64_t seed, const std::vector<std::string>& missing,
                                  double total_ms) {
  nlohmann::json j;
  j["scan"] = scenes.size() == 1 ? nlohmann::json(scenes.front().path) : nlohmann::json(nlohmann::json::array());
  if (scenes.size() > 1)
    for (const auto& in : scenes) j["scan"].push_back(in.path);
  j["graph"] = graph;
  j["seed"] = seed;
  size_t points = 0, parts = 0;
  for (const auto& s : r.scans) points += s.points.size();
  for (const auto& s : r.segmentations) parts += s.parts.size();
  j["points"] = points;
  j["parts"] = parts;
  j["stages_run"] = nlohmann::json::array();
  for (const auto& [tag, ms] : r.timings_ms) j["stages_run"].push_back(tag);
  if (!missing.empty()) j["missing_stages"] = missing;
  // Geometry is written in the (first) scan's file frame; the frames and grounds say how.
  const Scan* frame_scan = r.scans.empty() ? nullptr : &r.scans.front();
  j["frames"] = nlohmann::json::array();
  j["ground"] = nlohmann::json::array();
  for (const auto& s : r.scans) {
    j["frames"].push_back(ToJson(s.frame));
    j["ground"].push_back(s.ground ? ToJson(*s.ground) : nlohmann::json(nullptr));
  }
  // Several sinks (GraphConfig::Sinks): each detection names its own in "chain".
  if (r.sinks.size() > 1) j["sinks"] = r.sinks;
  j["detections"] = nlohmann::json::array();
  for (const auto& d : r.detections) j["detections"].push_back(DetectionToJson(d, frame_scan));
  j["timings_ms"] = nlohmann::json::object();
  for (const auto& [tag, ms] : r.timings_ms) j["timings_ms"][tag] = ms;
  j["timings_ms"]["total"] = total_ms;
  return j;
}

std::string OneLine(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    const int len = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    bool ok = len > 0 && i + len <= s.size();
    for (int k = 1; ok && k < len; ++k) ok = (static_cast<unsigned char>(s[i + k]) & 0xC0) == 0x80;
    if (!ok) {
      out += '?';
      ++i;
    } else if (len == 1) {
      out += (c < 0x20 || c == 0x7F) ? ' ' : static_cast<char>(c);
      ++i;
    } else {
      out.append(s, i, len);
      i += len;
    }
  }
  return out;
}

std::string ShareDir() {
  std::error_code ec;
  const std::string lib = HostLibraryDir();
  if (!lib.empty()) {
    const fs::path installed = fs::path(lib) / ".." / "share" / "furnihost";
    if (fs::is_directory(installed / "configs", ec)) return fs::weakly_canonical(installed, ec).string();
  }
  if (fs::is_directory(fs::path(FURNIHOST_SOURCE_TREE) / "configs", ec)) return FURNIHOST_SOURCE_TREE;
  return "";
}

std::string DefaultGraph(bool has_origin) {
  const std::string name = has_origin ? "laser_room.json" : "room.json";
  const std::string share = ShareDir();
  if (share.empty())
    throw InputError("no --graph given and no shipped configs found (looked for share/furnihost/configs beside " +
                     HostLibraryDir() + " and configs/ in " + FURNIHOST_SOURCE_TREE + "); give --graph G.json");
  const std::string path = (fs::path(share) / "configs" / name).string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw InputError("no --graph given and the default graph " + path + " is missing; give --graph G.json");
  return path;
}

}  // namespace furnihost
