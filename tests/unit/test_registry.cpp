#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "furnihost/host/config.hpp"
#include "furnihost/host/io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace furnihost;

namespace {
std::string TestPluginDir(const std::string& which) {
  return (fs::path(furnihost::testing::PluginDir()).parent_path() / "test_plugins" / which).string();
}
std::string ReasonFor(const Registry& reg, const std::string& file_part) {
  for (const auto& r : reg.Refusals())
    if (r.path.find(file_part) != std::string::npos) return r.reason;
  return "";
}
}  // namespace

TEST(Registry, LoadsShippedPlugins) {
  auto reg = furnihost::testing::MakeRegistry();
  ASSERT_NE(reg->Find("sensors.scan_file"), nullptr);
  ASSERT_NE(reg->Find("features.centroid"), nullptr);
  EXPECT_EQ(reg->Find("features.centroid")->kind, StageKind::Features);
  EXPECT_TRUE(reg->Refusals().empty());
  auto f = reg->CreateAs<Features>("features.centroid",
                                   reg->Find("features.centroid")->params.Resolve(nlohmann::json::object(), "t"));
  Scan s;
  s.points = {{0, 0, 0}, {1, 0, 1}};
  Segmentation seg;
  seg.parts.push_back({{0, 1}, {0.5f, 0, 0.5f}});
  auto m = f->Compute(s, seg, {});
  ASSERT_EQ(m.values.rows(), 1);
  EXPECT_FLOAT_EQ(m.values(0, 0), 0.5f);
  EXPECT_FLOAT_EQ(m.values(0, 4), 1.f);
}

TEST(Registry, RefusesBadLibrariesAndKeepsGoing) {
  Registry reg({furnihost::testing::PluginDir(), TestPluginDir("bad")});
  EXPECT_NE(ReasonFor(reg, "bad_abi").find("ABI version 999"), std::string::npos);
  EXPECT_NE(ReasonFor(reg, "no_factory").find("no factory"), std::string::npos);
  EXPECT_NE(ReasonFor(reg, "not_a_library").find("not a loadable shared library"), std::string::npos);
  EXPECT_NE(ReasonFor(reg, "duplicate").find("duplicate type features.centroid"), std::string::npos);
  // The good plugins are still there, and the first features.centroid wins.
  ASSERT_NE(reg.Find("features.centroid"), nullptr);
  EXPECT_EQ(reg.Find("features.centroid")->version, "1.0.0");
  ASSERT_NE(reg.Find("sensors.scan_file"), nullptr);
  ASSERT_NE(reg.Find("segmenters.throws"), nullptr);  // loads; fails only when called
}

TEST(Registry, PluginExceptionsAreCaughtWhileTheLibraryIsLoaded) {
  Registry reg({TestPluginDir("bad")});
  const auto* e = reg.Find("segmenters.throws");
  ASSERT_NE(e, nullptr);
  try {
    reg.Create("segmenters.throws", e->params.Resolve({{"throw_in_constructor", true}}, "t"));
    FAIL();
  } catch (const StageError& err) {
    EXPECT_NE(std::string(err.what()).find("segmenters.throws: constructor refuses"), std::string::npos) << err.what();
  }
  auto seg = reg.CreateAs<Segmenter>("segmenters.throws", e->params.Resolve(nullptr, "t"));
  EXPECT_THROW(seg->Segment(Scan{}, {}), std::logic_error);
  EXPECT_THROW(reg.Create("segmenters.nope", {}), InputError);
}

TEST(Registry, OutsidePluginFoundThroughSearchPath) {
  Registry reg({TestPluginDir("outside")});
  ASSERT_NE(reg.Find("features.outside_example"), nullptr);
  auto f = reg.CreateAs<Features>("features.outside_example", {{"scale", 2.0}});
  Segmentation seg;
  seg.parts.push_back({{0, 1, 2}, Eigen::Vector3f::Zero()});
  EXPECT_FLOAT_EQ(f->Compute(Scan{}, seg, {}).values(0, 0), 6.f);
}

namespace {
bool Mapped(const std::string& library) {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
    if (line.find(library) != std::string::npos) return true;
  return false;
}
}  // namespace

// The project's own plugin folder loads on demand: a look-up loads the library named for the
// type and no other (in a full build, not PCL's segmenter: ~0.1 s of relocations); the full
// listing loads every library. The checks run in a fresh process (gtest re-executes this test
// alone), so no earlier test of this binary can have mapped a library before; the child exits
// 0 when all hold and names the first that does not.
std::string LazyLoadingProblem() {
  const std::string centroid = "libfurnihost_features_centroid.so";
  std::vector<std::string> others;  // the other shipped libraries (which ones depends on the build)
  for (const auto& e : fs::directory_iterator(furnihost::testing::PluginDir())) {
    const std::string name = e.path().filename().string();
    if (name.rfind("libfurnihost_", 0) == 0 && e.path().extension() == ".so" && name != centroid)
      others.push_back(name);
  }
  if (others.empty()) return "no other shipped library";
  for (const auto& o : others)
    if (Mapped(o) || Mapped(centroid)) return o + " mapped before the registry";
  Registry reg({furnihost::testing::PluginDir()});
  const PluginEntry* first = reg.Find("features.centroid");
  if (!first) return "features.centroid not found";
  if (!Mapped(centroid)) return "features.centroid found but its library not mapped";
  for (const auto& o : others)
    if (Mapped(o)) return o + " mapped by the look-up of features.centroid";
  if (!reg.Create("features.centroid", first->params.Resolve(nlohmann::json::object(), "t"))) return "no stage";
  for (const auto& o : others)
    if (Mapped(o)) return o + " mapped by Create";
  if (reg.Find("voters.no_such_voter")) return "an unknown type was found";
  for (const auto& o : others)  // an unknown type looks everywhere
    if (!Mapped(o)) return o + " not mapped after looking for an unknown type";
  if (reg.Find("features.centroid") != first) return "the entry moved as other libraries loaded";
  if (reg.TypeNames().size() != others.size() + 1) return "TypeNames does not list every library";
  return "";
}

TEST(Registry, ShippedLibrariesLoadWhenFirstNeeded) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");  // re-executes the binary: nothing mapped before
  EXPECT_EXIT(
      {
        const std::string problem = LazyLoadingProblem();
        std::fprintf(stderr, "%s\n", problem.empty() ? "lazy loading ok" : problem.c_str());
        std::_Exit(problem.empty() ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "lazy loading ok");
}

// ---- graph configs ----------------------------------------------------------------------
namespace {
const char* kGood = R"({
  "seed": 7,
  "stages": {
    "input": {"type": "sensors.scan_file"},
    "segment": {"type": "segmenters.throws", "inputs": ["input"]},
    "feat": {"type": "features.centroid", "inputs": ["segment"], "params": {"log_count": false}}
  }
})";

std::string ConfigError(const std::string& text, const std::string& name = "g.json") {
  Registry reg({furnihost::testing::PluginDir(), TestPluginDir("bad"), TestPluginDir("outside")});
  auto dir = furnihost::testing::TempDir("cfg");
  const std::string p = dir + "/" + name;
  AtomicWriteText(p, text);
  try {
    LoadGraph(p, reg);
  } catch (const InputError& e) {
    std::string w = e.what();
    auto pos = w.find(name);
    return pos == std::string::npos ? w : w.substr(pos);
  }
  return "";
}

nlohmann::json Good() { return nlohmann::json::parse(kGood); }
std::string With(const nlohmann::json& patch) { return MergePatch(Good(), patch).dump(); }
}  // namespace

TEST(Config, ValidGraphResolvesDefaultsInOrder) {
  EXPECT_EQ(ConfigError(kGood), "");
  Registry reg({furnihost::testing::PluginDir(), TestPluginDir("bad")});
  auto dir = furnihost::testing::TempDir("cfg");
  AtomicWriteText(dir + "/g.json", kGood);
  auto g = LoadGraph(dir + "/g.json", reg);
  EXPECT_EQ(g.seed, 7u);
  ASSERT_EQ(g.stages.size(), 3u);
  EXPECT_EQ(g.stages[0].tag, "input");
  EXPECT_EQ(g.stages[2].tag, "feat");
  EXPECT_EQ(g.stages[2].params["log_count"], false);
  EXPECT_EQ(g.resolved["stages"]["input"]["params"]["voxel_m"], 0.0);
}

TEST(Config, EachErrorNamesFileAndPointer) {
  EXPECT_EQ(ConfigError(With({{"stages", {{"feat", {{"params", {{"log_count", "yes"}}}}}}}})),
            "g.json:/stages/feat/params/log_count: expected true or false, got \"yes\"");
  EXPECT_NE(ConfigError(With({{"stages", {{"feat", {{"params", {{"bogus", 1}}}}}}}}))
                .find("g.json:/stages/feat/params/bogus: unknown parameter; valid: log_count"),
            std::string::npos);
  const std::string unknown = ConfigError(With({{"stages", {{"vote", {{"type", "voters.nope"}, {"inputs", {"feat"}}}}}}}));
  EXPECT_NE(unknown.find("g.json:/stages/vote/type: missing plugin voters.nope; known: "), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("features.centroid"), std::string::npos);
  EXPECT_NE(ConfigError(With({{"stages", {{"feat", {{"inputs", {"input"}}}}}}})).find("kind mismatch"), std::string::npos);
  EXPECT_NE(ConfigError(With({{"stages", {{"feat", {{"inputs", {"nowhere"}}}}}}})).find("unknown stage 'nowhere'"),
            std::string::npos);
  EXPECT_NE(ConfigError(With({{"stagez", 1}})).find("g.json:/stagez: unknown key"), std::string::npos);
  EXPECT_NE(ConfigError(With({{"seed", "x"}})).find("/seed: expected a non-negative integer"), std::string::npos);
  EXPECT_NE(ConfigError(With({{"stages", {{"feat", {{"type", 5}}}}}})).find("/stages/feat/type"), std::string::npos);
  EXPECT_NE(ConfigError(With({{"stages", {{"feat", {{"type", "gizmos.x"}}}}}})).find("is not <kind>s.<name>"),
            std::string::npos);
  EXPECT_NE(ConfigError("[1, 2]").find("expected a JSON object"), std::string::npos);
  EXPECT_NE(ConfigError("{\"stages\": ").find("not valid JSON"), std::string::npos);
  EXPECT_NE(ConfigError(With({{"stages", {{"input2", {{"type", "sensors.scan_file"}}}}}})).find("more than one sensor"),
            std::string::npos);
  EXPECT_NE(ConfigError(With({{"training", {{"sensor", "feat"}}}})).find("is a features, not a sensor"),
            std::string::npos);
}

// The "ensemble" key: its values checked before anything runs, each error naming the key; a graph
// without it runs once.
TEST(Config, EnsembleIsValidatedAndDefaultsToOneRun) {
  Registry reg({furnihost::testing::PluginDir(), TestPluginDir("bad")});
  auto dir = furnihost::testing::TempDir("cfg_ens");
  AtomicWriteText(dir + "/g.json", kGood);
  EXPECT_EQ(LoadGraph(dir + "/g.json", reg).ensemble.runs, 1);
  AtomicWriteText(dir + "/e.json", With({{"ensemble", {{"runs", 3}, {"jitter_m", 0.001}, {"join_iou", 0.5}}}}));
  const auto g = LoadGraph(dir + "/e.json", reg);
  EXPECT_EQ(g.ensemble.runs, 3);
  EXPECT_DOUBLE_EQ(g.ensemble.jitter_m, 0.001);
  EXPECT_DOUBLE_EQ(g.ensemble.join_iou, 0.5);
  EXPECT_EQ(g.resolved["ensemble"]["runs"], 3);
  EXPECT_EQ(LoadGraph(dir + "/e.json", reg, {"ensemble.runs=1"}).ensemble.runs, 1);  // --set
  EXPECT_EQ(ConfigError(With({{"ensemble", {{"runs", 0}}}})), "g.json:/ensemble/runs: expected an integer in [1, 64], got 0");
  EXPECT_EQ(ConfigError(With({{"ensemble", {{"runs", 2.5}}}})), "g.json:/ensemble/runs: expected an integer in [1, 64], got 2.5");
  EXPECT_EQ(ConfigError(With({{"ensemble", {{"jitter_m", -1}}}})),
            "g.json:/ensemble/jitter_m: expected a number in [0, 0.1], got -1");
  EXPECT_EQ(ConfigError(With({{"ensemble", {{"jitter_m", 0}}}})), "g.json:/ensemble: jitter_m: must be above 0");
  EXPECT_EQ(ConfigError(With({{"ensemble", {{"join_iou", "x"}}}})),
            "g.json:/ensemble/join_iou: expected a number in [0, 1], got \"x\"");
  EXPECT_EQ(ConfigError(With({{"ensemble", {{"run", 2}}}})),
            "g.json:/ensemble/run: unknown parameter; valid: runs, jitter_m, join_iou");
  EXPECT_EQ(ConfigError(With({{"frame", {{"level", 1}}}})), "g.json:/frame/level: expected true or false, got 1");
  EXPECT_EQ(ConfigError(With({{"ground", {{"cell_m", 5}}}})), "g.json:/ground/cell_m: expected a number in [0.02, 2], got 5");
  // A "comment" is the reader's, in every host section.
  AtomicWriteText(dir + "/c.json", With({{"frame", {{"comment", "x"}, {"level", true}}}, {"ground", {{"comment", "y"}}}}));
  EXPECT_TRUE(LoadGraph(dir + "/c.json", reg).frame.level);
  EXPECT_NE(ConfigError(With({{"ensemble", 5}})).find("g.json:/ensemble: expected an object"), std::string::npos);
}

TEST(Config, ExtendsMergePatchLoopsAndMissingBases) {
  Registry reg({furnihost::testing::PluginDir(), TestPluginDir("bad")});
  auto dir = furnihost::testing::TempDir("cfg_ext");
  AtomicWriteText(dir + "/base.json", kGood);
  AtomicWriteText(dir + "/variant.json",
                  R"({"extends": "base.json", "stages": {"feat": {"params": {"log_count": true}}}})");
  auto g = LoadGraph(dir + "/variant.json", reg);
  EXPECT_EQ(g.Find("feat")->params["log_count"], true);
  EXPECT_EQ(g.seed, 7u);
  AtomicWriteText(dir + "/drop.json", R"({"extends": "base.json", "stages": {"feat": null}})");
  EXPECT_EQ(LoadGraph(dir + "/drop.json", reg).stages.size(), 2u);
  AtomicWriteText(dir + "/loop_a.json", R"({"extends": "loop_b.json"})");
  AtomicWriteText(dir + "/loop_b.json", R"({"extends": "loop_a.json"})");
  try {
    LoadGraph(dir + "/loop_a.json", reg);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("extends loop"), std::string::npos);
  }
  AtomicWriteText(dir + "/orphan.json", R"({"extends": "nothere.json"})");
  EXPECT_NE(ConfigError(R"({"extends": "nothere.json"})").find("unknown base config"), std::string::npos);
}

TEST(Config, FitterCycleIsRefused) {
  auto text = With({{"stages",
                     {{"f1", {{"type", "fitters.passthrough"}, {"inputs", {"f2"}}}},
                      {"f2", {{"type", "fitters.passthrough"}, {"inputs", {"f1"}}}}}}});
  EXPECT_NE(ConfigError(text).find("cycle in connections"), std::string::npos) << ConfigError(text);
  auto two = With({{"stages", {{"f1", {{"type", "fitters.passthrough"}, {"inputs", {"feat"}}}}}}});
  EXPECT_NE(ConfigError(two).find("kind mismatch: fitter 'f1' cannot take features"), std::string::npos);
}

using json = nlohmann::json;

// The graph may branch: one voter feeding two fitter chains, two segmenters side by side each
// with its features and voter. What the executor cannot run is refused naming the stage.
TEST(Config, FanOutAndSideBySideValidateWhatCannotRunIsRefused) {
  const json fan = {{"catalog", "cat.json"},
                    {"stages",
                     {{"vote", {{"type", "voters.nearest_neighbor"}, {"inputs", {"feat"}}}},
                      {"f1", {{"type", "fitters.passthrough"}, {"inputs", {"vote"}}}},
                      {"f2", {{"type", "fitters.passthrough"}, {"inputs", {"f1"}}}},
                      {"f3", {{"type", "fitters.passthrough"}, {"inputs", {"vote"}}}},
                      {"segment2", {{"type", "segmenters.throws"}, {"inputs", {"input"}}}},
                      {"feat2", {{"type", "features.centroid"}, {"inputs", {"segment2"}}}},
                      {"vote2", {{"type", "voters.nearest_neighbor"}, {"inputs", {"feat2"}}}}}}};
  EXPECT_EQ(ConfigError(With(fan)), "");
  Registry reg({furnihost::testing::PluginDir(), TestPluginDir("bad"), TestPluginDir("outside")});
  auto dir = furnihost::testing::TempDir("cfg_fan");
  AtomicWriteText(dir + "/g.json", With(fan));
  const GraphConfig g = LoadGraph(dir + "/g.json", reg);
  std::vector<std::string> sinks;
  for (const auto* s : g.Sinks()) sinks.push_back(s->tag);
  EXPECT_EQ(sinks, (std::vector<std::string>{"f2", "f3", "vote2"}));
  EXPECT_EQ(g.ChainRoot(*g.Find("f2"))->tag, "vote");
  EXPECT_EQ(g.SegmenterOf(*g.Find("vote2"))->tag, "segment2");
  EXPECT_EQ(g.SegmenterOf(*g.Find("f2"))->tag, "segment");
  EXPECT_EQ(g.Input(*g.Find("f2"), InputRole::Detections)->tag, "f1");
  EXPECT_EQ(g.Input(*g.Find("vote"), InputRole::Proposals), nullptr);
  EXPECT_EQ(g.InputOfKind(*g.Find("vote"), StageKind::Proposer), nullptr);

  // A voter's features and proposals must index the parts of one segmentation.
  const json mixed = {{"catalog", "cat.json"},
                      {"stages",
                       {{"segment2", {{"type", "segmenters.throws"}, {"inputs", {"input"}}}},
                        {"prop", {{"type", "proposals.clusters"}, {"inputs", {"segment2"}}}},
                        {"vote", {{"type", "voters.nearest_neighbor"}, {"inputs", {"feat", "prop"}}}}}}};
  EXPECT_EQ(ConfigError(With(mixed)),
            "g.json:/stages/vote/inputs: voter 'vote' takes features 'feat' (parts of segmenter 'segment') and "
            "proposer 'prop' (parts of segmenter 'segment2'); both must come from one segmenter");
  // A fitter may take a proposer beside its detections, if both see the parts of one segmenter.
  EXPECT_EQ(ConfigError(With({{"catalog", "cat.json"},
                              {"stages",
                               {{"prop", {{"type", "proposals.clusters"}, {"inputs", {"segment"}}}},
                                {"vote", {{"type", "voters.nearest_neighbor"}, {"inputs", {"feat"}}}},
                                {"f1", {{"type", "fitters.passthrough"}, {"inputs", {"vote", "prop"}}}}}}})),
            "");
  // Proposals without parts index no segmentation: a fitter may see them after any voter.
  EXPECT_EQ(ConfigError(With({{"catalog", "cat.json"},
                              {"stages",
                               {{"prop", {{"type", "proposals.clusters"}, {"inputs", {"input"}}}},
                                {"vote", {{"type", "voters.nearest_neighbor"}, {"inputs", {"feat"}}}},
                                {"f1", {{"type", "fitters.passthrough"}, {"inputs", {"vote", "prop"}}}}}}})),
            "");
  EXPECT_EQ(ConfigError(With({{"catalog", "cat.json"},
                              {"stages",
                               {{"segment2", {{"type", "segmenters.throws"}, {"inputs", {"input"}}}},
                                {"prop", {{"type", "proposals.clusters"}, {"inputs", {"segment2"}}}},
                                {"vote", {{"type", "voters.nearest_neighbor"}, {"inputs", {"feat"}}}},
                                {"f1", {{"type", "fitters.passthrough"}, {"inputs", {"vote", "prop"}}}}}}})),
            "g.json:/stages/f1/inputs: fitter 'f1' takes voter 'vote' (parts of segmenter 'segment') and proposer "
            "'prop' (parts of segmenter 'segment2'); both must come from one segmenter");
  EXPECT_EQ(ConfigError(With({{"catalog", "cat.json"},
                              {"stages",
                               {{"prop", {{"type", "proposals.clusters"}, {"inputs", {"segment"}}}},
                                {"f1", {{"type", "fitters.passthrough"}, {"inputs", {"prop"}}}}}}})),
            "g.json:/stages/f1/inputs: fitter 'f1' takes the detections of one voter or fitter, and optionally one "
            "proposer");
  // Scans come in through one sensor.
  EXPECT_NE(ConfigError(With({{"stages", {{"input2", {{"type", "sensors.scan_file"}}}}}}))
                .find("g.json:/stages/input2: more than one sensor stage (input, input2)"),
            std::string::npos);
  // Cycles and kind mismatches name the stage.
  const auto cycle = ConfigError(With({{"catalog", "cat.json"},
                                       {"stages",
                                        {{"vote", {{"type", "voters.nearest_neighbor"}, {"inputs", {"feat"}}}},
                                         {"f1", {{"type", "fitters.passthrough"}, {"inputs", {"f2"}}}},
                                         {"f2", {{"type", "fitters.passthrough"}, {"inputs", {"f1"}}}},
                                         {"f3", {{"type", "fitters.passthrough"}, {"inputs", {"vote"}}}}}}}));
  EXPECT_NE(cycle.find("cycle in connections: f1, f2, f1"), std::string::npos) << cycle;
  const auto mismatch = ConfigError(With({{"stages", {{"feat2", {{"type", "features.centroid"}, {"inputs", {"feat"}}}}}}}));
  EXPECT_NE(mismatch.find("/stages/feat2/inputs/0: kind mismatch: features 'feat2' cannot take features 'feat'"),
            std::string::npos)
      << mismatch;
}


// The kinds' names come from one table: each kind's name, and the kind of a plugin type by its
// prefix (a proposer's is "proposals."); another prefix is no kind.
TEST(StageKinds, NamesAndTypePrefixesComeFromTheTable) {
  const std::vector<std::pair<StageKind, std::string>> kinds = {
      {StageKind::Sensor, "sensors"},   {StageKind::Segmenter, "segmenters"}, {StageKind::Features, "features"},
      {StageKind::Voter, "voters"},     {StageKind::Fitter, "fitters"},       {StageKind::Proposer, "proposals"}};
  for (const auto& [kind, prefix] : kinds) {
    EXPECT_EQ(KindFromTypeName(prefix + ".x"), kind) << prefix;
    EXPECT_NE(KindTypePrefixes().find(prefix + "."), std::string::npos) << prefix;
  }
  EXPECT_STREQ(ToString(StageKind::Proposer), "proposer");
  EXPECT_EQ(KindFromTypeName("gizmos.x"), std::nullopt);
  EXPECT_EQ(KindFromTypeName("voters."), std::nullopt);
  EXPECT_EQ(KindFromTypeName("voter.x"), std::nullopt);
}
