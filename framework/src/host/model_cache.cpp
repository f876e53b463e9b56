#include "furnihost/host/model_cache.hpp"

#include <spdlog/spdlog.h>

#include <sys/stat.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "furnihost/log.hpp"
#include "furnihost/host/pipeline.hpp"

namespace fs = std::filesystem;

namespace furnihost {

namespace {
nlohmann::json StageKey(const StageConfig* s) {
  if (!s) return nullptr;
  return {{"type", s->type}, {"version", s->version},
          {"params", s->training_params.is_null() ? s->params : s->training_params}};
}
}  // namespace

nlohmann::json TrainingKey(const GraphConfig& g) {
  const StageConfig* tr = g.training_sensor.empty() ? nullptr : g.Find(g.training_sensor);
  nlohmann::json voters = nlohmann::json::object();
  for (const StageConfig* v : g.Trained())
    voters[v->tag] = {{"segmenter", StageKey(g.SegmenterOf(*v))},
                      {"features", StageKey(g.Input(*v, InputRole::Features))},
                      {"voter", StageKey(v)}};
  return {{"seed", g.seed}, {"training_sensor", StageKey(tr)}, {"voters", voters}};
}

std::string Incompatibility(const TrainedModel& m, const GraphConfig& g, const std::string& catalog_hash) {
  if (m.catalog_hash != catalog_hash) return "the catalog changed (hash " + m.catalog_hash + " -> " + catalog_hash + ")";
  nlohmann::json want = TrainingKey(g);
  // A version 1 file of one voter did not write its tag: it is the one voter's.
  if (m.voters.size() == 1 && m.voters.count("") && want["voters"].size() == 1)
    want["voters"] = {{"", want["voters"].begin().value()}};
  for (auto it = want.begin(); it != want.end(); ++it) {
    if (!m.training_config.contains(it.key()) || m.training_config[it.key()] != it.value()) {
      const nlohmann::json have = m.training_config.value(it.key(), nlohmann::json());
      nlohmann::json diff = nlohmann::json::diff(have, it.value());
      std::string d = diff.dump();
      if (d.size() > 200) d = d.substr(0, 197) + "...";
      return "'" + it.key() + "' differs from the model's: " + d;
    }
  }
  return "";
}

// A graph's model_cache (or `train --out`) may name a model file or nothing yet. A graph from
// elsewhere that names ~/.bashrc as its cache gets an error, never that file replaced by a model.
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

TrainedModel EnsureModel(Pipeline& p, const Catalog& catalog, const RunContext& ctx, bool force) {
  const std::string cache = p.Graph().model_cache;
  if (!cache.empty()) CheckModelCacheTarget(cache, p.Graph().path + ":/model_cache: ");
  if (!force && !cache.empty() && fs::exists(cache)) {
    try {
      TrainedModel m = LoadModel(cache);
      std::string why = Incompatibility(m, p.Graph(), catalog.hash);
      if (why.empty()) {
        spdlog::info("model: using cached {}", cache);
        return m;
      }
      spdlog::warn("model: cached {} is stale: {}; retraining", cache, why);
    } catch (const InputError& e) {
      spdlog::warn("model: {}; retraining", e.what());
    }
  }
  spdlog::info("model: training from {} ({} models)", catalog.path, catalog.models.size());
  Stopwatch sw;
  TrainedModel m = p.Train(catalog, ctx);
  spdlog::info("model: trained in {:.1f} s: {}", sw.Ms() / 1000.0, m.summary.dump());
  if (!cache.empty()) {
    SaveModel(cache, m);
    spdlog::info("model: written to {}", cache);
  }
  return m;
}

}  // namespace furnihost
