// The swappable segmenters on one real room, loaded through the registry as the host does:
//   bench_segmenter_alternatives [--benchmark_min_time=1]
// Scan: ../shared/data/scannet_votenet50k/scene0001_00.ply (50k points, a ScanNet room
// subsampled for VoteNet: ~5 cm spacing, so every segmenter gets the same radii scaled up
// for that density, listed in kParams). Counters: points/s, parts, unassigned points.
// segmenters.region_growing (the paper's) is included when it is built.
#include <benchmark/benchmark.h>

#include <cstdlib>

#include "furnihost/host/io.hpp"
#include "furnihost/host/registry.hpp"
#include "furnihost/stage.hpp"

namespace {

using namespace furnihost;

// $FURNIHOST_SOURCE_DIR overrides the configured source folder (as for the tests).
const Scan& Room() {
  static const Scan scan = [] {
    const char* env = std::getenv("FURNIHOST_SOURCE_DIR");
    const std::string src = env ? env : FURNIHOST_BENCH_SOURCE_DIR;
    return ReadScan(src + "/../shared/data/scannet_votenet50k/scene0001_00.ply");
  }();
  return scan;
}

Registry& Reg() {
  static Registry reg(std::vector<std::string>{FURNIHOST_BENCH_PLUGIN_DIR});
  return reg;
}

// Radii for ~5 cm spacing: normals in 10 cm, growing in 10 cm (kNN: 16).
const nlohmann::json kParams = {
    {"segmenters.region_growing", {{"normal_radius_m", 0.1}, {"distance_m", 0.1}}},
    {"segmenters.pcl_region_growing", {{"normal_radius_m", 0.1}, {"neighbours", 16}}},
    {"segmenters.cgal_region_growing", {{"normal_radius_m", 0.1}, {"distance_m", 0.1}, {"max_plane_distance_m", 0.03}}},
    {"segmenters.cgal_efficient_ransac",
     {{"normal_radius_m", 0.1}, {"epsilon_m", 0.03}, {"cluster_epsilon_m", 0.1}, {"distance_m", 0.1}}},
};

void Run(benchmark::State& state, const std::string& type, nlohmann::json extra) {
  const PluginEntry* e = Reg().Find(type);
  if (!e) {
    state.SkipWithError((type + " not built").c_str());
    return;
  }
  nlohmann::json p = kParams.at(type);
  p.update(extra);
  auto seg = Reg().CreateAs<Segmenter>(type, e->params.Resolve(p, "bench"));
  RunContext ctx;
  ctx.threads = int(state.range(0));
  const Scan& scan = Room();
  Segmentation out;
  for (auto _ : state) {
    out = seg->Segment(scan, ctx);
    benchmark::DoNotOptimize(out.parts.data());
  }
  state.counters["points/s"] = benchmark::Counter(double(scan.points.size()), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["parts"] = double(out.parts.size());
  state.counters["unassigned"] = double(out.discarded_points);
}

void BM_RegionGrowing(benchmark::State& s) { Run(s, "segmenters.region_growing", nlohmann::json::object()); }
void BM_PclRegionGrowingOmp(benchmark::State& s) { Run(s, "segmenters.pcl_region_growing", {{"normals", "omp"}}); }
void BM_PclRegionGrowingMls(benchmark::State& s) { Run(s, "segmenters.pcl_region_growing", {{"normals", "mls"}}); }
void BM_CgalRegionGrowingJet(benchmark::State& s) { Run(s, "segmenters.cgal_region_growing", {{"normals", "jet"}}); }
void BM_CgalRegionGrowingPca(benchmark::State& s) { Run(s, "segmenters.cgal_region_growing", {{"normals", "pca"}}); }
void BM_CgalEfficientRansac(benchmark::State& s) { Run(s, "segmenters.cgal_efficient_ransac", nlohmann::json::object()); }

// Argument: threads (2 = the target machine).
BENCHMARK(BM_RegionGrowing)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PclRegionGrowingOmp)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PclRegionGrowingMls)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_CgalRegionGrowingJet)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_CgalRegionGrowingPca)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_CgalEfficientRansac)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
