// The model file: every trained stage's model by stage tag (format version 2), and the version 1
// layout of one voter (its fields at the top, no tag), which is upgraded on load and still
// serves a graph of one voter.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "furnihost/host/pipeline.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;
using namespace furnihost;

namespace {

StageConfig Stage(const std::string& tag, const std::string& type, StageKind kind, std::vector<std::string> inputs) {
  StageConfig s;
  s.tag = tag;
  s.type = type;
  s.version = "1.0.0";
  s.kind = kind;
  s.inputs = std::move(inputs);
  s.params = {{"p", 1}};
  s.training_params = s.params;
  s.pointer = "/stages/" + tag;
  return s;
}

// input -> seg -> feat -> `voters` (each a voter on feat), built by hand (no plugins needed).
GraphConfig Graph(const std::vector<std::string>& voters) {
  GraphConfig g;
  g.path = "g.json";
  g.stages = {Stage("input", "sensors.x", StageKind::Sensor, {}), Stage("seg", "segmenters.x", StageKind::Segmenter, {"input"}),
              Stage("feat", "features.x", StageKind::Features, {"seg"})};
  for (const auto& v : voters) g.stages.push_back(Stage(v, "voters.x", StageKind::Voter, {"feat"}));
  return g;
}

void WriteCbor(const std::string& path, const json& j) {
  const auto cbor = json::to_cbor(j);
  std::ofstream out(path, std::ios::binary);
  out << "furnihost-model\n";
  out.write(reinterpret_cast<const char*>(cbor.data()), std::streamsize(cbor.size()));
}

}  // namespace

TEST(ModelFile, VersionOneOfOneVoterIsUpgradedAndServesItsGraph) {
  const std::string dir = furnihost::testing::TempDir("model_file_v1");
  fs::create_directories(dir);
  const GraphConfig one = Graph({"vote"});
  const json key = TrainingKey(one);
  ASSERT_EQ(key["voters"].size(), 1u);
  // What the version 1 writer wrote for this graph: the voter's key parts beside the seed.
  json v1_key = {{"seed", key["seed"]}, {"training_sensor", key["training_sensor"]}};
  v1_key.update(key["voters"]["vote"]);
  const json normaliser = {{"min", {0.0, 0.0}}, {"max", {1.0, 2.0}}};
  WriteCbor(dir + "/v1.fhm", {{"format_version", 1},
                              {"training_config", v1_key},
                              {"catalog_hash", "abc"},
                              {"voter_type", "voters.x"},
                              {"normaliser", normaliser},
                              {"voter_model", {{"words", 3}}},
                              {"summary", json::object()}});
  const TrainedModel m = LoadModel(dir + "/v1.fhm");
  ASSERT_EQ(m.voters.size(), 1u);
  ASSERT_NE(m.FindVoter("vote"), nullptr);  // the graph's one voter, whatever its tag
  EXPECT_EQ(m.FindVoter("vote")->voter_model, json({{"words", 3}}));
  EXPECT_EQ(m.FindVoter("vote")->voter_type, "voters.x");
  EXPECT_EQ(Incompatibility(m, one, "abc"), "");
  EXPECT_NE(Incompatibility(m, one, "abd"), "");
  EXPECT_NE(Incompatibility(m, Graph({"vote", "vote2"}), "abc"), "");  // a graph of two voters retrains
  GraphConfig other = one;
  other.stages.back().training_params = {{"p", 2}};
  EXPECT_NE(Incompatibility(m, other, "abc"), "");  // the voter's training parameters differ

  // Written again: version 2, the voters by tag.
  TrainedModel m2 = m;
  m2.voters = {{"vote", m.voters.begin()->second}};
  m2.training_config = key;
  SaveModel(dir + "/v2.fhm", m2);
  const TrainedModel back = LoadModel(dir + "/v2.fhm");
  EXPECT_EQ(back.format_version, kModelFormatVersion);
  ASSERT_EQ(back.voters.count("vote"), 1u);
  EXPECT_EQ(back.FindVoter("other"), nullptr);
  EXPECT_EQ(Incompatibility(back, one, "abc"), "");
  if (!HasFailure()) fs::remove_all(dir);
}

TEST(ModelFile, OtherVersionsAreRefusedNamingTheWayOut) {
  const std::string dir = furnihost::testing::TempDir("model_file_versions");
  fs::create_directories(dir);
  WriteCbor(dir + "/v3.fhm", {{"format_version", kModelFormatVersion + 1}});
  try {
    LoadModel(dir + "/v3.fhm");
    FAIL() << "a newer version was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("model file format version 3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("retrain"), std::string::npos) << e.what();
  }
  if (!HasFailure()) fs::remove_all(dir);
}
