// fitters.ransac_upright through the registry, on ray-cast scans of box-built furniture.
// Tolerances: pose recovery within 3 cm (bounding-box centre, world frame) and 5° (yaw).
#include <gtest/gtest.h>

#include "furnihost/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "furnihost/stage.hpp"
#include "furnihost/host/ground_estimation.hpp"
#include "synthetic_scene.hpp"
#include "test_support.hpp"

namespace {

using namespace furnihost;
using namespace furnihost::synthetic;

constexpr float kPi = 3.14159265358979f;
constexpr float kCentreTol = 0.03f;           // [m]
constexpr float kYawTol = 5.f * kPi / 180.f;  // [rad]

std::shared_ptr<Fitter> MakeFitter(const nlohmann::json& params = nlohmann::json::object()) {
  static const auto reg = furnihost::testing::MakeRegistry();
  const PluginEntry* e = reg->Find("fitters.ransac_upright");
  if (!e) throw std::runtime_error("fitters.ransac_upright not found in " + furnihost::testing::PluginDir());
  return reg->CreateAs<Fitter>("fitters.ransac_upright", e->params.Resolve(params, "test"));
}

float AngleDiff(float a, float b, float period = 2 * kPi) {
  float d = std::fmod(std::fabs(a - b), period);
  return std::min(d, period - d);
}

Eigen::Isometry3f Upright(float x, float y, float yaw) {
  Eigen::Isometry3f t = Eigen::Isometry3f::Identity();
  t.linear() = Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  t.translation() = Eigen::Vector3f(x, y, 0.f);
  return t;
}

// Catalog of box furniture; meshes follow the catalog convention (bbox bottom centre at 0).
struct Catalog {
  std::vector<CatalogModel> models;
  std::vector<const CatalogModel*> Ptrs() const {
    std::vector<const CatalogModel*> p;
    for (const auto& m : models) p.push_back(&m);
    return p;
  }
  const CatalogModel& Get(const std::string& id) const {
    for (const auto& m : models)
      if (m.id == id) return m;
    throw std::runtime_error("no model " + id);
  }
};

Catalog FurnitureCatalog() {
  Catalog c;
  c.models.push_back(Model("chair_a", "chair", Chair(0.45f, 0.45f, 0.45f, 0.45f).mesh));
  c.models.push_back(Model("chair_b", "chair", Chair(0.56f, 0.50f, 0.40f, 0.62f, 0.05f).mesh));
  c.models.push_back(Model("table_a", "table", Table(1.2f, 0.8f, 0.75f).mesh));
  return c;
}

// Scans and segmentations that FitContext points into (kept at stable addresses).
struct Scenes {
  std::vector<std::unique_ptr<SimScan>> scans;
  std::vector<std::unique_ptr<Segmentation>> segs;
  int Add(SimScan s, int object, std::vector<int>* parts) {
    scans.push_back(std::make_unique<SimScan>(std::move(s)));
    std::vector<int> dummy;
    segs.push_back(std::make_unique<Segmentation>(PartsOf(*scans.back(), object, parts ? parts : &dummy)));
    return static_cast<int>(scans.size()) - 1;
  }
  FitContext Ctx(const Catalog& cat, int threads = 0, uint64_t seed = 7) const {
    FitContext ctx;
    for (size_t i = 0; i < scans.size(); ++i) ctx.scenes.push_back({&scans[i]->scan, segs[i].get(), nullptr});
    ctx.catalog = cat.Ptrs();
    ctx.run.seed = seed;
    ctx.run.threads = threads;
    return ctx;
  }
};

// A voter-like hypothesis: its centre is the mean of its parts' points (world frame); invalid
// scene or part numbers are kept in the support (the fitter must refuse them).
Detection Hypothesis(const Scenes& sc, const std::string& cls, int scene, const std::vector<int>& parts) {
  Detection d;
  d.cls = cls;
  d.score = 1.f;
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  int n = 0;
  for (int p : parts) {
    d.support.push_back({scene, p, 1.f});
    if (scene < 0 || scene >= int(sc.scans.size()) || p < 0 || p >= int(sc.segs[scene]->parts.size())) continue;
    const Scan& scan = sc.scans[scene]->scan;
    for (int i : sc.segs[scene]->parts[p].indices) {
      sum += scan.pose * scan.points[i];
      ++n;
    }
  }
  if (n > 0) d.center = sum / float(n);
  return d;
}

const Eigen::Vector3f kSensor(0.f, 0.f, 1.3f);
// The scan frame differs from the world frame, so that Scan::pose is exercised.
const Eigen::Isometry3f kScanPose = Upright(0.4f, -0.3f, 0.5f);

// One object of the catalog placed in a room and scanned from kSensor.
SimScan ScanOf(const CatalogModel& m, const Eigen::Isometry3f& pose, uint64_t seed, bool with_origin = true,
               bool object_present = true, int rays = 90) {
  World w;
  w.AddRoom(5.f, 2.5f);
  Furniture f;
  f.mesh = m.mesh;
  f.component.assign(m.mesh.triangles.size(), 0);
  // Components = the 12 triangles of each box, which is how the furniture was built.
  for (size_t t = 0; t < f.component.size(); ++t) f.component[t] = static_cast<int>(t / 12);
  if (object_present) w.Add(f.mesh, pose, 0, &f.component);
  const Eigen::Vector3f centre = pose * BoundsOf(m.mesh).center();
  const float radius = 0.5f * m.size.norm() + 0.1f;
  // ~90 x 90 rays over the object's angular box: about 2-3k points on a chair at 2 m.
  return SimulateObject(w, kSensor, centre, radius, rays, 0.003f, 0.05f, seed, kScanPose, with_origin);
}

struct PoseError {
  float centre, yaw;
};
PoseError ErrorOf(const Detection& d, const CatalogModel& m, const Eigen::Isometry3f& truth, float period = 2 * kPi) {
  const Eigen::Vector3f c = truth * BoundsOf(m.mesh).center();
  const float yaw = std::atan2(truth.linear()(1, 0), truth.linear()(0, 0));
  return {(d.center - c).norm(), AngleDiff(d.yaw, yaw, period)};
}

// The chair most tests fit: chair_a at kChairPose, scanned from kSensor (scan seed 1); returns
// its scene index and fills its parts.
const Eigen::Isometry3f kChairPose = Upright(1.8f, 0.9f, 2.2f);
int AddChair(const Catalog& cat, Scenes* sc, std::vector<int>* parts) {
  return sc->Add(ScanOf(cat.Get("chair_a"), kChairPose, 1), 0, parts);
}

// The same fit, bit for bit (seeds, threads and caches must not change it).
void ExpectSameFit(const Detection& a, const Detection& b) {
  EXPECT_EQ(a.model, b.model);
  EXPECT_EQ(a.yaw, b.yaw);
  EXPECT_EQ(a.center, b.center);
  EXPECT_EQ(a.coverage, b.coverage);
  EXPECT_EQ(a.rms, b.rms);
  EXPECT_EQ(a.free_space_ratio, b.free_space_ratio);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.verified, b.verified);
  EXPECT_EQ(a.Rejection(), b.Rejection());
  EXPECT_EQ(a.checks.size(), b.checks.size());
  EXPECT_TRUE(a.model_pose.matrix() == b.model_pose.matrix());
}

TEST(RansacUpright, RecoversChairPoseAndModel) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = kChairPose;
  const int s = AddChair(cat, &sc, &parts);
  ASSERT_GT(sc.scans[0]->scan.points.size(), 1500u);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  const Detection& d = out[0];
  EXPECT_EQ(d.model, "chair_a");
  const PoseError e = ErrorOf(d, cat.Get("chair_a"), truth);
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
  ASSERT_TRUE(d.verified.has_value());
  EXPECT_TRUE(*d.verified) << d.Rejection();
  ASSERT_TRUE(d.coverage && d.free_space_ratio && d.rms);  // the scan has an origin: the test ran
  EXPECT_GT(*d.coverage, 0.8f);
  EXPECT_GE(*d.free_space_ratio, 0.f);
  EXPECT_LT(*d.free_space_ratio, 0.2f);
  EXPECT_GT(*d.rms, 0.f);
  EXPECT_LT(*d.rms, 0.015f);
  EXPECT_GT(d.iterations, 0);
  // model_pose maps the model's bbox centre onto the reported centre.
  EXPECT_LT((d.model_pose * BoundsOf(cat.Get("chair_a").mesh).center() - d.center).norm(), 1e-4f);
}

// A dense scan (a tilting laser close by: ~10x the part points of the tests above): each
// candidate is scored on at most max_score_points of them and the final coverage on an even
// subset, which must find the same model and pose as scoring on all of them, and about the same
// coverage.
TEST(RansacUpright, DenseScanFitsOnASubsetAsOnAllPoints) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = sc.Add(ScanOf(cat.Get("chair_a"), kChairPose, 1, true, true, 300), 0, &parts);
  const Detection h = Hypothesis(sc, "chair", s, parts);
  const auto sub = MakeFitter()->Fit({h}, sc.Ctx(cat));  // default: max_score_points 2000
  const auto all = MakeFitter({{"max_score_points", 0}})->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(sub.size(), 1u);
  ASSERT_EQ(all.size(), 1u);
  ASSERT_TRUE(sub[0].coverage && all[0].coverage);
  size_t part_points = 0;
  for (int p : parts) part_points += sc.segs[0]->parts[p].indices.size();
  ASSERT_GT(part_points, 4u * 2000u);  // both caps bind
  for (const Detection* d : {&sub[0], &all[0]}) {
    EXPECT_EQ(d->model, "chair_a");
    const PoseError e = ErrorOf(*d, cat.Get("chair_a"), kChairPose);
    EXPECT_LT(e.centre, kCentreTol);
    EXPECT_LT(e.yaw, kYawTol);
    EXPECT_TRUE(d->verified.value_or(false)) << d->Rejection();
  }
  EXPECT_NEAR(*sub[0].coverage, *all[0].coverage, 0.03f);
}

// A scan whose floor is 0.6 m below z = 0 (a robot's sensor frame, say): the models stand on
// the scan's ground (Scan::ground, in the scan's frame, here posed 0.6 m down), never on z = 0.
// A ground put at world z = 0 leaves every model 0.6 m too high and nothing fits; the ground
// the pipeline estimates from the scan (the room's floor is in view) fits the chair, as a level
// ground fixed at the true height does.
TEST(RansacUpright, ModelsStandOnTheScansGround) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = Upright(1.8f, 0.9f, 2.2f);
  SimScan sim = ScanOf(cat.Get("chair_a"), truth, 1);
  const Eigen::Isometry3f down(Eigen::Translation3f(0.f, 0.f, -0.6f));
  sim.scan.pose = down * sim.scan.pose;
  const int s = sc.Add(std::move(sim), 0, &parts);
  const Detection h = Hypothesis(sc, "chair", s, parts);
  Scan& scan = sc.scans[0]->scan;
  const GroundModel estimated = EstimateGround(scan.points, GroundOptions{});
  EXPECT_NEAR(scan.pose.translation().z() + estimated.HeightAt(1.8f, 0.9f), -0.6f, 0.005f);
  scan.ground = GroundModel::Level(0.6f, "fixed");  // world z = 0
  const auto at_zero = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(at_zero.size(), 1u);
  EXPECT_FALSE(at_zero[0].verified.value_or(true));
  // One RANSAC draw each (the sampling path changes with any change of the floor height, so
  // the two fits differ by sampling; the statistical accuracy bound is AccuracyOverRandomPlacements').
  for (const GroundModel& g : {estimated, GroundModel::Level(0.f, "fixed")}) {
    scan.ground = g;
    const auto out = MakeFitter()->Fit({h}, sc.Ctx(cat));
    ASSERT_EQ(out.size(), 1u);
    const Detection& d = out[0];
    EXPECT_TRUE(d.verified.value_or(false)) << ToString(g.kind) << ": " << d.Rejection();
    EXPECT_EQ(d.model, "chair_a");
    const Eigen::Vector3f c = down * truth * BoundsOf(cat.Get("chair_a").mesh).center();
    EXPECT_NEAR(d.center.z(), c.z(), 0.006f);  // stands on the floor
    EXPECT_LT((d.center - c).head<2>().norm(), 2 * kCentreTol);
    EXPECT_LT(ErrorOf(d, cat.Get("chair_a"), down * truth).yaw, kYawTol);
    // The box is the fitted model's: its bottom on the ground, its size the model's.
    ASSERT_TRUE(d.box.has_value());
    EXPECT_EQ(d.box_source, "model");
    EXPECT_NEAR(d.box->center.z() - 0.5f * d.box->size.z(), -0.6f, 0.006f);
    EXPECT_TRUE(d.box->size.isApprox(BoundsOf(cat.Get("chair_a").mesh).sizes(), 1e-4f));
  }
}

// The voter's support holds every part with a vote near the maximum, background parts (floor,
// walls) included: they are left out of the fit, else they dilute the coverage.
TEST(RansacUpright, BackgroundPartsInTheSupportAreLeftOut) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = kChairPose;
  const int s = AddChair(cat, &sc, &parts);
  const int background = static_cast<int>(sc.segs[s]->parts.size()) - 1;  // PartsOf puts the rest last
  ASSERT_EQ(std::find(parts.begin(), parts.end(), background), parts.end());
  Detection h = Hypothesis(sc, "chair", s, parts);
  h.support.push_back({s, background, 1.f});
  const auto out = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "chair_a");
  const PoseError e = ErrorOf(out[0], cat.Get("chair_a"), truth);
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
  EXPECT_TRUE(out[0].verified.value_or(false)) << out[0].Rejection();
  const std::string note = "support: 1 of " + std::to_string(h.support.size()) + " parts out of the class' reach";
  EXPECT_TRUE(std::any_of(out[0].notes.begin(), out[0].notes.end(),
                          [&](const std::string& n) { return n.rfind(note, 0) == 0; }));
  // Left out rather than cropped: the same pose.
  const auto left_out = MakeFitter({{"crop_parts", false}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(left_out[0].model, "chair_a");
  EXPECT_LT(ErrorOf(left_out[0], cat.Get("chair_a"), truth).centre, kCentreTol);
  // Without the filter the background's points count against the chair.
  const auto all = MakeFitter({{"part_inside_fraction", 0.0}})->Fit({h}, sc.Ctx(cat));
  std::printf("[ support ] coverage %.3f with the background part cropped to the reach, %.3f with all of it\n", out[0].coverage.value_or(-1.f),
              all[0].coverage.value_or(-1.f));
  ASSERT_TRUE(out[0].coverage && all[0].coverage);
  EXPECT_LT(*all[0].coverage, *out[0].coverage - 0.1f);
}

// max_shift_m: a hypothesis whose centre is 0.3 m off the chair. Unlimited, the fit finds the
// chair; limited to 0.15 m, no pose may put the centre farther than that from the hypothesis
// (the fit then covers too little and is rejected); limited to 0.5 m, the chair again.
TEST(RansacUpright, MaxShiftKeepsTheFitNearTheVotersCentre) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = kChairPose;
  const int s = AddChair(cat, &sc, &parts);
  Detection h = Hypothesis(sc, "chair", s, parts);
  const Eigen::Vector3f true_centre = truth * BoundsOf(cat.Get("chair_a").mesh).center();
  h.center = true_centre + Eigen::Vector3f(0.3f, 0.f, 0.f);
  const auto free = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(free.size(), 1u);
  EXPECT_LT(ErrorOf(free[0], cat.Get("chair_a"), truth).centre, kCentreTol);
  EXPECT_TRUE(free[0].verified.value_or(false)) << free[0].Rejection();

  const auto tight = MakeFitter({{"max_shift_m", 0.15}})->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(tight.size(), 1u);
  if (!tight[0].model.empty()) {
    EXPECT_LE((tight[0].center - h.center).head<2>().norm(), 0.15f + 1e-4f);
  }
  EXPECT_FALSE(tight[0].verified.value_or(true));

  const auto loose = MakeFitter({{"max_shift_m", 0.5}})->Fit({h}, sc.Ctx(cat));
  EXPECT_LT(ErrorOf(loose[0], cat.Get("chair_a"), truth).centre, kCentreTol);
  EXPECT_TRUE(loose[0].verified.value_or(false)) << loose[0].Rejection();

  EXPECT_THROW(MakeFitter({{"max_shift_m", -0.1}}), std::exception);
}

// cloud_cache: the first fitter samples the class's models and writes one file per model; a
// new fitter (a new run) reads them and fits exactly as the sampling one did; 'off' writes
// nothing; an unwritable folder only warns.
TEST(RansacUpright, ModelCloudsAreCachedBetweenRuns) {
  namespace fs = std::filesystem;
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = AddChair(cat, &sc, &parts);
  const Detection h = Hypothesis(sc, "chair", s, parts);
  const std::string dir = furnihost::testing::TempDir("cloud_cache") + "/clouds";
  auto files = [&] {
    size_t n = 0;
    if (fs::exists(dir))
      for (const auto& e : fs::directory_iterator(dir)) n += e.path().extension() == ".fhmc";
    return n;
  };
  const auto off = MakeFitter({{"cloud_cache", "off"}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(files(), 0u);
  const auto first = MakeFitter({{"cloud_cache", dir}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(files(), 2u);  // chair_a and chair_b; the table is not of the class
  const auto again = MakeFitter({{"cloud_cache", dir}})->Fit({h}, sc.Ctx(cat));
  ASSERT_EQ(first.size(), 1u);
  ASSERT_EQ(again.size(), 1u);
  ExpectSameFit(first[0], off[0]);
  ExpectSameFit(again[0], off[0]);
  const auto unwritable = MakeFitter({{"cloud_cache", "/proc/furnihost_no_such_dir"}})->Fit({h}, sc.Ctx(cat));
  EXPECT_EQ(unwritable[0].center, off[0].center);
  fs::remove_all(fs::path(dir).parent_path());
}

TEST(RansacUpright, RecoversTablePoseUpToItsSymmetry) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = Upright(-1.6f, 1.4f, 0.3f);
  const int s = sc.Add(ScanOf(cat.Get("table_a"), truth, 2), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "table", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "table_a");
  const PoseError e = ErrorOf(out[0], cat.Get("table_a"), truth, kPi);  // a rectangle: 180° symmetric
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
  EXPECT_TRUE(out[0].verified.value_or(false)) << out[0].Rejection();
}

// A scanned chair whose class has one catalog model, a table mesh filed as a chair: no pose of it
// covers the chair's points.
struct WrongShapeScene {
  Catalog cat;
  Scenes sc;
  std::vector<int> parts;
  int scene = 0;
};
WrongShapeScene MakeWrongShapeScene() {
  WrongShapeScene w;
  w.cat.models.push_back(Model("table_as_chair", "chair", Table(1.2f, 0.8f, 0.75f).mesh));
  const CatalogModel chair = Model("real_chair", "chair", Chair(0.45f, 0.45f, 0.45f, 0.45f).mesh);
  w.scene = w.sc.Add(ScanOf(chair, Upright(1.8f, 0.9f, 2.2f), 3), 0, &w.parts);
  return w;
}

TEST(RansacUpright, WrongShapeIsRejectedByCoverage) {
  const WrongShapeScene w = MakeWrongShapeScene();
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(w.sc, "chair", w.scene, w.parts)}, w.sc.Ctx(w.cat));
  ASSERT_EQ(out.size(), 1u);
  const Detection& d = out[0];
  ASSERT_TRUE(d.verified.has_value());
  EXPECT_FALSE(*d.verified);
  // The checks say what was measured and why it failed: coverage below min_coverage.
  ASSERT_EQ(d.checks.size(), 1u);
  EXPECT_EQ(d.checks[0].name, "coverage");
  EXPECT_FALSE(d.checks[0].passed);
  EXPECT_TRUE(d.checks[0].at_least);
  EXPECT_DOUBLE_EQ(d.checks[0].limit, 0.5);
  ASSERT_TRUE(d.coverage);
  EXPECT_FLOAT_EQ(float(d.checks[0].value), *d.coverage);
  EXPECT_EQ(d.Rejection().rfind("coverage ", 0), 0u) << d.Rejection();
  EXPECT_NE(d.Rejection().find(" < 0.5"), std::string::npos) << d.Rejection();
  EXPECT_GE(*d.coverage, 0.f);
  EXPECT_LT(*d.coverage, 0.5f);
  EXPECT_EQ(d.model, "table_as_chair");  // the pose that was rejected is still reported
}

// Seen from the front, a small cabinet's points are covered just as well by a wider cabinet of
// the same depth and height: the tie is broken by the share of each model explained.
TEST(RansacUpright, TiedModelsAreRankedByTheShareOfThemselvesExplained) {
  Catalog cat;
  Mesh wide, narrow;
  AddBox(&wide, nullptr, 0, {-0.6f, -0.25f, 0.f}, {0.6f, 0.25f, 0.6f});
  AddBox(&narrow, nullptr, 0, {-0.2f, -0.25f, 0.f}, {0.2f, 0.25f, 0.6f});
  cat.models.push_back(Model("wide_cabinet", "cabinet", wide));
  cat.models.push_back(Model("narrow_cabinet", "cabinet", narrow));
  Scenes sc;
  std::vector<int> parts;
  const Eigen::Isometry3f truth = Upright(0.f, 2.5f, 0.f);  // front face towards the sensor
  const int s = sc.Add(ScanOf(cat.Get("narrow_cabinet"), truth, 8), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "cabinet", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "narrow_cabinet");
  ASSERT_FALSE(out[0].notes.empty());
  // Both models reached (about) full coverage: the choice was the tie-break, not coverage.
  EXPECT_EQ(out[0].notes[0].find("abandoned"), std::string::npos) << out[0].notes[0];
  const PoseError e = ErrorOf(out[0], cat.Get("narrow_cabinet"), truth, kPi);  // a box: 180° symmetric
  EXPECT_LT(e.centre, kCentreTol);
  EXPECT_LT(e.yaw, kYawTol);
}

// The chair's points come from a reconstruction without origin; a second scan with a sensor
// origin saw the room without the chair, so its rays cross where the chair would stand.
TEST(RansacUpright, ModelInObservedFreeSpaceIsRejected) {
  const Catalog cat = FurnitureCatalog();
  const CatalogModel& chair = cat.Get("chair_a");
  const Eigen::Isometry3f where = Upright(1.8f, 0.9f, 2.2f);
  for (bool chair_in_laser_scan : {false, true}) {
    Scenes sc;
    std::vector<int> parts;
    sc.Add(ScanOf(chair, where, 4, true, chair_in_laser_scan), -2, nullptr);  // laser scan, origin known
    const int s = sc.Add(ScanOf(chair, where, 5, false), 0, &parts);            // chair points, no origin
    auto fitter = MakeFitter();
    const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat));
    ASSERT_EQ(out.size(), 1u);
    const Detection& d = out[0];
    EXPECT_EQ(d.model, "chair_a");
    ASSERT_TRUE(d.coverage && d.free_space_ratio);
    EXPECT_GE(*d.coverage, 0.5f);
    // Two checks, in order: coverage (passed), then free space.
    ASSERT_EQ(d.checks.size(), 2u);
    EXPECT_EQ(d.checks[0].name, "coverage");
    EXPECT_TRUE(d.checks[0].passed);
    EXPECT_EQ(d.checks[1].name, "free_space_ratio");
    EXPECT_FALSE(d.checks[1].at_least);
    EXPECT_EQ(d.checks[1].passed, chair_in_laser_scan);
    if (chair_in_laser_scan) {
      EXPECT_TRUE(d.verified.value_or(false)) << d.Rejection();
      EXPECT_LT(*d.free_space_ratio, 0.2f);
    } else {
      EXPECT_FALSE(d.verified.value_or(true));
      EXPECT_GT(*d.free_space_ratio, 0.5f);
      EXPECT_EQ(d.Rejection().rfind("free_space_ratio ", 0), 0u) << d.Rejection();
    }
    EXPECT_GE(*d.free_space_ratio, 0.f);
    std::printf("[ free space ] chair %s the laser scan: free_space_ratio %.3f, coverage %.3f\n",
                chair_in_laser_scan ? "in" : "missing from", *d.free_space_ratio, *d.coverage);
  }
}

TEST(RansacUpright, ScanWithoutOriginSkipsTheFreeSpaceTest) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = sc.Add(ScanOf(cat.Get("chair_b"), Upright(-1.2f, -1.9f, -0.8f), 6, false), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].model, "chair_b");
  EXPECT_TRUE(out[0].verified.value_or(false)) << out[0].Rejection();
  EXPECT_FALSE(out[0].free_space_ratio.has_value());
  EXPECT_NE(std::find(out[0].notes.begin(), out[0].notes.end(), "free-space test skipped: scan has no sensor origin"),
            out[0].notes.end());
}

// A recogniser of object proposals (voters.catalog_shape) names a proposal, not parts, and the
// graph has no segmentation: the fitter takes the proposal's points and estimates their normals
// itself (without them every sample would draw a random yaw, and 10 samples rarely find the
// pose).
TEST(RansacUpright, ProposalHypothesesFitTheProposalsPointsAndFreeSpaceChoosesAmongTiedPoses) {
  const Catalog cat = FurnitureCatalog();
  const CatalogModel& chair = cat.Get("chair_b");
  const SimScan sim = ScanOf(chair, kChairPose, 11);
  Proposals props;
  Proposal prop;
  Eigen::Vector3f sum = Eigen::Vector3f::Zero();
  for (size_t i = 0; i < sim.scan.points.size(); ++i)
    if (sim.object[i] == 0) {
      prop.indices.push_back(static_cast<int>(i));
      sum += sim.scan.pose * sim.scan.points[i];
    }
  ASSERT_GT(prop.indices.size(), 1000u);
  props.items.push_back(prop);
  FitContext ctx;
  ctx.scenes.push_back({&sim.scan, nullptr, nullptr, &props});  // no segmentation: no normals
  ctx.catalog = cat.Ptrs();
  ctx.run.seed = 3;
  Detection h;
  h.cls = "chair";
  h.score = 0.3f;
  h.center = sum / float(prop.indices.size());
  h.proposal = 0;
  // Seen from one side, the chair is covered as well by its turn by 180 degrees pushed back,
  // which free space refuses: free_space_alternatives then takes the near-tied right pose.
  int refused_by_free_space = 0;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    ctx.run.seed = seed;
    const auto plain = MakeFitter()->Fit({h}, ctx);
    ASSERT_EQ(plain.size(), 1u);
    EXPECT_EQ(plain[0].model, "chair_b") << "seed " << seed;
    EXPECT_GT(plain[0].coverage.value_or(0.f), 0.95f) << "seed " << seed;
    refused_by_free_space += !plain[0].verified.value_or(false);
    const auto out = MakeFitter({{"free_space_alternatives", true}})->Fit({h}, ctx);
    const PoseError e = ErrorOf(out[0], chair, kChairPose);
    EXPECT_TRUE(out[0].verified.value_or(false)) << "seed " << seed << ": " << out[0].Rejection();
    EXPECT_LT(e.centre, kCentreTol) << "seed " << seed;
    EXPECT_LT(e.yaw, kYawTol) << "seed " << seed;
    if (!plain[0].verified.value_or(false)) {
      EXPECT_EQ(plain[0].Rejection().rfind("free_space_ratio ", 0), 0u) << plain[0].Rejection();
      EXPECT_NE(out[0].notes.back().find("a near-tied pose passes"), std::string::npos) << out[0].notes.back();
    }
  }
  EXPECT_GT(refused_by_free_space, 0);  // the case the option is for occurred
  // A proposal the scene does not have is refused.
  h.proposal = 1;
  EXPECT_THROW(MakeFitter()->Fit({h}, ctx), StageError);
}

// one_class_per_object: two accepted readings of one proposal (its box overlapping another's by
// more than object_iou) keep only the higher-scored class; a proposal elsewhere is untouched.
TEST(RansacUpright, OneClassPerObjectRefusesTheWeakerReadingOfAProposal) {
  const Catalog cat = FurnitureCatalog();
  const SimScan sim = ScanOf(cat.Get("chair_b"), kChairPose, 12);
  Proposals props;
  Proposal chair_points, background;
  for (size_t i = 0; i < sim.scan.points.size(); ++i) {
    Proposal& p = sim.object[i] == 0 ? chair_points : background;
    p.indices.push_back(static_cast<int>(i));
    p.box.extend(sim.scan.points[i]);
  }
  ASSERT_FALSE(background.indices.empty());
  props.items = {chair_points, chair_points, background};
  FitContext ctx;
  ctx.scenes.push_back({&sim.scan, nullptr, nullptr, &props});
  ctx.catalog = cat.Ptrs();
  // Each accepted by its recogniser; keep_accepted with floor 0 keeps them whatever the fit says.
  auto accepted = [&](const std::string& cls, float score, int proposal) {
    Detection d;
    d.cls = cls;
    d.score = score;
    d.proposal = proposal;
    d.center = sim.scan.pose * props.items[size_t(proposal)].box.center();
    d.verified = true;
    d.checks = {Check::AtLeast("score", score, 0.1)};
    return d;
  };
  const std::vector<Detection> in = {accepted("table", 0.3f, 1), accepted("chair", 0.6f, 0),
                                     accepted("table", 0.2f, 2)};
  const nlohmann::json keep = {{"keep_accepted", true}, {"keep_min_coverage", 0.0}};
  nlohmann::json exclusive = keep;
  exclusive["one_class_per_object"] = true;
  const auto both = MakeFitter(keep)->Fit(in, ctx);
  const auto one = MakeFitter(exclusive)->Fit(in, ctx);
  ASSERT_EQ(both.size(), 3u);
  ASSERT_EQ(one.size(), 3u);
  for (const Detection& d : both) EXPECT_TRUE(d.verified.value_or(false)) << d.cls << ": " << d.Rejection();
  EXPECT_FALSE(one[0].verified.value_or(true));  // the table reading of the chair's points
  EXPECT_EQ(one[0].Rejection(), "iou_with_stronger_class 1 > 0.5");
  EXPECT_NE(one[0].notes.back().find("the same object as an accepted chair"), std::string::npos) << one[0].notes.back();
  EXPECT_TRUE(one[1].verified.value_or(false)) << one[1].Rejection();
  EXPECT_TRUE(one[2].verified.value_or(false)) << one[2].Rejection();  // the room around: another object
}

// keep_accepted: what the recogniser accepted on its own stays accepted, with its checks and box,
// when the fit fails, unless the fit covers less than keep_min_coverage (it contradicts it).
TEST(RansacUpright, KeepAcceptedTrustsTheRecogniserUnlessTheFitContradictsIt) {
  const WrongShapeScene w = MakeWrongShapeScene();
  const Catalog& cat = w.cat;
  const Scenes& sc = w.sc;
  Detection h = Hypothesis(sc, "chair", w.scene, w.parts);
  const auto plain = MakeFitter()->Fit({h}, sc.Ctx(cat));
  ASSERT_TRUE(plain[0].coverage.has_value());
  const float c = *plain[0].coverage;
  ASSERT_FALSE(plain[0].verified.value_or(true));
  ASSERT_GT(c, 0.02f);
  h.verified = true;  // as voters.catalog_shape leaves an accepted proposal
  h.checks = {Check::AtLeast("score", 0.3, 0.2)};
  h.box = OrientedBox{h.center, Eigen::Vector3f(0.45f, 0.45f, 0.9f), 0.f};
  h.box_source = "proposal";
  for (const float floor : {c - 0.01f, c + 0.01f}) {
    const auto out = MakeFitter({{"keep_accepted", true}, {"keep_min_coverage", floor}})->Fit({h}, sc.Ctx(cat));
    ASSERT_EQ(out.size(), 1u);
    const Detection& d = out[0];
    if (floor < c) {
      EXPECT_TRUE(d.verified.value_or(false));
      ASSERT_EQ(d.checks.size(), 1u);
      EXPECT_EQ(d.checks[0].name, "score");
      EXPECT_EQ(d.Rejection(), "");
      EXPECT_EQ(d.box_source, "proposal");
      EXPECT_EQ(d.center, h.center);
      ASSERT_TRUE(d.evidence.count("fit_coverage"));
      EXPECT_FLOAT_EQ(d.evidence.at("fit_coverage"), c);
      EXPECT_NE(d.notes.back().find("kept, its recogniser accepted it"), std::string::npos) << d.notes.back();
    } else {
      EXPECT_FALSE(d.verified.value_or(true));
      EXPECT_EQ(d.Rejection().rfind("coverage ", 0), 0u) << d.Rejection();
    }
  }
  // A hypothesis its recogniser left undecided (or refused) is the fit's to decide.
  h.verified.reset();
  EXPECT_FALSE(MakeFitter({{"keep_accepted", true}, {"keep_min_coverage", 0.0}})
                   ->Fit({h}, sc.Ctx(cat))[0]
                   .verified.value_or(true));
}

// free_space_alternatives consults the near-tied poses only when free space refuses the best:
// a fit that passes is unchanged bit for bit, and a chair the laser saw through stays refused
// (no near-tied pose of it escapes the free space).
TEST(RansacUpright, FreeSpaceAlternativesOnlyReplaceARefusedPose) {
  const Catalog cat = FurnitureCatalog();
  const CatalogModel& chair = cat.Get("chair_a");
  for (bool chair_in_laser_scan : {false, true}) {
    Scenes sc;
    std::vector<int> parts;
    sc.Add(ScanOf(chair, kChairPose, 4, true, chair_in_laser_scan), -2, nullptr);
    const int s = sc.Add(ScanOf(chair, kChairPose, 5, false), 0, &parts);
    const Detection h = Hypothesis(sc, "chair", s, parts);
    const auto base = MakeFitter()->Fit({h}, sc.Ctx(cat));
    const auto alt = MakeFitter({{"free_space_alternatives", true}})->Fit({h}, sc.Ctx(cat));
    ASSERT_EQ(alt.size(), 1u);
    EXPECT_EQ(alt[0].verified.value_or(false), chair_in_laser_scan) << alt[0].Rejection();
    if (chair_in_laser_scan) ExpectSameFit(base[0], alt[0]);
  }
}

TEST(RansacUpright, ClassWithoutModelsAndBadSupport) {
  const Catalog cat = FurnitureCatalog();
  Scenes sc;
  std::vector<int> parts;
  const int s = sc.Add(ScanOf(cat.Get("chair_a"), Upright(1.8f, 0.9f, 2.2f), 7), 0, &parts);
  auto fitter = MakeFitter();
  const auto out = fitter->Fit({Hypothesis(sc, "sofa", s, parts)}, sc.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_FALSE(out[0].verified.value_or(true));
  ASSERT_EQ(out[0].checks.size(), 1u);
  EXPECT_EQ(out[0].checks[0].name, "catalog_models");
  EXPECT_EQ(out[0].Rejection(), "catalog_models 0 < 1");
  EXPECT_NE(std::find(out[0].notes.begin(), out[0].notes.end(), "no catalog model of class 'sofa'"), out[0].notes.end());
  EXPECT_THROW(fitter->Fit({Hypothesis(sc, "chair", s, {999})}, sc.Ctx(cat)), StageError);
  EXPECT_THROW(fitter->Fit({Hypothesis(sc, "chair", 3, parts)}, sc.Ctx(cat)), StageError);
}

// One scan of a room with a chair (object 0) and a table (object 1); each object's parts are
// a scene of their own (the same scan twice).
struct ChairAndTableRoom {
  Scenes sc;
  std::vector<int> chair_parts, table_parts;
  int chair_scene = 0, table_scene = 0;
};
ChairAndTableRoom MakeChairAndTableRoom() {
  ChairAndTableRoom r;
  World w;
  w.AddRoom(5.f, 2.5f);
  const Furniture chair = Chair(0.45f, 0.45f, 0.45f, 0.45f), table = Table(1.2f, 0.8f, 0.75f);
  w.Add(chair.mesh, Upright(1.8f, 0.9f, 2.2f), 0, &chair.component);
  w.Add(table.mesh, Upright(1.2f, -1.4f, 0.3f), 1, &table.component);
  const SimScan room = Simulate(w, kSensor, -1.6f, 1.0f, 200, -0.9f, 0.1f, 60, 0.003f, 0.05f, 9, kScanPose);
  r.chair_scene = r.sc.Add(room, 0, &r.chair_parts);
  r.table_scene = r.sc.Add(room, 1, &r.table_parts);
  return r;
}

TEST(RansacUpright, DeterministicForASeedWhateverTheThreads) {
  const Catalog cat = FurnitureCatalog();
  const ChairAndTableRoom room = MakeChairAndTableRoom();
  const Scenes& sc = room.sc;
  const std::vector<Detection> in = {Hypothesis(sc, "chair", room.chair_scene, room.chair_parts),
                                     Hypothesis(sc, "table", room.table_scene, room.table_parts),
                                     Hypothesis(sc, "chair", room.table_scene, room.table_parts)};
  auto run = [&](int threads, uint64_t seed) { return MakeFitter()->Fit(in, sc.Ctx(cat, threads, seed)); };
  const auto a = run(1, 11), b = run(2, 11);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE("detection " + std::to_string(i));
    ExpectSameFit(a[i], b[i]);
    EXPECT_EQ(a[i].notes, b[i].notes);
  }
  EXPECT_TRUE(a[0].verified.value_or(false)) << a[0].Rejection();
  EXPECT_TRUE(a[1].verified.value_or(false)) << a[1].Rejection();
  EXPECT_FALSE(a[2].verified.value_or(true));  // chair models on the table's points
  // Another seed samples differently (the iteration counts are the seed's footprint).
  const auto c = run(2, 12);
  int differs = 0;
  for (size_t i = 0; i < a.size(); ++i) differs += a[i].iterations != c[i].iterations || a[i].yaw != c[i].yaw;
  EXPECT_GT(differs, 0);
}

// A hypothesis's RANSAC seed comes from the hypothesis, not its place in the list: fitted alone,
// behind others or in reverse order it gives the same pose (A/B runs that change one class's
// hypotheses leave the other classes' fits alone).
TEST(RansacUpright, AHypothesisFitsTheSameWhateverElseIsInTheList) {
  const Catalog cat = FurnitureCatalog();
  const ChairAndTableRoom room = MakeChairAndTableRoom();
  const Scenes& sc = room.sc;
  const Detection c = Hypothesis(sc, "chair", room.chair_scene, room.chair_parts),
                  t = Hypothesis(sc, "table", room.table_scene, room.table_parts);
  const auto fit = [&](const std::vector<Detection>& in) { return MakeFitter()->Fit(in, sc.Ctx(cat, 1, 5)); };
  const auto both = fit({c, t}), reversed = fit({t, c}), alone = fit({t});
  ASSERT_EQ(both.size(), 2u);
  ASSERT_EQ(reversed.size(), 2u);
  ASSERT_EQ(alone.size(), 1u);
  ExpectSameFit(reversed[0], both[1]);
  ExpectSameFit(alone[0], both[1]);
  EXPECT_EQ(reversed[1].yaw, both[0].yaw);
  EXPECT_EQ(reversed[1].iterations, both[0].iterations);
  EXPECT_TRUE(both[1].verified.value_or(false)) << both[1].Rejection();
}

// Accuracy over random placements (both chair models, random x, y, yaw): prints median and
// 90th percentile of the centre and yaw errors, for RANSAC alone (the paper) and with the
// optional upright ICP steps. Both: p90 within the tolerance, no placement off by more than
// twice the centre tolerance; the refinement lowers the median centre error by 30 % and halves
// the median yaw error at least (seeds 500/700/900/1100: by 49-78 % and 65-78 %). (About one
// placement in 20 of chair_b ends 3.5-4 cm off with or without the refinement, whichever the
// seed: the ICP steps do not leave that local minimum.)
// 20 random placements of the two chairs, fitted without refinement, with 5 point-to-point
// ICP steps and with 5 point-to-plane steps. Every fit must pick the right model and land
// within tolerance at p90 (one placement in ~20 lands 3.5-4 cm off whatever the seed: a
// RANSAC pose in a neighbouring basin that neither refinement leaves, hence the looser max).
// Each refinement must sharpen the median: point-to-point by 30 % (centre) and 50 % (yaw),
// point-to-plane at least twice as much again (measured: 10.2 -> 5.2 -> 0.3 mm, 1.05 -> 0.24
// -> 0.03 deg).
TEST(RansacUpright, AccuracyOverRandomPlacements) {
  const Catalog cat = FurnitureCatalog();
  struct Variant {
    int refine;
    const char* metric;
  };
  const Variant variants[] = {{0, "point"}, {5, "point"}, {5, "plane"}};
  float median_centre[3] = {0.f, 0.f, 0.f}, median_yaw[3] = {0.f, 0.f, 0.f};
  for (int v = 0; v < 3; ++v) {
    const Variant& var = variants[v];
    std::mt19937_64 rng(2024);
    std::uniform_real_distribution<float> uni(0.f, 1.f);
    std::vector<float> ce, ye;
    int right_model = 0;
    const int kRuns = 20;
    auto fitter = MakeFitter({{"refine_iterations", var.refine}, {"refine_metric", var.metric}});
    for (int r = 0; r < kRuns; ++r) {
      const std::string id = r % 2 ? "chair_b" : "chair_a";
      const float rad = 1.5f + 1.5f * uni(rng), az = 2 * kPi * uni(rng), yaw = 2 * kPi * uni(rng) - kPi;
      const Eigen::Isometry3f truth = Upright(rad * std::cos(az), rad * std::sin(az), yaw);
      Scenes sc;
      std::vector<int> parts;
      const int s = sc.Add(ScanOf(cat.Get(id), truth, 100 + r), 0, &parts);
      const auto out = fitter->Fit({Hypothesis(sc, "chair", s, parts)}, sc.Ctx(cat, 0, 500 + r));
      ASSERT_EQ(out.size(), 1u);
      right_model += out[0].model == id;
      const PoseError e = ErrorOf(out[0], cat.Get(id), truth);
      ce.push_back(e.centre);
      ye.push_back(e.yaw);
    }
    auto quantile = [](std::vector<float> x, double q) {
      std::sort(x.begin(), x.end());
      return x[std::min(x.size() - 1, static_cast<size_t>(q * (x.size() - 1) + 0.5))];
    };
    std::printf("[ accuracy ] refine_iterations %d (%s), %d placements: right model %d; centre error median %.4f m, "
                "p90 %.4f m, max %.4f m; yaw error median %.2f deg, p90 %.2f deg, max %.2f deg\n",
                var.refine, var.metric, kRuns, right_model, quantile(ce, 0.5), quantile(ce, 0.9), quantile(ce, 1.0),
                quantile(ye, 0.5) * 180 / kPi, quantile(ye, 0.9) * 180 / kPi, quantile(ye, 1.0) * 180 / kPi);
    const std::string what = std::to_string(var.refine) + " " + var.metric;
    EXPECT_EQ(right_model, kRuns) << what;
    EXPECT_LT(quantile(ce, 0.9), kCentreTol) << what;
    EXPECT_LT(quantile(ye, 0.9), kYawTol) << what;
    EXPECT_LT(quantile(ce, 1.0), 2 * kCentreTol) << what;
    median_centre[v] = quantile(ce, 0.5);
    median_yaw[v] = quantile(ye, 0.5);
  }
  EXPECT_LT(median_centre[1], 0.7f * median_centre[0]);
  EXPECT_LT(median_yaw[1], 0.5f * median_yaw[0]);
  EXPECT_LT(median_centre[2], 0.5f * median_centre[1]);
  EXPECT_LT(median_yaw[2], 0.5f * median_yaw[1]);
}

// ---- recognition by analysis by synthesis (synthesis: true) ----------------------------------

// A view of `obj` (or of nothing there: `present` false) and a proposal of what the view sees of
// it, for a synthesis hypothesis of class `cls`; the scan has its sensor origin.
struct SynthesisView {
  SimScan sim;
  Proposals props;
  Detection Hypothesis(const std::string& cls, float score) const {
    Detection h;
    h.cls = cls;
    h.score = score;
    h.proposal = 0;
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (int i : props.items[0].indices) sum += sim.scan.pose * sim.scan.points[size_t(i)];
    h.center = sum / float(props.items[0].indices.size());
    return h;
  }
  FitContext Ctx(const Catalog& cat) const {
    FitContext ctx;
    ctx.scenes.push_back({&sim.scan, nullptr, nullptr, &props});
    ctx.catalog = cat.Ptrs();
    ctx.run.seed = 5;
    return ctx;
  }
};
SynthesisView ViewOf(const Mesh& mesh, const Eigen::Isometry3f& pose, uint64_t seed) {
  SynthesisView v;
  World w;
  w.AddRoom(5.f, 2.5f);
  w.Add(mesh, pose, 0);
  const Eigen::Vector3f centre = pose * BoundsOf(mesh).center();
  v.sim = SimulateObject(w, kSensor, centre, 1.2f, 160, 0.003f, 0.05f, seed, kScanPose, true);
  Proposal p;
  for (size_t i = 0; i < v.sim.scan.points.size(); ++i)
    if (v.sim.object[i] == 0) {
      p.indices.push_back(int(i));
      p.box.extend(v.sim.scan.points[i]);
    }
  v.props.items.push_back(p);
  return v;
}

const nlohmann::json kSynthesis = {{"synthesis", true}, {"default_threshold", 0.0}, {"cloud_cache", "off"}};

// The free-space check of the analysis by synthesis: a chair that the view sees is accepted
// where it stands, with little of its rendered surface where the sensor saw through; a thin
// post standing where the chair stood, read as a chair, is refused by the free-space check
// (free_space_ratio, the first check): every pose of a chair model that explains the post puts
// its seat and back where the sensor saw the floor and the wall behind.
TEST(Synthesis, AModelWhereTheSensorSawThroughIsRejectedByTheFreeSpaceCheck) {
  const Catalog cat = FurnitureCatalog();
  const Eigen::Isometry3f where = Upright(1.6f, 0.7f, 2.2f);
  const SynthesisView chair = ViewOf(cat.Get("chair_a").mesh, where, 21);
  const auto got = MakeFitter(kSynthesis)->Fit({chair.Hypothesis("chair", 0.3f)}, chair.Ctx(cat));
  ASSERT_EQ(got.size(), 1u);
  ASSERT_TRUE(got[0].free_space_ratio.has_value());
  EXPECT_TRUE(got[0].verified.value_or(false)) << got[0].Rejection();
  EXPECT_LT(*got[0].free_space_ratio, 0.1f);
  EXPECT_LT((got[0].center - where * BoundsOf(cat.Get("chair_a").mesh).center()).head<2>().norm(), 0.1f);
  ASSERT_FALSE(got[0].checks.empty());
  EXPECT_EQ(got[0].checks[0].name, "free_space_ratio");

  Mesh post;
  AddBox(&post, nullptr, 0, Eigen::Vector3f(-0.025f, -0.025f, 0.f), Eigen::Vector3f(0.025f, 0.025f, 0.8f));
  const SynthesisView thin = ViewOf(post, where, 22);
  ASSERT_GT(thin.props.items[0].indices.size(), 50u);
  const auto out = MakeFitter(kSynthesis)->Fit({thin.Hypothesis("chair", 0.3f)}, thin.Ctx(cat));
  ASSERT_EQ(out.size(), 1u);
  const Detection& d = out[0];
  ASSERT_TRUE(d.free_space_ratio.has_value());
  EXPECT_GT(*d.free_space_ratio, 0.2f);
  EXPECT_FALSE(d.verified.value_or(true));
  EXPECT_EQ(d.Rejection().rfind("free_space_ratio ", 0), 0u) << d.Rejection();
  std::printf("[ synthesis ] chair: free_space_ratio %.3f; a post read as a chair: %.3f\n", *got[0].free_space_ratio,
              *d.free_space_ratio);
}

// The joint choice: two readings of one chair (as chair and as table) keep the better one; the
// other is explained away (its surface explained already, its box on the kept one's).
TEST(Synthesis, AnObjectReadAsTwoClassesKeepsTheBetterReading) {
  const Catalog cat = FurnitureCatalog();
  const SynthesisView chair = ViewOf(cat.Get("chair_b").mesh, Upright(1.5f, -0.4f, 0.7f), 23);
  const auto out = MakeFitter(kSynthesis)->Fit({chair.Hypothesis("chair", 0.3f), chair.Hypothesis("table", 0.05f)},
                                              chair.Ctx(cat));
  ASSERT_EQ(out.size(), 2u);
  const Detection& c = out[0].cls == "chair" ? out[0] : out[1];
  const Detection& t = out[0].cls == "chair" ? out[1] : out[0];
  EXPECT_TRUE(c.verified.value_or(false)) << c.Rejection();
  EXPECT_FALSE(t.verified.value_or(true));
  EXPECT_GT(c.score, t.score);
  EXPECT_NE(std::find(t.notes.begin(), t.notes.end(), "explained away by better-scored detections"), t.notes.end());
  EXPECT_TRUE(t.evidence.at("syn_new_share") < 0.5f ||
              std::any_of(t.checks.begin(), t.checks.end(),
                          [](const Check& k) { return k.name == "box_iou_with_kept" && !k.passed; }))
      << t.Rejection();
}

}  // namespace
