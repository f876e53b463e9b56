// framework/app/wire: what MPI ranks hand rank 0 must come back bit for bit (a detection's every
// field, a training view's scan, segmentation and features), and bad bytes are an error, never a
// crash.
#include <gtest/gtest.h>

#include <cstring>

#include "furnihost/host/pipeline.hpp"
#include "wire.hpp"

namespace {

using namespace furnihost;
namespace wire = furnihost::app::wire;

Detection FullDetection() {
  Detection d;
  d.cls = "chair";
  d.center = {1.25f, -2.5f, 0.375f};
  d.yaw = 0.7f;
  d.score = 0.123456789f;
  d.confidence = 0.8125f;
  d.model = "sh3d_chair2";
  d.verified = false;
  d.coverage = 0.61f;
  d.free_space_ratio = 0.05f;
  d.rms = 0.011f;
  d.iterations = 37;
  d.checks = {Check::AtLeast("coverage", 0.61, 0.5), Check::AtMost("free_space_ratio", 0.05, 0.3)};
  d.checks[1].passed = false;
  d.notes = {"a note", ""};
  d.support = {{0, 3, 1.5f}, {1, 7, 0.25f}};
  d.model_pose = Eigen::Translation3f(1, 2, 3) * Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitZ());
  d.box = OrientedBox{{1, 2, 0.4f}, {0.5f, 0.6f, 0.8f}, -1.2f};
  d.box_source = "model";
  d.proposal = 12;
  d.proposal_scene = 1;
  d.evidence = {{"length_m", 0.5f}, {"e_profile", std::nanf("")}};
  d.chain = "fit";
  return d;
}

Scan FullScan() {
  Scan s;
  s.source = "view 3 of x";
  s.points = {{0, 0, 0}, {1, 2, 3}, {-1e-7f, 5e6f, std::numeric_limits<float>::infinity()}};
  s.origin = Eigen::Vector3f(0.5f, 0.5f, 1.5f);
  s.pose = Eigen::Isometry3f(Eigen::Translation3f(0.1f, 0.2f, 0.3f));
  s.frame.shift = {691000.0, 5335000.0, 12.5};
  s.frame.to_upright = Eigen::Isometry3d(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitX()));
  s.frame.up = "-y";
  GroundModel g = GroundModel::Level(-0.02f, "known");
  g.kind = GroundKind::HeightMap;
  g.width = 2, g.height = 1, g.cell = 0.15f, g.origin = {-1, -2};
  g.heights = {0.01f, -0.02f};
  g.observed = {1, 0};
  g.observed_area_m2 = 0.0225f;
  s.ground = g;
  GroundTruthObject t;
  t.cls = "table", t.center = {1, 1, 0.4f}, t.size = {1.2f, 0.8f, 0.75f}, t.yaw = 0.5f, t.model = "m", t.yaw_symmetry = 2;
  s.truth = {t, GroundTruthObject()};
  s.attributes["label"] = {1, 2, 3};
  s.colors = {{{1, 2, 3}}, {{4, 5, 6}}, {{7, 8, 9}}};
  return s;
}

TEST(Wire, DetectionsComeBackBitForBit) {
  std::vector<Detection> in = {FullDetection(), Detection()};
  wire::Writer w;
  wire::Put(w, in);
  const std::string bytes = w.Take();
  wire::Reader r(bytes, "test");
  const std::vector<Detection> out = wire::GetDetections(r);
  r.End();
  ASSERT_EQ(out.size(), in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    // Every field DetectionToJson writes (NaN evidence aside, compared below) ...
    Detection a = in[i], b = out[i];
    a.evidence.erase("e_profile"), b.evidence.erase("e_profile");
    EXPECT_EQ(DetectionToJson(a).dump(), DetectionToJson(b).dump());
    // ... and the bits of the numbers.
    EXPECT_EQ(std::memcmp(in[i].center.data(), out[i].center.data(), 12), 0);
    EXPECT_EQ(std::memcmp(in[i].model_pose.data(), out[i].model_pose.data(), 64), 0);
    EXPECT_EQ(in[i].verified, out[i].verified);
    EXPECT_EQ(in[i].confidence, out[i].confidence);
    EXPECT_EQ(in[i].coverage, out[i].coverage);
    EXPECT_EQ(in[i].box.has_value(), out[i].box.has_value());
    EXPECT_EQ(in[i].proposal_scene, out[i].proposal_scene);
    EXPECT_EQ(in[i].chain, out[i].chain);
    EXPECT_EQ(in[i].evidence.size(), out[i].evidence.size());
  }
  EXPECT_TRUE(std::isnan(out[0].evidence.at("e_profile")));
}

TEST(Wire, TrainingViewsComeBackBitForBit) {
  TrainingView v;
  v.cls = "chair", v.model_id = "sh3d_chair2", v.view = 5;
  v.object_centroid = {0.1f, 0.2f, 0.3f};
  v.object_size = {0.5f, 0.5f, 0.8f};
  v.scan = FullScan();
  v.segmentation.normals = {{0, 0, 1}, {std::nanf(""), 0, 0}, {1, 0, 0}};
  v.segmentation.curvature = {0.01f, std::nanf(""), 0.2f};
  v.segmentation.parts = {Part{{0, 2}, {0.5f, 1, 1.5f}}};
  v.segmentation.discarded_points = 1;
  v.features.values = Eigen::MatrixXf::Random(3, 24);
  v.features.names = std::vector<std::string>(24, "f");
  v.features.excess = Eigen::VectorXf::Random(3);
  wire::Writer w;
  wire::Put(w, v);
  const std::string bytes = w.Take();
  wire::Reader r(bytes, "test");
  const TrainingView o = wire::GetTrainingView(r);
  r.End();
  EXPECT_EQ(o.cls, v.cls);
  EXPECT_EQ(o.model_id, v.model_id);
  EXPECT_EQ(o.view, v.view);
  EXPECT_EQ(o.object_centroid, v.object_centroid);
  EXPECT_EQ(o.object_size, v.object_size);
  EXPECT_EQ(o.scan.source, v.scan.source);
  ASSERT_EQ(o.scan.points.size(), v.scan.points.size());
  EXPECT_EQ(std::memcmp(o.scan.points.data(), v.scan.points.data(), 12 * v.scan.points.size()), 0);
  EXPECT_EQ(o.scan.origin, v.scan.origin);
  EXPECT_TRUE(o.scan.pose.isApprox(v.scan.pose, 0.f));
  EXPECT_EQ(o.scan.frame.shift, v.scan.frame.shift);
  EXPECT_TRUE(o.scan.frame.to_upright.isApprox(v.scan.frame.to_upright, 0.0));
  EXPECT_EQ(o.scan.frame.up, v.scan.frame.up);
  ASSERT_TRUE(o.scan.ground);
  EXPECT_EQ(ToJson(*o.scan.ground).dump(), ToJson(*v.scan.ground).dump());
  EXPECT_EQ(o.scan.ground->observed, v.scan.ground->observed);
  ASSERT_EQ(o.scan.truth.size(), 2u);
  EXPECT_EQ(o.scan.truth[0].yaw_symmetry, 2);
  EXPECT_EQ(o.scan.truth[0].model, "m");
  EXPECT_FALSE(o.scan.truth[1].yaw);
  EXPECT_EQ(o.scan.attributes, v.scan.attributes);
  EXPECT_EQ(o.scan.colors, v.scan.colors);
  EXPECT_EQ(std::memcmp(o.segmentation.normals.data(), v.segmentation.normals.data(), 36), 0);
  EXPECT_EQ(std::memcmp(o.segmentation.curvature.data(), v.segmentation.curvature.data(), 12), 0);
  ASSERT_EQ(o.segmentation.parts.size(), 1u);
  EXPECT_EQ(o.segmentation.parts[0].indices, v.segmentation.parts[0].indices);
  EXPECT_EQ(o.segmentation.discarded_points, 1);
  EXPECT_EQ(o.features.values, v.features.values);
  EXPECT_EQ(o.features.names, v.features.names);
  EXPECT_EQ(o.features.excess, v.features.excess);
}

// Every field of these types is encoded by hand in wire.cpp: a field added to one of them changes
// its size and fails this, so that wire.cpp is updated with it (else an MPI run would drop it).
TEST(Wire, EveryFieldIsEncoded) {
  EXPECT_EQ(sizeof(Detection), 432u) << "Detection changed: encode the new field in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(Scan), 720u) << "Scan changed: encode the new field in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(GroundModel), 128u) << "GroundModel changed: encode the new field in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(GroundTruthObject), 104u) << "GroundTruthObject changed: encode it in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(TrainingView), 976u) << "TrainingView changed: encode the new field in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(Segmentation), 80u) << "Segmentation changed: encode the new field in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(FeatureMatrix), 64u) << "FeatureMatrix changed: encode the new field in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(ScanFrame), 320u) << "ScanFrame changed: encode the new field in framework/app/wire.cpp";
  EXPECT_EQ(sizeof(Check), 56u) << "Check changed: encode the new field in framework/app/wire.cpp";
}

TEST(Wire, TruncatedOrCorruptBytesAreAnError) {
  wire::Writer w;
  wire::Put(w, FullScan());
  const std::string bytes = w.Take();
  for (size_t cut : {size_t(0), size_t(5), bytes.size() / 2, bytes.size() - 1}) {
    const std::string part = bytes.substr(0, cut);
    wire::Reader r(part, "cut");
    EXPECT_THROW(wire::GetScan(r), InputError) << cut;
  }
  std::string huge = bytes;
  const uint64_t n = ~uint64_t(0) / 2;
  std::memcpy(huge.data() + 8 + 11, &n, sizeof n);  // the point count after the source string
  wire::Reader r(huge, "huge");
  EXPECT_THROW(wire::GetScan(r), InputError);
  wire::Writer two;
  two.Pod(uint64_t(0));
  two.Pod(uint8_t(1));
  const std::string extra = two.Take();
  wire::Reader e(extra, "extra");
  EXPECT_EQ(wire::GetDetections(e).size(), 0u);
  EXPECT_THROW(e.End(), InputError);
}

// A model's bytes (what rank 0 hands the other ranks) are the model file's.
TEST(Wire, ModelBytesAreTheModelFile) {
  TrainedModel m;
  m.training_config = {{"seed", 42}};
  m.catalog_hash = "abc";
  m.voters["recognise"].voter_type = "voters.catalog_shape";
  m.voters["recognise"].voter_model = {{"format", "x"}};
  m.summary = {{"models", 1}};
  m.timings_ms = {{"voter", 12.5}};
  const std::string bytes = ModelBytes(m);
  const TrainedModel back = ModelFromBytes(bytes, "bytes");
  EXPECT_EQ(back.catalog_hash, "abc");
  EXPECT_EQ(back.summary, m.summary);
  ASSERT_NE(back.FindVoter("recognise"), nullptr);
  EXPECT_EQ(back.FindVoter("recognise")->voter_model, m.voters["recognise"].voter_model);
  EXPECT_TRUE(back.timings_ms.is_null());  // not in the file
  EXPECT_EQ(ModelBytes(back), bytes);
  EXPECT_THROW(ModelFromBytes(bytes.substr(0, bytes.size() / 2), "half"), InputError);
}

}  // namespace
