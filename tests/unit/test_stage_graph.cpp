// The stage graph: the executor follows each stage's `inputs`, so one output feeds several
// stages (a voter feeding two fitter chains) and two segmenters run side by side, each with its
// own features and voter, trained into one model file. Runs the furnihost binary on a room
// simulated from the hostile corpus's tiny catalog, with the test-only stub segmenter and voter
// (tests/hostile/plugins) and the passthrough fitter (tests/plugins), whose "note" marks each
// detection with the fitters it went through.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "furnihost/host/io.hpp"
#include "furnihost/host/pipeline.hpp"
#include "stub_chain.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

using furnihost::testing::StubGraph;

json Graph(const std::string& dir, const json& stages) { return StubGraph(dir, stages); }

// Writes `graph` to DIR/g.json, runs detection on the room and returns detections.json.
json Detect(const std::string& dir, const json& graph, std::string* err = nullptr) {
  const auto r = furnihost::testing::DetectStubRoom(dir, graph);
  if (err) *err = r.err;
  EXPECT_EQ(r.code, 0) << r.err;
  return r.code == 0 ? furnihost::ReadJson(dir + "/out/detections.json") : json();
}

// A detection as the two runs compared should agree on it: without its chain and notes.
json Bare(json d) {
  d.erase("chain");
  d.erase("notes");
  return d;
}

std::vector<json> OfChain(const json& detections, const std::string& chain) {
  std::vector<json> out;
  for (const auto& d : detections["detections"])
    if (d.value("chain", "") == chain) out.push_back(d);
  return out;
}

}  // namespace

// One sink: no "chain" on the detections and no "sinks" list, as before graphs could branch.
TEST(StageGraph, OneSinkKeepsTheOutputShape) {
  const std::string dir = furnihost::testing::TempDir("stage_graph_one");
  fs::remove_all(dir);
  const json j = Detect(dir, Graph(dir, {{"fit", {{"type", "fitters.passthrough"}, {"inputs", {"vote"}}}}}));
  ASSERT_FALSE(j["detections"].empty()) << "vacuous: nothing detected";
  EXPECT_FALSE(j.contains("sinks"));
  for (const auto& d : j["detections"]) EXPECT_FALSE(d.contains("chain")) << d.dump();
  const auto model = furnihost::LoadModel(dir + "/model.fhm");
  ASSERT_EQ(model.voters.size(), 1u);
  EXPECT_EQ(model.voters.count("vote"), 1u) << "one voter: its model by its tag, as with several";
}

// A voter feeding two fitter chains (a -> b, and c): each chain gets the voter's hypotheses,
// each detection names its chain's end, and each went through its own chain's fitters only.
TEST(StageGraph, FanOutGivesEachBranchTheVotersOutput) {
  const std::string dir = furnihost::testing::TempDir("stage_graph_fan_out");
  fs::remove_all(dir);
  const json fitters = {
      {"a", {{"type", "fitters.passthrough"}, {"inputs", {"vote"}}, {"params", {{"note", "a"}}}}},
      {"b", {{"type", "fitters.passthrough"}, {"inputs", {"a"}}, {"params", {{"note", "b"}}}}},
      {"c", {{"type", "fitters.passthrough"}, {"inputs", {"vote"}}, {"params", {{"note", "c"}}}}}};
  const json j = Detect(dir + "/fan", Graph(dir + "/fan", fitters));
  EXPECT_EQ(j.value("sinks", json()), json({"b", "c"}));
  const auto b = OfChain(j, "b"), c = OfChain(j, "c");
  ASSERT_FALSE(b.empty()) << j.dump(1);
  ASSERT_EQ(b.size(), c.size());
  EXPECT_EQ(b.size() + c.size(), j["detections"].size()) << "a detection without its chain";
  for (const auto& d : b) EXPECT_EQ(d["notes"], json({"a", "b"})) << d.dump();
  for (const auto& d : c) EXPECT_EQ(d["notes"], json({"c"})) << d.dump();
  // Both chains saw the same hypotheses: those of the plain chain, voter only.
  const json plain = Detect(dir + "/plain", Graph(dir + "/plain", json::object()));
  ASSERT_EQ(plain["detections"].size(), b.size());
  for (size_t i = 0; i < b.size(); ++i) {
    EXPECT_EQ(Bare(b[i]), plain["detections"][i]) << i;
    EXPECT_EQ(Bare(c[i]), plain["detections"][i]) << i;
  }
  // Each stage ran once, though the voter fed two chains.
  EXPECT_EQ(j["stages_run"], json({"input", "ground", "seg", "feat", "vote", "a", "b", "c"}));
}

// One proposer feeding a voter's fitter beside the voter: the fitter that names the proposer
// among its inputs sees its proposals, the one that does not sees none (its voter took none).
TEST(StageGraph, ProposerFeedsAFitter) {
  const std::string dir = furnihost::testing::TempDir("stage_graph_proposer");
  fs::remove_all(dir);
  const json stages = {
      {"prop", {{"type", "proposals.clusters"}, {"inputs", {"seg"}}}},
      {"with", {{"type", "fitters.passthrough"}, {"inputs", {"vote", "prop"}}, {"params", {{"note_proposals", true}}}}},
      {"without", {{"type", "fitters.passthrough"}, {"inputs", {"vote"}}, {"params", {{"note_proposals", true}}}}}};
  const json j = Detect(dir, Graph(dir, stages));
  EXPECT_EQ(j.value("sinks", json()), json({"with", "without"}));
  const auto with = OfChain(j, "with"), without = OfChain(j, "without");
  ASSERT_FALSE(with.empty()) << j.dump(1);
  for (const auto& d : without) EXPECT_EQ(d["notes"], json({"proposals none"})) << d.dump();
  for (const auto& d : with) {
    ASSERT_EQ(d["notes"].size(), 1u);
    EXPECT_NE(d["notes"][0], "proposals none") << d.dump();
  }
}

// Two segmenters side by side on the one input, each with its own features and voter: training
// trains both voters into one model file (by voter tag), and each voter's detections are those
// its chain gives on its own.
TEST(StageGraph, TwoSegmentersSideBySide) {
  const std::string dir = furnihost::testing::TempDir("stage_graph_side_by_side");
  fs::remove_all(dir);
  const json coarse = {{"seg", {{"params", {{"cell_m", 0.5}}}}}};
  const json both = {{"seg2", {{"type", "segmenters.hostile_stub"}, {"inputs", {"input"}}, {"params", {{"cell_m", 0.5}}}}},
                     {"feat2", {{"type", "features.centroid"}, {"inputs", {"seg2"}}}},
                     {"vote2", {{"type", "voters.hostile_stub"}, {"inputs", {"feat2"}}}}};
  std::string err;
  const json j = Detect(dir + "/both", Graph(dir + "/both", both), &err);
  EXPECT_EQ(j.value("sinks", json()), json({"vote", "vote2"}));
  const auto m = furnihost::LoadModel(dir + "/both/model.fhm");
  ASSERT_EQ(m.voters.size(), 2u);
  EXPECT_EQ(m.voters.count("vote"), 1u);
  EXPECT_EQ(m.voters.at("vote2").voter_type, "voters.hostile_stub");
  EXPECT_TRUE(m.training_config.contains("voters")) << m.training_config.dump();

  const json fine = Detect(dir + "/fine", Graph(dir + "/fine", json::object()));
  const json wide = Detect(dir + "/wide", Graph(dir + "/wide", coarse));
  const auto v1 = OfChain(j, "vote"), v2 = OfChain(j, "vote2");
  ASSERT_FALSE(v1.empty());
  ASSERT_EQ(v1.size(), fine["detections"].size());
  ASSERT_EQ(v2.size(), wide["detections"].size());
  for (size_t i = 0; i < v1.size(); ++i) EXPECT_EQ(Bare(v1[i]), fine["detections"][i]) << i;
  for (size_t i = 0; i < v2.size(); ++i) EXPECT_EQ(Bare(v2[i]), wide["detections"][i]) << i;
  EXPECT_NE(v1, v2) << "vacuous: both segmenters gave the same parts";

  // The second run reads the two-voter cache; a one-voter cache is stale for the two-voter
  // graph (and the other way round) and is retrained, not misread.
  Detect(dir + "/both", Graph(dir + "/both", both), &err);
  EXPECT_NE(err.find("model: using cached"), std::string::npos) << err;
  fs::copy_file(dir + "/fine/model.fhm", dir + "/both/model.fhm", fs::copy_options::overwrite_existing);
  const json again = Detect(dir + "/both", Graph(dir + "/both", both), &err);
  EXPECT_NE(err.find("is stale"), std::string::npos) << err;
  EXPECT_EQ(again["detections"], j["detections"]);
  fs::copy_file(dir + "/both/model.fhm", dir + "/fine/model.fhm", fs::copy_options::overwrite_existing);
  const json single = Detect(dir + "/fine", Graph(dir + "/fine", json::object()), &err);
  EXPECT_NE(err.find("is stale"), std::string::npos) << err;
  EXPECT_EQ(single["detections"], fine["detections"]);
  if (!HasFailure()) fs::remove_all(dir);
}
