#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "furnihost/geometry.hpp"
#include "furnihost/host/io.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;
using namespace furnihost;

namespace {

Scan SampleScan() {
  Scan s;
  for (int i = 0; i < 100; ++i) s.points.emplace_back(0.01f * i, -0.5f + 0.02f * i, 1e3f + 0.003f * i);
  s.origin = Eigen::Vector3f(1, 2, 1.5f);
  return s;
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadScan(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Io, PcdRoundTripKeepsViewpoint) {
  auto dir = furnihost::testing::TempDir("io");
  auto s = SampleScan();
  const std::string p = dir + "/a.pcd";
  WritePcd(p, s);
  auto r = ReadScan(p);
  ASSERT_EQ(r.points.size(), s.points.size());
  // 1 km up: read shifted, compared in the file's frame (the viewpoint too).
  for (size_t i = 0; i < s.points.size(); ++i) EXPECT_LT((r.frame.ToFile(r.points[i]) - s.points[i].cast<double>()).norm(), 1e-4);
  ASSERT_TRUE(r.origin.has_value());
  EXPECT_TRUE(r.frame.ToFile(*r.origin).isApprox(s.origin->cast<double>()));
}

TEST(Io, PcdAsciiDropsNaNAndKnowsPclsDefaultViewpoint) {
  auto dir = furnihost::testing::TempDir("io");
  const std::string p = dir + "/ascii.pcd";
  WriteText(p, "VERSION .7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\n"
               "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n1 2 3 0\nnan nan nan 0\n4 5 6 0\n");
  ReadStats st;
  auto r = ReadScan(p, &st);
  EXPECT_EQ(st.read, 3u);
  EXPECT_EQ(st.non_finite, 1u);
  ASSERT_EQ(r.points.size(), 2u);
  EXPECT_EQ(r.points[1], Eigen::Vector3f(4, 5, 6));
  EXPECT_FALSE(r.origin.has_value());  // PCL's default viewpoint means "unknown"
}

TEST(Io, PlyBinaryWithColourAndExtraProperties) {
  auto dir = furnihost::testing::TempDir("io");
  const std::string p = dir + "/b.ply";
  {
    std::ofstream out(p, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
           "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
           "property ushort label\nproperty int instance\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n";
    auto put = [&](float x, float y, float z, uint8_t c, uint16_t l, int32_t in) {
      out.write(reinterpret_cast<char*>(&x), 4);
      out.write(reinterpret_cast<char*>(&y), 4);
      out.write(reinterpret_cast<char*>(&z), 4);
      for (int k = 0; k < 3; ++k) out.write(reinterpret_cast<char*>(&c), 1);
      out.write(reinterpret_cast<char*>(&l), 2);
      out.write(reinterpret_cast<char*>(&in), 4);
    };
    put(1, 2, 3, 200, 5, 7);
    put(4, 5, 6, 10, 7, 9);
  }
  auto r = ReadScan(p);
  ASSERT_EQ(r.points.size(), 2u);
  EXPECT_EQ(r.points[1], Eigen::Vector3f(4, 5, 6));
  ASSERT_EQ(r.colors.size(), 2u);
  EXPECT_EQ(r.colors[0][0], 200);
  EXPECT_EQ(r.attributes.at("label"), std::vector<int32_t>({5, 7}));
  EXPECT_EQ(r.attributes.at("instance"), std::vector<int32_t>({7, 9}));
}

TEST(Io, PlyAndXyzRoundTrip) {
  auto dir = furnihost::testing::TempDir("io");
  auto s = SampleScan();
  WriteScan(dir + "/c.ply", s);
  WriteScan(dir + "/c.xyz", s);
  auto a = ReadScan(dir + "/c.ply");
  auto b = ReadScan(dir + "/c.xyz");
  ASSERT_EQ(a.points.size(), s.points.size());
  ASSERT_EQ(b.points.size(), s.points.size());
  // 1 km up: read shifted (every point, by the first one's 100 m), compared in the file's frame.
  EXPECT_TRUE(a.frame.shift.isApprox(Eigen::Vector3d(0, 0, 1000)));
  for (size_t i = 0; i < s.points.size(); ++i) {
    EXPECT_LT((a.frame.ToFile(a.points[i]) - s.points[i].cast<double>()).norm(), 1e-4);
    EXPECT_LT((b.frame.ToFile(b.points[i]) - s.points[i].cast<double>()).norm(), 1e-2);  // %.6g text
  }
  WriteText(dir + "/ascii.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                "property float z\nend_header\n1 2 3\n4 5 inf\n");
  ReadStats st;
  auto c = ReadScan(dir + "/ascii.ply", &st);
  EXPECT_EQ(c.points.size(), 1u);
  EXPECT_EQ(st.non_finite, 1u);
}

TEST(Io, BadFilesGiveOneLineErrorsNamingTheFile) {
  auto dir = furnihost::testing::TempDir("io_bad");
  EXPECT_NE(ErrorOf(dir + "/missing.pcd").find("missing.pcd: no such scan file"), std::string::npos);
  EXPECT_NE(ErrorOf(dir).find("is a directory"), std::string::npos);
  WriteText(dir + "/empty.pcd", "");
  EXPECT_NE(ErrorOf(dir + "/empty.pcd").find("empty.pcd: is empty"), std::string::npos);
  WriteText(dir + "/corrupt.pcd", "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1000\n"
                                  "HEIGHT 1\nPOINTS 1000\nDATA binary\nabc");
  EXPECT_NE(ErrorOf(dir + "/corrupt.pcd").find("corrupt.pcd"), std::string::npos);
  WriteText(dir + "/garbage.pcd", "hello world\n");
  EXPECT_NE(ErrorOf(dir + "/garbage.pcd").find("garbage.pcd"), std::string::npos);
  WriteText(dir + "/short.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\n"
                                "property float y\nproperty float z\nend_header\n0123");
  EXPECT_NE(ErrorOf(dir + "/short.ply").find("declares 1000 vertices"), std::string::npos);
  WriteText(dir + "/neg.ply", "ply\nformat ascii 1.0\nelement vertex -5\nproperty float x\nend_header\n");
  EXPECT_NE(ErrorOf(dir + "/neg.ply").find("bad count"), std::string::npos);
  WriteText(dir + "/bad.xyz", "1 2 3\n4 five 6\n");
  EXPECT_NE(ErrorOf(dir + "/bad.xyz").find("bad.xyz:2: expected x y z"), std::string::npos);
  WriteText(dir + "/x.obj", "v 1 2 3\n");
  EXPECT_NE(ErrorOf(dir + "/x.obj").find("unknown scan format"), std::string::npos);
  WriteText(dir + "/nan.xyz", "nan 1 2\n");
  EXPECT_NE(ErrorOf(dir + "/nan.xyz").find("no finite points"), std::string::npos);
  // The cap refuses before reading everything.
  WriteScan(dir + "/big.ply", SampleScan());
  EXPECT_THROW(ReadScan(dir + "/big.ply", nullptr, 10), InputError);
}

TEST(Io, AtomicWriteLeavesNoPartialFile) {
  auto dir = furnihost::testing::TempDir("io_atomic");
  const std::string p = dir + "/out.json";
  WriteJson(p, {{"a", 1}});
  EXPECT_THROW(AtomicWrite(p, [](const std::string& tmp) {
                 std::ofstream(tmp) << "half";
                 throw InputError("interrupted");
               }),
               InputError);
  EXPECT_EQ(ReadJson(p)["a"], 1);  // the old content survives
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename(), "out.json");
}

TEST(Io, JsonErrorsAndGroundTruth) {
  auto dir = furnihost::testing::TempDir("io_json");
  WriteText(dir + "/bad.json", "{\"a\": [1, 2,}\n");
  try {
    ReadJson(dir + "/bad.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json: not valid JSON"), std::string::npos) << e.what();
  }
  WriteText(dir + "/deep.json", std::string(1000, '[') + std::string(1000, ']'));
  EXPECT_THROW(ReadJson(dir + "/deep.json"), InputError);
  GroundTruthObject g;
  g.cls = "chair";
  g.center = {1, 2, 0.4f};
  g.size = {0.5f, 0.5f, 0.8f};
  g.yaw = 0.5f;
  WriteJson(dir + "/x.gt.json", GroundTruthToJson({g}));
  auto back = ReadGroundTruth(dir + "/x.gt.json");
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].cls, "chair");
  EXPECT_TRUE(back[0].center.isApprox(g.center));
  EXPECT_FLOAT_EQ(*back[0].yaw, 0.5f);
  EXPECT_FALSE(back[0].yaw_symmetry.has_value());
  g.yaw_symmetry = 2;
  WriteJson(dir + "/x.gt.json", GroundTruthToJson({g}));
  EXPECT_EQ(ReadGroundTruth(dir + "/x.gt.json")[0].yaw_symmetry, 2);
  WriteText(dir + "/y.gt.json", R"({"objects": [{"class": "table", "center": [0, 0, 0], "size": [1, 1, 1], "yaw_symmetry": 1.5}]})");
  try {
    ReadGroundTruth(dir + "/y.gt.json");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("y.gt.json:/objects/0/yaw_symmetry"), std::string::npos) << e.what();
  }
}

TEST(Io, ReadsSharedScanNetPly) {
  const std::string data = furnihost::testing::SharedDataDir();
  ASSERT_FALSE(data.empty());
  auto s = ReadScan(data + "/scannet_votenet50k/scene0001_00.ply");
  EXPECT_EQ(s.points.size(), 50000u);
  EXPECT_EQ(s.attributes.at("label").size(), 50000u);
  EXPECT_EQ(s.colors.size(), 50000u);
}

TEST(Geometry, VoxelDownsampleAndSampling) {
  Points p = {{0.01f, 0.01f, 0.01f}, {0.02f, 0.02f, 0.02f}, {0.5f, 0, 0}};
  std::vector<int> kept;
  auto d = VoxelDownsample(p, 0.1f, &kept);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_TRUE(d[0].isApprox(Eigen::Vector3f(0.015f, 0.015f, 0.015f)));
  EXPECT_EQ(kept, std::vector<int>({0, 2}));
  Mesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  m.triangles = {{0, 1, 2}, {1, 3, 2}};
  auto s = SampleSurface(m, 10000, 1);
  EXPECT_NEAR(static_cast<double>(s.size()), 10000.0, 5.0);
  for (const auto& q : s) EXPECT_TRUE(q.x() >= 0 && q.x() <= 1 && q.y() >= 0 && q.y() <= 1 && q.z() == 0);
  EXPECT_EQ(SampleSurface(m, 100, 7), SampleSurface(m, 100, 7));
}

// Turn symmetries of simple shapes in a catalog model's frame (bottom centre at the origin):
// a 1.2 x 0.6 box turns onto itself by half turns, a square box by quarter turns, a 48-sided
// prism by any turn, and a box with a back panel (a chair's seat and back) by none.
TEST(Geometry, YawSymmetryOfBoxesAPrismAndAChairShape) {
  auto box = [](Mesh& m, Eigen::Vector3f lo, Eigen::Vector3f hi) {
    const int b = static_cast<int>(m.vertices.size());
    for (int i = 0; i < 8; ++i)
      m.vertices.emplace_back(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z());
    const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                          {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    for (const auto& t : f) m.triangles.emplace_back(b + t[0], b + t[1], b + t[2]);
  };
  Mesh rect, square, chair, prism;
  box(rect, {-0.6f, -0.3f, 0.f}, {0.6f, 0.3f, 0.75f});
  box(square, {-0.4f, -0.4f, 0.f}, {0.4f, 0.4f, 0.75f});
  box(chair, {-0.25f, -0.25f, 0.4f}, {0.25f, 0.25f, 0.45f});
  box(chair, {-0.25f, 0.2f, 0.45f}, {0.25f, 0.25f, 0.9f});
  const int n = 48;
  for (int i = 0; i < n; ++i) {
    const float a = 6.2831853f * static_cast<float>(i) / n;
    prism.vertices.emplace_back(0.4f * std::cos(a), 0.4f * std::sin(a), 0.f);
    prism.vertices.emplace_back(0.4f * std::cos(a), 0.4f * std::sin(a), 0.7f);
  }
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    prism.triangles.emplace_back(2 * i, 2 * j, 2 * i + 1);
    prism.triangles.emplace_back(2 * j, 2 * j + 1, 2 * i + 1);
    if (i > 0 && j > 0) {
      prism.triangles.emplace_back(0, 2 * j, 2 * i);
      prism.triangles.emplace_back(1, 2 * i + 1, 2 * j + 1);
    }
  }
  EXPECT_EQ(YawSymmetry(rect), 2);
  EXPECT_EQ(YawSymmetry(square), 4);
  EXPECT_EQ(YawSymmetry(prism), 0);
  EXPECT_EQ(YawSymmetry(chair), 1);
  EXPECT_EQ(YawSymmetry(Mesh{}), 1);
}

// XYZ text as it comes: decimal commas with semicolons or blanks read as decimals, never as
// more values; styles that change mid-file, lines of several points and UTF-16 refused naming
// the line; a UTF-8 byte-order mark and Leica .pts count lines skipped.
TEST(Io, XyzSeparatorsDecimalCommasAndEncodings) {
  auto dir = furnihost::testing::TempDir("io_xyz");
  auto first = [&](const std::string& name, const std::string& text) {
    WriteText(dir + "/" + name, text);
    return ReadScan(dir + "/" + name).points.front();
  };
  EXPECT_EQ(first("semi.xyz", "1,250;2,500;0,750\n2;3;4\n"), Eigen::Vector3f(1.25f, 2.5f, 0.75f));
  EXPECT_EQ(first("blank.xyz", "1,250 2,500\t0,750\n"), Eigen::Vector3f(1.25f, 2.5f, 0.75f));
  EXPECT_EQ(first("blank_int.xyz", "1,25 2 0,75\n3 4,5 6\n"), Eigen::Vector3f(1.25f, 2.f, 0.75f));
  EXPECT_EQ(first("csv.xyz", "1,2,3\n4,5,6\n"), Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(first("csv_spaces.xyz", "1, 2, 3, 9\n4, 5, 6, 9\n"), Eigen::Vector3f(1, 2, 3));
  EXPECT_EQ(first("bom.xyz", "\xEF\xBB\xBF" "7 8 9\n"), Eigen::Vector3f(7, 8, 9));
  WriteText(dir + "/count.pts", "2\n1 2 3 10 0 0 0\n4 5 6 10 0 0 0\n");
  EXPECT_EQ(ReadScan(dir + "/count.pts").points.size(), 2u);
  WriteText(dir + "/count.xyz", "2\n1 2 3\n");  // a count line belongs to .pts only
  EXPECT_NE(ErrorOf(dir + "/count.xyz").find("count.xyz:1: expected x y z"), std::string::npos);
  WriteText(dir + "/mixed.xyz", "1,0;2,0;3,0\n1,2,3\n");
  EXPECT_NE(ErrorOf(dir + "/mixed.xyz").find("mixed.xyz:2:"), std::string::npos);
  WriteText(dir + "/two.xyz", "0 0 0\n1 1 1 2 2 2\n");
  EXPECT_NE(ErrorOf(dir + "/two.xyz").find("two.xyz:2: holds 6 values, line 1 held 3"), std::string::npos);
  std::string line;
  for (int i = 0; i < 30000; ++i) line += "1.5 2.5 3.5 ";
  WriteText(dir + "/long.xyz", line + "\n");
  EXPECT_NE(ErrorOf(dir + "/long.xyz").find("long.xyz:1: is longer than 64 KiB"), std::string::npos);
  WriteText(dir + "/u16.xyz", std::string("\xFF\xFE" "1\0 \0" "2\0 \0" "3\0\n\0", 14));
  EXPECT_NE(ErrorOf(dir + "/u16.xyz").find("u16.xyz: is UTF-16 text"), std::string::npos);
  WriteText(dir + "/u16_plain.xyz", std::string("1\0 \0" "2\0 \0" "3\0\n\0", 12));
  const std::string e = ErrorOf(dir + "/u16_plain.xyz");
  EXPECT_NE(e.find("u16_plain.xyz:1: holds NUL bytes"), std::string::npos) << e;
}

// A PLY with a second vertex element (normals in an element of their own) is refused by name,
// not read as vertices with too few values.
TEST(Io, PlyWithTwoVertexElements) {
  auto dir = furnihost::testing::TempDir("io_ply2");
  WriteText(dir + "/two.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                              "property float z\nelement vertex 2\nproperty float nx\nend_header\n0 0 0\n1 1 1\n0\n1\n");
  EXPECT_NE(ErrorOf(dir + "/two.ply").find("two.ply: PLY has two 'vertex' elements"), std::string::npos);
}

// Stray far returns are dropped with their colours and attributes, whichever axis they lie on
// and wherever in the file; a scan without a 100 m gap keeps every point; a stray first point
// does not decide the global shift.
TEST(Io, StrayFarReturnsAreDroppedOnEveryAxis) {
  auto dir = furnihost::testing::TempDir("io_stray");
  Scan room;
  for (int i = 0; i < 500; ++i) room.points.emplace_back(0.008f * float(i), 0.006f * float(i % 97), 0.005f * float(i % 53));
  const size_t n = room.points.size();
  for (const Eigen::Vector3f& far : {Eigen::Vector3f(9e5f, 0, 0), Eigen::Vector3f(0, -9e5f, 0), Eigen::Vector3f(1, 1, 5e3f)})
    for (bool at_front : {false, true}) {
      Scan s = room;
      if (at_front) s.points.insert(s.points.begin(), far);
      else s.points.push_back(far);
      s.origin.reset();
      WritePly(dir + "/stray.ply", s.points);
      const Scan r = ReadScan(dir + "/stray.ply");
      ASSERT_EQ(r.points.size(), n) << far.transpose() << " first " << at_front;
      EXPECT_TRUE(r.frame.shift.isZero()) << r.frame.shift.transpose();
      for (const auto& p : r.points) EXPECT_LT(p.cwiseAbs().maxCoeff(), 1e3f);
    }
  // A long scan without such a gap keeps every point.
  Points corridor;
  for (int i = 0; i < 20000; ++i) corridor.emplace_back(0.05f * float(i), float(i % 3), 1.f);
  WritePly(dir + "/corridor.ply", corridor);
  EXPECT_EQ(ReadScan(dir + "/corridor.ply").points.size(), corridor.size());
  // Georeferenced points keep their shift; a stray at the file's origin is dropped, not a shift of 0.
  Points utm = {Eigen::Vector3f(0.5f, 0.5f, 0.f)};
  for (int i = 0; i < 2000; ++i) utm.emplace_back(0.1f * float(i % 50), 0.1f * float(i / 50), 1.f);
  std::ofstream out(dir + "/utm.xyz");
  out.precision(12);
  for (size_t i = 0; i < utm.size(); ++i)
    out << (i == 0 ? 0.5 : 651000.0 + utm[i].x()) << " " << (i == 0 ? 0.5 : 5423000.0 + utm[i].y()) << " " << utm[i].z() << "\n";
  out.close();
  const Scan g = ReadScan(dir + "/utm.xyz");
  EXPECT_EQ(g.points.size(), utm.size() - 1);
  EXPECT_EQ(g.frame.shift, Eigen::Vector3d(651000.0, 5423000.0, 0.0));
}

// Ground truth boxes of no size match nothing: refused naming the object.
TEST(Io, GroundTruthSizesMustBePositive) {
  auto dir = furnihost::testing::TempDir("io_gt");
  for (const char* size : {"[0, 1, 1]", "[1, -0.5, 1]", "[1, 1, -0.0]"}) {
    WriteText(dir + "/b.gt.json", std::string(R"({"objects": [{"class": "chair", "center": [0, 0, 0], "size": [1, 1, 1]},)") +
                                      R"({"class": "chair", "center": [0, 0, 0], "size": )" + size + "}]}");
    try {
      ReadGroundTruth(dir + "/b.gt.json");
      ADD_FAILURE() << size;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("b.gt.json:/objects/1/size: expected three positive extents"), std::string::npos)
          << e.what();
    }
  }
}

// JSON from the command line: nesting is bounded as config files' is, bare words are strings
// for --set, and errors name the option.
TEST(Io, CommandLineJsonIsBounded) {
  EXPECT_EQ(JsonDepth(R"({"a": [[1], "[[["], "b": {}})"), 3u);
  EXPECT_EQ(ParseCliJson("height_map", "--set ground.kind", true), nlohmann::json("height_map"));
  EXPECT_EQ(ParseCliJson("[1, 2]", "--set a.b", true), nlohmann::json({1, 2}));
  const std::string deep = std::string(60000, '[') + std::string(60000, ']');
  for (bool bare : {true, false}) {
    try {
      ParseCliJson(deep, "--set seg.x", bare);
      ADD_FAILURE();
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()), "--set seg.x: JSON nested deeper than 256 levels");
    }
  }
  EXPECT_NO_THROW(ParseCliJson(std::string(256, '[') + std::string(256, ']'), "--sensor x"));
  EXPECT_THROW(ParseCliJson("{", "--sensor x"), InputError);
  // fuzz_cli_json: nlohmann takes a NUL byte for the end ("0\0..." parsed as 0) and invalid UTF-8
  // reached the run record, whose dump threw (exit 1).
  for (const std::string& bad : {std::string("0\0junk", 6), std::string("/tmp/a\xff b")})
    for (bool bare : {true, false}) EXPECT_THROW(ParseCliJson(bad, "--set fit.cloud_cache", bare), InputError);
  EXPECT_THROW(ParseJsonText(std::string("{}\0junk", 6), "g.json"), InputError);
  EXPECT_EQ(DumpJson(nlohmann::json("r\xffm.pcd")), "\"r\xef\xbf\xbdm.pcd\"");
}

// Output names from input names stay one path component and distinct.
TEST(Io, SafeAndUniqueOutputNames) {
  EXPECT_EQ(SafeName(".."), "__");
  EXPECT_EQ(SafeName("."), "_");
  EXPECT_EQ(SafeName(""), "_");
  EXPECT_EQ(SafeName("../../x"), "___.._x");
  EXPECT_EQ(SafeName("/etc/passwd"), "_etc_passwd");
  EXPECT_EQ(SafeName(".hidden"), "_hidden");
  EXPECT_EQ(SafeName("scene0001_00.v2"), "scene0001_00.v2");
  EXPECT_EQ(SafeName(std::string(300, 'a')).size(), 100u);
  EXPECT_EQ(UniqueSafeNames({"room", "room", "Room", "room_2", "a/b", "a_b"}),
            (std::vector<std::string>{"room", "room_2", "Room_3", "room_2_2", "a_b", "a_b_2"}));
}
