// simd/left_pack.hpp: the AVX2 appends keep the scalar loops' values, order and count bit for
// bit, on random clouds with copies, NaN coordinates and every tail length.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include "simd/left_pack.hpp"

namespace {

namespace simd = furnihost::simd;

struct Cloud {
  std::vector<float> x, y, z;
};

// n points in a 10 cm cube, a quarter of them copies of earlier ones, a few NaN.
Cloud RandomCloud(int n, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-0.05f, 0.05f);
  Cloud c;
  for (int i = 0; i < n; ++i) {
    float px = u(rng), py = u(rng), pz = u(rng);
    if (i > 0 && rng() % 4 == 0) {
      const int k = int(rng() % unsigned(i));
      px = c.x[k], py = c.y[k], pz = c.z[k];
    }
    if (rng() % 50 == 0) px = std::numeric_limits<float>::quiet_NaN();
    c.x.push_back(px), c.y.push_back(py), c.z.push_back(pz);
  }
  return c;
}

bool SameBits(const float* a, const float* b, int n) { return std::memcmp(a, b, sizeof(float) * size_t(n)) == 0; }

// `fast` is the path the dispatch picks: AVX2 where the CPU has it (then each test compares it
// with the scalar loop), else the scalar loop again (the values must still agree, and the
// dispatch test below checks that the choice follows the CPU). No test is skipped either way.
class LeftPack : public ::testing::Test {
 protected:
  void SetUp() override {
    simd::SetAvx2(true);
    fast = simd::UseAvx2();
  }
  void TearDown() override { simd::SetAvx2(true); }
  bool fast = false;
};

TEST_F(LeftPack, ScaledOffsetsAreTheScalarLoops) {
  std::mt19937 rng(1);
  const Cloud c = RandomCloud(200, rng);
  int kept = 0, calls = 0;
  for (int b = 0; b < 60; b += 3)
    for (int e = b; e <= b + 41; ++e) {
      const int q = int(rng() % 200);
      const float inv_r = 1.f / 0.03f;
      std::vector<float> s[4], v[4];
      for (auto& a : s) a.assign(64, -1.f);
      for (auto& a : v) a.assign(64, -2.f);
      const int ns = simd::AppendScaledWithin(false, c.x.data(), c.y.data(), c.z.data(), b, e, c.x[q], c.y[q], c.z[q],
                                              inv_r, s[0].data(), s[1].data(), s[2].data(), s[3].data(), 3);
      const int nv = simd::AppendScaledWithin(fast, c.x.data(), c.y.data(), c.z.data(), b, e, c.x[q], c.y[q], c.z[q],
                                              inv_r, v[0].data(), v[1].data(), v[2].data(), v[3].data(), 3);
      ASSERT_EQ(ns, nv) << b << " " << e;
      for (int a = 0; a < 4; ++a) ASSERT_TRUE(SameBits(s[a].data() + 3, v[a].data() + 3, ns - 3)) << b << " " << e;
      kept += ns - 3, ++calls;
    }
  EXPECT_GT(kept, calls);  // neighbours were found, not only rejected
}

TEST_F(LeftPack, SlotListsAreTheScalarLoops) {
  std::mt19937 rng(2);
  const Cloud c = RandomCloud(200, rng);
  int kept = 0;
  for (int b = 0; b < 60; b += 3)
    for (int e = b; e <= b + 41; ++e) {
      const int self = b + int(rng() % unsigned(e - b + 1));  // inside the range or just past it
      const float r2 = 0.04f * 0.04f;
      std::vector<uint32_t> s(64, 7u), v(64, 9u);
      const int ns = simd::AppendSlotsWithin(false, c.x.data(), c.y.data(), c.z.data(), b, e, c.x[self], c.y[self],
                                             c.z[self], r2, self, s.data(), 0);
      const int nv = simd::AppendSlotsWithin(fast, c.x.data(), c.y.data(), c.z.data(), b, e, c.x[self], c.y[self],
                                             c.z[self], r2, self, v.data(), 0);
      ASSERT_EQ(ns, nv) << b << " " << e;
      ASSERT_EQ(std::memcmp(s.data(), v.data(), sizeof(uint32_t) * size_t(ns)), 0) << b << " " << e;
      for (int k = 0; k < ns; ++k) ASSERT_NE(int(s[k]), self);
      kept += ns;
    }
  EXPECT_GT(kept, 1000);
}

TEST_F(LeftPack, TangentCoordinatesAreTheScalarLoops) {
  std::mt19937 rng(3);
  const Cloud c = RandomCloud(200, rng);
  // A tangent basis of a tilted normal: every component non-zero, so the sums' order matters.
  const float u[3] = {0.48f, 0.64f, -0.6f}, v[3] = {-0.8f, 0.36f, -0.48f};
  int kept = 0;
  for (int b = 0; b < 60; b += 3)
    for (int e = b; e <= b + 41; ++e) {
      const int q = int(rng() % 200);
      std::vector<float> sa(64, 1.f), sb(64, 1.f), va(64, 2.f), vb(64, 2.f);
      const int ns = simd::AppendTangentWithin(false, c.x.data(), c.y.data(), c.z.data(), b, e, c.x[q], c.y[q], c.z[q],
                                               u, v, 0.03f * 0.03f, 1e-10f, sa.data(), sb.data(), 0);
      const int nv = simd::AppendTangentWithin(fast, c.x.data(), c.y.data(), c.z.data(), b, e, c.x[q], c.y[q], c.z[q],
                                               u, v, 0.03f * 0.03f, 1e-10f, va.data(), vb.data(), 0);
      ASSERT_EQ(ns, nv) << b << " " << e;
      ASSERT_TRUE(SameBits(sa.data(), va.data(), ns)) << b << " " << e;
      ASSERT_TRUE(SameBits(sb.data(), vb.data(), ns)) << b << " " << e;
      kept += ns;
    }
  EXPECT_GT(kept, 500);
}

// Directions on the axes, the diagonals, signed zeros and at random: each range's sectors are
// the scalar loop's on both paths, and a direction's sector is the 45 deg slice of its angle.
TEST_F(LeftPack, SectorBitsAreTheScalarLoops) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  const float special[] = {0.f, -0.f, 1.f, -1.f, 0.5f, -0.5f, 1e-30f, -1e-30f};
  std::vector<float> a, b;
  for (float x : special)
    for (float y : special) a.push_back(x), b.push_back(y);
  for (int i = 0; i < 200; ++i) a.push_back(u(rng)), b.push_back(u(rng));
  for (size_t j = 64; j < a.size(); ++j) {
    const double deg = std::atan2(double(b[j]), double(a[j])) * 180.0 / M_PI;
    const int k = int(std::floor((deg < 0 ? deg + 360.0 : deg) / 45.0));
    if (std::fabs(deg - 45.0 * std::round(deg / 45.0)) > 1e-3) {
      ASSERT_EQ(simd::Octant(a[j], b[j]), k) << a[j] << " " << b[j];
    }
  }
  std::set<unsigned> seen;
  for (int first = 0; first < 80; first += 5)
    for (int last = first; last <= first + 19; ++last) {
      unsigned scalar = 0;
      for (int j = first; j < last; ++j) scalar |= 1u << simd::Octant(a[size_t(j)], b[size_t(j)]);
      ASSERT_EQ(simd::SectorBits(false, a.data(), b.data(), first, last), scalar) << first << " " << last;
      ASSERT_EQ(simd::SectorBits(fast, a.data(), b.data(), first, last), scalar) << first << " " << last;
      seen.insert(scalar);
    }
  EXPECT_GT(seen.size(), 20u);  // the ranges give many different sector sets
}

TEST_F(LeftPack, SwitchedOffMeansScalar) {
  simd::SetAvx2(false);
  EXPECT_FALSE(simd::UseAvx2());
  simd::SetAvx2(true);
  // Never AVX2 on a CPU without it, nor with FURNIHOST_SIMD=scalar in the environment.
  const char* env = std::getenv("FURNIHOST_SIMD");
  const bool forced = env && std::string(env) == "scalar";
  EXPECT_EQ(simd::UseAvx2(), bool(__builtin_cpu_supports("avx2")) && !forced);
}

// FURNIHOST_SIMD=scalar switches the AVX2 paths off for the whole process (CI runs the tests of
// the SIMD paths once more that way); other values leave the CPU's choice.
TEST_F(LeftPack, EnvironmentForcesTheScalarLoops) {
  const char* env = std::getenv("FURNIHOST_SIMD");
  const std::string saved = env ? env : "";
  ::setenv("FURNIHOST_SIMD", "scalar", 1);
  simd::SetAvx2(true);
  EXPECT_FALSE(simd::UseAvx2());
  ::setenv("FURNIHOST_SIMD", "avx2", 1);
  simd::SetAvx2(true);
  EXPECT_EQ(simd::UseAvx2(), bool(__builtin_cpu_supports("avx2")));
  if (env)
    ::setenv("FURNIHOST_SIMD", saved.c_str(), 1);
  else
    ::unsetenv("FURNIHOST_SIMD");
  simd::SetAvx2(true);
}

}  // namespace
