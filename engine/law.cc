// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "law.h"

#include <cmath>

namespace mjrft::law {
namespace {

// Constants the reference derives with libm (tanh, atanh, exp, log, pow), written exactly (hex
// floats) so that the results do not depend on this platform's libm.
constexpr f64 kTanhF1Shift = 0x1.d897242c8f6d7p-1;    // tanh(kF1Shift)
constexpr f64 kAtanhF23Shift = 0x1.147900f87795dp+1;  // atanh(kF23Shift)
constexpr f64 kC1 = kF1Gain / kF1Norm;
constexpr f64 kC23 = kF23Gain / kF23Norm;
constexpr f64 kLn2 = 0x1.62e42fefa39efp-1;  // log(2)

// exp on the bounded argument of tanh in f1: x = 2 (slope |v1| - shift) with |v1| <= 1 lies in
// [-2 shift, 2 (slope - shift)]; exp(x) = e^mid p((x - mid) / 16)^16, mid the centre, p the
// Taylor polynomial of exp of degree kExpDegree (truncation below 1e-18 for |y| <= 0.23; the
// four squarings multiply the rounding error by 16: ~2e-15 relative).
constexpr f64 kExpMid = 0.5 * (-2.0 * kF1Shift + 2.0 * (kF1Slope - kF1Shift));
static_assert(kExpMid == 0x1.9e213ccd1f964p-2, "the reference's centre");
constexpr f64 kExpScale = 0x1.7f99ace4f6f11p+0;  // exp(kExpMid)
constexpr int kExpDegree = 12;
constexpr f64 kExpTaylor[kExpDegree + 1] = {  // 1 / i!
    1.0,         1.0,          1.0 / 2,         1.0 / 6,         1.0 / 24,
    1.0 / 120,   1.0 / 720,    1.0 / 5040,      1.0 / 40320,     1.0 / 362880,
    1.0 / 3628800, 1.0 / 39916800, 1.0 / 479001600};

// log on (1 + u) / (1 - u), u = slope |v23| - shift in f23 (ratio in [0.013, 4.6]): five exact
// power-of-two steps bring the ratio into [2^-0.5, 2^0.5], then log r = 2 atanh(s),
// s = (r - 1) / (r + 1), |s| <= 0.1716, by its odd series to s^19 (next term < 1e-17 relative).
// Each step: below (true) or above the threshold on the ratio, the factor, log2 of the factor.
struct LogStep {
  f64 threshold;
  bool below;
  f64 factor, log2;
};
constexpr LogStep kLogSteps[5] = {
    {0x1.bdb8cdadbe11fp-3, true, 16.0, 4.0},    // 2^-2.2
    {0x1.125fbee250664p+1, false, 0.25, -2.0},  // 2^1.1
    {0x1.ddb680117ab12p-2, true, 4.0, 2.0},     // 2^-1.1
    {0x1.6a09e667f3bcdp+0, false, 0.5, -1.0},   // 2^0.5
    {0x1.6a09e667f3bcdp-1, true, 2.0, 1.0},     // 2^-0.5
};
constexpr int kLogTerms = 10;
// 1 / rho for rho = 1 - eps, |eps| <= 1 - kHorizontalPlateNz^2 (< 2e-3): geometric series to
// eps^6.
constexpr int kInvTerms = 7;
// In-plane speed |v23| below this counts as zero (gamma = 0): f23 there is below 1e-99.
constexpr f64 kVnMin = 1e-100;

// exp(x) for x in the f1 argument's range, without libm: vectorisable.
inline f64 ExpF1(f64 x) {
  f64 y = (x - kExpMid) * (1.0 / 16.0);
  f64 p = kExpTaylor[kExpDegree];
  #pragma GCC unroll 16
  for (int i = kExpDegree - 1; i >= 0; i--) p = std::fma(p, y, kExpTaylor[i]);
  p = p * p;
  p = p * p;
  p = p * p;
  p = p * p;
  return p * kExpScale;
}

// sum_k p[k] T_k(x1, x2, x3) over the monomials 1, x1, x2, x3, x1^2, x2^2, x3^2, x1 x2, x2 x3,
// x3 x1, x1^3, x2^3, x3^3, x1 x2^2, x2 x1^2, x2 x3^2, x3 x2^2, x3 x1^2, x1 x3^2, x1 x2 x3.
inline f64 Cubic(const f64* p, f64 x1, f64 x2, f64 x3) {
  return p[0] + p[1] * x1 + p[2] * x2 + p[3] * x3 + p[4] * x1 * x1 + p[5] * x2 * x2 +
         p[6] * x3 * x3 + p[7] * x1 * x2 + p[8] * x2 * x3 + p[9] * x3 * x1 +
         p[10] * x1 * x1 * x1 + p[11] * x2 * x2 * x2 + p[12] * x3 * x3 * x3 +
         p[13] * x1 * x2 * x2 + p[14] * x2 * x1 * x1 + p[15] * x2 * x3 * x3 +
         p[16] * x3 * x2 * x2 + p[17] * x3 * x1 * x1 + p[18] * x1 * x3 * x3 +
         p[19] * x1 * x2 * x3;
}

}  // namespace

void EvaluateTreers(Buf& buf, int k, const f64* co, f64 ay, f64 zeta) {
  const f64* __restrict bnx = buf[kNx];
  const f64* __restrict bny = buf[kNx + 1];
  const f64* __restrict bnz = buf[kNx + 2];
  const f64* __restrict bhx = buf[kHx];
  const f64* __restrict bhy = buf[kHx + 1];
  const f64* __restrict bwx = buf[kWx];
  const f64* __restrict bwy = buf[kWx + 1];
  const f64* __restrict bwz = buf[kWx + 2];
  const f64* __restrict bda = buf[kDepthArea];
  f64* __restrict fx = buf[kFx];
  f64* __restrict fy = buf[kFx + 1];
  f64* __restrict fz = buf[kFx + 2];
  f64 caz[9], cax[9];
  for (int c = 0; c < 9; c++) {
    caz[c] = co[c];
    cax[c] = co[9 + c];
  }
#pragma GCC ivdep
  for (int j = 0; j < k; j++) {
    f64 nx = bnx[j], ny = bny[j], nz = bnz[j];
    f64 hx = bhx[j], hy = bhy[j];
    f64 wx = bwx[j], wy = bwy[j], wz = bwz[j];
    f64 h2 = std::fma(hx, hx, hy * hy);
    f64 s2 = std::fma(wx, wx, std::fma(wy, wy, wz * wz));
    f64 big_a = std::sqrt(h2);     // |h|
    f64 t = std::sqrt(s2 * h2);    // |w| |h|
    f64 p = std::fma(wx, hy, -(wy * hx));  // (w . e1) |h|, e1 = e2 x z
    f64 q = std::fma(wx, hx, wy * hy);     // (w . e2) |h|
    f64 r = std::sqrt(std::fma(q, q, wz * wz * h2));  // |w| |h| |v23|
    bool moving = r > kVnMin * t;
    f64 rg = moving ? r : t;
    f64 x = 1.0 / (t * big_a * rg);  // the one division of the frame: 1/t, 1/|h|, 1/rg below
    f64 inv_t = big_a * rg * x;
    f64 inv_a = t * rg * x;
    f64 inv_r = t * big_a * x;
    f64 ex = hx * inv_a;
    f64 ey = hy * inv_a;
    f64 a = p * inv_t;   // v^ . e1
    f64 vn = r * inv_t;  // |v23|
    f64 cg = moving ? q * inv_r : 1.0;  // gamma = -atan2(v^.z, v^.e2)
    f64 sg = moving ? -wz * big_a * inv_r : 0.0;
    // beta = atan2(nz, n2) + pi/2: cos 2 beta = (nz^2 - n2^2) / rho, sin 2 beta = -2 nz n2 / rho
    // with rho = n2^2 + nz^2 = 1 - (n . e1)^2 within 2e-3 of 1 (docs/design.md 2.2 frame).
    f64 n2 = std::fma(nx, ex, ny * ey);
    f64 eps = 1.0 - std::fma(n2, n2, nz * nz);
    f64 inv_rho = 1.0;
    #pragma GCC unroll 16
    for (int i = 0; i < kInvTerms - 1; i++) inv_rho = std::fma(inv_rho, eps, 1.0);
    f64 c2 = (nz - n2) * (nz + n2) * inv_rho;
    f64 s2b = -2.0 * nz * n2 * inv_rho;
    // The Fourier sums by angle addition: terms 1, cos 2b, sin 2b, cos g, sin g and the four
    // products, in the order of the combined coefficients.
    f64 p1 = c2 * cg, p2 = s2b * sg, p3 = c2 * sg, p4 = s2b * cg;
    f64 az = std::fma(caz[1], c2, caz[0]);
    f64 ax = std::fma(cax[1], c2, cax[0]);
    az = std::fma(caz[2], s2b, az);
    ax = std::fma(cax[2], s2b, ax);
    az = std::fma(caz[3], cg, az);
    ax = std::fma(cax[3], cg, ax);
    az = std::fma(caz[4], sg, az);
    ax = std::fma(cax[4], sg, ax);
    az = std::fma(caz[5], p1, az);
    ax = std::fma(cax[5], p1, ax);
    az = std::fma(caz[6], p2, az);
    ax = std::fma(cax[6], p2, ax);
    az = std::fma(caz[7], p3, az);
    ax = std::fma(cax[7], p3, ax);
    az = std::fma(caz[8], p4, az);
    ax = std::fma(cax[8], p4, ax);
    // f1 = C1 (tanh(slope |a| - shift) + tanh(shift)), tanh(z) = 1 - 2 / (exp(2z) + 1).
    f64 e1 = ExpF1(std::fma(2.0 * kF1Slope, std::fabs(a), -2.0 * kF1Shift)) + 1.0;
    // f23 = C23 (atanh(u) + atanh(shift)), atanh(u) = log(num / den) / 2.
    f64 num = std::fma(kF23Slope, vn, 1.0 - kF23Shift);  // 1 + u
    f64 den = std::fma(-kF23Slope, vn, 1.0 + kF23Shift);  // 1 - u
    f64 lg = 0.0;
    #pragma GCC unroll 16
    for (const LogStep& st : kLogSteps) {
      bool hit = st.below ? num < st.threshold * den : num > st.threshold * den;
      num = hit ? num * st.factor : num;
      lg = hit ? lg - st.log2 : lg;
    }
    f64 y = 1.0 / ((num + den) * e1);  // the second division: 1 / (num + den) and 1 / e1
    f64 sr = (num - den) * e1 * y;
    f64 s_sq = sr * sr;
    f64 ser = 1.0 / (2 * kLogTerms - 1);
    #pragma GCC unroll 16
    for (int i = kLogTerms - 2; i >= 0; i--) ser = std::fma(ser, s_sq, 1.0 / (2 * i + 1));
    f64 log_r = std::fma(lg, kLn2, 2.0 * sr * ser);
    f64 f1 = kC1 * (std::fma(-2.0 * (num + den), y, 1.0) + kTanhF1Shift);
    // docs/design.md 2.8: F = zeta d dA [-f1 ay sign(v^.e1) e1 - f23 ax e2 + f23 az z].
    f64 s = zeta * bda[j];
    f64 g23 = s * kC23 * std::fma(0.5, log_r, kAtanhF23Shift);
    f64 sgn = a > 0.0 ? 1.0 : (a < 0.0 ? -1.0 : 0.0);
    f64 g1 = -s * f1 * ay * sgn;
    f64 gx = -g23 * ax;
    fx[j] = std::fma(g1, ey, gx * ex);
    fy[j] = std::fma(-g1, ex, gx * ey);
    fz[j] = g23 * az;
  }
}

void EvaluateAgarwal(Buf& buf, int k, const f64* p) {
  const f64* __restrict bnx = buf[kNx];
  const f64* __restrict bny = buf[kNx + 1];
  const f64* __restrict bnz = buf[kNx + 2];
  const f64* __restrict bwx = buf[kWx];
  const f64* __restrict bwy = buf[kWx + 1];
  const f64* __restrict bwz = buf[kWx + 2];
  const f64* __restrict bda = buf[kDepthArea];
  f64* __restrict fx = buf[kFx];
  f64* __restrict fy = buf[kFx + 1];
  f64* __restrict fz = buf[kFx + 2];
  f64 xi = p[kAgarwalXi], mu = p[kAgarwalMu];
  f64 c[3 * kAgarwalTerms];
  for (int i = 0; i < 3 * kAgarwalTerms; i++) c[i] = p[kAgarwalCoef0 + i];
  // Branch-free (each choice a select between values computed either way, as the reference's
  // branches compute them), so the loop vectorises.
#pragma GCC ivdep
  for (int j = 0; j < k; j++) {
    f64 nx = bnx[j], ny = bny[j], nz = bnz[j];
    f64 wx = bwx[j], wy = bwy[j], wz = bwz[j];
    f64 inv = 1.0 / std::sqrt(wx * wx + wy * wy + wz * wz);
    f64 vx = wx * inv, vy = wy * inv, vz = wz * inv;
    f64 vh = std::sqrt(vx * vx + vy * vy), nh = std::sqrt(nx * nx + ny * ny);  // unit vectors
    // The local frame: r the horizontal direction of v, or of n when v is vertical, or world x.
    bool by_v = vh > kAgarwalHorizontalEps, by_n = nh > kAgarwalHorizontalEps;
    f64 rx = by_v ? vx / vh : (by_n ? nx / nh : 1.0);
    f64 ry = by_v ? vy / vh : (by_n ? ny / nh : 0.0);
    f64 tx = -ry, ty = rx;  // theta = z x r
    // The angles' sines and cosines from components (no trigonometric calls): beta = -+acos(nz)
    // or +-(pi - acos(nz)) by the signs of n . r and nz, so cos beta = |nz| and |sin beta| =
    // |n_h|; gamma = +-acos(v . r), + when moving down; psi = atan((n . theta) / (n . r)) in
    // (-pi/2, pi/2), so cos psi >= 0.
    f64 nr = nx * rx + ny * ry, nt = nx * tx + ny * ty;
    f64 cb = std::fabs(nz);
    f64 sb = (nr >= 0.0) == (nz >= 0.0) ? -nh : nh;
    f64 cg = vx * rx + vy * ry;
    f64 sg = std::sqrt(Max(0.0, 1.0 - cg * cg));
    sg = vz > 0.0 ? -sg : sg;
    bool tilted = by_n && nr != 0.0;
    f64 inv_h = 1.0 / std::sqrt(nr * nr + nt * nt);
    f64 cp = tilted ? std::fabs(nr) * inv_h : 1.0;
    f64 sp = tilted ? (nr > 0.0 ? nt * inv_h : -nt * inv_h) : 0.0;  // tan psi cos psi
    f64 x1 = sg, x2 = cb, x3 = cp * cg * sb + sg * cb;
    f64 f1 = Cubic(c, x1, x2, x3);
    f64 f2 = Cubic(c + kAgarwalTerms, x1, x2, x3);
    f64 f3 = Cubic(c + 2 * kAgarwalTerms, x1, x2, x3);
    f64 ar = f1 * sb * cp + f2 * cg;
    f64 at = f1 * sb * sp;
    f64 gx = ar * rx + at * tx, gy = ar * ry + at * ty, gz = -f1 * cb - f2 * sg - f3;
    f64 an = -(gx * nx + gy * ny + gz * nz);  // alpha . (-n)
    f64 ux = gx + an * nx, uy = gy + an * ny, uz = gz + an * nz;  // tangential part
    bool turn = ux * vx + uy * vy + uz * vz > 0.0;  // turned to oppose the motion
    ux = turn ? -ux : ux;
    uy = turn ? -uy : uy;
    uz = turn ? -uz : uz;
    f64 mag_n = std::fabs(an), mag_t = std::sqrt(ux * ux + uy * uy + uz * uz);
    // mu_surf caps the tangential part at mu_surf |alpha_n| (intruder-medium friction).
    f64 cap = mu * mag_n >= mag_t ? 1.0 : mu * mag_n / mag_t;
    f64 s = xi * bda[j];
    fx[j] = s * (-mag_n * nx + cap * ux);
    fy[j] = s * (-mag_n * ny + cap * uy);
    fz[j] = s * (-mag_n * nz + cap * uz);
  }
}

void EvaluateModel(Buf& buf, int k, const f64* co, i64 ncoef, f64 ay, f64 zeta) {
  if (ncoef == kAgarwalSize || ncoef == kAgarwalSize + 1) {
    EvaluateAgarwal(buf, k, co);
  } else {
    EvaluateTreers(buf, k, co, ay, zeta);
  }
}

}  // namespace mjrft::law
