// The one FNV-1a helper (furnihost/hash.hpp): both offsets give the values the former copies
// gave, so cache keys and seeds derived from them do not change.
#include <gtest/gtest.h>

#include <string>

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
