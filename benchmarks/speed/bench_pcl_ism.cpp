// Speed of voters.pcl_ism through the registry, as the host runs it: ISM training on synthetic
// views of ~3k points (the size of a simulated catalog view) and voting on a synthetic room.
#include <benchmark/benchmark.h>

#include <cstdlib>

#include "furnihost/log.hpp"
#include "furnihost/host/registry.hpp"
#include "synthetic_furniture.hpp"

namespace furnihost {
namespace {

using nlohmann::json;
using namespace ism_synth;

std::shared_ptr<Voter> MakeVoter(const json& params) {
  static Registry reg(std::vector<std::string>{FURNIHOST_BENCH_PLUGIN_DIR});
  return reg.CreateAs<Voter>("voters.pcl_ism", reg.Find("voters.pcl_ism")->params.Resolve(params, "bench"));
}

// Views of a chair and a table at ~3k points each (step 1.1 cm); range(0) views per class,
// range(1) = k.
void BM_Train(benchmark::State& state) {
  const auto views = MakeViews({Chair(), Table()}, static_cast<int>(state.range(0)), 0.02f, 3);
  size_t points = 0;
  for (const auto& v : views) points += v.scan.points.size();
  auto voter = MakeVoter({{"number_of_clusters", state.range(1)}});
  RunContext ctx;
  for (auto _ : state) benchmark::DoNotOptimize(voter->Train(views, ctx));
  state.counters["views"] = static_cast<double>(views.size());
  state.counters["points_per_view"] = static_cast<double>(points) / static_cast<double>(views.size());
}
BENCHMARK(BM_Train)->Args({8, 40})->Args({16, 40})->Args({32, 40})->Args({64, 40})->Args({32, 184})
    ->Unit(benchmark::kMillisecond)->Iterations(1);

// A 5 x 4 m room with floor (3 cm grid), 4 chairs and 2 tables (1 cm grid): ~50k points.
void BM_Vote(benchmark::State& state) {
  const auto views = MakeViews({Chair(), Table()}, 16, 0.02f, 3);
  auto voter = MakeVoter({{"number_of_clusters", state.range(0)}});
  RunContext ctx;
  voter->Train(views, ctx);
  const std::vector<Placed> objects = {{Chair(), Placement(1.f, 1.f, 0.3f)},   {Chair(), Placement(1.f, 2.f, 1.f)},
                                       {Chair(), Placement(4.f, 3.f, 2.f)},   {Chair(), Placement(2.f, 3.5f, 3.f)},
                                       {Table(), Placement(3.f, 1.5f, 0.f)},  {Table(), Placement(2.5f, 3.f, 1.5f)}};
  const Room room = MakeRoom(objects, {2.5f, -1.f, 1.5f}, 0.01f, 0.03f, 5.f, 4.f, 5);
  for (auto _ : state) benchmark::DoNotOptimize(voter->Vote({{&room.scan, &room.seg, nullptr}}, ctx));
  state.counters["points"] = static_cast<double>(room.scan.points.size());
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(room.scan.points.size()),
                                                  benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Vote)->Arg(40)->Arg(184)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace
}  // namespace furnihost

int main(int argc, char** argv) {
  // ISM_BENCH_VERBOSE=2 shows the per-class vote counts and times of voters.pcl_ism.
  const char* v = std::getenv("ISM_BENCH_VERBOSE");
  furnihost::SetupLogging(v ? std::atoi(v) : 1);
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
