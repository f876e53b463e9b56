// The home-slot functions of the open-addressing voxel tables (shape::BlockNormals,
// EstimateVoxelNormals' FlatSlots, GroupEqualPoints, the parts' VoxelVolume), old against new in
// one run: the key -> cell table of a scan's 5 cm voxels as BlockNormals uses it (every occupied
// voxel inserted, then its 27 neighbours looked up), with
//   shape_old  ((k * phi) >> 20) & mask     BlockNormals' former slot: blind to x below 2^22 slots
//   flat_old   x = k * phi; x ^= x >> 29     FlatSlots' former slot: blind to z below 2^14 slots
//   new        HashSlot (SplitMix64's finaliser, every key bit in every slot bit)
// on each scan in its canonical working frame (what the stages see: walls on the axes), keys
// packed x-high (BlockNormals) and x-low (FlatSlots). The ratios old / new are printed after the
// table. Also times the whole BlockNormals and EstimateVoxelNormals (new) for scale.
//
//   build/bin/bench_voxel_hash [--scan=NAME=FILE ...] [--benchmark_filter=...]
// Default scans: ScanNet scene0000_00 ($FURNIHOST_SHARED_DATA_DIR); always lines of 100k points
// (1 km) along x, y and z. benchmarks/speed/run.sh's dense rooms: --scan=room_1.5M=runs/speed/rooms/room_1.5M.pcd
#include <benchmark/benchmark.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "furnihost/host/frame.hpp"
#include "furnihost/geometry.hpp"
#include "furnihost/hash.hpp"
#include "furnihost/host/io.hpp"
#include "shape/shape.hpp"

namespace {

using namespace furnihost;

constexpr float kVoxel = 0.05f;  // BlockNormals' wall_voxel_m default and the ground's normal voxel

struct Input {
  std::string name;
  Points points;                       // working frame
  std::vector<uint64_t> high, low;     // distinct voxel keys: x packed highest / lowest
};
std::vector<Input> g_inputs;

std::vector<uint64_t> DistinctKeys(const Points& pts, bool x_high) {
  std::vector<uint64_t> keys;
  keys.reserve(pts.size());
  for (const auto& p : pts) {
    auto c = [](float v) { return uint64_t(int64_t(std::floor(double(v) / kVoxel)) & 0x1FFFFF); };
    keys.push_back(x_high ? (c(p.x()) << 42) | (c(p.y()) << 21) | c(p.z()) : c(p.x()) | (c(p.y()) << 21) | (c(p.z()) << 42));
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

Input Prepare(const std::string& name, Scan scan) {
  FrameOptions fo;
  ToWorkingFrame(scan, fo);
  Input in{name, std::move(scan.points), {}, {}};
  in.high = DistinctKeys(in.points, true);
  in.low = DistinctKeys(in.points, false);
  return in;
}

enum class Slot { kShapeOld, kFlatOld, kNew };

inline size_t Home(uint64_t k, size_t mask, Slot s) {
  switch (s) {
    case Slot::kShapeOld: return size_t((k * 0x9E3779B97F4A7C15ull) >> 20) & mask;
    case Slot::kFlatOld: {
      uint64_t x = k * 0x9E3779B97F4A7C15ull;
      x ^= x >> 29;
      return size_t(x) & mask;
    }
    case Slot::kNew: break;
  }
  return HashSlot(k, mask);
}

// Inserts every key, then looks up the 27 neighbours of each (21 bits per axis, as packed).
void BM_Table(benchmark::State& st, const Input* in, bool x_high, Slot slot) {
  const std::vector<uint64_t>& keys = x_high ? in->high : in->low;
  size_t cap = 16;
  while (cap < 2 * keys.size()) cap <<= 1;
  const size_t mask = cap - 1;
  std::vector<uint64_t> table(cap);
  std::vector<char> used(cap);
  size_t found = 0;
  for (auto _ : st) {
    std::fill(used.begin(), used.end(), 0);
    for (uint64_t k : keys) {
      size_t h = Home(k, mask, slot);
      while (used[h]) h = (h + 1) & mask;
      used[h] = 1, table[h] = k;
    }
    found = 0;
    for (uint64_t k : keys) {
      const int64_t a = int64_t(k >> 42) & 0x1FFFFF, b = int64_t(k >> 21) & 0x1FFFFF, c = int64_t(k) & 0x1FFFFF;
      for (int64_t da = -1; da <= 1; ++da)
        for (int64_t db = -1; db <= 1; ++db)
          for (int64_t dc = -1; dc <= 1; ++dc) {
            const uint64_t q = (uint64_t((a + da) & 0x1FFFFF) << 42) | (uint64_t((b + db) & 0x1FFFFF) << 21) |
                               uint64_t((c + dc) & 0x1FFFFF);
            for (size_t h = Home(q, mask, slot); used[h]; h = (h + 1) & mask)
              if (table[h] == q) {
                ++found;
                break;
              }
          }
    }
    benchmark::DoNotOptimize(found);
  }
  st.counters["voxels"] = double(keys.size());
  st.counters["neighbours"] = double(found);
}

void BM_BlockNormals(benchmark::State& st, const Input* in) {
  for (auto _ : st) benchmark::DoNotOptimize(shape::BlockNormals(in->points, kVoxel).data());
  st.counters["points"] = double(in->points.size());
}

void BM_VoxelNormals(benchmark::State& st, const Input* in) {
  for (auto _ : st) benchmark::DoNotOptimize(EstimateVoxelNormals(in->points, kVoxel).voxel_of.data());
  st.counters["points"] = double(in->points.size());
}

// Keeps every run's CPU time (the table is one thread: on a shared machine its wall time
// measures the neighbours), then prints old / new per scan and packing.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const auto& r : runs)
      if (r.run_type == Run::RT_Iteration) ms_[r.run_name.function_name] = r.GetAdjustedCPUTime();
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    std::cout << "\nCPU time of the table, old / new:\n| scan | keys | voxels | new [ms] | shape_old / new | flat_old / new |\n"
                 "|---|---|---:|---:|---:|---:|\n";
    for (const auto& in : g_inputs)
      for (const char* pack : {"x_high", "x_low"}) {
        const std::string base = "table/" + in.name + "/" + pack + "/";
        auto at = [&](const std::string& s) { return ms_.count(base + s) ? ms_[base + s] : NAN; };
        std::printf("| %s | %s | %zu | %.2f | %.2f | %.2f |\n", in.name.c_str(), pack,
                    std::string(pack) == "x_high" ? in.high.size() : in.low.size(), at("new"),
                    at("shape_old") / at("new"), at("flat_old") / at("new"));
      }
  }

 private:
  std::map<std::string, double> ms_;
};

Scan Line(size_t n, float length, int axis) {
  Scan s;
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3f p(0.f, 0.f, 1.f);
    p[axis] = length * float(i) / float(n);
    p[(axis + 1) % 3] += 0.002f * float((i * 7919) % 11);
    s.points.push_back(p);
  }
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<char*> rest{argv[0]};
  std::vector<std::pair<std::string, std::string>> files;
  for (int a = 1; a < argc; ++a) {
    const std::string arg = argv[a];
    if (arg.rfind("--scan=", 0) == 0) {
      const size_t eq = arg.find('=', 7);
      if (eq == std::string::npos) {
        std::cerr << "bench_voxel_hash: --scan=NAME=FILE\n";
        return 2;
      }
      files.emplace_back(arg.substr(7, eq - 7), arg.substr(eq + 1));
    } else {
      rest.push_back(argv[a]);
    }
  }
  int rest_argc = int(rest.size());
  rest.push_back(nullptr);
  spdlog::set_level(spdlog::level::warn);
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
  const std::string scannet = std::string(FURNIHOST_SHARED_DATA_DIR) + "/scannet_votenet50k/scene0000_00.ply";
  if (files.empty() && std::filesystem::exists(scannet)) files.emplace_back("scannet0000_00", scannet);
  for (const auto& [name, path] : files) g_inputs.push_back(Prepare(name, ReadScan(path)));
  for (int axis : {0, 1, 2}) {  // no frame: the run stays on its axis
    Input in{std::string("line_") + "xyz"[axis] + "_1km", Line(100000, 1000.f, axis).points, {}, {}};
    in.high = DistinctKeys(in.points, true), in.low = DistinctKeys(in.points, false);
    g_inputs.push_back(std::move(in));
  }
  for (const auto& in : g_inputs) {
    for (bool x_high : {true, false}) {
      const std::string base = "table/" + in.name + "/" + (x_high ? "x_high" : "x_low") + "/";
      for (const auto& [tag, slot] : {std::make_pair("shape_old", Slot::kShapeOld), std::make_pair("flat_old", Slot::kFlatOld),
                                      std::make_pair("new", Slot::kNew)})
        benchmark::RegisterBenchmark((base + tag).c_str(), BM_Table, &in, x_high, slot)
            ->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(0.5);
    }
    benchmark::RegisterBenchmark(("BlockNormals/" + in.name).c_str(), BM_BlockNormals, &in)
        ->Unit(benchmark::kMillisecond)->UseRealTime();
    benchmark::RegisterBenchmark(("EstimateVoxelNormals/" + in.name).c_str(), BM_VoxelNormals, &in)
        ->Unit(benchmark::kMillisecond)->UseRealTime();
  }
  benchmark::Initialize(&rest_argc, rest.data());
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  return 0;
}
