// voters.esf_catalog on catalog models simulated by sensors.simulated_laser: a table (a top on
// four legs), a chair (seat, back, legs) and a cabinet (a closed box) are trained from 8 views
// each; a proposal made of a new, partial scan of one of them (other sensor positions, turned
// and moved) ranks its own class first. Also: the same seed gives the same model and scores, bad
// parameters are refused naming the parameter, and a model survives the host's model file.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "furnihost/geometry.hpp"
#include "furnihost/host/pipeline.hpp"
#include "furnihost/stage.hpp"
#include "test_stages.hpp"

namespace furnihost {
namespace {

using nlohmann::json;

using testing::AddBox;

template <class T>
std::shared_ptr<T> Make(const std::string& type, const json& params = json::object()) {
  return testing::MakeStage<T>(type, params);
}

// Catalog models stand with their bounding-box bottom centre at the origin.
CatalogModel Table() { return testing::BoxTable(); }

CatalogModel Chair() {
  CatalogModel m;
  m.id = "test_chair";
  m.cls = "chair";
  AddBox(m.mesh, {-0.22f, -0.22f, 0.42f}, {0.22f, 0.22f, 0.46f});  // seat
  AddBox(m.mesh, {-0.22f, 0.18f, 0.46f}, {0.22f, 0.22f, 0.9f});    // back
  for (float x : {-0.22f, 0.18f})
    for (float y : {-0.22f, 0.18f}) AddBox(m.mesh, {x, y, 0.f}, {x + 0.04f, y + 0.04f, 0.42f});
  m.size = m.mesh.Bounds().sizes();
  return m;
}

CatalogModel Cabinet() { return testing::BoxCabinet(); }

CatalogModel Scaled(CatalogModel m, float f) {
  for (auto& v : m.mesh.vertices) v *= f;
  m.size = m.mesh.Bounds().sizes();
  return m;
}

std::vector<TrainingView> Views(const std::vector<const CatalogModel*>& models) {
  return testing::SimulatedTrainingViews(models);
}

// A scene: `m` turned by 0.5 rad and moved, scanned from two sensor positions on one side (a
// partial view none of the training views saw), fused in the world frame; one proposal holding
// all its points, its box down to the floor at z = 0.
struct Scene {
  Scan scan;
  Proposals proposals;
};
Scene SceneOf(const CatalogModel& m, int points = -1) {
  SensorRequest req;
  const Eigen::Isometry3f at = UprightPose(1.5f, -0.7f, 0.f, 0.5f);
  req.objects.push_back({&m, at});
  for (float a : {0.3f, 1.1f}) {
    req.poses.push_back(UprightPose(1.5f + 2.5f * std::cos(a), -0.7f + 2.5f * std::sin(a), 1.4f, a + float(M_PI)));
  }
  auto sensor = Make<Sensor>("sensors.simulated_laser", {{"voxel_m", 0.02}});
  RunContext ctx;
  Scene sc;
  for (auto& s : sensor->Acquire(req, ctx))
    for (const auto& p : s.points) sc.scan.points.push_back(s.pose * p);
  if (points >= 0 && size_t(points) < sc.scan.points.size()) sc.scan.points.resize(size_t(points));
  Proposal p;
  p.box = Eigen::AlignedBox3f();
  for (size_t i = 0; i < sc.scan.points.size(); ++i) {
    p.indices.push_back(int(i));
    p.box.extend(sc.scan.points[i]);
  }
  p.box.min().z() = 0.f;
  p.ground_z = 0.f;
  p.group = 0;
  p.how = "test";
  sc.proposals.items.push_back(p);
  return sc;
}

VoteResult VoteOn(Voter& voter, const Scene& sc) {
  SceneParts parts;
  parts.scan = &sc.scan;
  parts.proposals = &sc.proposals;
  return voter.Vote({parts}, RunContext{});
}

const Hypothesis* Best(const VoteResult& r) {
  const Hypothesis* b = nullptr;
  for (const auto& h : r.hypotheses)
    if (!b || h.score > b->score) b = &h;
  return b;
}

float ScoreOf(const VoteResult& r, const std::string& cls) {
  float s = 0.f;
  for (const auto& h : r.hypotheses)
    if (h.cls == cls) s = std::max(s, h.score);
  return s;
}

// Trained once per test process (ctest runs each test in its own): the simulated views and the
// model of the default parameters, seed 0. Training is most of each test's time.
struct Catalog3 {
  CatalogModel table = Table(), chair = Chair(), cabinet = Cabinet();
  std::vector<TrainingView> views = Views({&table, &chair, &cabinet});
};
const Catalog3& Trained() {
  static const Catalog3 c;
  return c;
}
const json& TrainedModel3() {
  static const json m = Make<Voter>("voters.esf_catalog")->Train(Trained().views, RunContext{});
  return m;
}
TEST(EsfCatalog, TrainsOneDescriptorPerViewWithTheModelsSize) {
  auto voter = Make<Voter>("voters.esf_catalog");
  const json& model = TrainedModel3();
  EXPECT_EQ(model.at("format"), "esf_catalog/1");
  EXPECT_EQ(model.at("voxel_m"), 0.02);  // the parameter as given, not its float rounding
  ASSERT_EQ(model.at("models").size(), 3u);
  for (size_t m = 0; m < 3; ++m) {
    const json& md = model["models"][m];
    const auto& esf = md.at("esf");
    EXPECT_EQ(esf.size(), 8u) << md.at("id");  // one per view
    for (const auto& d : esf) {
      ASSERT_EQ(d.size(), 640u);
      double sum = 0;
      for (const auto& b : d) sum += b.get<double>();
      EXPECT_NEAR(sum, 1e6, 1e3);  // unit sum, in parts per million
    }
    // Two views of one model from other sides describe it differently (a real descriptor).
    EXPECT_NE(esf[0], esf[4]);
  }
  const json& table = model["models"][0];
  EXPECT_EQ(table.at("id"), "test_table");
  EXPECT_EQ(table.at("class"), "table");
  EXPECT_NEAR(table.at("size")[0].get<float>(), 1.2f, 1e-4f);
  EXPECT_NEAR(table.at("size")[2].get<float>(), 0.75f, 1e-4f);
  EXPECT_NO_THROW(voter->Load(model));
}

// Each model's new partial scan ranks its own class first, by ESF alone and with the size term.
TEST(EsfCatalog, ProposalOfAModelRanksItsClassFirst) {
  const auto& cat = Trained();
  for (double size_weight : {0.0, 1.0}) {
    auto voter = Make<Voter>("voters.esf_catalog", {{"size_weight", size_weight}});
    voter->Load(TrainedModel3());  // size_weight is detection-only: the same model
    for (const CatalogModel* m : {&cat.table, &cat.chair, &cat.cabinet}) {
      const Scene sc = SceneOf(*m);
      const VoteResult r = VoteOn(*voter, sc);
      const Hypothesis* b = Best(r);
      ASSERT_TRUE(b) << m->id;
      EXPECT_EQ(b->cls, m->cls) << m->id << " size_weight " << size_weight << ": chair " << ScoreOf(r, "chair")
                                << " table " << ScoreOf(r, "table") << " cabinet " << ScoreOf(r, "cabinet");
      EXPECT_EQ(b->proposal, 0);
      ASSERT_TRUE(b->box.has_value());
      EXPECT_NEAR(b->box->center.x(), sc.proposals.items[0].box.center().x(), 1e-4f);
      // What was measured: the votes and the proposal's metric size.
      ASSERT_TRUE(b->evidence.count("esf_vote") && b->evidence.count("top_m") && b->evidence.count("esf_share"));
      EXPECT_NEAR(b->evidence.at("top_m"), m->size.z(), 0.05f);
      EXPECT_GT(b->evidence.at("esf_share"), 0.5f);
      if (size_weight == 0.0) {
        EXPECT_FLOAT_EQ(b->score, b->evidence.at("esf_vote"));
      }
    }
  }
}

// ESF is scale-invariant; the size term is not: a table twice the catalog table's size keeps its
// ESF vote but loses most of its score once the size counts.
TEST(EsfCatalog, SizeTermPenalisesAWrongMetricSize) {
  const auto& cat = Trained();
  const CatalogModel big = Scaled(cat.table, 2.f);
  auto esf_only = Make<Voter>("voters.esf_catalog", {{"size_weight", 0.0}});
  auto sized = Make<Voter>("voters.esf_catalog", {{"size_weight", 1.0}});
  esf_only->Load(TrainedModel3());
  sized->Load(TrainedModel3());
  const Scene normal = SceneOf(cat.table), twice = SceneOf(big);
  const VoteResult a = VoteOn(*sized, normal), b = VoteOn(*sized, twice), c = VoteOn(*esf_only, twice);
  ASSERT_GT(ScoreOf(c, "table"), 0.f);
  EXPECT_LT(ScoreOf(b, "table"), 0.2f * ScoreOf(c, "table"));
  EXPECT_LT(ScoreOf(b, "table"), 0.2f * ScoreOf(a, "table"));
  for (const auto& h : b.hypotheses)
    if (h.cls == "table") {
      EXPECT_GT(h.evidence.at("e_size"), 1.f);
    }
}

TEST(EsfCatalog, ThresholdsDecideAcceptanceAndSmallProposalsAreSkipped) {
  const auto& cat = Trained();
  auto voter = Make<Voter>("voters.esf_catalog",
                           {{"size_weight", 0.0}, {"thresholds", {{"cabinet", 0.0}, {"table", 1.0}}}, {"min_points", 50}});
  voter->Load(TrainedModel3());
  const VoteResult r = VoteOn(*voter, SceneOf(cat.cabinet));
  ASSERT_FALSE(r.hypotheses.empty());
  for (const auto& h : r.hypotheses) {
    ASSERT_TRUE(h.accepted.has_value());
    if (h.cls == "cabinet") {
      EXPECT_TRUE(*h.accepted);
    }
    if (h.cls == "table") {
      EXPECT_FALSE(*h.accepted);
      ASSERT_EQ(h.checks.size(), 1u);
      EXPECT_EQ(h.checks[0].name, "score");
      EXPECT_FALSE(h.checks[0].passed);
      EXPECT_DOUBLE_EQ(h.checks[0].value, h.score);
    }
  }
  // A second copy of the same proposal is suppressed (box IoU 1): still one per class.
  Scene twice = SceneOf(cat.cabinet);
  twice.proposals.items.push_back(twice.proposals.items[0]);
  const VoteResult r2 = VoteOn(*voter, twice);
  EXPECT_EQ(r2.hypotheses.size(), r.hypotheses.size());
  // 40 points (fewer than min_points): nothing to say.
  EXPECT_TRUE(VoteOn(*voter, SceneOf(cat.cabinet, 40)).hypotheses.empty());
}

TEST(EsfCatalog, RefusesForeignOrBrokenModels) {
  const auto& cat = Trained();
  auto voter = Make<Voter>("voters.esf_catalog");
  const json& good = TrainedModel3();
  auto refused = [&](const json& m, const std::string& says) {
    try {
      voter->Load(m);
      ADD_FAILURE() << "accepted: expected an InputError saying " << says;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  refused(json::array(), "not a voters.esf_catalog model");
  refused({{"format", "catalog_shape/1"}, {"models", json::array()}}, "not a voters.esf_catalog model");
  json m = good;
  m["bins"] = 308;
  refused(m, "640-bin");
  m = good;
  m["models"][1]["esf"][2].erase(m["models"][1]["esf"][2].begin());
  refused(m, "without 640 bins");
  m = good;
  m["models"][0]["size"][1] = -0.5;
  refused(m, "bad size");
  m = good;
  m["models"][2]["esf"][0][7] = 3000000;  // no longer a unit-sum histogram
  refused(m, "does not sum to 1");
  m = good;
  m["models"][2]["esf"][0][7] = -1;
  refused(m, "counts >= 0");
  m = good;
  m["models"][0].erase("class");
  refused(m, "without id, class");
  m = good;
  for (auto& md : m["models"]) md["esf"] = json::array();
  refused(m, "no descriptors");
  // Detection without a proposer is a graph error with the way out.
  voter->Load(good);
  Scene sc = SceneOf(cat.cabinet);
  SceneParts parts;
  parts.scan = &sc.scan;
  try {
    voter->Vote({parts}, RunContext{});
    ADD_FAILURE() << "voted without proposals";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("proposer"), std::string::npos) << e.what();
  }
}

// The same seed gives the same model and the same scores (PCL's ESF alone would draw from the
// wall clock); another seed draws other samples.
TEST(EsfCatalog, DeterministicForASeed) {
  const auto& cat = Trained();
  // Training: the chair's views (a third of the catalog keeps the test short).
  const std::vector<TrainingView> chair(cat.views.begin() + 8, cat.views.begin() + 16);
  ASSERT_EQ(chair.front().model_id, "test_chair");
  RunContext ctx;
  ctx.seed = 42;
  const json a = Make<Voter>("voters.esf_catalog")->Train(chair, ctx);
  const json b = Make<Voter>("voters.esf_catalog")->Train(chair, ctx);
  EXPECT_EQ(a, b);
  ctx.seed = 7;
  const json c = Make<Voter>("voters.esf_catalog")->Train(chair, ctx);
  EXPECT_NE(a["models"][0]["esf"][0], c["models"][0]["esf"][0]);

  // Detection: two voters on the same model and scene give the same hypotheses and scores.
  const Scene sc = SceneOf(cat.chair);
  std::vector<std::pair<std::string, float>> first;
  for (int run = 0; run < 2; ++run) {
    auto voter = Make<Voter>("voters.esf_catalog");
    voter->Load(TrainedModel3());
    const VoteResult r = VoteOn(*voter, sc);
    ASSERT_FALSE(r.hypotheses.empty());
    std::vector<std::pair<std::string, float>> got;
    for (const auto& h : r.hypotheses) got.emplace_back(h.cls, h.score);
    if (run == 0) {
      first = got;
    } else {
      EXPECT_EQ(got, first);
    }
  }
}

// A new scan of the chair against a catalog that also holds a table of very different size
// (1.2 x 0.8 x 0.75 m against 0.44 x 0.44 x 0.9 m), every training view voting (k 24) and no
// candidate dropped (min_score 0): ESF alone already prefers the chair; with the metric size the
// table's candidate all but vanishes.
TEST(EsfCatalog, ChairBeatsATableOfVeryDifferentSize) {
  const auto& cat = Trained();
  const Scene sc = SceneOf(cat.chair);
  auto esf_only = Make<Voter>("voters.esf_catalog", {{"k", 24}, {"min_score", 0}, {"size_weight", 0}});
  auto sized = Make<Voter>("voters.esf_catalog", {{"k", 24}, {"min_score", 0}});
  esf_only->Load(TrainedModel3());
  sized->Load(TrainedModel3());
  const VoteResult a = VoteOn(*esf_only, sc), b = VoteOn(*sized, sc);
  EXPECT_GT(ScoreOf(a, "chair"), 2.f * ScoreOf(a, "table"));
  const float chair = ScoreOf(b, "chair"), table = ScoreOf(b, "table");
  ASSERT_GT(table, 0.f);  // a real candidate, not a missing one
  EXPECT_GT(chair, 100.f * table) << "chair " << chair << " table " << table;
  for (const auto& h : b.hypotheses) {
    if (h.cls == "chair") {
      EXPECT_EQ(h.model, "test_chair");
      EXPECT_LT(h.evidence.at("e_size"), 0.5f);
    }
    if (h.cls == "table") {
      EXPECT_GT(h.evidence.at("e_size"), 3.f);
    }
  }
}

// Every bad parameter is refused before anything runs, with an error naming it.
TEST(EsfCatalog, BadParametersNameTheParameter) {
  auto refused = [](const json& params, const std::string& says) {
    try {
      Make<Voter>("voters.esf_catalog", params);
      ADD_FAILURE() << params.dump() << " accepted: expected an InputError saying " << says;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << params.dump() << ": " << e.what();
    }
  };
  refused({{"k", 0}}, "/k: expected an integer in [1, 1000]");
  refused({{"k", 2.5}}, "/k: ");
  refused({{"distance", "cosine"}}, "/distance: ");
  refused({{"distance", "cosine"}}, "chi2");  // says what would do
  refused({{"kernel_scale", 0}}, "/kernel_scale: expected a number in [0.001, 100]");
  refused({{"voxel_m", -0.02}}, "/voxel_m: ");
  refused({{"sig_size", "wide"}}, "/sig_size: ");
  refused({{"min_points", 2}}, "/min_points: ");
  refused({{"nms_iou", 1.5}}, "/nms_iou: ");
  refused({{"neighbours", 5}}, "neighbours");  // an unknown name
  refused({{"thresholds", {{"chair", -0.1}}}}, "thresholds/chair: expected a number in [0, inf]");
  refused({{"thresholds", {{"table", "high"}}}}, "thresholds/table: ");
  refused({{"class_map", {{"desk", ""}}}}, "class_map/desk: expected a class name");
  refused({{"class_map", {{"desk", 3}}}}, "class_map/desk: ");
  EXPECT_NO_THROW(Make<Voter>("voters.esf_catalog", {{"k", 1}, {"distance", "chi2"}, {"size_weight", 0}}));
}

// Train -> model file (the host's format: magic line + CBOR) -> load: the same model and the
// same scores as the model in memory.
TEST(EsfCatalog, ModelFileRoundTrip) {
  const auto& cat = Trained();
  TrainedModel tm;
  tm.voters["vote"].voter_type = "voters.esf_catalog";
  tm.voters["vote"].voter_model = TrainedModel3();
  const std::string dir = testing::TempDir("esf_catalog"), path = dir + "/model.fhm";
  SaveModel(path, tm);
  const TrainedModel back = LoadModel(path);
  std::filesystem::remove_all(dir);
  const TrainedVoter* tv = back.FindVoter("vote");
  ASSERT_NE(tv, nullptr);
  EXPECT_EQ(tv->voter_type, "voters.esf_catalog");
  EXPECT_EQ(tv->voter_model, TrainedModel3());

  const Scene sc = SceneOf(cat.table);
  auto from_memory = Make<Voter>("voters.esf_catalog"), from_file = Make<Voter>("voters.esf_catalog");
  from_memory->Load(TrainedModel3());
  from_file->Load(tv->voter_model);
  const VoteResult a = VoteOn(*from_memory, sc), b = VoteOn(*from_file, sc);
  ASSERT_FALSE(a.hypotheses.empty());
  ASSERT_EQ(a.hypotheses.size(), b.hypotheses.size());
  for (size_t i = 0; i < a.hypotheses.size(); ++i) {
    EXPECT_EQ(a.hypotheses[i].cls, b.hypotheses[i].cls);
    EXPECT_EQ(a.hypotheses[i].score, b.hypotheses[i].score);
    EXPECT_EQ(a.hypotheses[i].model, b.hypotheses[i].model);
  }
  EXPECT_EQ(Best(b)->cls, "table");
}

}  // namespace
}  // namespace furnihost
