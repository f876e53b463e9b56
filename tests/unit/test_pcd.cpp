// The project's PCD reader against files PCL writes (ascii, binary, binary_compressed with
// real LZF back references; packed colours, labels, an organised cloud's NaN padding, a sensor
// origin), hand-made LZF streams, and headers it must refuse with one line naming the file.
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include "furnihost/host/io.hpp"
#include "test_support.hpp"

using namespace furnihost;

namespace {

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

std::string ErrorOf(const std::string& path) {
  try {
    ReadScan(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string Floats(std::initializer_list<float> v) {
  std::string s;
  for (float f : v) s.append(reinterpret_cast<const char*>(&f), 4);
  return s;
}

const char* const kXyzHeader = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";

// An organised 8 x 6 cloud with a few NaN (invalid) returns, colours that need all 24 bits,
// labels beyond 16 bits, and a sensor origin off PCL's default.
pcl::PointCloud<pcl::PointXYZRGBL> OrganisedCloud() {
  pcl::PointCloud<pcl::PointXYZRGBL> c(8, 6);
  for (uint32_t r = 0; r < c.height; ++r)
    for (uint32_t k = 0; k < c.width; ++k) {
      auto& p = c.at(k, r);
      p.x = 0.5f * k, p.y = 2.f, p.z = 0.25f * r;  // repeated values: LZF back references
      p.r = uint8_t(30 * k + 1), p.g = uint8_t(40 * r + 2), p.b = uint8_t(k * r + 200);
      p.label = 70000 + k + 10 * r;
    }
  c.at(3, 2).x = c.at(3, 2).y = c.at(3, 2).z = std::numeric_limits<float>::quiet_NaN();
  c.at(7, 5).x = c.at(7, 5).y = c.at(7, 5).z = std::numeric_limits<float>::quiet_NaN();
  c.is_dense = false;
  c.sensor_origin_ = Eigen::Vector4f(1.5f, -2.f, 1.25f, 0.f);
  return c;
}

}  // namespace

TEST(Pcd, ReadsWhatPclWritesInEveryEncoding) {
  const auto dir = furnihost::testing::TempDir("pcd");
  const auto cloud = OrganisedCloud();
  pcl::PCDWriter writer;
  for (const char* how : {"ascii", "binary", "binary_compressed"}) {
    SCOPED_TRACE(how);
    const std::string p = dir + "/" + how + ".pcd";
    if (std::string(how) == "ascii") writer.writeASCII(p, cloud);
    else if (std::string(how) == "binary") writer.writeBinary(p, cloud);
    else writer.writeBinaryCompressed(p, cloud);
    ReadStats st;
    const Scan s = ReadScan(p, &st);
    EXPECT_EQ(st.read, 48u);
    EXPECT_EQ(st.non_finite, 2u);
    ASSERT_EQ(s.points.size(), 46u);
    ASSERT_EQ(s.colors.size(), 46u);
    ASSERT_EQ(s.attributes.count("label"), 1u);
    ASSERT_EQ(s.attributes.at("label").size(), 46u);
    size_t j = 0;
    for (const auto& p : cloud.points) {
      if (!std::isfinite(p.x)) continue;
      EXPECT_EQ(s.points[j], Eigen::Vector3f(p.x, p.y, p.z)) << j;
      EXPECT_EQ(s.colors[j][0], p.r) << j;
      EXPECT_EQ(s.colors[j][1], p.g) << j;
      EXPECT_EQ(s.colors[j][2], p.b) << j;
      EXPECT_EQ(s.attributes.at("label")[j], int32_t(p.label)) << j;
      ++j;
    }
    ASSERT_TRUE(s.origin.has_value());
    EXPECT_EQ(*s.origin, Eigen::Vector3f(1.5f, -2.f, 1.25f));
  }
}

TEST(Pcd, PackedFloatRgbAndDefaultViewpoint) {
  const auto dir = furnihost::testing::TempDir("pcd");
  pcl::PointCloud<pcl::PointXYZRGB> c;
  for (int i = 0; i < 5; ++i) {
    pcl::PointXYZRGB p;
    p.r = uint8_t(250 - i), p.g = uint8_t(i), p.b = 128;
    p.x = float(i), p.y = -float(i), p.z = 0.25f * float(i);
    c.push_back(p);
  }
  pcl::PCDWriter writer;
  for (bool ascii : {true, false}) {
    const std::string p = dir + (ascii ? "/rgb_ascii.pcd" : "/rgb_binary.pcd");
    ascii ? writer.writeASCII(p, c) : writer.writeBinary(p, c);
    const Scan s = ReadScan(p);
    ASSERT_EQ(s.colors.size(), 5u);
    EXPECT_EQ(s.colors[4][0], 246);
    EXPECT_EQ(s.colors[4][1], 4);
    EXPECT_EQ(s.colors[4][2], 128);
    EXPECT_EQ(s.points[3], Eigen::Vector3f(3.f, -3.f, 0.75f));
    EXPECT_FALSE(s.origin.has_value()) << "PCL's default viewpoint means no sensor origin";
  }
}

TEST(Pcd, DecodesLzfBackReferencesAndRefusesBadStreams) {
  const auto dir = furnihost::testing::TempDir("pcd");
  // 4 points (1, 2, 3), stored field by field: per field a 4-byte literal run, then a back
  // reference 4 bytes back copying 12 (overlapping what it writes; the 3-byte long form).
  std::string lzf;
  for (float v : {1.f, 2.f, 3.f}) {
    lzf += char(3) + Floats({v});
    lzf += std::string{char(0xE0), char(12 - 2 - 7), char(4 - 1)};
  }
  auto compressed = [&](const std::string& stream, uint32_t raw) {
    std::string words(8, '\0');
    const uint32_t packed = uint32_t(stream.size());
    std::memcpy(&words[0], &packed, 4);
    std::memcpy(&words[4], &raw, 4);
    return std::string(kXyzHeader) + "WIDTH 4\nHEIGHT 1\nPOINTS 4\nDATA binary_compressed\n" + words + stream;
  };
  WriteBytes(dir + "/lzf.pcd", compressed(lzf, 48));
  const Scan s = ReadScan(dir + "/lzf.pcd");
  ASSERT_EQ(s.points.size(), 4u);
  for (const auto& p : s.points) EXPECT_EQ(p, Eigen::Vector3f(1, 2, 3));
  // A reference before the start of the output, a literal run past the end of the stream, a
  // stream that stops short of the size it declares.
  WriteBytes(dir + "/back.pcd", compressed(std::string{char(0x20), char(0)} + lzf, 48));
  WriteBytes(dir + "/run.pcd", compressed(lzf + char(31) + "abc", 48));
  WriteBytes(dir + "/short.pcd", compressed(lzf.substr(0, lzf.size() - 3), 48));
  for (const char* f : {"back", "run", "short"}) {
    const std::string e = ErrorOf(dir + "/" + f + ".pcd");
    EXPECT_NE(e.find(std::string(f) + ".pcd: corrupt or truncated PCD data"), std::string::npos) << e;
  }
}

TEST(Pcd, RefusesInconsistentHeadersNamingTheFile) {
  const auto dir = furnihost::testing::TempDir("pcd");
  const std::string xyz = kXyzHeader;
  const std::string body = Floats({1, 2, 3, 4, 5, 6});
  const std::vector<std::pair<std::string, std::string>> cases = {
      // A second header inside the first (the fuzzer's crash of PCL's reader).
      {xyz + "WIDTH 2\nHEIGHT 1\n" + xyz + "POINTS 2\nDATA binary\n" + body, "VERSION given twice"},
      {xyz + "WIDTH 2\nHEIGHT 1\nPOINTS 3\nDATA binary\n" + body, "POINTS 3 but WIDTH x HEIGHT = 2"},
      {xyz + "WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0\nDATA binary\n" + body, "VIEWPOINT needs 7 numbers"},
      {xyz + "WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 zero 1 0 0 0\nDATA binary\n" + body, "VIEWPOINT value 'zero'"},
      {xyz + "WIDTH 2\nHEIGHT 1\nLENGTH 3\nDATA binary\n" + body, "unknown line 'LENGTH 3'"},
      {xyz + "WIDTH 2x\nDATA binary\n" + body, "WIDTH '2x' is not a count"},
      {xyz + "WIDTH 2\nHEIGHT 1\nDATA binary\n", "PCD data shorter than its header says"},
      {xyz + "WIDTH 2\nHEIGHT 1\n", "no DATA line"},
      {"FIELDS x y z x\nSIZE 4 4 4 4\nTYPE F F F F\nWIDTH 1\nDATA ascii\n1 2 3 4\n", "field 'x' given twice"},
      {"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 2\nWIDTH 1\nDATA ascii\n1 2 3 4\n", "field z has COUNT 2"},
      {"FIELDS x y z\nSIZE 4 4 2\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n", "is a float of size 2"},
      {"FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1048577\nWIDTH 1\nDATA ascii\n1 2 3\n", "COUNT '1048577'"},
      {xyz + "WIDTH 2\nDATA ascii\n1 2 3\n4 5\n", "PCD point 1 has 2 values, its header's fields need 3"},
      {xyz + "WIDTH 2\nDATA ascii\n1 2 3\n4 5 six\n", "PCD point 1: 'six' is not a number"},
      {xyz + "WIDTH 3\nDATA ascii\n1 2 3\n4 5 6\n", "PCD ends after 2 of 3 points"},
      {xyz + "WIDTH 2\nDATA lzma\n" + body, "DATA 'lzma', expected ascii, binary or binary_compressed"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const std::string p = dir + "/case" + std::to_string(i) + ".pcd";
    WriteBytes(p, cases[i].first);
    const std::string e = ErrorOf(p);
    EXPECT_EQ(e.rfind(p + ": ", 0), 0u) << e;
    EXPECT_NE(e.find(cases[i].second), std::string::npos) << "case " << i << ": " << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  }
  // PCD 0.5 (POINTS, no WIDTH), COLUMNS for FIELDS, comments, CRLF line ends and 8-byte
  // coordinates are all read.
  WriteBytes(dir + "/old.pcd", "# old\r\nCOLUMNS x y z\r\nSIZE 8 8 8\r\nTYPE F F F\r\nPOINTS 1\r\nDATA ascii\r\n1 2 3\r\n");
  const Scan s = ReadScan(dir + "/old.pcd");
  ASSERT_EQ(s.points.size(), 1u);
  EXPECT_EQ(s.points[0], Eigen::Vector3f(1, 2, 3));
}

// binary_compressed is decoded as a stream through a window: a cloud far larger than the window
// (6.4 MB of fields, PCL's LZF with back references across every flush), with a field the reader
// does not keep, comes back exact, and only the kept columns are held.
TEST(Pcd, CompressedStreamLargerThanTheDecodeWindow) {
  const auto dir = furnihost::testing::TempDir("pcd");
  pcl::PointCloud<pcl::PointXYZINormal> cloud;
  const size_t n = 200000;
  cloud.resize(n);
  for (size_t i = 0; i < n; ++i) {
    auto& p = cloud.points[i];
    p.x = 0.01f * float(i % 1000), p.y = 0.5f * float(i / 1000), p.z = float(i % 7);
    p.intensity = float(i % 13), p.normal_x = 0.f, p.normal_y = 0.f, p.normal_z = 1.f, p.curvature = 0.f;
  }
  const std::string path = dir + "/big_compressed.pcd";
  pcl::PCDWriter().writeBinaryCompressed(path, cloud);
  const Scan s = ReadScan(path);
  ASSERT_EQ(s.points.size(), n);
  for (size_t i = 0; i < n; i += 997) EXPECT_EQ(s.points[i], Eigen::Vector3f(cloud[i].x, cloud[i].y, cloud[i].z)) << i;
  EXPECT_EQ(s.points.back(), Eigen::Vector3f(cloud[n - 1].x, cloud[n - 1].y, cloud[n - 1].z));
}
