#pragma once
// furnihost::simd — the points of a slot range that lie within a radius of a query, appended
// ("left-packed") to output arrays without branches, and the 45 deg sectors a set of directions
// falls in: 8 candidates at a time on CPUs with AVX2, chosen at run time (the build stays without
// -march), one at a time elsewhere.
//
// Both paths compute every value by the same IEEE operations in the same order (the AVX2
// functions are compiled for "avx2" alone, which has no fused multiply-add to contract into),
// so the kept values, their order and their count are the scalar loop's bit for bit: callers
// get the same neighbours whichever path runs (simd tests compare them on random clouds).
//
// Every Append* writes past the last kept value (the scalar loop one slot, AVX2 up to 8): the
// output arrays need kAppendSlack elements of room after the most values the call could keep.
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define FURNIHOST_SIMD_X86 1
#endif

namespace furnihost::simd {

constexpr int kAppendSlack = 8;

namespace internal {
// -1: not yet asked; 0: scalar; 1: AVX2.
inline std::atomic<int>& Avx2Flag() {
  static std::atomic<int> flag{-1};
  return flag;
}
inline bool CpuHasAvx2() {
#if FURNIHOST_SIMD_X86
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}
// FURNIHOST_SIMD=scalar in the environment forces the scalar loops, so that anyone can run
// the suite (or a detection) both ways on one machine and compare.
inline bool ScalarForced() {
  const char* e = std::getenv("FURNIHOST_SIMD");
  return e && std::strcmp(e, "scalar") == 0;
}
}  // namespace internal

// Whether the AVX2 paths run: the CPU has AVX2, unless FURNIHOST_SIMD=scalar is set or
// SetAvx2(false) switched them off.
inline bool UseAvx2() {
  int f = internal::Avx2Flag().load(std::memory_order_relaxed);
  if (f < 0) {
    f = internal::CpuHasAvx2() && !internal::ScalarForced() ? 1 : 0;
    internal::Avx2Flag().store(f, std::memory_order_relaxed);
  }
  return f == 1;
}
// For tests and comparisons: on = AVX2 where the CPU has it (and FURNIHOST_SIMD does not force
// the scalar loops); off = the scalar loops.
inline void SetAvx2(bool on) {
  internal::Avx2Flag().store(on && internal::CpuHasAvx2() && !internal::ScalarForced() ? 1 : 0);
}

#if FURNIHOST_SIMD_X86
namespace internal {
// Row m: the lanes whose bit is set in m, in increasing order, then zeros.
struct PackTable {
  alignas(32) int32_t row[256][8];
  constexpr PackTable() : row() {
    for (int m = 0; m < 256; ++m) {
      int k = 0;
      for (int l = 0; l < 8; ++l)
        if (m & (1 << l)) row[m][k++] = l;
      for (; k < 8; ++k) row[m][k] = 0;
    }
  }
};
inline constexpr PackTable kPack{};

// The lanes of [j, e) when fewer than 8 remain, as a load mask and a bit mask.
[[gnu::target("avx2")]] inline __m256i TailMask(int left) {
  return _mm256_cmpgt_epi32(_mm256_set1_epi32(left), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
}
[[gnu::target("avx2")]] inline __m256 Load8(const float* p, int left) {
  return left >= 8 ? _mm256_loadu_ps(p) : _mm256_maskload_ps(p, TailMask(left));
}
[[gnu::target("avx2")]] inline int LaneBits(int left) { return left >= 8 ? 0xff : (1 << left) - 1; }
[[gnu::target("avx2")]] inline void Store8(float* out, __m256 v, __m256i perm) {
  _mm256_storeu_ps(out, _mm256_permutevar8x32_ps(v, perm));
}
// The offsets q - p of the slots j.. (up to `left` of them), per axis.
struct Offsets8 {
  __m256 x, y, z;
};
[[gnu::target("avx2")]] inline Offsets8 Offsets(const float* x, const float* y, const float* z, int j, int left,
                                                __m256 px, __m256 py, __m256 pz) {
  return {_mm256_sub_ps(Load8(x + j, left), px), _mm256_sub_ps(Load8(y + j, left), py),
          _mm256_sub_ps(Load8(z + j, left), pz)};
}
// a.x b.x + a.y b.y + a.z b.z, summed left to right as the scalar loops do.
[[gnu::target("avx2")]] inline __m256 Dot(__m256 ax, __m256 ay, __m256 az, __m256 bx, __m256 by, __m256 bz) {
  return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ax, bx), _mm256_mul_ps(ay, by)), _mm256_mul_ps(az, bz));
}

[[gnu::target("avx2,popcnt")]] inline int AppendScaledWithinAvx2(const float* x, const float* y, const float* z, int b, int e,
                                                          float px, float py, float pz, float inv_r, float* ox,
                                                          float* oy, float* oz, float* od, int cnt) {
  const __m256 PX = _mm256_set1_ps(px), PY = _mm256_set1_ps(py), PZ = _mm256_set1_ps(pz);
  const __m256 IR = _mm256_set1_ps(inv_r), ONE = _mm256_set1_ps(1.f);
  for (int j = b; j < e; j += 8) {
    const int left = e - j;
    const Offsets8 d = Offsets(x, y, z, j, left, PX, PY, PZ);
    const __m256 dx = _mm256_mul_ps(d.x, IR), dy = _mm256_mul_ps(d.y, IR), dz = _mm256_mul_ps(d.z, IR);
    const __m256 d2 = Dot(dx, dy, dz, dx, dy, dz);
    const int m = _mm256_movemask_ps(_mm256_cmp_ps(d2, ONE, _CMP_LT_OQ)) & LaneBits(left);
    const __m256i perm = _mm256_load_si256(reinterpret_cast<const __m256i*>(kPack.row[m]));
    Store8(ox + cnt, dx, perm), Store8(oy + cnt, dy, perm), Store8(oz + cnt, dz, perm), Store8(od + cnt, d2, perm);
    cnt += __builtin_popcount(unsigned(m));
  }
  return cnt;
}

[[gnu::target("avx2,popcnt")]] inline int AppendSlotsWithinAvx2(const float* x, const float* y, const float* z, int b, int e,
                                                         float px, float py, float pz, float r2, int self,
                                                         uint32_t* out, int cnt) {
  const __m256 PX = _mm256_set1_ps(px), PY = _mm256_set1_ps(py), PZ = _mm256_set1_ps(pz), R2 = _mm256_set1_ps(r2);
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  for (int j = b; j < e; j += 8) {
    const int left = e - j;
    const Offsets8 d = Offsets(x, y, z, j, left, PX, PY, PZ);
    const __m256 d2 = Dot(d.x, d.y, d.z, d.x, d.y, d.z);
    int m = _mm256_movemask_ps(_mm256_cmp_ps(d2, R2, _CMP_LT_OQ)) & LaneBits(left);
    if (unsigned(self - j) < 8u) m &= ~(1 << (self - j));
    const __m256i perm = _mm256_load_si256(reinterpret_cast<const __m256i*>(kPack.row[m]));
    const __m256i slots = _mm256_add_epi32(_mm256_set1_epi32(j), lane);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + cnt), _mm256_permutevar8x32_epi32(slots, perm));
    cnt += __builtin_popcount(unsigned(m));
  }
  return cnt;
}

[[gnu::target("avx2,popcnt")]] inline int AppendTangentWithinAvx2(const float* x, const float* y, const float* z, int b,
                                                           int e, float px, float py, float pz, const float u[3],
                                                           const float v[3], float r2, float min_len2, float* pa,
                                                           float* pb, int cnt) {
  const __m256 PX = _mm256_set1_ps(px), PY = _mm256_set1_ps(py), PZ = _mm256_set1_ps(pz), R2 = _mm256_set1_ps(r2);
  const __m256 UX = _mm256_set1_ps(u[0]), UY = _mm256_set1_ps(u[1]), UZ = _mm256_set1_ps(u[2]);
  const __m256 VX = _mm256_set1_ps(v[0]), VY = _mm256_set1_ps(v[1]), VZ = _mm256_set1_ps(v[2]);
  const __m256 ML = _mm256_set1_ps(min_len2);
  for (int j = b; j < e; j += 8) {
    const int left = e - j;
    const Offsets8 d = Offsets(x, y, z, j, left, PX, PY, PZ);
    const __m256 a = Dot(UX, UY, UZ, d.x, d.y, d.z), bb = Dot(VX, VY, VZ, d.x, d.y, d.z);
    const __m256 d2 = Dot(d.x, d.y, d.z, d.x, d.y, d.z);
    const __m256 l2 = _mm256_add_ps(_mm256_mul_ps(a, a), _mm256_mul_ps(bb, bb));
    const __m256 keep = _mm256_and_ps(_mm256_cmp_ps(d2, R2, _CMP_LT_OQ), _mm256_cmp_ps(l2, ML, _CMP_GT_OQ));
    const int m = _mm256_movemask_ps(keep) & LaneBits(left);
    const __m256i perm = _mm256_load_si256(reinterpret_cast<const __m256i*>(kPack.row[m]));
    Store8(pa + cnt, a, perm), Store8(pb + cnt, bb, perm);
    cnt += __builtin_popcount(unsigned(m));
  }
  return cnt;
}
// The OR of 1 << Octant(a[j], b[j]) over j in [first, last), 8 directions at a time.
[[gnu::target("avx2")]] inline unsigned SectorBitsAvx2(const float* a, const float* b, int first, int last) {
  const __m256 sign = _mm256_set1_ps(-0.f), zero = _mm256_setzero_ps();
  const __m256i one = _mm256_set1_epi32(1);
  __m256i bits = _mm256_setzero_si256();
  for (int j = first; j < last; j += 8) {
    const int left = last - j;
    const __m256 va = Load8(a + j, left), vb = Load8(b + j, left);
    const __m256i bn = _mm256_srli_epi32(_mm256_castps_si256(_mm256_cmp_ps(vb, zero, _CMP_LT_OQ)), 31);
    const __m256i an = _mm256_srli_epi32(_mm256_castps_si256(_mm256_cmp_ps(va, zero, _CMP_LT_OQ)), 31);
    const __m256i q = _mm256_add_epi32(_mm256_slli_epi32(bn, 1), _mm256_xor_si256(an, bn));
    const __m256 fa = _mm256_andnot_ps(sign, va), fb = _mm256_andnot_ps(sign, vb);
    // q odd: fb <= fa; q even: fb >= fa (as all-ones lanes, shifted down to 0 / 1).
    const __m256 odd = _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(q, one), one));
    const __m256 upper = _mm256_blendv_ps(_mm256_cmp_ps(fb, fa, _CMP_GE_OQ), _mm256_cmp_ps(fb, fa, _CMP_LE_OQ), odd);
    const __m256i octant = _mm256_add_epi32(_mm256_slli_epi32(q, 1), _mm256_srli_epi32(_mm256_castps_si256(upper), 31));
    const __m256i bit = _mm256_and_si256(_mm256_sllv_epi32(one, octant), TailMask(left));
    bits = _mm256_or_si256(bits, bit);
  }
  alignas(32) uint32_t lanes[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), bits);
  return lanes[0] | lanes[1] | lanes[2] | lanes[3] | lanes[4] | lanes[5] | lanes[6] | lanes[7];
}
}  // namespace internal
#endif

// The 45 deg sector of direction (a, b), by comparisons only: quadrant q (0: a >= 0, b >= 0;
// 1: a < 0 <= b; 2: a, b < 0; 3: b < 0 <= a), then its upper half where |b| >= |a| (q even)
// or |b| <= |a| (q odd). Sector k holds the directions of angle [k, k + 1) * 45 deg up to
// ties on the diagonals. Without branches: on dense parts a branch here mispredicts half the
// time. Finite a, b.
inline int Octant(float a, float b) {
  const int bn = b < 0, an = a < 0;
  const int q = 2 * bn + (an ^ bn);
  const float fa = __builtin_fabsf(a), fb = __builtin_fabsf(b);
  const int upper = (q & 1) ? int(fb <= fa) : int(fb >= fa);
  return 2 * q + upper;
}

// The sectors (Octant) holding the directions (a[j], b[j]), j in [first, last), as bits
// 1 << sector: the same bits on both paths (an OR does not depend on the order).
inline unsigned SectorBits(bool avx2, const float* a, const float* b, int first, int last) {
#if FURNIHOST_SIMD_X86
  if (avx2) return internal::SectorBitsAvx2(a, b, first, last);
#else
  (void)avx2;
#endif
  unsigned bits = 0;
  for (int j = first; j < last; ++j) bits |= 1u << Octant(a[j], b[j]);
  return bits;
}

// Offsets d = (q - p) * inv_r of the slots j in [b, e) with |d|^2 < 1, appended to ox, oy, oz
// with |d|^2 to od from position cnt; returns the new count. (The normals' neighbourhoods.)
inline int AppendScaledWithin(bool avx2, const float* x, const float* y, const float* z, int b, int e, float px,
                              float py, float pz, float inv_r, float* ox, float* oy, float* oz, float* od, int cnt) {
#if FURNIHOST_SIMD_X86
  if (avx2) return internal::AppendScaledWithinAvx2(x, y, z, b, e, px, py, pz, inv_r, ox, oy, oz, od, cnt);
#else
  (void)avx2;
#endif
  for (int j = b; j < e; ++j) {
    const float dx = (x[j] - px) * inv_r, dy = (y[j] - py) * inv_r, dz = (z[j] - pz) * inv_r;
    const float d2 = dx * dx + dy * dy + dz * dz;
    ox[cnt] = dx, oy[cnt] = dy, oz[cnt] = dz, od[cnt] = d2;  // written always, kept when near
    cnt += d2 < 1.f;
  }
  return cnt;
}

// The slots q in [b, e), q != self, with |q - p|^2 < r2 (unscaled), appended to out from
// position cnt; returns the new count. (The growth's neighbour lists.)
inline int AppendSlotsWithin(bool avx2, const float* x, const float* y, const float* z, int b, int e, float px,
                             float py, float pz, float r2, int self, uint32_t* out, int cnt) {
#if FURNIHOST_SIMD_X86
  if (avx2) return internal::AppendSlotsWithinAvx2(x, y, z, b, e, px, py, pz, r2, self, out, cnt);
#else
  (void)avx2;
#endif
  for (int q = b; q < e; ++q) {
    const float dx = x[q] - px, dy = y[q] - py, dz = z[q] - pz;
    out[cnt] = uint32_t(q);  // written always, kept when near
    cnt += int((dx * dx + dy * dy + dz * dz < r2) & (q != self));
  }
  return cnt;
}

// The tangent-plane coordinates a = u . d, b = v . d of d = q - p for the slots in [b, e) with
// |d|^2 < r2 and a^2 + b^2 > min_len2, appended to pa, pb from position cnt; returns the new
// count. (The boundary test of the part features.)
inline int AppendTangentWithin(bool avx2, const float* x, const float* y, const float* z, int b, int e, float px,
                               float py, float pz, const float u[3], const float v[3], float r2, float min_len2,
                               float* pa, float* pb, int cnt) {
#if FURNIHOST_SIMD_X86
  if (avx2) return internal::AppendTangentWithinAvx2(x, y, z, b, e, px, py, pz, u, v, r2, min_len2, pa, pb, cnt);
#else
  (void)avx2;
#endif
  for (int j = b; j < e; ++j) {
    const float dx = x[j] - px, dy = y[j] - py, dz = z[j] - pz;
    const float a = u[0] * dx + u[1] * dy + u[2] * dz;
    const float bb = v[0] * dx + v[1] * dy + v[2] * dz;
    pa[cnt] = a, pb[cnt] = bb;
    cnt += (dx * dx + dy * dy + dz * dz < r2) & (a * a + bb * bb > min_len2);
  }
  return cnt;
}

}  // namespace furnihost::simd
