#include "mpi_train.hpp"

#include <algorithm>
#include <optional>
#include <stdexcept>

#include "furnihost/log.hpp"
#include "mpi_jobs.hpp"
#include "wire.hpp"

namespace furnihost::app {

namespace {

std::string Encode(const ModelViews& mv) {
  wire::Writer w;
  w.Pod(uint64_t(mv.time_ms.size()));
  for (const auto& [tag, ms] : mv.time_ms) w.Str(tag), w.Pod(ms);
  w.Pod(uint64_t(mv.branches.size()));
  for (const auto& views : mv.branches) {
    w.Pod(uint64_t(views.size()));
    for (const auto& v : views) wire::Put(w, v);
  }
  return w.Take();
}

ModelViews Decode(const std::string& bytes, const std::string& what) {
  wire::Reader r(bytes, what);
  ModelViews mv;
  for (uint64_t k = 0, n = r.Count(sizeof(uint64_t)); k < n; ++k) {
    std::string tag = r.Str();
    mv.time_ms[tag] = r.Pod<double>();
  }
  mv.branches.resize(r.Count(sizeof(uint64_t)));
  for (auto& views : mv.branches) {
    views.resize(r.Count(sizeof(uint64_t)));
    for (auto& v : views) v = wire::GetTrainingView(r);
  }
  r.End();
  return mv;
}

std::string Encode(const TrainedRun& run) {
  nlohmann::json counts = nlohmann::json::array();
  for (const auto& per_class : run.counts) {
    nlohmann::json c = nlohmann::json::object();
    for (const auto& [cls, n] : per_class) c[cls] = {n.views, n.parts, n.meshes};
    counts.push_back(std::move(c));
  }
  const nlohmann::json j = {{"begin", run.begin},     {"end", run.end},         {"models", run.voter_models},
                            {"counts", counts},       {"time_ms", run.time_ms}, {"from_meshes", run.from_meshes}};
  const std::vector<uint8_t> cbor = nlohmann::json::to_cbor(j);
  return std::string(cbor.begin(), cbor.end());
}

TrainedRun DecodeRun(const std::string& bytes, const std::string& what) {
  try {
    const nlohmann::json j = nlohmann::json::from_cbor(bytes);
    TrainedRun run;
    run.begin = j.at("begin").get<size_t>();
    run.end = j.at("end").get<size_t>();
    run.voter_models = j.at("models").get<std::vector<nlohmann::json>>();
    for (const auto& c : j.at("counts")) {
      std::map<std::string, TrainingCount>& per_class = run.counts.emplace_back();
      for (const auto& [cls, n] : c.items()) per_class[cls] = {n.at(0).get<int>(), n.at(1).get<int>(), n.at(2).get<int>()};
    }
    run.time_ms = j.at("time_ms").get<std::map<std::string, double>>();
    run.from_meshes = j.at("from_meshes").get<size_t>();
    return run;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(what + ": " + e.what());
  }
}

// Training whose voters merge (Pipeline::TrainingMerges): the catalog in one run of consecutive
// models per rank, each trained where it is taken; rank 0 merges the runs in catalog order.
TrainedModel TrainRuns(const World& world, Pipeline& p, const Catalog& catalog, const RunContext& ctx) {
  const size_t n = catalog.models.size(), runs = std::min(n, size_t(world.Size()));
  const auto bounds = [&](size_t r) { return std::make_pair(r * n / runs, (r + 1) * n / runs); };
  if (world.Root())
    spdlog::info("train: the voters learn the catalog in {} runs of consecutive models, one per rank, merged on rank 0",
                 runs);
  const std::vector<std::string> trained = ShareJobs(
      world, runs,
      [&](size_t r) {
        const auto [begin, end] = bounds(r);
        return Encode(p.TrainRun(catalog, begin, end, ctx));
      },
      [&](size_t r) {
        const auto [begin, end] = bounds(r);
        return "training on catalog models " + std::to_string(begin + 1) + " to " + std::to_string(end) + " (" +
               catalog.models[begin].id + " to " + catalog.models[end - 1].id + ") of " + catalog.path;
      });
  std::optional<TrainedModel> merged;  // rank 0's, with its timings
  const std::string bytes = FromRoot(world, [&] {
    std::vector<TrainedRun> parts;
    for (size_t r = 0; r < trained.size(); ++r)
      parts.push_back(DecodeRun(trained[r], "the models of run " + std::to_string(r + 1)));
    merged = p.MergeRuns(catalog, std::move(parts), ctx);
    return ModelBytes(*merged);
  });
  return merged ? std::move(*merged) : ModelFromBytes(bytes, "the model from rank 0");
}

}  // namespace

TrainedModel TrainShared(const World& world, Pipeline& p, const Catalog& catalog, const RunContext& ctx) {
  if (!world.Shared()) return p.Train(catalog, ctx);
  if (p.TrainingMerges()) return TrainRuns(world, p, catalog, ctx);
  Progress progress("train: scanning models (rank " + std::to_string(world.Rank()) + ")", catalog.models.size());
  const std::vector<std::string> scanned = ShareJobs(
      world, catalog.models.size(),
      [&](size_t i) {
        const std::string bytes = Encode(p.ScanModel(catalog, i, ctx));
        progress.Tick();
        return bytes;
      },
      [&](size_t i) { return "training on catalog model " + catalog.models[i].id + " of " + catalog.path; });
  progress.Done();
  std::optional<TrainedModel> trained;  // rank 0's, with its timings
  const std::string bytes = FromRoot(world, [&] {
    std::vector<ModelViews> views;
    views.reserve(scanned.size());
    for (size_t i = 0; i < scanned.size(); ++i) views.push_back(Decode(scanned[i], "the views of " + catalog.models[i].id));
    trained = p.TrainFromViews(catalog, std::move(views), ctx);
    return ModelBytes(*trained);
  });
  return trained ? std::move(*trained) : ModelFromBytes(bytes, "the model from rank 0");
}

TrainedModel EnsureModelShared(const World& world, Pipeline& p, const Catalog& catalog, const RunContext& ctx,
                               bool force) {
  if (!world.Shared()) return EnsureModel(p, catalog, ctx, force);
  const std::string cache = p.Graph().model_cache;
  // Rank 0 decides: "1" + the cached model, or "0": train.
  const std::string cached = FromRoot(world, [&]() -> std::string {
    const std::optional<TrainedModel> m = CachedModel(p, catalog, force);
    return m ? "1" + ModelBytes(*m) : "0";
  });
  if (cached[0] == '1') return ModelFromBytes(cached.substr(1), "the cached model from rank 0");
  if (world.Root())
    spdlog::info("model: training from {} ({} models) on {} ranks", catalog.path, catalog.models.size(), world.Size());
  Stopwatch sw;
  TrainedModel m = TrainShared(world, p, catalog, ctx);
  if (world.Root()) {
    spdlog::info("model: trained in {:.1f} s: {}, time per stage [ms] {}", sw.Ms() / 1000.0, m.summary.dump(),
                 m.timings_ms.dump());
    if (!cache.empty()) {
      SaveModel(cache, m);
      spdlog::info("model: written to {}", cache);
    }
  }
  return m;
}

void ShareTraining(const World& world, DetectorOptions& options) {
  if (!world.Shared()) return;
  options.ensure_model = [&world](Pipeline& p, const Catalog& catalog, const RunContext& ctx, bool force) {
    return EnsureModelShared(world, p, catalog, ctx, force);
  };
}

}  // namespace furnihost::app
