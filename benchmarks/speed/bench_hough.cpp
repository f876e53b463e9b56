// Speed of voters.hough_vocabulary (and the NN baseline) at the scale:
//   training set: 38 models x 16 views x 10 parts, 24 features (k-means, k = 40);
//   scene: a 10 m x 8 m room of ~50k points segmented into N parts (15 objects + clutter).
// Synthetic features (class prototypes + noise, clutter uniform in [0, 1]) so the bench needs
// no data; the cost of voting depends on part and element counts, not on feature values.
//   ./bench_hough --benchmark_min_time=1
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "furnihost/geometry.hpp"
#include "furnihost/host/registry.hpp"
#include "furnihost/host/ground_estimation.hpp"
#include "synthetic_views.hpp"

namespace {

using namespace furnihost;

constexpr int kFeatureDim = 24;
constexpr int kPartTypes = 10;

float U(std::mt19937_64& rng) { return static_cast<float>(rng() >> 40) / static_cast<float>(1 << 24); }

struct ClassGen {
  std::string cls;
  int models;
  Eigen::Vector3f size;
  std::vector<std::vector<float>> protos;
  std::vector<Eigen::Vector3f> offsets;
};

std::vector<ClassGen> Classes() {
  std::mt19937_64 rng(99);
  std::vector<ClassGen> cs = {{"chair", 20, {0.55f, 0.55f, 0.9f}, {}, {}},
                              {"table", 10, {1.4f, 0.8f, 0.75f}, {}, {}},
                              {"cabinet", 8, {1.6f, 0.45f, 0.8f}, {}, {}}};
  for (auto& c : cs)
    for (int p = 0; p < kPartTypes; ++p) {
      std::vector<float> f(kFeatureDim);
      for (float& x : f) x = U(rng);
      c.protos.push_back(f);
      c.offsets.emplace_back((U(rng) - 0.5f) * c.size.x(), (U(rng) - 0.5f) * c.size.y(),
                             (U(rng) - 0.5f) * c.size.z());
    }
  return cs;
}

Eigen::Matrix3f Rz(float a) { return Eigen::AngleAxisf(a, Eigen::Vector3f::UnitZ()).toRotationMatrix(); }

std::vector<TrainingView> TrainingSet() {
  std::mt19937_64 rng(5);
  std::vector<TrainingView> views;
  for (const auto& c : Classes())
    for (int m = 0; m < c.models; ++m)
      for (int v = 0; v < 16; ++v) {
        TrainingView tv;
        tv.cls = c.cls;
        tv.model_id = c.cls + std::to_string(m);
        tv.view = v;
        tv.object_centroid = Eigen::Vector3f(0.f, 0.f, 0.4f);
        tv.scan.origin = Eigen::Vector3f(-2.5f, 0.f, 1.5f);
        tv.object_size = c.size * (0.9f + 0.2f * U(rng));
        tv.features.values.resize(kPartTypes, kFeatureDim);
        const Eigen::Matrix3f r = Rz(6.2831853f * v / 16.f);  // the sensor circles the object
        for (int p = 0; p < kPartTypes; ++p) {
          synth::AddPart(tv.scan, tv.segmentation, tv.object_centroid + r * c.offsets[p]);
          for (int j = 0; j < kFeatureDim; ++j)
            tv.features.values(p, j) = std::clamp(c.protos[p][j] + 0.1f * (U(rng) - 0.5f), 0.f, 1.f);
        }
        views.push_back(std::move(tv));
      }
  return views;
}

struct Room {
  Scan scan;
  Segmentation seg;
  FeatureMatrix features;
};

Room MakeRoom(int parts) {
  std::mt19937_64 rng(17);
  const auto classes = Classes();
  Room room;
  std::vector<std::vector<float>> rows;
  for (int o = 0; o < 15 && static_cast<int>(rows.size()) + kPartTypes <= parts; ++o) {
    const auto& c = classes[o % 3];
    const Eigen::Vector3f centre(1.f + 8.f * U(rng), 1.f + 6.f * U(rng), 0.4f);
    const Eigen::Matrix3f r = Rz(6.2831853f * U(rng));
    for (int p = 0; p < kPartTypes; ++p) {
      synth::AddPart(room.scan, room.seg, centre + r * c.offsets[p]);
      std::vector<float> f = c.protos[p];
      for (float& x : f) x = std::clamp(x + 0.1f * (U(rng) - 0.5f), 0.f, 1.f);
      rows.push_back(f);
    }
  }
  while (static_cast<int>(rows.size()) < parts) {
    synth::AddPart(room.scan, room.seg, Eigen::Vector3f(10.f * U(rng), 8.f * U(rng), 2.5f * U(rng)));
    std::vector<float> f(kFeatureDim);
    for (float& x : f) x = U(rng);
    rows.push_back(f);
  }
  room.features.values.resize(static_cast<Eigen::Index>(rows.size()), kFeatureDim);
  for (size_t i = 0; i < rows.size(); ++i)
    for (int j = 0; j < kFeatureDim; ++j) room.features.values(static_cast<Eigen::Index>(i), j) = rows[i][j];
  return room;
}

Registry& Reg() {
  static Registry reg({FURNIHOST_BENCH_PLUGIN_DIR});
  return reg;
}

std::shared_ptr<Voter> MakeVoter(const std::string& type, const nlohmann::json& params = nlohmann::json::object()) {
  return Reg().CreateAs<Voter>(type, Reg().Find(type)->params.Resolve(params, "bench"));
}

const std::vector<TrainingView>& Training() {
  static const auto views = TrainingSet();
  return views;
}

void BM_Train(benchmark::State& state, const char* type) {
  if (!Reg().Find(type)) return state.SkipWithError((std::string(type) + " not built").c_str());
  auto voter = MakeVoter(type);
  RunContext ctx;
  for (auto _ : state) benchmark::DoNotOptimize(voter->Train(Training(), ctx));
  state.counters["parts"] = static_cast<double>(Training().size() * kPartTypes);
}

// `gated`: with scannet.json's height gate (heights above the scan's z: it has no ground model).
void BM_Vote(benchmark::State& state, const char* type, bool gated) {
  if (!Reg().Find(type)) return state.SkipWithError((std::string(type) + " not built").c_str());
  auto voter = MakeVoter(type, gated ? nlohmann::json{{"height_tolerance_m", 0.15}} : nlohmann::json::object());
  RunContext ctx;
  voter->Train(Training(), ctx);
  const Room room = MakeRoom(static_cast<int>(state.range(0)));
  const std::vector<SceneParts> scenes = {{&room.scan, &room.seg, &room.features}};
  size_t votes = 0, hyps = 0;
  for (auto _ : state) {
    const VoteResult r = voter->Vote(scenes, ctx);
    votes = r.votes.size();
    hyps = r.hypotheses.size();
    benchmark::DoNotOptimize(r.hypotheses.data());
  }
  state.counters["votes"] = static_cast<double>(votes);
  state.counters["hypotheses"] = static_cast<double>(hyps);
  state.counters["parts/s"] = benchmark::Counter(static_cast<double>(state.range(0)),
                                                 benchmark::Counter::kIsIterationInvariantRate);
}

// The pipeline's ground estimates over a room scan (the room's parts, a floor, a wall), each
// kind: what every scan pays once before the stages run.
void BM_Ground(benchmark::State& state, const char* kind) {
  Room room = MakeRoom(1500);
  std::mt19937_64 rng(23);
  for (int i = 0; i < 30000; ++i)  // a floor (1 cm noise) and a wall, as a room scan has
    room.scan.points.emplace_back(10.f * U(rng), 8.f * U(rng), 0.01f * (U(rng) - 0.5f));
  for (int i = 0; i < 10000; ++i) room.scan.points.emplace_back(0.f, 8.f * U(rng), 2.5f * U(rng));
  GroundOptions o;
  o.kind = kind;
  float z = 0.f;
  for (auto _ : state) {
    z = EstimateGround(room.scan.points, o).HeightAt(5.f, 4.f);
    benchmark::DoNotOptimize(z);
  }
  state.counters["points"] = static_cast<double>(room.scan.points.size());
}

BENCHMARK_CAPTURE(BM_Ground, level, "level")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Ground, plane, "plane")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Ground, height_map, "height_map")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Train, hough_k40, "voters.hough_vocabulary")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Train, nearest_neighbor, "voters.nearest_neighbor")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vote, hough, "voters.hough_vocabulary", false)
    ->Arg(300)->Arg(1000)->Arg(1500)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vote, hough_height_gate, "voters.hough_vocabulary", true)
    ->Arg(300)->Arg(1000)->Arg(1500)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Vote, nearest_neighbor, "voters.nearest_neighbor", false)
    ->Arg(300)->Arg(1000)->Arg(1500)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
