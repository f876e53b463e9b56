#include "mpi_train.hpp"

#include <optional>

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

}  // namespace

TrainedModel TrainShared(const World& world, Pipeline& p, const Catalog& catalog, const RunContext& ctx) {
  if (!world.Shared()) return p.Train(catalog, ctx);
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
