// fitters.icp_refine through the registry: a chair-like catalog model (seat, back, four legs)
// placed at a known upright pose, its surface sampled as the scene, the detection perturbed
// by 5 cm and 4 deg; the refinement must land within 1 cm and 1 deg and stay upright.
#include <cmath>
#include <random>

#include "furnihost/geometry.hpp"
#include "furnihost/stage.hpp"
#include "test_meshes.hpp"
#include "test_support.hpp"

namespace furnihost::testing {
namespace {

const char* kType = "fitters.icp_refine";

std::shared_ptr<Fitter> Make(const Registry& reg, nlohmann::json params = nlohmann::json::object()) {
  const PluginEntry* e = reg.Find(kType);
  if (!e) throw std::runtime_error(std::string(kType) + " not found in " + PluginDir());
  return reg.CreateAs<Fitter>(kType, e->params.Resolve(params, "test"));
}

// Model frame: z up, metres, bounding-box bottom centre at the origin (as the catalog does).
CatalogModel MakeChair() {
  CatalogModel c;
  c.id = "test_chair";
  c.cls = "chair";
  for (float x : {-0.21f, 0.17f})
    for (float y : {-0.21f, 0.17f}) AddBox(c.mesh, {x, y, 0.f}, {x + 0.04f, y + 0.04f, 0.42f});
  AddBox(c.mesh, {-0.225f, -0.225f, 0.42f}, {0.225f, 0.225f, 0.47f});  // seat
  AddBox(c.mesh, {-0.225f, 0.175f, 0.47f}, {0.225f, 0.225f, 0.92f});   // back
  c.size = {0.45f, 0.45f, 0.92f};
  return c;
}

struct ChairScene {
  CatalogModel chair = MakeChair();
  Scan scan;
  Segmentation seg;
  Eigen::Isometry3f truth;
  FitContext ctx;
  Detection det;  // perturbed input

  // Scene: the model's surface at `truth` (5000 points/m^2, another seed than the fitter's,
  // 1 mm noise), split in part 0 (seat + legs, z < 0.47) and part 1 (back), plus a floor
  // patch as part 2 that nobody supports. The scan frame is not the world frame.
  // `at`: true (x, y) of the model; far values exercise map coordinates.
  explicit ChairScene(Eigen::Vector2f at = Eigen::Vector2f(3.2f, -1.7f)) {
    truth = UprightPose(at.x(), at.y(), 0.f, float(35 * M_PI / 180));
    scan.pose = UprightPose(10.f, 5.f, 0.3f, float(M_PI / 2));
    std::mt19937_64 rng(99);
    std::normal_distribution<float> g(0.f, 0.001f);
    Part seat, back, floor;
    for (const auto& p : SampleSurface(chair.mesh, 5000.f, 12345)) {
      const Eigen::Vector3f w = truth * p + Eigen::Vector3f(g(rng), g(rng), g(rng));
      (p.z() < 0.47f ? seat : back).indices.push_back(int(scan.points.size()));
      scan.points.push_back(scan.pose.inverse() * w);
    }
    for (int i = -40; i <= 40; ++i)
      for (int j = -40; j <= 40; ++j) {
        floor.indices.push_back(int(scan.points.size()));
        scan.points.push_back(scan.pose.inverse() * Eigen::Vector3f(at.x() + 0.01f * i, at.y() + 0.01f * j, 0.f));
      }
    seg.parts = {seat, back, floor};
    seg.normals.assign(scan.points.size(), Eigen::Vector3f::UnitZ());
    seg.curvature.assign(scan.points.size(), 0.f);
    ctx.scenes.push_back(SceneParts{&scan, &seg, nullptr});
    ctx.catalog.push_back(&chair);

    det.cls = "chair";
    det.model = chair.id;
    det.yaw = float(39 * M_PI / 180);  // +4 deg
    det.model_pose = UprightPose(at.x() + 0.03f, at.y() - 0.04f, 0.f, det.yaw);  // 5 cm off
    det.center = det.model_pose * Eigen::Vector3f(0.f, 0.f, 0.46f);
    det.support = {{0, 0, 1.f}, {0, 1, 1.f}};
    det.rms = 0.05f;
  }
};

double YawDeg(const Eigen::Isometry3f& p) {
  return std::atan2(p.linear()(1, 0), p.linear()(0, 0)) * 180.0 / M_PI;
}

// Within 1 cm (x, y of the model origin and of the centre) and 1 deg; upright; z kept.
void ExpectRefined(const ChairScene& s, const Detection& d) {
  const Eigen::Vector3f t = d.model_pose.translation(), t0 = s.truth.translation();
  EXPECT_LT((t - t0).head<2>().norm(), 0.01f) << t.transpose();
  EXPECT_NEAR(t.z(), s.det.model_pose.translation().z(), 1e-5f);
  EXPECT_NEAR(YawDeg(d.model_pose), 35.0, 1.0);
  EXPECT_NEAR(d.yaw * 180.0 / M_PI, 35.0, 1.0);
  EXPECT_LT((d.center - s.truth * Eigen::Vector3f(0.f, 0.f, 0.46f)).norm(), 0.01f);
  // Upright: the model's z axis stays the world's (roll = pitch = 0).
  EXPECT_LT((d.model_pose.linear().col(2) - Eigen::Vector3f::UnitZ()).norm(), 1e-5f);
  EXPECT_NEAR(d.model_pose.linear().determinant(), 1.f, 1e-4f);
  ASSERT_TRUE(d.rms);
  EXPECT_GT(*d.rms, 0.f);
  EXPECT_LT(*d.rms, 0.01f);  // 1 mm noise, ~5 mm sample spacing
  ASSERT_FALSE(d.notes.empty());
  EXPECT_EQ(d.notes.back().rfind("icp: moved", 0), 0u) << d.notes.back();
}

TEST(IcpRefine, RecoversPerturbedPoseAndStaysUpright) {
  auto reg = MakeRegistry();
  ChairScene s;
  const auto out = Make(*reg)->Fit({s.det}, s.ctx);
  ASSERT_EQ(out.size(), 1u);
  ExpectRefined(s, out[0]);
  EXPECT_EQ(out[0].model, s.det.model);
  EXPECT_EQ(out[0].support.size(), s.det.support.size());
}

TEST(IcpRefine, MapCoordinatesFarFromOrigin) {
  auto reg = MakeRegistry();
  ChairScene s(Eigen::Vector2f(812.5f, -640.25f));
  const auto out = Make(*reg)->Fit({s.det}, s.ctx);
  ASSERT_EQ(out.size(), 1u);
  ExpectRefined(s, out[0]);
}

TEST(IcpRefine, GeneralizedIcpProjectedUpright) {
  auto reg = MakeRegistry();
  ChairScene s;
  const auto out = Make(*reg, {{"method", "gicp"}})->Fit({s.det}, s.ctx);
  ASSERT_EQ(out.size(), 1u);
  ExpectRefined(s, out[0]);
}

TEST(IcpRefine, NearbyPointsCompleteAPartialSupport) {
  auto reg = MakeRegistry();
  ChairScene s;
  s.det.support = {{0, 0, 1.f}};  // seat + legs only; the back comes in as nearby points
  const auto out = Make(*reg, {{"nearby_radius_m", 0.1}})->Fit({s.det}, s.ctx);
  ASSERT_EQ(out.size(), 1u);
  ExpectRefined(s, out[0]);
  // The note counts part points + nearby points; nearby must be the back (not the floor).
  const std::string& note = out[0].notes.back();
  const size_t plus = note.rfind(" + ");
  ASSERT_NE(plus, std::string::npos) << note;
  const int nearby = std::stoi(note.substr(plus + 3));
  EXPECT_GT(nearby, int(0.9 * double(s.seg.parts[1].indices.size()))) << note;
  EXPECT_LT(nearby, int(1.1 * double(s.seg.parts[1].indices.size()))) << note;
}

TEST(IcpRefine, LeavesUnfittedAndTooSmallDetectionsAlone) {
  auto reg = MakeRegistry();
  ChairScene s;
  Detection unfitted = s.det;
  unfitted.model.clear();
  Detection tiny = s.det;
  tiny.support.clear();
  const auto out = Make(*reg)->Fit({unfitted, s.det, tiny}, s.ctx);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_TRUE(out[0].model_pose.isApprox(unfitted.model_pose));
  EXPECT_EQ(out[0].center, unfitted.center);
  EXPECT_EQ(out[0].yaw, unfitted.yaw);
  EXPECT_EQ(out[0].rms, unfitted.rms);
  EXPECT_TRUE(out[0].notes.empty());
  ExpectRefined(s, out[1]);
  EXPECT_TRUE(out[2].model_pose.isApprox(tiny.model_pose));
  ASSERT_EQ(out[2].notes.size(), 1u);
  EXPECT_EQ(out[2].notes[0].rfind("icp: skipped", 0), 0u) << out[2].notes[0];
}

TEST(IcpRefine, DeterministicAndErrors) {
  auto reg = MakeRegistry();
  ChairScene s;
  auto fit = Make(*reg, {{"seed", 5}});
  const auto a = fit->Fit({s.det}, s.ctx), b = fit->Fit({s.det}, s.ctx);
  EXPECT_TRUE(a[0].model_pose.isApprox(b[0].model_pose, 0.f));
  EXPECT_EQ(a[0].notes, b[0].notes);

  Detection unknown = s.det;
  unknown.model = "no_such_model";
  EXPECT_THROW(fit->Fit({unknown}, s.ctx), StageError);
  Detection bad = s.det;
  bad.support = {{0, 7, 1.f}};  // part 7 of 3
  EXPECT_THROW(fit->Fit({bad}, s.ctx), StageError);
}

}  // namespace
}  // namespace furnihost::testing
