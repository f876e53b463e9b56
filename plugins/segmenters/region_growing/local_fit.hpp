// segmenters.region_growing, private to normals.cpp: the local fit of one query's neighbourhood
// (PCA frame, weighted height-function fit, its normal), header-only so that the normals' inner
// loop inlines it.
#pragma once

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "region_growing_detail.hpp"
#include "simd/left_pack.hpp"

namespace furnihost::rg::detail {

// Neighbours of one query as offsets scaled by 1/r (so every quantity below is O(1)) and
// their squared scaled distance.
// The arrays have room for every candidate; the first `count` entries are the neighbours.
struct Neighbours {
  std::vector<float> x, y, z, d2;
  std::vector<float> mult;     // points per neighbour (voxel centroids; FitPoint<true> only)
  std::vector<float> scratch;  // FitPoint's work arrays
  int count = 0;
  void reserve(int m) {
    // Room past the neighbours for FitPoint's padding to a multiple of 4 (3) and the appends'
    // writes past the last kept candidate (simd::kAppendSlack).
    constexpr int kMore = std::max(3, simd::kAppendSlack);
    if (int(x.size()) < m + kMore)
      x.resize(m + kMore), y.resize(m + kMore), z.resize(m + kMore), d2.resize(m + kMore), mult.resize(m + kMore);
  }
  int size() const { return count; }
};

// Four floats as one vector value (GCC/Clang vector extension): lane-wise arithmetic, compiled
// to SSE2 on x86-64 and NEON on arm64, with no -march flag.
typedef float F4 __attribute__((vector_size(16)));
inline F4 Load4(const float* p) {
  F4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline F4 Splat4(float a) { return F4{a, a, a, a}; }
inline float Sum4(F4 v) { return (v[0] + v[1]) + (v[2] + v[3]); }

// Two doubles as one vector value (SSE2 on x86-64, NEON on arm64).
typedef double D2 __attribute__((vector_size(16)));
inline D2 Sqrt2(D2 v) {
#if defined(__SSE2__)
  return (D2)_mm_sqrt_pd((__m128d)v);
#else
  return D2{std::sqrt(v[0]), std::sqrt(v[1])};
#endif
}

// The local surface of one query from its radius neighbourhood (the query's own point included
// when it is one).
// 1. PCA of the neighbourhood: tangent frame U (largest), V, N (smallest eigenvector) and the
//    curvature lambda0 / sum.
// 2. Height function h(u, v) = c0 + c1 u + c2 v + c3 uv + c4 u^2 + c5 v^2 over the PCA plane,
//    origin at the query projected on that plane (eq. 1), fitted by weighted least squares with
//    Gaussian weights exp(-d^2 / r^2) of the distance to the query (as in PCL's MLS).
// 3. The normal at a point of offset (u, v) from the origin: n = (U + h_u N) x (V + h_v N) =
//    N - h_u U - h_v V, with U x V = N (at the query: N - c1 U - c2 V). NormalAt below.
// Fewer than `min_fit` points or a neighbourhood without 2-D extent (a line of points, where
// the quadratic terms are undetermined): the PCA normal. Fewer than 3 points: NaN.
// The paper also projects the point onto the fitted surface; we keep the measured points.
// kCentroids: the neighbours are voxel centroids, each standing for nb.mult[i] points, which
// weigh the moments and the fit as that many points at the centroid would.
struct LocalFit {
  bool valid = false;  // false: fewer than 3 neighbours (NaN normal)
  bool poly = false;   // the height function was fitted; false: the PCA normal N
  Eigen::Vector3f N = Eigen::Vector3f::Zero(), U = Eigen::Vector3f::Zero(), V = Eigen::Vector3f::Zero();
  Eigen::Vector3f o = Eigen::Vector3f::Zero();  // frame and origin (offsets scaled by 1/r from the query)
  float c[6] = {0, 0, 0, 0, 0, 0};
};

// The fit in two halves, so that several points' 6x6 systems can be solved together
// (SolveSpd6Pair): FitSystem up to the normal equations (false: nothing to solve, the fit is
// final), FitFinish from their solution. FitSystem itself in steps, so that FitSystemPair can
// run the sums of two points' neighbourhoods side by side in the two halves of AVX2 vectors:
// RawSums (the moments of the offsets), FitFrame (PCA frame and Gaussian weights), PolySums
// (the weighted moments of the height function), FitEquations.
struct NormalEquations {
  double A[6][6], y[6];  // A: upper triangle only
};

// Raw moments of the offsets, in 4 lanes: lane l sums neighbours l, l + 4, ... (m: the
// centroids' point counts, for FitSystem<true>).
struct RawSums {
  F4 x{}, y{}, z{}, xx{}, xy{}, xz{}, yy{}, yz{}, zz{}, m{};
};
// Groups [from, k4) of 4 neighbours added to s, in order.
template <bool kCentroids>
void AddRawSums(const Neighbours& nb, int from, int k4, RawSums& s) {
  for (int i = from; i < k4; i += 4) {
    const F4 x = Load4(&nb.x[i]), y = Load4(&nb.y[i]), z = Load4(&nb.z[i]);
    if constexpr (kCentroids) {
      const F4 m = Load4(&nb.mult[i]);
      const F4 mx = m * x, my = m * y, mz = m * z;
      s.m += m, s.x += mx, s.y += my, s.z += mz;
      s.xx += mx * x, s.xy += mx * y, s.xz += mx * z, s.yy += my * y, s.yz += my * z, s.zz += mz * z;
    } else {
      s.x += x, s.y += y, s.z += z;
      s.xx += x * x, s.xy += x * y, s.xz += x * z, s.yy += y * y, s.yz += y * z, s.zz += z * z;
    }
  }
}

// The frame of the height function, splatted: origin o, tangents U, V, normal N.
struct PolyFrame {
  F4 ox, oy, oz, Ux, Uy, Uz, Vx, Vy, Vz, Nx, Ny, Nz;
};
// The 15 distinct moments w u^i v^j (i + j <= 4) and the 6 of w h b_r, in 4 lanes.
struct PolySums {
  F4 m00{}, m10{}, m01{}, m20{}, m11{}, m02{}, m30{}, m21{}, m12{}, m03{}, m40{}, m31{}, m22{}, m13{}, m04{};
  F4 h00{}, h10{}, h01{}, h11{}, h20{}, h02{};
};
inline void AddPolySums(const Neighbours& nb, int from, int k4, const PolyFrame& f, PolySums& s) {
  for (int i = from; i < k4; i += 4) {
    const F4 ex = Load4(&nb.x[i]) - f.ox, ey = Load4(&nb.y[i]) - f.oy, ez = Load4(&nb.z[i]) - f.oz;
    const F4 u = ex * f.Ux + ey * f.Uy + ez * f.Uz;
    const F4 v = ex * f.Vx + ey * f.Vy + ez * f.Vz;
    const F4 h = ex * f.Nx + ey * f.Ny + ez * f.Nz;
    const F4 w = Load4(&nb.scratch[i]);
    const F4 wu = w * u, wv = w * v, wuu = wu * u, wuv = wu * v, wvv = wv * v;
    const F4 wuuu = wuu * u, wuuv = wuu * v, wuvv = wuv * v, wvvv = wvv * v;
    s.m00 += w, s.m10 += wu, s.m01 += wv, s.m20 += wuu, s.m11 += wuv, s.m02 += wvv;
    s.m30 += wuuu, s.m21 += wuuv, s.m12 += wuvv, s.m03 += wvvv;
    s.m40 += wuuu * u, s.m31 += wuuu * v, s.m22 += wuuv * v, s.m13 += wuvv * v, s.m04 += wvvv * v;
    s.h00 += w * h, s.h10 += wu * h, s.h01 += wv * h, s.h11 += wuv * h, s.h20 += wuu * h, s.h02 += wvv * h;
  }
}

// Pads nb to a multiple of 4 with zero offsets of weight 0; returns the padded count.
inline int PadNeighbours(Neighbours& nb) {
  const int k = nb.size(), k4 = (k + 3) & ~3;
  for (int i = k; i < k4; ++i) nb.x[i] = nb.y[i] = nb.z[i] = nb.d2[i] = nb.mult[i] = 0.f;
  return k4;
}

#if defined(__x86_64__) || defined(__i386__)
// out[i] = exp(-d2[i]) for i < n as Eigen's `(-Array).exp()` computes it on a 16-byte aligned
// `out` without AVX (its SSE2 packet exp, Eigen 3.4's pexp_float with pldexp_generic, on the
// whole groups of 4; std::exp on the last n % 4), 8 lanes at a time: the same IEEE operations in
// the same order, no fused multiply-add, so the same bits (RegionGrowing.PairedFitsAreTheSingleFits).
// 2^b as a float (b + bias in the exponent field).
[[gnu::target("avx2")]] inline __m256 Pow2(__m256i b, __m256i bias) {
  return _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(b, bias), 23));
}
[[gnu::target("avx2")]] inline void ExpNegAvx2(const float* d2, float* out, int n) {
  const int whole = n & ~3;
  const __m256 one = _mm256_set1_ps(1.0f), half = _mm256_set1_ps(0.5f);
  const __m256 hi = _mm256_set1_ps(88.723f), lo = _mm256_set1_ps(-88.723f);
  const __m256 log2e = _mm256_set1_ps(1.44269504088896341f);
  const __m256 p0 = _mm256_set1_ps(1.9875691500E-4f), p1 = _mm256_set1_ps(1.3981999507E-3f),
               p2 = _mm256_set1_ps(8.3334519073E-3f), p3 = _mm256_set1_ps(4.1665795894E-2f),
               p4 = _mm256_set1_ps(1.6666665459E-1f), p5 = _mm256_set1_ps(5.0000001201E-1f);
  const __m256 c1 = _mm256_set1_ps(-0.693359375f), c2 = _mm256_set1_ps(2.12194440e-4f);
  const __m256 max_e = _mm256_set1_ps(278.f), min_e = _mm256_set1_ps(-278.f);
  const __m256i bias = _mm256_set1_epi32(127);
  const __m256 sign = _mm256_set1_ps(-0.0f);
  for (int i = 0; i < whole; i += 8) {
    const int left = whole - i;  // 4 or a multiple of 8 at least 8
    const __m256i mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(left), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    const __m256 xin = _mm256_xor_ps(left >= 8 ? _mm256_loadu_ps(d2 + i) : _mm256_maskload_ps(d2 + i, mask), sign);
    // pmax(pmin(x, hi), lo): Eigen's SSE pmin(a, b) / pmax(a, b) are minps / maxps (b, a).
    const __m256 x = _mm256_max_ps(lo, _mm256_min_ps(hi, xin));
    // m = floor(x log2(e) + 0.5); Eigen's SSE2 pfloor is exact, as floor is.
    const __m256 m = _mm256_floor_ps(_mm256_add_ps(_mm256_mul_ps(x, log2e), half));
    __m256 r = _mm256_add_ps(_mm256_mul_ps(m, c1), x);
    r = _mm256_add_ps(_mm256_mul_ps(m, c2), r);
    const __m256 r2 = _mm256_mul_ps(r, r), r3 = _mm256_mul_ps(r2, r);
    __m256 y = _mm256_add_ps(_mm256_mul_ps(p0, r), p1);
    __m256 y1 = _mm256_add_ps(_mm256_mul_ps(p3, r), p4);
    const __m256 y2 = _mm256_add_ps(r, one);
    y = _mm256_add_ps(_mm256_mul_ps(y, r), p2);
    y1 = _mm256_add_ps(_mm256_mul_ps(y1, r), p5);
    y = _mm256_add_ps(_mm256_mul_ps(y, r3), y1);
    y = _mm256_add_ps(_mm256_mul_ps(y, r2), y2);
    // pldexp_generic(y, m): e = clamp(m, -278, 278), b = e >> 2, y 2^b 2^b 2^b 2^(e - 3b).
    const __m256i e = _mm256_cvttps_epi32(_mm256_min_ps(max_e, _mm256_max_ps(min_e, m)));
    const __m256i b = _mm256_srai_epi32(e, 2);
    const __m256 c = Pow2(b, bias);
    __m256 res = _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(y, c), c), c);
    res = _mm256_mul_ps(res, Pow2(_mm256_sub_epi32(_mm256_sub_epi32(_mm256_sub_epi32(e, b), b), b), bias));
    res = _mm256_max_ps(xin, res);  // pmax(ldexp, _x)
    if (left >= 8)
      _mm256_storeu_ps(out + i, res);
    else
      _mm256_maskstore_ps(out + i, mask, res);
  }
  for (int i = whole; i < n; ++i) out[i] = std::exp(-d2[i]);
}
#endif

// From the raw sums: the PCA frame and curvature (fit.N, curvature), and, when the height
// function is to be fitted (true), its frame (fit.U, V, o; `pf`) and the Gaussian weights of
// the neighbours in nb.scratch (padding: 0).
template <bool kCentroids>
bool FitFrame(bool avx2, Neighbours& nb, int k4, const RawSums& s, int min_fit, LocalFit& fit, float& curvature,
              PolyFrame& pf) {
  const int k = nb.size();
  // Raw moments scaled to |d| < 1 so float sums lose nothing that matters before the centring
  // in double.
  const double inv_m = 1.0 / (kCentroids ? double(Sum4(s.m)) : double(k));
  const Eigen::Vector3d mean = Eigen::Vector3d(Sum4(s.x), Sum4(s.y), Sum4(s.z)) * inv_m;
  Eigen::Matrix3d cov;
  cov << Sum4(s.xx), Sum4(s.xy), Sum4(s.xz), 0, Sum4(s.yy), Sum4(s.yz), 0, 0, Sum4(s.zz);
  cov *= inv_m;
  cov -= mean * mean.transpose();
  cov(1, 0) = cov(0, 1), cov(2, 0) = cov(0, 2), cov(2, 1) = cov(1, 2);
  // Closed-form 3x3 solver in float: the scaled covariance is O(1); double costs 10 % of the
  // normals and changed none of 300k normals of a noisy room by more than 0.05 deg but one
  // (a degenerate neighbourhood).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> es;
  es.computeDirect(cov.cast<float>());
  const Eigen::Vector3d lambda = es.eigenvalues().cast<double>().cwiseMax(0.0);  // ascending
  const double sum = lambda.sum();
  curvature = sum > 0 ? float(lambda[0] / sum) : 0.f;
  const Eigen::Vector3f N = es.eigenvectors().col(0).cast<float>().normalized();
  fit.N = N;
  if (k < min_fit || !(lambda[1] > 1e-4 * lambda[2])) return false;
  const Eigen::Vector3f U = es.eigenvectors().col(2).cast<float>().normalized();
  const Eigen::Vector3f V = N.cross(U);
  // Origin: the query (offset 0) projected on the plane through the mean.
  const Eigen::Vector3f o = mean.cast<float>().dot(N) * N;
  // Gaussian weights in one vectorised pass (Eigen's packet exp, or the same in AVX2 lanes).
  nb.scratch.resize(size_t(k4));
  Eigen::Map<Eigen::ArrayXf> weight(nb.scratch.data(), k);
  using Arr = Eigen::Map<const Eigen::ArrayXf>;
#if defined(__x86_64__) || defined(__i386__)
  if (avx2 && (reinterpret_cast<uintptr_t>(nb.scratch.data()) & 15) == 0)
    ExpNegAvx2(nb.d2.data(), nb.scratch.data(), k);
  else
    weight = (-Arr(nb.d2.data(), k)).exp();
#else
  weight = (-Arr(nb.d2.data(), k)).exp();
#endif
  if constexpr (kCentroids) weight *= Arr(nb.mult.data(), k);
  for (int i = k; i < k4; ++i) nb.scratch[i] = 0.f;
  pf = {Splat4(o.x()), Splat4(o.y()), Splat4(o.z()), Splat4(U.x()), Splat4(U.y()), Splat4(U.z()),
        Splat4(V.x()), Splat4(V.y()), Splat4(V.z()), Splat4(N.x()), Splat4(N.y()), Splat4(N.z())};
  // Kept aside until FitFinish: NormalAt reads them only when `poly`.
  fit.U = U, fit.V = V, fit.o = o;
  return true;
}

// Normal equations A c = y of the 6 coefficients: A(r, c) = sum w b_r b_c, y(r) = sum w h b_r
// with b = (1, u, v, uv, u^2, v^2). The lanes are added in a fixed order, so the sums do not
// depend on the thread or the vector width.
inline void FitEquations(const PolySums& s, NormalEquations& eq) {
  const double M00 = Sum4(s.m00), M10 = Sum4(s.m10), M01 = Sum4(s.m01), M20 = Sum4(s.m20), M11 = Sum4(s.m11),
               M02 = Sum4(s.m02), M30 = Sum4(s.m30), M21 = Sum4(s.m21), M12 = Sum4(s.m12), M03 = Sum4(s.m03),
               M40 = Sum4(s.m40), M31 = Sum4(s.m31), M22 = Sum4(s.m22), M13 = Sum4(s.m13), M04 = Sum4(s.m04);
  // Rows and columns: 1, u, v, uv, u^2, v^2; the upper triangle (all the solves read).
  double(*A)[6] = eq.A;
  A[0][0] = M00, A[0][1] = M10, A[0][2] = M01, A[0][3] = M11, A[0][4] = M20, A[0][5] = M02;
  A[1][1] = M20, A[1][2] = M11, A[1][3] = M21, A[1][4] = M30, A[1][5] = M12;
  A[2][2] = M02, A[2][3] = M12, A[2][4] = M21, A[2][5] = M03;
  A[3][3] = M22, A[3][4] = M31, A[3][5] = M13;
  A[4][4] = M40, A[4][5] = M22;
  A[5][5] = M04;
  double* y = eq.y;
  y[0] = Sum4(s.h00), y[1] = Sum4(s.h10), y[2] = Sum4(s.h01), y[3] = Sum4(s.h11), y[4] = Sum4(s.h20), y[5] = Sum4(s.h02);
}

// The first half of one fit: false when nothing is left to solve (fewer than 3 neighbours, too
// few for the height function, or no 2-D extent: `fit` is final).
// Sums in 4 lanes (GCC/Clang vector types: SSE2 on any x86-64, NEON on arm64), lane l taking
// neighbours l, l + 4, ...; padding neighbours weigh 0.
template <bool kCentroids>
bool FitSystem(bool avx2, Neighbours& nb, int min_fit, LocalFit& fit, float& curvature, NormalEquations& eq) {
  fit = LocalFit();
  if (nb.size() < 3) {
    curvature = kNaN;
    return false;
  }
  fit.valid = true;
  const int k4 = PadNeighbours(nb);
  RawSums rs;
  AddRawSums<kCentroids>(nb, 0, k4, rs);
  PolyFrame pf;
  if (!FitFrame<kCentroids>(avx2, nb, k4, rs, min_fit, fit, curvature, pf)) return false;
  PolySums ps;
  AddPolySums(nb, 0, k4, pf, ps);
  FitEquations(ps, eq);
  return true;
}

#if defined(__x86_64__) || defined(__i386__)
// Two exact fits at once: the neighbourhoods' groups of 4 side by side in the two halves of
// AVX2 vectors (a's in the low half, b's in the high) up to the shorter one's end, each half
// the 4-lane sums of AddRawSums / AddPolySums with the same IEEE operations in the same order
// (compiled for "avx2" alone: no fused multiply-add to contract into), then the longer one's
// remaining groups by the 4-lane loops. So each point's equations are FitSystem<false>'s bit
// for bit (RegionGrowing.PairedFitsAreTheSingleFits), with about half the loop iterations.
[[gnu::target("avx2")]] inline __m256 Load44(const float* a, const float* b) {
  return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(a)), _mm_loadu_ps(b), 1);
}
[[gnu::target("avx2")]] inline __m256 Join(F4 a, F4 b) {
  return _mm256_insertf128_ps(_mm256_castps128_ps256((__m128)a), (__m128)b, 1);
}
[[gnu::target("avx2")]] inline void Split(__m256 v, F4& a, F4& b) {
  a = (F4)_mm256_castps256_ps128(v);
  b = (F4)_mm256_extractf128_ps(v, 1);
}
[[gnu::target("avx2")]] inline __m256 add(__m256 p, __m256 q) { return _mm256_add_ps(p, q); }
[[gnu::target("avx2")]] inline __m256 mul(__m256 p, __m256 q) { return _mm256_mul_ps(p, q); }
[[gnu::target("avx2")]] inline void RawSumsPair(const Neighbours& a, const Neighbours& b, int groups_end, RawSums& sa,
                                         RawSums& sb) {
  __m256 x_ = _mm256_setzero_ps(), y_ = x_, z_ = x_, xx = x_, xy = x_, xz = x_, yy = x_, yz = x_, zz = x_;
  for (int i = 0; i < groups_end; i += 4) {
    const __m256 x = Load44(&a.x[i], &b.x[i]), y = Load44(&a.y[i], &b.y[i]), z = Load44(&a.z[i], &b.z[i]);
    x_ = _mm256_add_ps(x_, x), y_ = _mm256_add_ps(y_, y), z_ = _mm256_add_ps(z_, z);
    xx = _mm256_add_ps(xx, _mm256_mul_ps(x, x)), xy = _mm256_add_ps(xy, _mm256_mul_ps(x, y));
    xz = _mm256_add_ps(xz, _mm256_mul_ps(x, z)), yy = _mm256_add_ps(yy, _mm256_mul_ps(y, y));
    yz = _mm256_add_ps(yz, _mm256_mul_ps(y, z)), zz = _mm256_add_ps(zz, _mm256_mul_ps(z, z));
  }
  Split(x_, sa.x, sb.x), Split(y_, sa.y, sb.y), Split(z_, sa.z, sb.z), Split(xx, sa.xx, sb.xx);
  Split(xy, sa.xy, sb.xy), Split(xz, sa.xz, sb.xz), Split(yy, sa.yy, sb.yy), Split(yz, sa.yz, sb.yz);
  Split(zz, sa.zz, sb.zz);
}
[[gnu::target("avx2")]] inline void PolySumsPair(const Neighbours& a, const PolyFrame& fa, const Neighbours& b,
                                          const PolyFrame& fb, int groups_end, PolySums& sa, PolySums& sb) {
  const __m256 ox = Join(fa.ox, fb.ox), oy = Join(fa.oy, fb.oy), oz = Join(fa.oz, fb.oz);
  const __m256 Ux = Join(fa.Ux, fb.Ux), Uy = Join(fa.Uy, fb.Uy), Uz = Join(fa.Uz, fb.Uz);
  const __m256 Vx = Join(fa.Vx, fb.Vx), Vy = Join(fa.Vy, fb.Vy), Vz = Join(fa.Vz, fb.Vz);
  const __m256 Nx = Join(fa.Nx, fb.Nx), Ny = Join(fa.Ny, fb.Ny), Nz = Join(fa.Nz, fb.Nz);
  __m256 m00 = _mm256_setzero_ps(), m10 = m00, m01 = m00, m20 = m00, m11 = m00, m02 = m00, m30 = m00, m21 = m00,
         m12 = m00, m03 = m00, m40 = m00, m31 = m00, m22 = m00, m13 = m00, m04 = m00;
  __m256 h00 = m00, h10 = m00, h01 = m00, h11 = m00, h20 = m00, h02 = m00;
  for (int i = 0; i < groups_end; i += 4) {
    const __m256 ex = _mm256_sub_ps(Load44(&a.x[i], &b.x[i]), ox), ey = _mm256_sub_ps(Load44(&a.y[i], &b.y[i]), oy),
                 ez = _mm256_sub_ps(Load44(&a.z[i], &b.z[i]), oz);
    const __m256 u = add(add(mul(ex, Ux), mul(ey, Uy)), mul(ez, Uz));
    const __m256 v = add(add(mul(ex, Vx), mul(ey, Vy)), mul(ez, Vz));
    const __m256 h = add(add(mul(ex, Nx), mul(ey, Ny)), mul(ez, Nz));
    const __m256 w = Load44(&a.scratch[i], &b.scratch[i]);
    const __m256 wu = mul(w, u), wv = mul(w, v), wuu = mul(wu, u), wuv = mul(wu, v), wvv = mul(wv, v);
    const __m256 wuuu = mul(wuu, u), wuuv = mul(wuu, v), wuvv = mul(wuv, v), wvvv = mul(wvv, v);
    m00 = add(m00, w), m10 = add(m10, wu), m01 = add(m01, wv), m20 = add(m20, wuu), m11 = add(m11, wuv);
    m02 = add(m02, wvv), m30 = add(m30, wuuu), m21 = add(m21, wuuv), m12 = add(m12, wuvv), m03 = add(m03, wvvv);
    m40 = add(m40, mul(wuuu, u)), m31 = add(m31, mul(wuuu, v)), m22 = add(m22, mul(wuuv, v));
    m13 = add(m13, mul(wuvv, v)), m04 = add(m04, mul(wvvv, v));
    h00 = add(h00, mul(w, h)), h10 = add(h10, mul(wu, h)), h01 = add(h01, mul(wv, h));
    h11 = add(h11, mul(wuv, h)), h20 = add(h20, mul(wuu, h)), h02 = add(h02, mul(wvv, h));
  }
  Split(m00, sa.m00, sb.m00), Split(m10, sa.m10, sb.m10), Split(m01, sa.m01, sb.m01), Split(m20, sa.m20, sb.m20);
  Split(m11, sa.m11, sb.m11), Split(m02, sa.m02, sb.m02), Split(m30, sa.m30, sb.m30), Split(m21, sa.m21, sb.m21);
  Split(m12, sa.m12, sb.m12), Split(m03, sa.m03, sb.m03), Split(m40, sa.m40, sb.m40), Split(m31, sa.m31, sb.m31);
  Split(m22, sa.m22, sb.m22), Split(m13, sa.m13, sb.m13), Split(m04, sa.m04, sb.m04);
  Split(h00, sa.h00, sb.h00), Split(h10, sa.h10, sb.h10), Split(h01, sa.h01, sb.h01), Split(h11, sa.h11, sb.h11);
  Split(h20, sa.h20, sb.h20), Split(h02, sa.h02, sb.h02);
}
#endif

// FitSystem<false> of two neighbourhoods: has[l] is its answer for nb[l], fit[l], curvature[l]
// and eq[l] its outputs. With avx2, the sums of both run side by side (RawSumsPair,
// PolySumsPair); the results are FitSystem's bit for bit either way.
inline void FitSystemPair(bool avx2, Neighbours* nb[2], int min_fit, LocalFit fit[2], float curvature[2], NormalEquations eq[2],
                   bool has[2]) {
#if defined(__x86_64__) || defined(__i386__)
  if (avx2 && nb[0]->size() >= 3 && nb[1]->size() >= 3) {
    int k4[2];
    RawSums rs[2];
    for (int l = 0; l < 2; ++l) fit[l] = LocalFit(), fit[l].valid = true, k4[l] = PadNeighbours(*nb[l]);
    const int common = std::min(k4[0], k4[1]), longer = k4[0] >= k4[1] ? 0 : 1;
    RawSumsPair(*nb[0], *nb[1], common, rs[0], rs[1]);
    AddRawSums<false>(*nb[longer], common, k4[longer], rs[longer]);
    PolyFrame pf[2];
    for (int l = 0; l < 2; ++l)
      has[l] = FitFrame<false>(true, *nb[l], k4[l], rs[l], min_fit, fit[l], curvature[l], pf[l]);
    PolySums ps[2];
    if (has[0] && has[1]) {
      PolySumsPair(*nb[0], pf[0], *nb[1], pf[1], common, ps[0], ps[1]);
      AddPolySums(*nb[longer], common, k4[longer], pf[longer], ps[longer]);
    } else {
      for (int l = 0; l < 2; ++l)
        if (has[l]) AddPolySums(*nb[l], 0, k4[l], pf[l], ps[l]);
    }
    for (int l = 0; l < 2; ++l)
      if (has[l]) FitEquations(ps[l], eq[l]);
    return;
  }
#else
  (void)avx2;
#endif
  for (int l = 0; l < 2; ++l) has[l] = FitSystem<false>(avx2, *nb[l], min_fit, fit[l], curvature[l], eq[l]);
}

// The second half: `solved` and the coefficients c of FitSystem's equations.
inline void FitFinish(bool solved, const double c[6], LocalFit& fit) {
  if (!solved || !std::isfinite(c[1]) || !std::isfinite(c[2])) {
    fit.U = fit.V = fit.o = Eigen::Vector3f::Zero();
    return;
  }
  for (int i = 0; i < 6; ++i) fit.c[i] = float(c[i]);
  if (!std::isfinite(fit.c[3]) || !std::isfinite(fit.c[4]) || !std::isfinite(fit.c[5])) fit.c[3] = fit.c[4] = fit.c[5] = 0.f;
  fit.poly = true;
}

template <bool kCentroids>
void FitPoint(bool avx2, Neighbours& nb, int min_fit, LocalFit& fit, float& curvature) {
  NormalEquations eq;
  if (!FitSystem<kCentroids>(avx2, nb, min_fit, fit, curvature, eq)) return;
  double c[6];
  const bool solved = SolveSpd6(eq.A, eq.y, c);
  FitFinish(solved, c, fit);
}

// The normal of a fit at a point of offset d (scaled by 1/r) from its query: the fitted surface's
// at the point's (u, v); at the query itself (d = 0) N - c1 U - c2 V, as a fit of that point alone.
inline Eigen::Vector3f NormalAt(const LocalFit& f, const Eigen::Vector3f& d) {
  if (!f.valid) return Eigen::Vector3f::Constant(kNaN);
  if (!f.poly) return f.N;
  if (d.isZero(0.f)) return (f.N - f.c[1] * f.U - f.c[2] * f.V).normalized();
  const Eigen::Vector3f e = d - f.o;
  const float u = e.dot(f.U), v = e.dot(f.V);
  const float hu = f.c[1] + f.c[3] * v + 2.f * f.c[4] * u, hv = f.c[2] + f.c[3] * u + 2.f * f.c[5] * v;
  return (f.N - hu * f.U - hv * f.V).normalized();
}

}  // namespace furnihost::rg::detail
