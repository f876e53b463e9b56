// The way catalog models and detections face: a catalog's "front" (in the mesh file's axes), its
// estimate from the mesh where the catalog gives none, and Detection::yaw as the fitted model's
// front, whichever model and however its file is turned.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "furnihost/host/catalog.hpp"
#include "furnihost/host/evaluation.hpp"
#include "furnihost/host/io.hpp"
#include "test_meshes.hpp"
#include "test_support.hpp"

namespace furnihost {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using testing::AddBox;

// Catalog frame (z up, bottom centre at the origin). A chair whose back stands at -y: it faces +y.
Mesh Chair() {
  Mesh m;
  for (float x : {-0.2f, 0.17f})
    for (float y : {-0.2f, 0.17f}) AddBox(m, {x, y, 0.f}, {x + 0.03f, y + 0.03f, 0.45f});
  AddBox(m, {-0.2f, -0.2f, 0.45f}, {0.2f, 0.2f, 0.5f});
  AddBox(m, {-0.2f, -0.2f, 0.5f}, {0.2f, -0.16f, 0.95f});
  return m;
}

// A sofa 1.8 m long along x, back at +y, arms at both ends: it faces -y.
Mesh Sofa() {
  Mesh m;
  AddBox(m, {-0.9f, -0.4f, 0.f}, {0.9f, 0.4f, 0.42f});
  AddBox(m, {-0.9f, 0.25f, 0.42f}, {0.9f, 0.4f, 0.85f});
  AddBox(m, {-0.9f, -0.4f, 0.42f}, {-0.75f, 0.25f, 0.62f});
  AddBox(m, {0.75f, -0.4f, 0.42f}, {0.9f, 0.25f, 0.62f});
  return m;
}

// A bookcase 0.8 m wide, its back panel at +y, shelves open to -y: it faces -y.
Mesh Bookcase() {
  Mesh m;
  AddBox(m, {-0.4f, 0.13f, 0.f}, {0.4f, 0.15f, 1.8f});
  for (float x : {-0.4f, 0.38f}) AddBox(m, {x, -0.15f, 0.f}, {x + 0.02f, 0.15f, 1.8f});
  for (float z : {0.f, 0.45f, 0.9f, 1.35f, 1.78f}) AddBox(m, {-0.38f, -0.15f, z}, {0.38f, 0.13f, z + 0.02f});
  return m;
}

Mesh Turned(Mesh m, float deg) {
  const Eigen::Matrix3f r = Eigen::AngleAxisf(deg * float(M_PI) / 180.f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  for (auto& v : m.vertices) v = r * v;
  return m;
}

void ExpectFront(const Mesh& m, const Eigen::Vector3f& want, const std::string& what) {
  const FrontEstimate e = EstimateFront(m);
  EXPECT_FALSE(e.ambiguous) << what << ": " << e.how;
  EXPECT_LT((e.front - want).norm(), 1e-4f) << what << ": " << e.how;
  EXPECT_NE(e.how.find("estimated"), std::string::npos) << e.how;
}

TEST(Front, EstimatedFromTheOpenSideOfAChairASofaAndABookcase) {
  ExpectFront(Chair(), Eigen::Vector3f::UnitY(), "chair");
  ExpectFront(Turned(Chair(), 90.f), -Eigen::Vector3f::UnitX(), "chair turned 90 deg");
  ExpectFront(Turned(Chair(), 180.f), -Eigen::Vector3f::UnitY(), "chair turned 180 deg");
  ExpectFront(Sofa(), -Eigen::Vector3f::UnitY(), "sofa");
  ExpectFront(Turned(Sofa(), 90.f), Eigen::Vector3f::UnitX(), "sofa turned 90 deg");
  ExpectFront(Bookcase(), -Eigen::Vector3f::UnitY(), "bookcase");
  ExpectFront(Turned(Bookcase(), -90.f), -Eigen::Vector3f::UnitX(), "bookcase turned -90 deg");
  // A closed box has no open side: the catalog frame's depth axis, and it says so.
  Mesh chest;
  AddBox(chest, {-0.5f, -0.25f, 0.f}, {0.5f, 0.25f, 0.8f});
  const FrontEstimate e = EstimateFront(chest);
  EXPECT_TRUE(e.ambiguous) << e.how;
  EXPECT_LT((e.front + Eigen::Vector3f::UnitY()).norm(), 1e-4f);
}

// An OBJ of `m` in a file whose up axis is +y: (x, y, z) of the catalog frame -> (x, z, -y).
void WriteObjYUp(const std::string& path, const Mesh& m) {
  std::ofstream o(path);
  for (const auto& v : m.vertices) o << "v " << v.x() << " " << v.z() << " " << -v.y() << "\n";
  for (const auto& t : m.triangles) o << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
}

TEST(Front, TheCatalogGivesItInTheFilesAxesAndRefusesOneAlongUp) {
  const std::string dir = testing::TempDir("front_catalog");
  WriteObjYUp(dir + "/chair.obj", Chair());
  // The file's +z is the catalog frame's -y (up +y: (x, y, z) -> (x, -z, y)).
  const json cat = json::parse(R"({"models": [
    {"id": "given", "class": "chair", "mesh": "chair.obj", "up": "+y", "scale": 1.0, "front": "+z"},
    {"id": "vector", "class": "chair", "mesh": "chair.obj", "up": "+y", "scale": 1.0, "front": [1, 0, 0]},
    {"id": "estimated", "class": "chair", "mesh": "chair.obj", "up": "+y", "scale": 1.0},
    {"id": "along_up", "class": "chair", "mesh": "chair.obj", "up": "+y", "scale": 1.0, "front": "-y"},
    {"id": "bad_name", "class": "chair", "mesh": "chair.obj", "up": "+y", "scale": 1.0, "front": "forward"},
    {"id": "bad_vector", "class": "chair", "mesh": "chair.obj", "up": "+y", "scale": 1.0, "front": [1, 0]}]})");
  WriteJson(dir + "/catalog.json", cat);
  const Catalog c = LoadCatalog(dir + "/catalog.json");
  ASSERT_EQ(c.models.size(), 3u);
  ASSERT_EQ(c.fronts.size(), 3u);
  const ModelFront* given = c.FrontOf("given");
  ASSERT_TRUE(given);
  EXPECT_EQ(given->source, "catalog");
  EXPECT_LT((given->front + Eigen::Vector3f::UnitY()).norm(), 1e-5f);
  EXPECT_LT((c.FrontOf("vector")->front - Eigen::Vector3f::UnitX()).norm(), 1e-5f);
  // Estimated where the catalog is silent: the chair's open side, +y of the catalog frame.
  EXPECT_LT((c.FrontOf("estimated")->front - Eigen::Vector3f::UnitY()).norm(), 1e-5f);
  EXPECT_EQ(c.FrontOf("estimated")->source.rfind("estimated", 0), 0u) << c.FrontOf("estimated")->source;
  EXPECT_EQ(c.FrontOf("along_up"), nullptr);
  std::map<std::string, std::string> why;
  for (const auto& s : c.skipped) why[s.id] = s.reason;
  EXPECT_NE(why["along_up"].find("along \"up\""), std::string::npos) << why["along_up"];
  EXPECT_NE(why["bad_name"].find("bad \"front\""), std::string::npos) << why["bad_name"];
  EXPECT_NE(why["bad_vector"].find("bad \"front\""), std::string::npos) << why["bad_vector"];
  fs::remove_all(dir);
}

// A scene of one object of `model` at (x, y) facing `yaw_deg` from its model's front, seen by two
// sensors across the room.
json OneObjectScene(const std::string& model, double x, double y, double yaw_deg) {
  json scene = json::parse(R"({"room": {"size_m": [4.0, 3.5], "height_m": 2.5},
    "sensors": [{"position": [0.6, 0.6, 1.5], "yaw_deg": 40}, {"position": [3.4, 2.9, 1.5], "yaw_deg": -140}]})");
  scene["objects"] = json::array({{{"model", model}, {"x", x}, {"y", y}, {"yaw_deg", yaw_deg}}});
  return scene;
}

// A catalog in `dir`: a chair without a "front" and a sofa whose front catalog.json gives (+z).
void WriteChairAndSofaCatalog(const std::string& dir) {
  WriteObjYUp(dir + "/chair.obj", Chair());
  WriteObjYUp(dir + "/sofa.obj", Sofa());
  WriteJson(dir + "/catalog.json", json::parse(R"({"models": [
    {"id": "plain_chair", "class": "chair", "mesh": "chair.obj", "up": "+y", "scale": 1.0},
    {"id": "known_sofa", "class": "sofa", "mesh": "sofa.obj", "up": "+y", "scale": 1.0, "front": "+z"}]})"));
}

TEST(Front, AMissingFrontIsEstimatedAndLogged) {
  const std::string dir = testing::TempDir("front_logged");
  WriteChairAndSofaCatalog(dir);
  WriteJson(dir + "/scene.json", OneObjectScene("plain_chair", 2.0, 1.7, 90.0));
  const auto r = testing::RunFurnihost("simulate --catalog " + dir + "/catalog.json --scene " + dir +
                                       "/scene.json --out " + dir + "/room.pcd");
  ASSERT_EQ(r.code, 0) << r.err;
  // The log says which model's front is estimated, which way and on what evidence.
  EXPECT_NE(r.err.find("1 of 2 model(s) have no \"front\""), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("estimated from its mesh: plain_chair estimated +y\n"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("known_sofa"), std::string::npos) << r.err;
  // With -vv (debug), the depths it chose on.
  const auto v = testing::RunFurnihost("simulate -vv --catalog " + dir + "/catalog.json --scene " + dir +
                                       "/scene.json --out " + dir + "/room_v.pcd");
  ASSERT_EQ(v.code, 0) << v.err;
  EXPECT_NE(v.err.find("model plain_chair: no \"front\", estimated +y (open depth"), std::string::npos) << v.err;
  // The ground truth gives the way the chair faces: its estimated front (+y) turned by 90 deg.
  const auto truth = ReadGroundTruth(dir + "/room.gt.json");
  ASSERT_EQ(truth.size(), 1u);
  ASSERT_TRUE(truth[0].yaw.has_value());
  EXPECT_NEAR(std::abs(std::remainder(double(*truth[0].yaw) - M_PI, 2 * M_PI)), 0.0, 1e-4) << *truth[0].yaw;
  fs::remove_all(dir);
}

// `furnihost catalog` lists each model's front and where it comes from, and draws them: the
// estimated chair faces its open side (+y), the sofa the way catalog.json says (+z of its y-up
// file: -y of the catalog frame).
TEST(Front, TheCatalogCommandListsAndDrawsEachModelsFront) {
  const std::string dir = testing::TempDir("front_catalog_command");
  WriteChairAndSofaCatalog(dir);
  const auto r = testing::RunFurnihost("catalog " + dir + "/catalog.json --out " + dir + "/out");
  ASSERT_EQ(r.code, 0) << r.err;
  const json j = ReadJson(dir + "/out/fronts.json");
  ASSERT_EQ(j["models"].size(), 2u);
  std::map<std::string, json> by_id;
  for (const auto& m : j["models"]) by_id[m["id"].get<std::string>()] = m;
  EXPECT_NEAR(by_id["plain_chair"]["front_deg"].get<double>(), 90.0, 1e-3);
  EXPECT_EQ(by_id["plain_chair"]["source"].get<std::string>().rfind("estimated", 0), 0u) << by_id["plain_chair"];
  EXPECT_EQ(by_id["known_sofa"]["source"], "catalog");
  EXPECT_NEAR(by_id["known_sofa"]["front_deg"].get<double>(), -90.0, 1e-3);
  EXPECT_GT(fs::file_size(dir + "/out/fronts.png"), 1000u);
  EXPECT_GT(fs::file_size(dir + "/out/fronts.svg"), 1000u);
  EXPECT_NE(r.out.find("plain_chair"), std::string::npos) << r.out;
  // A catalog that is not there: one line naming it, exit 2, nothing written.
  const auto bad = testing::RunFurnihost("catalog " + dir + "/nothere.json --out " + dir + "/bad");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("nothere.json"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir + "/bad"));
  fs::remove_all(dir);
}

// The catalog chair's OBJ turned by `deg` about its file's up axis (+y).
std::string TurnedObj(const std::string& source, float deg) {
  std::ifstream in(source);
  std::ostringstream out;
  const float c = std::cos(deg * float(M_PI) / 180.f), s = std::sin(deg * float(M_PI) / 180.f);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("v ", 0) == 0) {
      std::istringstream v(line.substr(2));
      float x, y, z;
      v >> x >> y >> z;
      out << "v " << (c * x + s * z) << " " << y << " " << (-s * x + c * z) << "\n";
    } else {
      out << line << "\n";
    }
  }
  return out.str();
}

// The yaw of the best-scored chair detection within 0.3 m of (x, y), NaN when none.
double ChairYawNear(const std::string& detections, double x, double y) {
  const json j = ReadJson(detections);
  double best = -1, yaw = NAN;
  for (const auto& d : j["detections"]) {
    if (d["class"] != "chair") continue;
    if (std::hypot(d["center"][0].get<double>() - x, d["center"][1].get<double>() - y) > 0.3) continue;
    if (d["score"].get<double>() > best) best = d["score"].get<double>(), yaw = d["yaw"].get<double>();
  }
  return yaw;
}

double AngleDeg(double a, double b) { return std::abs(std::remainder(a - b, 2 * M_PI)) * 180.0 / M_PI; }

// A catalog model's mesh turned by 90 deg about up in its file, its "front" turned with it:
// the same chair, so the way the detection says it faces is the same, and it is the way the
// chair was placed facing.
TEST(Facing, TurningAModelsFileAndItsFrontLeavesTheReportedFacing) {
  const std::string dir = testing::TempDir("facing_turned");
  const std::string src = testing::SourceDir();
  const std::string obj = src + "/data/catalog/chair/sh3d_chair/chair.obj";
  fs::create_directories(dir + "/a");
  fs::create_directories(dir + "/b");
  fs::copy_file(obj, dir + "/a/chair.obj", fs::copy_options::overwrite_existing);
  {
    std::ofstream(dir + "/b/chair.obj") << TurnedObj(obj, 90.f);
  }
  // The file's +z (SweetHome3D's front) turns into its +x; width and depth swap.
  WriteJson(dir + "/a/catalog.json", json::parse(R"({"models": [{"id": "chair", "class": "chair", "mesh": "chair.obj",
    "up": "+y", "size_m": [0.4, 0.42, 0.9], "front": "+z"}]})"));
  WriteJson(dir + "/b/catalog.json", json::parse(R"({"models": [{"id": "chair", "class": "chair", "mesh": "chair.obj",
    "up": "+y", "size_m": [0.42, 0.4, 0.9], "front": "+x"}]})"));
  const Catalog a = LoadCatalog(dir + "/a/catalog.json"), b = LoadCatalog(dir + "/b/catalog.json");
  ASSERT_EQ(a.models.size(), 1u);
  ASSERT_EQ(b.models.size(), 1u);
  EXPECT_LT((b.FrontOf("chair")->front - Eigen::AngleAxisf(float(M_PI / 2), Eigen::Vector3f::UnitZ()) * a.FrontOf("chair")->front).norm(),
            1e-4f);
  // A room with the chair facing 130 deg from catalog a's front (what simulate writes as its yaw).
  WriteJson(dir + "/scene.json", OneObjectScene("chair", 2.2, 1.6, 130.0));
  auto sim = testing::RunFurnihost("simulate -q --catalog " + dir + "/a/catalog.json --scene " + dir +
                                   "/scene.json --sensor-params '{\"voxel_m\": 0.02}' --out " + dir + "/room.pcd");
  ASSERT_EQ(sim.code, 0) << sim.err;
  const auto truth = ReadGroundTruth(dir + "/room.gt.json");
  ASSERT_EQ(truth.size(), 1u);
  ASSERT_TRUE(truth[0].yaw.has_value());
  // The demo's graph (laser_room.json): the chair recognised and its model fitted.
  for (const char* which : {"a", "b"}) {
    const std::string d = dir + "/" + which;
    json g = json::object();
    g["extends"] = src + "/configs/laser_room.json";
    g["catalog"] = d + "/catalog.json";
    g["model_cache"] = d + "/model.fhm";
    WriteJson(d + "/graph.json", g);
    auto r = testing::RunFurnihost("--graph " + d + "/graph.json " + dir + "/room.pcd -q --out " + d + "/out");
    ASSERT_EQ(r.code, 0) << r.err;
  }
  const double ya = ChairYawNear(dir + "/a/out/detections.json", 2.2, 1.6);
  const double yb = ChairYawNear(dir + "/b/out/detections.json", 2.2, 1.6);
  ASSERT_TRUE(std::isfinite(ya)) << "no chair found with catalog a";
  ASSERT_TRUE(std::isfinite(yb)) << "no chair found with catalog b";
  EXPECT_LT(AngleDeg(ya, yb), 5.0) << "facing " << ya << " against " << yb << " rad";
  EXPECT_LT(AngleDeg(ya, *truth[0].yaw), 20.0) << "facing " << ya << ", the chair faces " << *truth[0].yaw;
  if (!HasFailure()) fs::remove_all(dir);
}

// An object of `cls` at (x, y) standing on the floor, `size` its axis-aligned extents, facing `yaw_deg`.
GroundTruthObject Object(const std::string& cls, float x, float y, const Eigen::Vector3f& size, float yaw_deg) {
  GroundTruthObject g;
  g.cls = cls;
  g.center = Eigen::Vector3f(x, y, 0.5f * size.z());
  g.size = size;
  g.yaw = yaw_deg * float(M_PI) / 180.f;
  return g;
}

// A detection with a placed model and its box along the scan's axes.
Detection Placed(const std::string& cls, float x, float y, const Eigen::Vector3f& size, float yaw_deg, float score) {
  Detection d;
  d.cls = cls;
  d.center = Eigen::Vector3f(x, y, 0.5f * size.z());
  d.score = score;
  d.model = cls + "_model";
  d.verified = true;
  d.yaw = yaw_deg * float(M_PI) / 180.f;
  OrientedBox b;
  b.center = d.center;
  b.size = size;
  d.box = b;
  return d;
}

// The Scan2CAD rule: centre within 0.2 m, facing within 20 deg folded by the object's symmetry,
// mean extent ratio within 20 %; each criterion on its own.
TEST(Alignment, CentreFacingAndSizeEachDecide) {
  const Eigen::Vector3f chair(0.5f, 0.5f, 0.8f);
  const GroundTruthObject g = Object("chair", 2.f, 2.f, chair, 30.f);
  EXPECT_EQ(AlignmentMiss(Placed("chair", 2.1f, 2.1f, chair, 45.f, 1.f), g), "");
  EXPECT_EQ(AlignmentMiss(Placed("chair", 2.2f, 2.1f, chair, 30.f, 1.f), g), "centre 0.22 m off");
  EXPECT_EQ(AlignmentMiss(Placed("chair", 2.f, 2.f, chair, -150.f, 1.f), g), "facing 180 deg off");
  EXPECT_EQ(AlignmentMiss(Placed("chair", 2.f, 2.f, 1.3f * chair, 30.f, 1.f), g), "size 30 % off");
  Detection unplaced = Placed("chair", 2.f, 2.f, chair, 30.f, 1.f);
  unplaced.model.clear();
  EXPECT_EQ(AlignmentMiss(unplaced, g), "no model placed");
  // A rectangular table (2-fold): facing the other way is the same table; a quarter turn is not.
  GroundTruthObject table = Object("table", 4.f, 2.f, Eigen::Vector3f(1.6f, 0.8f, 0.75f), 0.f);
  table.yaw_symmetry = 2;
  EXPECT_TRUE(Aligned(Placed("table", 4.f, 2.f, Eigen::Vector3f(1.6f, 0.8f, 0.75f), 175.f, 1.f), table));
  EXPECT_EQ(AlignmentMiss(Placed("table", 4.f, 2.f, Eigen::Vector3f(1.6f, 0.8f, 0.75f), 90.f, 1.f), table),
            "facing 90 deg off");
}

// Alignment accuracy: the share of objects with a yaw that an accepted detection aligns, each
// detection at most one object; the dataset's class symmetry stands in where an object has none.
TEST(Alignment, AccuracyPerClassAndTheDatasetsClassSymmetry) {
  const Eigen::Vector3f chair(0.5f, 0.5f, 0.8f), desk(1.4f, 0.7f, 0.75f);
  std::vector<GroundTruthObject> truth = {Object("chair", 1.f, 1.f, chair, 0.f), Object("chair", 1.4f, 1.f, chair, 0.f),
                                          Object("chair", 3.f, 1.f, chair, 90.f), Object("table", 5.f, 5.f, desk, 0.f)};
  truth.push_back(truth[0]);
  truth.back().yaw.reset();  // no yaw: not counted
  Detection rejected = Placed("chair", 3.f, 1.f, chair, 90.f, 0.9f);
  rejected.verified = false;
  const std::vector<Detection> dets = {Placed("chair", 1.15f, 1.f, chair, 5.f, 0.8f),  // aligns the first
                                       rejected,                                       // not accepted
                                       Placed("table", 5.f, 5.f, desk, 180.f, 0.7f)};  // the desk turned round
  ClassMap classes;
  classes.classes = {"chair", "table"};
  const EvalMetrics plain = Evaluate({{dets, truth, true, "room", {}}}, classes, WidthConvention::Max);
  ASSERT_EQ(plain.classes.size(), 2u);
  EXPECT_EQ(plain.classes[0].alignment.objects, 3);
  EXPECT_EQ(plain.classes[0].alignment.aligned, 1);
  EXPECT_NEAR(plain.classes[0].alignment.accuracy, 1.0 / 3.0, 1e-12);
  EXPECT_EQ(plain.classes[1].alignment.aligned, 0);
  EXPECT_EQ(plain.alignment.objects, 4);
  EXPECT_EQ(plain.alignment.aligned, 1);
  classes.yaw_symmetry["table"] = 2;
  const EvalMetrics folded = Evaluate({{dets, truth, true, "room", {}}}, classes, WidthConvention::Max);
  EXPECT_EQ(folded.classes[1].alignment.aligned, 1);
  EXPECT_NEAR(folded.alignment.accuracy, 0.5, 1e-12);
  int aligned_records = 0;
  for (const auto& r : folded.objects) aligned_records += r.alignment == "aligned";
  EXPECT_GE(aligned_records, 2);
}

}  // namespace
}  // namespace furnihost
