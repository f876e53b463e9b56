// The one FNV-1a helper (furnihost/hash.hpp): both offsets give the values the former copies
// gave, so cache keys and seeds derived from them do not change.
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "furnihost/hash.hpp"

using namespace furnihost;

TEST(Hash, StandardOffsetMatchesTheReferenceValue) {
  EXPECT_EQ(Fnv1a("a", 1), 0xaf63dc4c8601ec8cull);  // FNV-1a 64 reference value of "a"
  EXPECT_EQ(Fnv1a(std::string("a")), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(Fnv1a("", 0), kFnvOffset);
}

TEST(Hash, TruncatedOffsetKeepsTheFormerValues) {
  // Values of the former copies in catalog.cpp, ransac_upright and icp_refine.
  EXPECT_EQ(Fnv1a("a", 1, kFnvOffsetTruncated), 0x44bd8ad473cd9906ull);
  EXPECT_EQ(Fnv1a(std::string("chair"), kFnvOffsetTruncated), 0x0206f0812b49bc4cull);
}

TEST(Hash, ContinuesFromTheGivenState) {
  const std::string ab = "ab";
  EXPECT_EQ(Fnv1a(ab.data() + 1, 1, Fnv1a(ab.data(), 1)), Fnv1a(ab));
  EXPECT_EQ(Fnv1a(std::string("b"), Fnv1a(std::string("a"), kFnvOffsetTruncated)),
            Fnv1a(ab, kFnvOffsetTruncated));
}

TEST(Hash, SplitMix64MatchesTheReferenceGenerator) {
  // The reference SplitMix64 generator seeded with 0 outputs these; each step adds the golden
  // gamma to its state and returns the finaliser of the new state, as SplitMix64(state) does.
  EXPECT_EQ(SplitMix64(0), 0xe220a8397b1dcdafull);
  EXPECT_EQ(SplitMix64(0x9e3779b97f4a7c15ull), 0x6e789e6aa1b965f4ull);
  EXPECT_EQ(SplitMix64(2 * 0x9e3779b97f4a7c15ull), 0x06c45d188009454full);
  EXPECT_NE(SplitMix64(1), SplitMix64(2));
}

// UnitOpen: the top 53 bits as a double in (0, 1], never 0, the same value on every build.
TEST(Hash, UnitOpenIsNeverZero) {
  const double step = 1.0 / 9007199254740992.0;  // 2^-53
  EXPECT_EQ(furnihost::UnitOpen(0), 0.5 * step);
  EXPECT_EQ(furnihost::UnitOpen(1ull << 11), 1.5 * step);
  EXPECT_EQ(furnihost::UnitOpen(2047), furnihost::UnitOpen(0));  // the low 11 bits are not used
  EXPECT_LE(furnihost::UnitOpen(~0ull), 1.0);
  EXPECT_GT(furnihost::UnitOpen(~0ull), 1.0 - 2 * step);
}

// HashSlot, the home slot of every open-addressing table of packed coordinates (voxel keys of
// 21 bits per axis, x lowest or highest; a point's float bits): a run of keys along any one
// field spreads over the table at every size, so linear probing stays linear. A multiply whose
// low or middle bits were taken (shape.cpp's, 0.5 s -> minutes along x) put a whole run on one
// slot.
TEST(Hash, HashSlotSpreadsRunsAlongEveryAxis) {
  // Linear probing of `keys` into 2^bits slots (at most half full): probes per key.
  auto probes_per_key = [](const std::vector<uint64_t>& keys, int bits) {
    const size_t mask = (size_t(1) << bits) - 1;
    std::vector<char> used(mask + 1, 0);
    size_t probes = 0;
    for (uint64_t k : keys) {
      size_t h = furnihost::HashSlot(k, mask);
      while (used[h]) h = (h + 1) & mask, ++probes;
      used[h] = 1;
    }
    return double(probes) / double(keys.size());
  };
  for (int shift : {0, 21, 42})        // the axis the run goes along
    for (int bits = 4; bits <= 22; bits += 3) {
      const size_t n = (size_t(1) << bits) / 2;
      std::vector<uint64_t> keys(n);
      for (size_t i = 0; i < n; ++i) {
        const uint64_t c = (i + 1000) & 0x1FFFFF;
        keys[i] = (c << shift) | (uint64_t(7) << (shift == 0 ? 21 : 0)) | (uint64_t(3) << (shift == 42 ? 21 : 42));
      }
      EXPECT_LT(probes_per_key(keys, bits), 2.0) << "run along bit " << shift << ", 2^" << bits << " slots";
    }
  // Float bits: points 1 cm apart along each axis, packed as GroupEqualPoints packs them.
  for (int axis = 0; axis < 3; ++axis) {
    const size_t n = 1 << 17;
    std::vector<uint64_t> keys(n);
    for (size_t i = 0; i < n; ++i) {
      float v[3] = {1.f, 2.f, 3.f};
      v[axis] += 0.01f * float(i);
      uint32_t b[3];
      std::memcpy(b, v, 12);
      keys[i] = furnihost::SplitMix64((uint64_t(b[0]) << 32) | b[1]) ^ b[2];
    }
    EXPECT_LT(probes_per_key(keys, 18), 2.0) << "float run along axis " << axis;
  }
}
