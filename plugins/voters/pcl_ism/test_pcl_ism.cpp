// voters.pcl_ism through the registry: PCL's ISM trained on point-sampled synthetic views of a
// chair and a table (synthetic_furniture.hpp), then run on a room with both placed at known
// poses on a floor.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "furnihost/log.hpp"
#include "synthetic_furniture.hpp"
#include "test_support.hpp"

namespace furnihost {
namespace {

using nlohmann::json;
using namespace ism_synth;

Registry& Reg() {
  static auto reg = testing::MakeRegistry();
  return *reg;
}

std::shared_ptr<Voter> MakeVoter(const json& params) {
  const auto* entry = Reg().Find("voters.pcl_ism");
  if (!entry) throw std::runtime_error("plugin not found: voters.pcl_ism");
  return Reg().CreateAs<Voter>("voters.pcl_ism", entry->params.Resolve(params, "test"));
}

float Dist2D(const Eigen::Vector3f& a, const Eigen::Vector3f& b) { return (a.head<2>() - b.head<2>()).norm(); }

// Two chairs and a table on a 5 x 4 m floor seen from one side (~34k points).
const std::vector<Placed> kObjects = {{Chair(), Placement(1.f, 1.f, 0.5f)},
                                      {Chair(), Placement(2.f, 3.2f, 2.0f)},
                                      {Table(), Placement(3.2f, 1.6f, 0.3f)}};

// Trained once per process on eight views per class (~3k points each, 3 mm noise, the density
// of the simulated catalog views) with the default params, and its votes on the room.
struct Fixture {
  std::vector<TrainingView> views = MakeViews({Chair(), Table()}, 8, 0.02f, 11);
  Room room = MakeRoom(kObjects, {2.f, -1.f, 1.5f}, 0.015f, 0.03f, 5.f, 4.f, 5);
  std::shared_ptr<Voter> voter = MakeVoter(json::object());
  json model;
  VoteResult result;
  Fixture() {
    if (std::getenv("ISM_VERBOSE")) SetupLogging(2);
    RunContext ctx;
    model = voter->Train(views, ctx);
    result = voter->Vote({{&room.scan, &room.seg, nullptr}}, ctx);
  }
};
const Fixture& F() {
  static const Fixture f;
  return f;
}

const Hypothesis* Strongest(const VoteResult& r, const std::string& cls) {
  for (const auto& h : r.hypotheses)
    if (h.cls == cls) return &h;  // sorted by score
  return nullptr;
}

TEST(PclIsm, StrongestHypothesisOfEachClassIsWithinHalfAWidthAndHasItsParts) {
  const VoteResult& r = F().result;
  const Room& room = F().room;
  ASSERT_EQ(r.classes, (std::vector<std::string>{"chair", "table"}));
  ASSERT_FALSE(r.votes.empty());
  for (const auto& v : r.votes) {
    EXPECT_TRUE(v.z() == 0.f || v.z() == 1.f);
    EXPECT_GT(v.w(), 0.f);
  }
  ASSERT_EQ(r.grids.size(), 2u);
  EXPECT_GT(r.grids[0].width * r.grids[0].height, 0);
  for (size_t i = 1; i < r.hypotheses.size(); ++i) EXPECT_GE(r.hypotheses[i - 1].score, r.hypotheses[i].score);
  EXPECT_LE(r.hypotheses.size(), 20u);  // max_hypotheses 10 per class

  // ISM locates the centroid of an object's points (its training centre). Tolerance: half the
  // object's width (chair 0.25 m, table 0.6 m). The table's peak is the strongest table
  // hypothesis for every seed we tried (1-9, 42), but the strongest chair peak is not always on
  // a chair (seed 6: a spurious peak 0.5 m off outscores both chairs by 15 %), so each chair
  // must be among the top (chairs + 1) chair hypotheses.
  std::vector<const Hypothesis*> matched(kObjects.size(), nullptr);
  for (size_t o = 0; o < kObjects.size(); ++o) {
    const std::string& cls = kObjects[o].shape.cls;
    const size_t instances = std::count_if(kObjects.begin(), kObjects.end(),
                                           [&](const Placed& p) { return p.shape.cls == cls; });
    const size_t top = instances == 1 ? 1 : instances + 1;
    size_t rank = 0;
    float best = 1e9f;
    for (const auto& h : r.hypotheses) {
      if (h.cls != cls || rank++ >= top) continue;
      const float d = Dist2D(h.center, room.centre[o]);
      if (d < best) best = d, matched[o] = &h;
    }
    EXPECT_LT(best, 0.5f * kObjects[o].shape.size.x()) << cls << " " << o << " at " << room.centre[o].transpose();
    if (std::getenv("ISM_VERBOSE")) std::printf("%s %zu: %.3f m from the best of the top %zu\n", cls.c_str(), o, best, top);
  }
  const Hypothesis* table = Strongest(r, "table");
  ASSERT_NE(table, nullptr);
  EXPECT_GT(table->score, 0.f);

  // ISM has no parts: the segment parts around a peak support it.
  size_t supported = 0;
  for (const auto& h : r.hypotheses) {
    // Parts whose centroid lies within the class's footprint radius (half the diagonal).
    const float radius = h.cls == "chair" ? 0.5f * std::hypot(0.5f, 0.5f) : 0.5f * std::hypot(1.2f, 0.8f);
    for (const auto& s : h.support) {
      EXPECT_EQ(s.scene, 0);
      ASSERT_LT(static_cast<size_t>(s.part), room.seg.parts.size());
      EXPECT_LE(Dist2D(room.seg.parts[s.part].centroid, h.center), radius + 1e-4f);
      EXPECT_EQ(s.weight, 1.f);
    }
    supported += !h.support.empty();
  }
  EXPECT_GT(supported, 0u);
  // A hypothesis on an object is supported by that object's parts (seat, back, legs; top, legs).
  for (size_t o = 0; o < kObjects.size(); ++o) {
    if (!matched[o]) continue;
    int own = 0;
    for (const auto& s : matched[o]->support) own += room.part_object[s.part] == static_cast<int>(o);
    EXPECT_GE(own, 3) << kObjects[o].shape.cls << " " << o;
  }
}

TEST(PclIsm, LoadOfTheTrainedModelVotesIdentically) {
  RunContext ctx;
  auto loaded = MakeVoter(json::object());
  loaded->Load(json::from_cbor(json::to_cbor(F().model)));
  const Room& room = F().room;
  const VoteResult& ra = F().result;
  const VoteResult rb = loaded->Vote({{&room.scan, &room.seg, nullptr}}, ctx);
  ASSERT_EQ(ra.votes.size(), rb.votes.size());
  for (size_t i = 0; i < ra.votes.size(); ++i) ASSERT_EQ(ra.votes[i], rb.votes[i]) << i;
  ASSERT_EQ(ra.hypotheses.size(), rb.hypotheses.size());
  for (size_t i = 0; i < ra.hypotheses.size(); ++i) {
    EXPECT_EQ(ra.hypotheses[i].cls, rb.hypotheses[i].cls);
    EXPECT_EQ(ra.hypotheses[i].center, rb.hypotheses[i].center);
    EXPECT_EQ(ra.hypotheses[i].score, rb.hypotheses[i].score);
    EXPECT_EQ(ra.hypotheses[i].support.size(), rb.hypotheses[i].support.size());
  }
}

// Noise-free views: faces exactly along the axes, whose normals make PCL's local frame 0/0.
// A small model on noise-free views, for the tests that do not look at detection quality.
std::vector<TrainingView> ExactViews() { return MakeViews({Chair(), Table()}, 3, 0.03f, 4, 0.f); }
const json kSmall = {{"number_of_clusters", 12}};

TEST(PclIsm, TrainingIsDeterministicForASeedAndTheSeedReachesPclsKMeans) {
  const auto views = ExactViews();
  const json& params = kSmall;
  RunContext ctx;
  ctx.seed = 7;
  const json a = MakeVoter(params)->Train(views, ctx);
  const json b = MakeVoter(params)->Train(views, ctx);
  EXPECT_TRUE(a == b);
  // PCL seeds its k-means from time(): without the redirection these two would only differ
  // from the first ones if a second had passed, and would not repeat.
  ctx.seed = 8;
  const json c = MakeVoter(params)->Train(views, ctx);
  EXPECT_NE(a.at("ism"), c.at("ism"));
  EXPECT_EQ(a.at("ism").get<std::string>().find("nan"), std::string::npos);
}

// A table alone, no floor.
Room TableRoom() { return MakeRoom({{Table(), Placement(1.f, 1.f, 0.f)}}, {1.f, -2.f, 1.5f}, 0.03f, 0.f, 0, 0, 2); }

TEST(PclIsm, RefusesForeignOrUnreadableModelsAndUnknownClasses) {
  auto voter = MakeVoter(kSmall);
  RunContext ctx;
  const Room room = TableRoom();
  EXPECT_THROW(voter->Vote({{&room.scan, nullptr, nullptr}}, ctx), StageError);  // no model yet
  EXPECT_THROW(voter->Load({{"format", "voters.hough_vocabulary/1"}}), StageError);
  const json model = voter->Train(ExactViews(), ctx);
  json broken = model;
  std::string text = broken.at("ism");
  text.insert(text.find(' ') + 1, "nan ");
  broken["ism"] = text;
  EXPECT_THROW(voter->Load(broken), StageError);
  json truncated = model;
  truncated["ism"] = model.at("ism").get<std::string>().substr(0, 2000);
  EXPECT_THROW(voter->Load(truncated), StageError);

  auto sofa = MakeVoter({{"classes", "sofa"}});
  sofa->Load(model);
  try {
    sofa->Vote({{&room.scan, nullptr, nullptr}}, ctx);
    ADD_FAILURE() << "no error for an untrained class";
  } catch (const StageError& e) {
    EXPECT_NE(std::string(e.what()).find("chair, table"), std::string::npos) << e.what();
  }
}

TEST(PclIsm, ClassesParameterRestrictsTheVoting) {
  json params = kSmall;
  params.update({{"classes", "table"}, {"thresholds", {{"table", 1e-6}}}, {"max_hypotheses", 2}});
  auto voter = MakeVoter(params);
  RunContext ctx;
  voter->Train(ExactViews(), ctx);
  const Room room = TableRoom();
  const VoteResult r = voter->Vote({{&room.scan, nullptr, nullptr}}, ctx);
  ASSERT_FALSE(r.hypotheses.empty());
  EXPECT_LE(r.hypotheses.size(), 2u);
  for (const auto& h : r.hypotheses) {
    EXPECT_EQ(h.cls, "table");
    EXPECT_GE(h.score, 1e-6f);
  }
  for (const auto& v : r.votes) EXPECT_EQ(v.z(), 1.f);  // index of "table" in r.classes
}


// min_vote_weight only lowers findObjects' FLT_EPSILON cut on vote strength: the votes that
// passed before still pass with the same weight (reported in ISM's units), and more join them.
TEST(PclIsm, RelativeVoteCutOnlyAddsVotes) {
  RunContext ctx;
  json pcl_only = kSmall;
  pcl_only["min_vote_weight"] = 0.0;
  auto a = MakeVoter(pcl_only);
  const json model = a->Train(ExactViews(), ctx);
  json relaxed = kSmall;
  // Merged votes keep their total strength, so totals compare without the raw votes.
  relaxed.update({{"min_vote_weight", 1e-6}, {"max_plot_votes", 0}});
  pcl_only["max_plot_votes"] = 0;
  a = MakeVoter(pcl_only);
  a->Load(model);
  auto b = MakeVoter(relaxed);
  b->Load(model);
  const Room room = TableRoom();
  const VoteResult ra = a->Vote({{&room.scan, nullptr, nullptr}}, ctx);
  const VoteResult rb = b->Vote({{&room.scan, nullptr, nullptr}}, ctx);
  EXPECT_GT(rb.votes.size(), ra.votes.size());  // merged cells: a superset
  double wa = 0, wb = 0;
  for (const auto& v : ra.votes) wa += v.w();
  for (const auto& v : rb.votes) wb += v.w();
  EXPECT_GT(wb, wa * (1 - 1e-4));
  EXPECT_GT(wb, 0.);
  // The added votes are each below FLT_EPSILON, a few per cent of the weight; a scale left in
  // the reported weights would multiply the total by ~10 here.
  EXPECT_LT(wb, 1.5 * wa);
  if (std::getenv("ISM_VERBOSE")) std::printf("votes %zu -> %zu, weight %g -> %g\n", ra.votes.size(), rb.votes.size(), wa, wb);
}

}  // namespace
}  // namespace furnihost
