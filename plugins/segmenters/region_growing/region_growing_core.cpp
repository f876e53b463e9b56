#include "region_growing_core.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Eigenvalues>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <numeric>
#include <tuple>
#include <type_traits>

#include "furnihost/log.hpp"
#include "furnihost/voxel_index.hpp"
#include "parallel/tbb_for.hpp"
#include "simd/left_pack.hpp"

namespace furnihost::rg {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
// Cells with more points than this are checked for copies of one point (NormalsLocal).
constexpr size_t kCopiesCheckedFrom = 32;
// Dense cells fit voxel centroids, voxel edge = normal radius / this: ~50 centroids in a planar
// ball (pi 4^2), ~2.5x fewer than the fewest points a dense cell's ball holds on average. The
// points of one such voxel share one fit.
constexpr int kCentroidVoxelsPerRadius = 4;

// The finite points of a scan shifted by the centre of their bounding box, computed in double:
// float coordinates of a scan in map coordinates (1e5 m) would leave ~8 mm of resolution for
// the squares accumulated below. Every later step works in this frame.
struct LocalCloud {
  Points pts;                 // finite points, local frame
  std::vector<int> input;     // input index of each local point
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
};

LocalCloud ToLocal(const Points& points) {
  LocalCloud lc;
  Eigen::AlignedBox3d box;
  for (const auto& p : points)
    if (p.allFinite()) box.extend(p.cast<double>());
  if (box.isEmpty()) return lc;
  lc.centre = box.center();
  lc.pts.reserve(points.size());
  lc.input.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i)
    if (points[i].allFinite()) {
      lc.pts.push_back((points[i].cast<double>() - lc.centre).cast<float>());
      lc.input.push_back(int(i));
    }
  return lc;
}

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

}  // namespace

namespace detail {

// Solves the symmetric positive definite 6x6 system A c = y (upper triangle of A given) by
// Cholesky. False when a pivot is not clearly positive (a degenerate neighbourhood).
bool SolveSpd6(const double A[6][6], const double y[6], double c[6]) {
  double L[6][6], inv[6];  // L lower triangular, inv[j] = 1 / L[j][j]
  const double scale = std::max({A[0][0], A[1][1], A[2][2], A[3][3], A[4][4], A[5][5]});
  for (int j = 0; j < 6; ++j) {
    double d = A[j][j];
    for (int k = 0; k < j; ++k) d -= L[j][k] * L[j][k];
    if (!(d > 1e-10 * scale)) return false;
    inv[j] = 1.0 / std::sqrt(d);
    for (int i = j + 1; i < 6; ++i) {
      double v = A[j][i];
      for (int k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
      L[i][j] = v * inv[j];
    }
  }
  double t[6];
  for (int i = 0; i < 6; ++i) {
    double v = y[i];
    for (int k = 0; k < i; ++k) v -= L[i][k] * t[k];
    t[i] = v * inv[i];
  }
  for (int i = 5; i >= 0; --i) {
    double v = t[i];
    for (int k = i + 1; k < 6; ++k) v -= L[k][i] * c[k];
    c[i] = v * inv[i];
  }
  return true;
}

// Two systems at once, system l in lane l: SolveSpd6's operations lane by lane. IEEE addition,
// multiplication, division and square root are correctly rounded, so each lane's c is
// SolveSpd6's bit for bit (RegionGrowing.PairedSolvesAreTheSingleSolves); the two dependency
// chains run side by side (one solve is a chain of 6 square roots and divisions: latency, not
// work). ok[l]: SolveSpd6's answer for system l; a failed lane runs on with NaNs and its c is
// not to be read.
void SolveSpd6Pair(const double (*A0)[6], const double* y0, const double (*A1)[6], const double* y1, double c0[6],
                   double c1[6], bool ok[2]) {
  D2 L[6][6], inv[6];
  const double s0 = std::max({A0[0][0], A0[1][1], A0[2][2], A0[3][3], A0[4][4], A0[5][5]});
  const double s1 = std::max({A1[0][0], A1[1][1], A1[2][2], A1[3][3], A1[4][4], A1[5][5]});
  const double lim0 = 1e-10 * s0, lim1 = 1e-10 * s1;
  ok[0] = ok[1] = true;
  for (int j = 0; j < 6; ++j) {
    D2 d = D2{A0[j][j], A1[j][j]};
    for (int k = 0; k < j; ++k) d -= L[j][k] * L[j][k];
    ok[0] = ok[0] && d[0] > lim0;
    ok[1] = ok[1] && d[1] > lim1;
    inv[j] = D2{1.0, 1.0} / Sqrt2(d);
    for (int i = j + 1; i < 6; ++i) {
      D2 v = D2{A0[j][i], A1[j][i]};
      for (int k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
      L[i][j] = v * inv[j];
    }
  }
  D2 t[6], c[6];
  for (int i = 0; i < 6; ++i) {
    D2 v = D2{y0[i], y1[i]};
    for (int k = 0; k < i; ++k) v -= L[i][k] * t[k];
    t[i] = v * inv[i];
  }
  for (int i = 5; i >= 0; --i) {
    D2 v = t[i];
    for (int k = i + 1; k < 6; ++k) v -= L[k][i] * c[k];
    c[i] = v * inv[i];
  }
  for (int i = 0; i < 6; ++i) c0[i] = c[i][0], c1[i] = c[i][1];
}

}  // namespace detail

namespace {

using detail::SolveSpd6;
using detail::SolveSpd6Pair;

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
void AddPolySums(const Neighbours& nb, int from, int k4, const PolyFrame& f, PolySums& s) {
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
int PadNeighbours(Neighbours& nb) {
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
[[gnu::target("avx2")]] void ExpNegAvx2(const float* d2, float* out, int n) {
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
void FitEquations(const PolySums& s, NormalEquations& eq) {
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
[[gnu::target("avx2")]] void RawSumsPair(const Neighbours& a, const Neighbours& b, int groups_end, RawSums& sa,
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
[[gnu::target("avx2")]] void PolySumsPair(const Neighbours& a, const PolyFrame& fa, const Neighbours& b,
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
void FitSystemPair(bool avx2, Neighbours* nb[2], int min_fit, LocalFit fit[2], float curvature[2], NormalEquations eq[2],
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
void FitFinish(bool solved, const double c[6], LocalFit& fit) {
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
Eigen::Vector3f NormalAt(const LocalFit& f, const Eigen::Vector3f& d) {
  if (!f.valid) return Eigen::Vector3f::Constant(kNaN);
  if (!f.poly) return f.N;
  if (d.isZero(0.f)) return (f.N - f.c[1] * f.U - f.c[2] * f.V).normalized();
  const Eigen::Vector3f e = d - f.o;
  const float u = e.dot(f.U), v = e.dot(f.V);
  const float hu = f.c[1] + f.c[3] * v + 2.f * f.c[4] * u, hv = f.c[2] + f.c[3] * u + 2.f * f.c[5] * v;
  return (f.N - hu * f.U - hv * f.V).normalized();
}

// The centroids of the voxels of edge grid.cell / q inside cell c of `grid` (voxels aligned
// with the cell: the grid is anchored at the points' minimum corner `lo`), one per non-empty
// voxel, in voxel order, with its number of points as w. A centroid lies inside its cell, so the centroids within the radius
// of any point of a cell are among those of the cell's 27 neighbour cells.
struct CentroidScratch {
  std::vector<int> count;
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> used;
};
void CellCentroids(const VoxelIndex& grid, int c, const Eigen::Vector3f& lo, int q, CentroidScratch& w,
                   std::vector<Eigen::Vector4f>& out) {
  const int q3 = q * q * q;
  if (int(w.count.size()) < q3) w.count.assign(size_t(q3), 0), w.sum.assign(size_t(q3), Eigen::Vector3d::Zero());
  w.used.clear();
  const Eigen::Vector3i cc = grid.CellCoords(c);
  const float inv_v = float(q) / grid.cell;
  auto sub = [&](float p, float l, int a) { return std::clamp(int((p - l) * inv_v) - q * cc[a], 0, q - 1); };
  for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
    const int key = sub(grid.x[s], lo.x(), 0) + q * (sub(grid.y[s], lo.y(), 1) + q * sub(grid.z[s], lo.z(), 2));
    if (w.count[key]++ == 0) w.used.push_back(key);
    w.sum[key] += Eigen::Vector3d(grid.x[s], grid.y[s], grid.z[s]);
  }
  std::sort(w.used.begin(), w.used.end());
  out.clear();
  for (int key : w.used) {
    const Eigen::Vector3f centroid = (w.sum[key] / double(w.count[key])).cast<float>();
    out.emplace_back(centroid.x(), centroid.y(), centroid.z(), float(w.count[key]));
    w.count[key] = 0;
    w.sum[key].setZero();
  }
}

// Boxes as 6 floats (min x y z, max x y z): empty, grown by a point, and the squared gap
// between two (0 where they touch or overlap).
inline void EmptyBox(float* b) {
  b[0] = b[1] = b[2] = std::numeric_limits<float>::infinity();
  b[3] = b[4] = b[5] = -std::numeric_limits<float>::infinity();
}
inline void ExtendBox(float* b, float x, float y, float z) {
  b[0] = std::min(b[0], x), b[1] = std::min(b[1], y), b[2] = std::min(b[2], z);
  b[3] = std::max(b[3], x), b[4] = std::max(b[4], y), b[5] = std::max(b[5], z);
}
inline float BoxGap2(const float* a, const float* b) {
  const float dx = std::max(std::max(a[0] - b[3], b[0] - a[3]), 0.f);
  const float dy = std::max(std::max(a[1] - b[4], b[1] - a[4]), 0.f);
  const float dz = std::max(std::max(a[2] - b[5], b[2] - a[5]), 0.f);
  return dx * dx + dy * dy + dz * dz;
}

// The tight box of each cell's points, 6 floats per cell (min x y z, max x y z).
std::vector<float> CellBoxes(const VoxelIndex& grid) {
  const int cells = grid.NumCells();
  std::vector<float> box(size_t(cells) * 6);
  tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
    for (int c = range.begin(); c != range.end(); ++c) {
      float* b = &box[size_t(c) * 6];
      EmptyBox(b);
      for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) ExtendBox(b, grid.x[s], grid.y[s], grid.z[s]);
    }
  });
  return box;
}

// True when cell c's tight box lies at squared distance >= d2 from p: none of its points is
// closer (in float too: per axis the box's gap is never above a point's, and rounding is
// monotonic).
// Called per point and neighbour cell in the normals and per member and neighbour cell in the
// growth: forced inline, branch-free (std::max over an initializer list stayed an out-of-line
// call, 2 % of a dense room's samples).
[[gnu::always_inline]] inline bool Far(const std::vector<float>& box, int c, const Eigen::Vector3f& p, float d2) {
  const float* b = &box[size_t(c) * 6];
  const float dx = std::max(std::max(b[0] - p.x(), 0.f), p.x() - b[3]);
  const float dy = std::max(std::max(b[1] - p.y(), 0.f), p.y() - b[4]);
  const float dz = std::max(std::max(b[2] - p.z(), 0.f), p.z() - b[5]);
  return dx * dx + dy * dy + dz * dz >= d2;
}

// Normals of `lc` (by local index) with the grid of cell = radius. Per cell, the candidates of
// its 27 neighbour cells are copied once into a contiguous buffer that every point of the cell
// then scans (a tight, vectorisable loop). Cells whose neighbourhood is dense (see
// RegionGrowingOptions::max_normal_points) scan the voxel centroids of those cells instead.
void NormalsLocal(const LocalCloud& lc, const Eigen::Vector3f& view_local, const RegionGrowingOptions& o,
                  Points& normals, std::vector<float>& curvature) {
  const size_t n = lc.pts.size();
  normals.assign(n, Eigen::Vector3f::Constant(kNaN));
  curvature.assign(n, kNaN);
  if (n == 0) return;
  const float r = float(o.normal_radius_m);
  const float inv_r = 1.f / r;
  VoxelIndex grid;
  grid.Build(lc.pts, r, VoxelIndex::Anchor::kBoundingBox, TbbFor());
  const int cells = grid.NumCells();

  // Dense cells and the voxel centroids of every cell next to one.
  const int K = o.max_normal_points;
  const int q = kCentroidVoxelsPerRadius;
  const Eigen::Vector3f lo = grid.Origin();
  std::vector<char> dense(size_t(cells), 0);
  std::vector<std::vector<Eigen::Vector4f>> centroids;
  if (K > 0) {
    const int64_t dense_above = 4 * int64_t(K);
    tbb::parallel_for(tbb::blocked_range<int>(0, cells, 256), [&](const tbb::blocked_range<int>& range) {
      for (int c = range.begin(); c != range.end(); ++c) {
        int64_t m = 0;
        for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k)
          m += grid.cell_start[grid.nb[k] + 1] - grid.cell_start[grid.nb[k]];
        dense[c] = m > dense_above;
      }
    });
    size_t dense_points = 0;
    for (int c = 0; c < cells; ++c)
      if (dense[c]) dense_points += size_t(grid.cell_start[c + 1] - grid.cell_start[c]);
    if (dense_points > 0)
      spdlog::debug("region_growing: {} of {} points in cells denser than {} points per 3x3x3 cells: normals from "
                    "voxel centroids (voxel {:.4f} m)",
                    dense_points, n, dense_above, r / float(q));
    if (dense_points > 0) {
      centroids.resize(size_t(cells));
      tbb::parallel_for(tbb::blocked_range<int>(0, cells, 64), [&](const tbb::blocked_range<int>& range) {
        CentroidScratch w;
        for (int c = range.begin(); c != range.end(); ++c) {
          bool near_dense = false;  // the neighbour relation is symmetric
          for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1] && !near_dense; ++k) near_dense = dense[grid.nb[k]];
          if (near_dense) CellCentroids(grid, c, lo, q, w, centroids[c]);
        }
      });
    }
  }

  const std::vector<float> cell_box = CellBoxes(grid);
  const float r2 = r * r;
  const bool avx2 = simd::UseAvx2();
  tbb::parallel_for(tbb::blocked_range<int>(0, cells, 16), [&](const tbb::blocked_range<int>& range) {
    Neighbours nb;
    std::vector<float> cx, cy, cz, cw;
    std::vector<int> slots, key, start, members, pending, run_first, run_last, run_b, run_e;
    std::vector<float> run_box;  // tight box of each run's points (6 floats)
    std::vector<Eigen::Vector3f> query;
    // Neighbours of p among the m candidates (cx, cy, cz) into nb, scaled by 1/r; with
    // kCentroids also their point counts cw.
    auto collect = [&](auto centroids_tag, const Eigen::Vector3f& p) {
      constexpr bool kCentroids = decltype(centroids_tag)::value;
      const float px = p.x(), py = p.y(), pz = p.z();
      const int m = int(cx.size());
      // Branch-free compaction: every candidate is written, only hits advance the cursor.
      nb.reserve(m);
      int cnt = 0;
      float *nx = nb.x.data(), *ny = nb.y.data(), *nz = nb.z.data(), *nd = nb.d2.data(), *nm = nb.mult.data();
      for (int j = 0; j < m; ++j) {
        const float dx = (cx[j] - px) * inv_r, dy = (cy[j] - py) * inv_r, dz = (cz[j] - pz) * inv_r;
        const float d2 = dx * dx + dy * dy + dz * dz;
        nx[cnt] = dx, ny[cnt] = dy, nz[cnt] = dz, nd[cnt] = d2;
        if constexpr (kCentroids) nm[cnt] = cw[j];
        cnt += d2 < 1.f;
      }
      nb.count = cnt;
    };
    // Fits the neighbourhood in nb around query point qp and gives the slots [first, last) of
    // `list` the normal of that surface at their own positions (NormalAt; a slot at qp itself
    // gets the fit's normal at the query, as before voxels were shared).
    auto fit = [&](auto centroids_tag, const Eigen::Vector3f& qp, const int* first, const int* last) {
      LocalFit f;
      float curv;
      FitPoint<decltype(centroids_tag)::value>(avx2, nb, o.min_fit_points, f, curv);
      for (const int* it = first; it != last; ++it) {
        const int s = *it;
        const Eigen::Vector3f p(grid.x[s], grid.y[s], grid.z[s]);
        Eigen::Vector3f nrm = NormalAt(f, (p - qp) * inv_r);
        if (nrm.dot(view_local - p) < 0) nrm = -nrm;
        const uint32_t i = grid.order[s];
        normals[i] = nrm;
        curvature[i] = curv;
      }
    };
    // Exact fits in pairs: a point's neighbourhood waits (nbs) for the next point's, in this
    // cell or a later one of the range; then both are fitted together (FitSystemPair) and their
    // 6x6 systems solved together (SolveSpd6Pair). The same normals as FitPoint.
    Neighbours nbs[2];
    int queued = 0, queued_slot[2] = {0, 0};
    auto write = [&](const LocalFit& f, float curv, int s) {
      const Eigen::Vector3f p(grid.x[s], grid.y[s], grid.z[s]);
      Eigen::Vector3f nrm = NormalAt(f, Eigen::Vector3f::Zero());  // at the query itself
      if (nrm.dot(view_local - p) < 0) nrm = -nrm;
      const uint32_t i = grid.order[s];
      normals[i] = nrm;
      curvature[i] = curv;
    };
    auto flush = [&] {
      if (queued == 0) return;
      LocalFit f[2];
      float curv[2];
      NormalEquations eq[2];
      bool has[2] = {false, false};
      if (queued == 2) {
        Neighbours* both[2] = {&nbs[0], &nbs[1]};
        FitSystemPair(avx2, both, o.min_fit_points, f, curv, eq, has);
      } else {
        has[0] = FitSystem<false>(avx2, nbs[0], o.min_fit_points, f[0], curv[0], eq[0]);
      }
      if (has[0] && has[1]) {
        double c0[6], c1[6];
        bool ok[2];
        SolveSpd6Pair(eq[0].A, eq[0].y, eq[1].A, eq[1].y, c0, c1, ok);
        FitFinish(ok[0], c0, f[0]);
        FitFinish(ok[1], c1, f[1]);
      } else {
        for (int l = 0; l < queued; ++l)
          if (has[l]) {
            double c[6];
            const bool solved = SolveSpd6(eq[l].A, eq[l].y, c);
            FitFinish(solved, c, f[l]);
          }
      }
      for (int l = 0; l < queued; ++l) write(f[l], curv[l], queued_slot[l]);
      queued = 0;
    };
    // The exact normals of `slots` (points of cell c) from every point of their ball.
    auto exact = [&](int c) {
      // The 27 cells' points are read in place (a copy into one buffer cost more than it
      // saved), as runs of consecutive cells (neighbours along x are stored one after the other,
      // their slots contiguous): up to 9 loops instead of 27, each run with its tight box.
      grid.NeighbourRuns(c, run_first, run_last);
      const size_t runs = run_first.size();
      run_b.resize(runs), run_e.resize(runs), run_box.resize(runs * 6);
      int cands = 0;
      for (size_t k = 0; k < runs; ++k) {
        run_b[k] = grid.cell_start[run_first[k]], run_e[k] = grid.cell_start[run_last[k] + 1];
        cands += run_e[k] - run_b[k];
        float* rb = &run_box[k * 6];
        EmptyBox(rb);
        for (int nc = run_first[k]; nc <= run_last[k]; ++nc) {
          const float* cb = &cell_box[size_t(nc) * 6];
          for (int a = 0; a < 3; ++a) rb[a] = std::min(rb[a], cb[a]), rb[a + 3] = std::max(rb[a + 3], cb[a + 3]);
        }
      }
      // Copies of one point have the same neighbourhood, so one fit serves them all: without
      // this, N identical points (a (0, 0, 0) flood) cost N fits of N neighbours each. Only
      // cells that could hold many copies are sorted; a small cell costs at most its size
      // times its neighbourhood, which the neighbourhood's own points pay for.
      const bool copies = slots.size() > kCopiesCheckedFrom;
      if (copies)
        std::sort(slots.begin(), slots.end(), [&](int a, int b) {
          return std::make_tuple(grid.x[a], grid.y[a], grid.z[a], a) < std::make_tuple(grid.x[b], grid.y[b], grid.z[b], b);
        });
      for (size_t t = 0; t < slots.size(); ++t) {
        const int s = slots[t];
        const Eigen::Vector3f p(grid.x[s], grid.y[s], grid.z[s]);
        if (copies && t > 0) {
          const int prev = slots[t - 1];
          if (grid.x[prev] == p.x() && grid.y[prev] == p.y() && grid.z[prev] == p.z()) {
            flush();  // prev's normal
            normals[grid.order[s]] = normals[grid.order[prev]];
            curvature[grid.order[s]] = curvature[grid.order[prev]];
            continue;
          }
        }
        // The neighbours, skipping the runs whose tight box lies r or farther from p (they
        // hold none: the same neighbours in the same order as scanning all 27 cells).
        Neighbours& nq = nbs[queued];
        nq.reserve(cands);
        int cnt = 0;
        float *nx = nq.x.data(), *ny = nq.y.data(), *nz = nq.z.data(), *nd = nq.d2.data();
        const float *gx = grid.x.data(), *gy = grid.y.data(), *gz = grid.z.data();
        for (size_t k = 0; k < run_b.size(); ++k) {
          if (Far(run_box, int(k), p, r2)) continue;
          cnt = simd::AppendScaledWithin(avx2, gx, gy, gz, run_b[k], run_e[k], p.x(), p.y(), p.z(), inv_r, nx, ny, nz, nd,
                                         cnt);
        }
        nq.count = cnt;
        queued_slot[queued] = s;
        if (++queued == 2) flush();
      }
    };
    for (int c = range.begin(); c != range.end(); ++c) {
      if (!dense[c]) {
        slots.resize(size_t(grid.cell_start[c + 1] - grid.cell_start[c]));
        std::iota(slots.begin(), slots.end(), grid.cell_start[c]);
        exact(c);
        continue;
      }
      // A dense cell: its points by voxel (edge r / q; a counting sort, slot order within a
      // voxel) and each voxel's centroid (summed in slot order in double, as CellCentroids
      // does). The points of a voxel share one fit centred on its centroid, each taking the
      // normal of the fitted surface at its own position, so the fits are bounded by the
      // voxels, not the points: the cost per point stops growing with the density.
      const int b = grid.cell_start[c], e = grid.cell_start[c + 1];
      const Eigen::Vector3i cc = grid.CellCoords(c);
      const float inv_v = float(q) / grid.cell;
      auto sub = [&](float p, float l, int a) { return std::clamp(int((p - l) * inv_v) - q * cc[a], 0, q - 1); };
      const int q3 = q * q * q;
      key.resize(size_t(e - b));
      start.assign(size_t(q3 + 1), 0);
      for (int s = b; s < e; ++s) {
        key[s - b] = sub(grid.x[s], lo.x(), 0) + q * (sub(grid.y[s], lo.y(), 1) + q * sub(grid.z[s], lo.z(), 2));
        ++start[key[s - b] + 1];
      }
      for (int k = 0; k < q3; ++k) start[k + 1] += start[k];
      members.resize(size_t(e - b));
      pending.assign(start.begin(), start.end() - 1);  // write cursor per voxel
      for (int s = b; s < e; ++s) members[pending[key[s - b]]++] = s;
      int nv = 0;  // the non-empty voxels, renumbered
      for (int k = 0; k < q3; ++k)
        if (start[k + 1] > start[k]) start[nv++] = start[k];
      start.resize(size_t(nv) + 1);
      start[nv] = e - b;
      query.resize(size_t(nv));
      for (int v = 0; v < nv; ++v) {
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int t = start[v]; t < start[v + 1]; ++t)
          sum += Eigen::Vector3d(grid.x[members[t]], grid.y[members[t]], grid.z[members[t]]);
        query[size_t(v)] = (sum / double(start[v + 1] - start[v])).cast<float>();
      }
      // Voxel centroids of the 27 cells; a voxel with fewer than 3 of them in its ball (a clump,
      // e.g. copies of one point) is fitted to every point of its ball instead.
      cx.clear(), cy.clear(), cz.clear(), cw.clear();
      for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k)
        for (const auto& p : centroids[grid.nb[k]])
          cx.push_back(p.x()), cy.push_back(p.y()), cz.push_back(p.z()), cw.push_back(p.w());
      pending.clear();
      for (int v = 0; v < nv; ++v) {
        collect(std::true_type(), query[size_t(v)]);
        if (nb.count < 3)
          pending.push_back(v);
        else
          fit(std::true_type(), query[size_t(v)], members.data() + start[v], members.data() + start[v + 1]);
      }
      if (pending.empty()) continue;
      grid.GatherNeighbourhood(c, cx, cy, cz);
      for (int v : pending) {
        collect(std::false_type(), query[size_t(v)]);
        fit(std::false_type(), query[size_t(v)], members.data() + start[v], members.data() + start[v + 1]);
      }
    }
    flush();  // the last point's fit, if it waits for a pair
  });
}

// Whether the growth walks sub-cells: the growth's grid (cells of delta) with each cell split
// into 2 x 2 x 2 cubes of edge delta / 2 (see Segment). Its non-empty sub-cells are numbered
// cell after cell (cell c's are [sub_first[c], sub_first[c + 1])); Segment then gives each a
// contiguous range of its cell's slots and a tight box. Sized by the non-empty sub-cells, not 8
// per cell: a sparse scan has about one point per sub-cell.
// Sparse scans grow point by point, each cell its own sub-cell: sub-cells pay only where they
// hold several points (the 1M-point demo room ~4, 3.7M ~11). Fewer than 2 points per cell
// (the demo room's 5 cm cells) or per non-empty sub-cell (ScanNet's) count as sparse.
// True (grow by sub-cells) with half_of (each slot's sub-cell in its cell) and sub_first's
// counts filled; false leaves both empty.
bool CountSubCells(const VoxelIndex& grid, bool allowed, std::vector<uint8_t>& half_of,
                   std::vector<uint32_t>& sub_first) {
  const size_t n = grid.x.size();
  const int cells = grid.NumCells();
  if (!allowed || n < 2 * size_t(cells)) return false;
  const Eigen::Vector3f lo = grid.Origin();
  const float inv_half = 2.f / grid.cell;
  sub_first.assign(size_t(cells) + 1, 0);
  half_of.resize(n);
  tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
    for (int c = range.begin(); c != range.end(); ++c) {
      const Eigen::Vector3i cc = grid.CellCoords(c);
      auto half = [&](float p, float l, int a) { return std::clamp(int((p - l) * inv_half) - 2 * cc[a], 0, 1); };
      unsigned used = 0;
      for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
        const int h = half(grid.x[s], lo.x(), 0) + 2 * half(grid.y[s], lo.y(), 1) + 4 * half(grid.z[s], lo.z(), 2);
        half_of[s] = uint8_t(h);
        used |= 1u << h;
      }
      sub_first[size_t(c) + 1] = uint32_t(__builtin_popcount(used));
    }
  });
  for (int c = 0; c < cells; ++c) sub_first[size_t(c) + 1] += sub_first[size_t(c)];
  if (n >= 2 * size_t(sub_first[size_t(cells)])) return true;
  half_of.clear();
  sub_first.clear();
  return false;
}

// Every slot's neighbours within sqrt(delta2) in `grid` (itself excluded), by slot: slot s's
// are nb[start[s], start[s + 1]), in neighbour-cell then slot order. Built in chunks of cells
// (contiguous slots) in parallel. Not built (false) when the candidate pairs, each point times
// the points of its 27 cells, exceed max_per_point per point.
struct NeighbourLists {
  std::vector<uint32_t> start, nb;
};
bool BuildNeighbourLists(const VoxelIndex& grid, float delta2, int max_per_point, NeighbourLists& out) {
  const int cells = grid.NumCells();
  const size_t n = grid.x.size();
  if (max_per_point <= 0 || n == 0) return false;
  auto count_of = [&](int c) { return int64_t(grid.cell_start[c + 1] - grid.cell_start[c]); };
  const int64_t pairs = tbb::parallel_reduce(
      tbb::blocked_range<int>(0, cells, 1024), int64_t(0),
      [&](const tbb::blocked_range<int>& range, int64_t acc) {
        for (int c = range.begin(); c != range.end(); ++c) {
          int64_t around = 0;
          for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k) around += count_of(grid.nb[k]);
          acc += count_of(c) * around;
        }
        return acc;
      },
      std::plus<int64_t>());
  if (pairs > int64_t(max_per_point) * int64_t(n)) return false;
  constexpr int kChunk = 512;
  const int chunks = (cells + kChunk - 1) / kChunk;
  std::vector<std::vector<uint32_t>> lists(static_cast<size_t>(chunks));
  out.start.assign(n + 1, 0);
  const bool avx2 = simd::UseAvx2();
  tbb::parallel_for(tbb::blocked_range<int>(0, chunks, 1), [&](const tbb::blocked_range<int>& range) {
    std::vector<int> run_b, run_e;
    for (int ch = range.begin(); ch != range.end(); ++ch) {
      auto& list = lists[size_t(ch)];
      size_t used = 0;
      for (int c = ch * kChunk; c < std::min(cells, (ch + 1) * kChunk); ++c) {
        // The 27 cells as up to 9 runs of contiguous slots.
        const int cands = grid.NeighbourSlotRuns(c, run_b, run_e);
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
          const size_t room = used + size_t(cands) + simd::kAppendSlack;
          if (list.size() < room) list.resize(std::max(2 * list.size(), room));
          uint32_t* w = list.data() + used;
          int cnt = 0;
          const float px = grid.x[s], py = grid.y[s], pz = grid.z[s];
          for (size_t r = 0; r < run_b.size(); ++r)
            cnt = simd::AppendSlotsWithin(avx2, grid.x.data(), grid.y.data(), grid.z.data(), run_b[r], run_e[r], px, py,
                                          pz, delta2, s, w, cnt);
          used += size_t(cnt);
          out.start[size_t(s) + 1] = uint32_t(cnt);
        }
      }
      list.resize(used);
    }
  });
  for (size_t s = 0; s < n; ++s) out.start[s + 1] += out.start[s];
  out.nb.resize(out.start[n]);
  tbb::parallel_for(tbb::blocked_range<int>(0, chunks, 1), [&](const tbb::blocked_range<int>& range) {
    for (int ch = range.begin(); ch != range.end(); ++ch) {
      const auto& list = lists[size_t(ch)];
      std::copy(list.begin(), list.end(), out.nb.begin() + out.start[size_t(grid.cell_start[ch * kChunk])]);
    }
  });
  return true;
}

Eigen::Vector3f LocalViewpoint(const LocalCloud& lc, const std::optional<Eigen::Vector3f>& viewpoint) {
  if (viewpoint && viewpoint->allFinite()) return (viewpoint->cast<double>() - lc.centre).cast<float>();
  return Eigen::Vector3f::Zero();  // the bounding-box centre
}

}  // namespace

void RegionGrowingOptions::Check() const {
  if (!(normal_radius_m > 0)) throw StageError("normal_radius_m must be > 0");
  if (!(distance_m > 0)) throw StageError("distance_m must be > 0");
  if (!(angle_deg >= 0 && angle_deg <= 180)) throw StageError("angle_deg must be in [0, 180]");
  if (min_points < 1) throw StageError("min_points must be >= 1");
  if (min_fit_points < 3) throw StageError("min_fit_points must be >= 3");
  if (max_normal_points < 0) throw StageError("max_normal_points must be >= 0 (0: always exact)");
  if (max_list_candidates < 0) throw StageError("max_list_candidates must be >= 0 (0: never list)");
}

NormalResult EstimateNormals(const Points& points, const std::optional<Eigen::Vector3f>& viewpoint,
                             const RegionGrowingOptions& o) {
  o.Check();
  const LocalCloud lc = ToLocal(points);
  Points nl;
  std::vector<float> cl;
  NormalsLocal(lc, LocalViewpoint(lc, viewpoint), o, nl, cl);
  NormalResult res;
  res.normals.assign(points.size(), Eigen::Vector3f::Constant(kNaN));
  res.curvature.assign(points.size(), kNaN);
  for (size_t k = 0; k < lc.input.size(); ++k) {
    res.normals[lc.input[k]] = nl[k];
    res.curvature[lc.input[k]] = cl[k];
  }
  return res;
}

Segmentation Segment(const Scan& scan, const RegionGrowingOptions& o, SegmentTimings* timings) {
  o.Check();
  Stopwatch watch;
  const LocalCloud lc = ToLocal(scan.points);
  const size_t n = lc.pts.size();
  Points normals_local;
  std::vector<float> curv_local;
  // The growing runs on a grid with cells of delta, so a point's candidates are the slices of
  // its 27 neighbour cells. Built beside the normals: it needs only the points.
  const float delta = float(o.distance_m);
  const float delta2 = delta * delta;
  VoxelIndex grid;
  // Dense scans grow by sub-cells (CountSubCells), sparse ones from neighbour lists when they
  // are affordable, else point by point over the cells.
  bool by_sub = false, listed = false;
  std::vector<uint8_t> half_of;
  std::vector<uint32_t> sub_first;
  NeighbourLists lists;
  tbb::parallel_invoke([&] { NormalsLocal(lc, LocalViewpoint(lc, scan.origin), o, normals_local, curv_local); },
                       [&] {
                         grid.Build(lc.pts, delta, VoxelIndex::Anchor::kBoundingBox, TbbFor());
                         by_sub = CountSubCells(grid, o.growth_by_sub_cells, half_of, sub_first);
                       });
  // The growth's neighbour lists need only its grid; the normals in scan order, the normals by
  // slot and the seed order need only the normals: side by side.
  Segmentation seg;
  std::vector<float> nx, ny, nz;
  std::vector<uint32_t> seeds;
  tbb::parallel_invoke(
      [&] {
        if (!by_sub) listed = BuildNeighbourLists(grid, delta2, o.max_list_candidates, lists);
      },
      [&] {
        seg.normals.assign(scan.points.size(), Eigen::Vector3f::Constant(kNaN));
        seg.curvature.assign(scan.points.size(), kNaN);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16384), [&](const tbb::blocked_range<size_t>& r) {
          for (size_t k = r.begin(); k != r.end(); ++k) {
            seg.normals[lc.input[k]] = normals_local[k];
            seg.curvature[lc.input[k]] = curv_local[k];
          }
        });
        nx.resize(n), ny.resize(n), nz.resize(n);
        std::vector<uint64_t> seed_key(n);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16384), [&](const tbb::blocked_range<size_t>& r) {
          for (size_t s = r.begin(); s != r.end(); ++s) {
            const uint32_t i = grid.order[s];
            nx[s] = normals_local[i].x();
            ny[s] = normals_local[i].y();
            nz[s] = normals_local[i].z();
            // Non-negative floats order like their bit patterns; NaN curvature seeds last.
            const float c = curv_local[i];
            uint32_t bits = 0xffffffffu;
            if (std::isfinite(c)) {
              const float cc = std::max(0.f, c);
              std::memcpy(&bits, &cc, 4);
            }
            seed_key[s] = bits;
          }
        });
        // Seeds by increasing curvature; ties keep slot order, so deterministic.
        seeds = SortedByKey(seed_key, 32, TbbFor());
      });
  const double normals_ms = watch.Ms();
  seg.discarded_points = int(scan.points.size() - n);  // non-finite points never join a part
  if (n == 0) return seg;

  const float cos_a = float(std::cos(o.angle_deg * M_PI / 180.0));
  const bool signed_normals = o.signed_normals;
  std::vector<int> label(n, -1);
  const int cells = grid.NumCells();

  // Sub-cells: each cell of delta split into 2 x 2 x 2 cubes of edge delta / 2, so that any two
  // points of one sub-cell lie within 0.87 delta of each other. A region is the connected
  // component, under "within delta", of the seed and the points its normal admits (admission
  // depends on the point and the seed only), so the admitted free points of a sub-cell join a
  // region together, and the growth walks sub-cells: a sub-cell joins when one of its admitted
  // free points lies within delta of a member of a joined neighbour. The same parts as growing
  // point by point; a dense scan costs a walk over its sub-cells instead of a scan of every
  // member's neighbourhood (3.7M-point room: growing 2.5 s -> see the commit).
  if (!by_sub) {
    sub_first.resize(size_t(cells) + 1);
    for (int c = 0; c <= cells; ++c) sub_first[size_t(c)] = uint32_t(c);
  }
  const size_t subs = sub_first[size_t(cells)];
  std::vector<uint32_t> sub_of(by_sub ? n : 0), sub_start(subs);
  std::vector<float> sub_box(by_sub ? subs * 6 : 0);
  if (by_sub) {
    tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
      for (int c = range.begin(); c != range.end(); ++c) {
        int count[8] = {0, 0, 0, 0, 0, 0, 0, 0}, id[8];
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) ++count[half_of[s]];
        uint32_t k = sub_first[size_t(c)], at = uint32_t(grid.cell_start[c]);
        for (int h = 0; h < 8; ++h) {
          id[h] = count[h] ? int(k) : -1;
          if (!count[h]) continue;
          sub_start[k] = at;
          EmptyBox(&sub_box[size_t(k) * 6]);
          at += uint32_t(count[h]), ++k;
        }
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s) {
          const uint32_t q = uint32_t(id[half_of[s]]);
          sub_of[s] = q;
          ExtendBox(&sub_box[size_t(q) * 6], grid.x[s], grid.y[s], grid.z[s]);
        }
      }
    });
    half_of.clear();
    half_of.shrink_to_fit();
  } else {
    for (int c = 0; c < cells; ++c) sub_start[size_t(c)] = uint32_t(grid.cell_start[c]);
  }
  auto sub_cell = [&](uint32_t s) { return by_sub ? size_t(sub_of[s]) : size_t(grid.cell_of[s]); };
  // Unlabelled slots of each sub-cell are kept at the front of its range of `free_slots`
  // (swap-remove on labelling), in slot order after a reset; free_in_cell counts a cell's.
  // (Not needed when growing from the lists.)
  std::vector<uint32_t> free_in_sub(listed ? 0 : subs), free_slots(listed ? 0 : n), pos(listed ? 0 : n);
  std::vector<int> free_in_cell(listed ? 0 : size_t(cells), 0);
  auto reset_free = [&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, cells, 1024), [&](const tbb::blocked_range<int>& range) {
      for (int c = range.begin(); c != range.end(); ++c) {
        const uint32_t k0 = sub_first[size_t(c)], k1 = sub_first[size_t(c) + 1];
        for (uint32_t k = k0; k < k1; ++k) free_in_sub[k] = 0;
        int free_here = 0;
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s)
          if (label[s] == -1) {
            const uint32_t k = uint32_t(sub_cell(uint32_t(s))), w = sub_start[k] + free_in_sub[k]++;
            free_slots[w] = uint32_t(s), pos[s] = w, ++free_here;
          }
        free_in_cell[c] = free_here;
        uint32_t used[8];
        for (uint32_t k = k0; k < k1; ++k) used[k - k0] = free_in_sub[k];
        for (int s = grid.cell_start[c]; s < grid.cell_start[c + 1]; ++s)
          if (label[s] != -1) {
            const uint32_t k = uint32_t(sub_cell(uint32_t(s))), w = sub_start[k] + used[k - k0]++;
            free_slots[w] = uint32_t(s), pos[s] = w;
          }
      }
    });
  };
  auto take = [&](uint32_t q) {
    const size_t k = sub_cell(q);
    --free_in_cell[grid.cell_of[q]];
    const uint32_t last = sub_start[k] + --free_in_sub[k];
    const uint32_t moved = free_slots[last];
    free_slots[pos[q]] = moved;
    pos[moved] = pos[q];
    free_slots[last] = q;
    pos[q] = last;
  };
  if (!listed) reset_free();
  std::vector<uint32_t> members;  // slots of all parts, part after part
  std::vector<size_t> part_begin{0};
  members.reserve(n);

  // Cells' tight boxes: a neighbour cell at delta or farther from a joined sub-cell's members
  // holds none of their neighbours.
  const std::vector<float> box = listed ? std::vector<float>() : CellBoxes(grid);

  // Growth from `seed` over unlabelled slots accepted by `admit`, point by point (breadth
  // first; sparse scans).
  auto grow_points = [&](uint32_t seed, int id, auto&& admit) {
    const size_t begin = members.size();
    label[seed] = id;
    take(seed);
    members.push_back(seed);
    for (size_t head = begin; head < members.size(); ++head) {
      const uint32_t p = members[head];
      const float px = grid.x[p], py = grid.y[p], pz = grid.z[p];
      const int c = grid.cell_of[p];
      for (int k = grid.nb_start[c]; k < grid.nb_start[c + 1]; ++k) {
        const int nc = grid.nb[k];
        if (free_in_cell[nc] == 0 || Far(box, nc, Eigen::Vector3f(px, py, pz), delta2)) continue;
        const uint32_t kc = sub_first[size_t(nc)];  // the cell's one sub-cell
        for (uint32_t i = sub_start[kc]; i < sub_start[kc] + free_in_sub[kc];) {
          const uint32_t q = free_slots[i];
          const float dx = grid.x[q] - px, dy = grid.y[q] - py, dz = grid.z[q] - pz;
          if (dx * dx + dy * dy + dz * dz >= delta2 || !admit(q)) {
            ++i;
            continue;
          }
          label[q] = id;
          take(q);  // moves another free slot to position i: look at i again
          members.push_back(q);
        }
      }
    }
  };

  // Growth from `seed` over unlabelled slots accepted by `admit`, sub-cell by sub-cell.
  struct Joined {
    size_t begin, end;  // a sub-cell's members in `members`
    int cell;           // the cell it lies in
  };
  std::vector<Joined> joined;
  std::vector<int> joined_in(by_sub ? subs : 0, -1);  // the region a sub-cell last joined
  // The same from the neighbour lists (sparse scans): a member's free neighbours are read
  // from its list. The same parts: a part is the seed's connected component of admitted points.
  // (Raw pointers: through the vectors, each push_back would make the compiler reload them.)
  auto grow_listed = [&](uint32_t seed, int id, auto&& admit) {
    int* const lab = label.data();
    const uint32_t *const start = lists.start.data(), *const nbs = lists.nb.data();
    const size_t begin = members.size();
    lab[seed] = id;
    members.push_back(seed);
    for (size_t head = begin; head < members.size(); ++head) {
      const uint32_t p = members[head];
      for (uint32_t j = start[p], e = start[size_t(p) + 1]; j < e; ++j) {
        const uint32_t q = nbs[j];
        if (lab[q] != -1 || !admit(q)) continue;
        lab[q] = id;
        members.push_back(q);
      }
    }
  };
  auto grow = [&](uint32_t seed, int id, auto&& admit) {
    if (listed) return grow_listed(seed, id, admit);
    if (!by_sub) return grow_points(seed, id, admit);
    joined.clear();
    auto join = [&](size_t k, int cell, size_t mb) {
      joined_in[k] = id;
      for (uint32_t i = sub_start[k]; i < sub_start[k] + free_in_sub[k];) {
        const uint32_t q = free_slots[i];
        if (!admit(q)) {
          ++i;
          continue;
        }
        label[q] = id;
        take(q);  // moves another free slot to position i: look at i again
        members.push_back(q);
      }
      joined.push_back({mb, members.size(), cell});
    };
    const size_t begin = members.size();
    label[seed] = id;
    take(seed);
    members.push_back(seed);
    join(sub_cell(seed), grid.cell_of[seed], begin);
    for (size_t h = 0; h < joined.size(); ++h) {
      const Joined a = joined[h];
      float mbox[6];
      EmptyBox(mbox);
      for (size_t t = a.begin; t < a.end; ++t) ExtendBox(mbox, grid.x[members[t]], grid.y[members[t]], grid.z[members[t]]);
      const int c = a.cell;
      const bool one = a.end - a.begin == 1;  // sparse scans: most sub-cells hold one point
      for (int kk = grid.nb_start[c]; kk < grid.nb_start[c + 1]; ++kk) {
        const int nc = grid.nb[kk];
        if (free_in_cell[nc] == 0 || BoxGap2(mbox, &box[size_t(nc) * 6]) >= delta2) continue;
        for (size_t k = sub_first[size_t(nc)]; k < sub_first[size_t(nc) + 1]; ++k) {
          const uint32_t nf = free_in_sub[k];
          if (nf == 0 || joined_in[k] == id || (nf > 1 && BoxGap2(mbox, &sub_box[k * 6]) >= delta2)) continue;
          bool hit = false;
          for (uint32_t i = sub_start[k]; i < sub_start[k] + nf && !hit; ++i) {
            const uint32_t q = free_slots[i];
            if (!one) {
              const float qb[6] = {grid.x[q], grid.y[q], grid.z[q], grid.x[q], grid.y[q], grid.z[q]};
              if (BoxGap2(mbox, qb) >= delta2) continue;
            }
            if (!admit(q)) continue;
            for (size_t t = a.begin; t < a.end; ++t) {
              const uint32_t m = members[t];
              const float dx = grid.x[q] - grid.x[m], dy = grid.y[q] - grid.y[m], dz = grid.z[q] - grid.z[m];
              if (dx * dx + dy * dy + dz * dz < delta2) {
                hit = true;
                break;
              }
            }
          }
          if (hit) join(k, nc, members.size());
        }
      }
    }
  };

  // Pass 1: normal-based growing. A seed without a normal stays alone (and is regrouped).
  int parts = 0;
  for (uint32_t seed : seeds) {
    if (label[seed] != -1) continue;
    const float sx = nx[seed], sy = ny[seed], sz = nz[seed];
    const bool seed_ok = std::isfinite(sx);
    const float *const fx = nx.data(), *const fy = ny.data(), *const fz = nz.data();
    grow(seed, parts, [=](int q) {  // by value: kept in registers
      if (!seed_ok) return false;
      const float d = fx[q] * sx + fy[q] * sy + fz[q] * sz;  // NaN normals compare false
      return signed_normals ? d >= cos_a : std::fabs(d) >= cos_a;
    });
    part_begin.push_back(members.size());
    ++parts;
  }

  // Pass 2: parts below min_points are released and regrouped among themselves by distance.
  std::vector<uint32_t> pool;
  std::vector<std::pair<size_t, size_t>> kept;  // [begin, end) ranges into members
  for (int p = 0; p < parts; ++p) {
    const size_t b = part_begin[p], e = part_begin[p + 1];
    if (int(e - b) >= o.min_points) {
      kept.emplace_back(b, e);
      continue;
    }
    for (size_t k = b; k < e; ++k) pool.push_back(members[k]);
  }
  std::sort(pool.begin(), pool.end());
  // Pass 1 labelled every slot, so after this only the pool is unlabelled and the distance-only
  // growth below cannot reach into the kept parts.
  for (uint32_t s : pool) label[s] = -1;
  if (!listed) reset_free();
  int regrouped = 0, discarded = 0;
  std::vector<std::pair<size_t, size_t>> regroup_parts;
  for (uint32_t s : pool) {
    if (label[s] != -1) continue;
    const size_t b = members.size();
    grow(s, parts + int(regroup_parts.size()), [](int) { return true; });
    const size_t e = members.size();
    if (int(e - b) >= o.min_points) {
      regroup_parts.emplace_back(b, e);
      regrouped += int(e - b);
    } else {
      discarded += int(e - b);
    }
  }
  const double growing_ms = watch.Ms() - normals_ms;

  // A part's points in input order (so its centroid's sum does not depend on the growth's order).
  auto emit = [&](size_t b, size_t e, Part& part) {
    std::vector<uint32_t> local(e - b);
    for (size_t k = b; k < e; ++k) local[k - b] = grid.order[members[k]];
    std::sort(local.begin(), local.end());
    part.indices.reserve(e - b);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (uint32_t i : local) {
      part.indices.push_back(lc.input[i]);
      sum += lc.pts[i].cast<double>();
    }
    part.centroid = (sum / double(e - b) + lc.centre).cast<float>();
  };
  kept.insert(kept.end(), regroup_parts.begin(), regroup_parts.end());
  seg.parts.resize(kept.size());
  tbb::parallel_for(size_t(0), kept.size(), [&](size_t p) { emit(kept[p].first, kept[p].second, seg.parts[p]); });
  seg.discarded_points += discarded;
  if (discarded > 0 || pool.size() > 0)
    spdlog::info("region_growing: {} parts; {} points of parts below {} regrouped into {} parts, {} discarded",
                 seg.parts.size(), pool.size(), o.min_points, regroup_parts.size(), discarded);
  if (timings) {
    timings->normals_ms = normals_ms;
    timings->growing_ms = growing_ms;
    timings->growth = by_sub ? "sub-cells" : listed ? "lists" : "cells";
  }
  return seg;
}

}  // namespace furnihost::rg
