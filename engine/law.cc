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
    1.0,        1.0,         1.0 / 2,      1.0 / 6,       1.0 / 24,       1.0 / 120,      1.0 / 720,
    1.0 / 5040, 1.0 / 40320, 1.0 / 362880, 1.0 / 3628800, 1.0 / 39916800, 1.0 / 479001600};

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
         p[6] * x3 * x3 + p[7] * x1 * x2 + p[8] * x2 * x3 + p[9] * x3 * x1 + p[10] * x1 * x1 * x1 +
         p[11] * x2 * x2 * x2 + p[12] * x3 * x3 * x3 + p[13] * x1 * x2 * x2 + p[14] * x2 * x1 * x1 +
         p[15] * x2 * x3 * x3 + p[16] * x3 * x2 * x2 + p[17] * x3 * x1 * x1 + p[18] * x1 * x3 * x3 +
         p[19] * x1 * x2 * x3;
}

// The frame of docs/design.md 2.2 for one gathered element, from its unit normal's
// components and h, w (Gather): unit e2 = (ex, ey, 0), e1 = e2 x z, v^ = w / |w|.
struct Frame {
  f64 ex, ey;  // e2
  f64 a;       // v^ . e1
  f64 vn;      // |v23|, the in-plane speed fraction
  f64 cg, sg;  // cos and sin gamma, gamma = -atan2(v^ . z, v^ . e2); (1, 0) at no in-plane speed
  f64 n2;      // n . e2
};

// Frame of an element: normal (nx, ny), h (hx, hy), velocity w. Three square roots and one
// division; no angle is formed.
inline Frame FrameOf(f64 nx, f64 ny, f64 hx, f64 hy, f64 wx, f64 wy, f64 wz) {
  f64 h2 = std::fma(hx, hx, hy * hy);
  f64 s2 = std::fma(wx, wx, std::fma(wy, wy, wz * wz));
  f64 big_a = std::sqrt(h2);                        // |h|
  f64 t = std::sqrt(s2 * h2);                       // |w| |h|
  f64 p = std::fma(wx, hy, -(wy * hx));             // (w . e1) |h|, e1 = e2 x z
  f64 q = std::fma(wx, hx, wy * hy);                // (w . e2) |h|
  f64 r = std::sqrt(std::fma(q, q, wz * wz * h2));  // |w| |h| |v23|
  bool moving = r > kVnMin * t;
  f64 rg = moving ? r : t;
  f64 x = 1.0 / (t * big_a * rg);  // the one division of the frame: 1/t, 1/|h|, 1/rg below
  f64 inv_t = big_a * rg * x;
  f64 inv_a = t * rg * x;
  f64 inv_r = t * big_a * x;
  Frame f;
  f.ex = hx * inv_a;
  f.ey = hy * inv_a;
  f.a = p * inv_t;
  f.vn = r * inv_t;
  f.cg = moving ? q * inv_r : 1.0;  // gamma = -atan2(v^.z, v^.e2)
  f.sg = moving ? -wz * big_a * inv_r : 0.0;
  f.n2 = std::fma(nx, f.ex, ny * f.ey);
  return f;
}

// The scaling functions of the 3D decomposition (docs/design.md 2.7) at |v^ . e1| = |a| and
// |v23| = vn: f1, and f23 / kC23 = atanh(slope vn - shift) + atanh(shift).
struct Scalings {
  f64 f1, t23;
};

inline Scalings ScalingsOf(f64 a, f64 vn) {
  // f1 = C1 (tanh(slope |a| - shift) + tanh(shift)), tanh(z) = 1 - 2 / (exp(2z) + 1).
  f64 e1 = ExpF1(std::fma(2.0 * kF1Slope, std::fabs(a), -2.0 * kF1Shift)) + 1.0;
  // f23 = C23 (atanh(u) + atanh(shift)), atanh(u) = log(num / den) / 2.
  f64 num = std::fma(kF23Slope, vn, 1.0 - kF23Shift);   // 1 + u
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
  Scalings out;
  out.f1 = kC1 * (std::fma(-2.0 * (num + den), y, 1.0) + kTanhF1Shift);
  out.t23 = std::fma(0.5, log_r, kAtanhF23Shift);
  return out;
}

// The force [N] on an element from its frame, scalings and generic alphas; s = zeta d dA [N]:
// docs/design.md 2.8, F = zeta d dA [-f1 ay sign(v^.e1) e1 - f23 ax e2 + f23 az z].
struct Force {
  f64 x, y, z;
};

inline Force ForceOf(const Frame& fr, const Scalings& sc, f64 ax, f64 ay, f64 az, f64 s) {
  f64 g23 = s * kC23 * sc.t23;
  f64 sgn = fr.a > 0.0 ? 1.0 : (fr.a < 0.0 ? -1.0 : 0.0);
  f64 g1 = -s * sc.f1 * ay * sgn;
  f64 gx = -g23 * ax;
  return {std::fma(g1, fr.ey, gx * fr.ex), std::fma(-g1, fr.ex, gx * fr.ey), g23 * az};
}

// Cubic Hermite weights on [0, 1] at s: of the values at 0 and 1 (w0, w1) and of the slopes
// (times the step) at 0 and 1 (d0, d1).
struct Hermite {
  f64 w0, w1, d0, d1;
};

inline Hermite HermiteAt(f64 s) {
  f64 t = 1.0 - s;
  f64 s2 = s * s, t2 = t * t;
  return {(1.0 + 2.0 * s) * t2, (3.0 - 2.0 * s) * s2, s * t2, -s2 * t};
}

// The cell of a table axis (nodes x0 + i h, i < n) holding x, and x's position in it; an x off
// the axis (round-off at its ends) takes the edge cell.
inline i64 Cell(f64 x, f64 x0, f64 inv_h, i64 n, f64* s) {
  f64 u = (x - x0) * inv_h;
  f64 c = std::fmin(std::fmax(std::floor(u), 0.0), static_cast<f64>(n - 2));
  *s = u - c;
  return static_cast<i64>(c);
}

// Bicubic Hermite interpolation on the four nodes (n00, n01 at (i, j), (i, j + 1); n10, n11
// at (i + 1, ...)) of one function (value, beta, gamma and cross derivative, scaled by h).
inline f64 Bicubic(const f64* n00, const f64* n01, const f64* n10, const f64* n11, const Hermite& b,
                   const Hermite& g) {
  // Along gamma at beta nodes i and i + 1: the value and the beta slope.
  f64 v0 = g.w0 * n00[0] + g.d0 * n00[2] + g.w1 * n01[0] + g.d1 * n01[2];
  f64 s0 = g.w0 * n00[1] + g.d0 * n00[3] + g.w1 * n01[1] + g.d1 * n01[3];
  f64 v1 = g.w0 * n10[0] + g.d0 * n10[2] + g.w1 * n11[0] + g.d1 * n11[2];
  f64 s1 = g.w0 * n10[1] + g.d0 * n10[3] + g.w1 * n11[1] + g.d1 * n11[3];
  return b.w0 * v0 + b.d0 * s0 + b.w1 * v1 + b.d1 * s1;
}

constexpr f64 kPi = 0x1.921fb54442d18p+1;
constexpr f64 kHalfPi = 0x1.921fb54442d18p+0;
constexpr f64 kQuarterPi = 0x1.921fb54442d18p-1;
constexpr f64 kTanEighthPi = 0x1.a827999fcef32p-2;  // sqrt(2) - 1
// atan on [-tan(pi/8), tan(pi/8)] by its Taylor series to t^(2 kAtanTerms - 1): the first
// omitted term is below 3e-17.
constexpr int kAtanTerms = 19;

// atan2(y, x) [rad] without libm, so that loops over it vectorise: within 4.5e-16 of libm's
// (2 ulp at pi; measured on 2e7 random pairs), and the same at signed zeros (atan2(+-0, -0) =
// +-pi, ...). One division: atan(min / max) is reduced to |t| <= tan(pi/8) by atan(m) = pi/4 +
// atan((m - 1) / (m + 1)), then the quadrant.
inline f64 Atan2(f64 y, f64 x) {
  f64 ax = std::fabs(x), ay = std::fabs(y);
  f64 mn = ay < ax ? ay : ax, mx = ay < ax ? ax : ay;
  bool big = mn > kTanEighthPi * mx;
  f64 num = big ? mn - mx : mn, den = big ? mn + mx : mx;
  f64 t = den > 0.0 ? num / den : 0.0;
  f64 t2 = t * t;
  f64 p = 1.0 / (2 * kAtanTerms - 1);
#pragma GCC unroll 32
  for (int i = kAtanTerms - 2; i >= 0; i--) {
    p = std::fma(p, t2, (i % 2 ? -1.0 : 1.0) / (2 * i + 1));
  }
  f64 r = (big ? kQuarterPi : 0.0) + t * p;  // atan(mn / mx), in [0, pi/4]
  r = ay > ax ? kHalfPi - r : r;
  r = std::copysign(1.0, x) < 0.0 ? kPi - r : r;  // the sign bit, -0 included
  return std::copysign(r, y);
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
    f64 nz = bnz[j];
    Frame fr = FrameOf(bnx[j], bny[j], bhx[j], bhy[j], bwx[j], bwy[j], bwz[j]);
    // beta = atan2(nz, n2) + pi/2: cos 2 beta = (nz^2 - n2^2) / rho, sin 2 beta = -2 nz n2 / rho
    // with rho = n2^2 + nz^2 = 1 - (n . e1)^2 within 2e-3 of 1 (docs/design.md 2.2 frame).
    f64 n2 = fr.n2;
    f64 eps = 1.0 - std::fma(n2, n2, nz * nz);
    f64 inv_rho = 1.0;
#pragma GCC unroll 16
    for (int i = 0; i < kInvTerms - 1; i++) inv_rho = std::fma(inv_rho, eps, 1.0);
    f64 c2 = (nz - n2) * (nz + n2) * inv_rho;
    f64 s2b = -2.0 * nz * n2 * inv_rho;
    // The Fourier sums by angle addition: terms 1, cos 2b, sin 2b, cos g, sin g and the four
    // products, in the order of the combined coefficients.
    f64 cg = fr.cg, sg = fr.sg;
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
    Force f = ForceOf(fr, ScalingsOf(fr.a, fr.vn), ax, ay, az, zeta * bda[j]);
    fx[j] = f.x;
    fy[j] = f.y;
    fz[j] = f.z;
  }
}

void EvaluateTabulated(Buf& buf, int k, const f64* co, f64 zeta) {
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
  // 1. The frame, the scalings and the angles, one branch-free loop the compiler vectorises
  // (as EvaluateTreers'). The angles as mjrft.core.rft forms them for callables: beta =
  // atan2(n.z, n.e2) + pi/2, gamma = -atan2(v^.z, v^.e2) = atan2(sin gamma, cos gamma) (the
  // same side of the cut at +-pi for either sign of zero).
  alignas(64) f64 ex[kChunk], ey[kChunk], beta[kChunk], gamma[kChunk];
  alignas(64) f64 g1[kChunk], g23[kChunk];  // -zeta d dA f1 sign(v^.e1); zeta d dA f23
#pragma GCC ivdep
  for (int j = 0; j < k; j++) {
    Frame fr = FrameOf(bnx[j], bny[j], bhx[j], bhy[j], bwx[j], bwy[j], bwz[j]);
    Scalings sc = ScalingsOf(fr.a, fr.vn);
    f64 s = zeta * bda[j];
    f64 sgn = fr.a > 0.0 ? 1.0 : (fr.a < 0.0 ? -1.0 : 0.0);
    ex[j] = fr.ex;
    ey[j] = fr.ey;
    beta[j] = Atan2(bnz[j], fr.n2) + kHalfPi;
    gamma[j] = Atan2(fr.sg, fr.cg);
    g1[j] = -s * sc.f1 * sgn;
    g23[j] = s * kC23 * sc.t23;
  }
  // 2. The alphas, scalar: each element reads its own table cells.
  const i64 nb = static_cast<i64>(co[kTabNb]), ng = static_cast<i64>(co[kTabNg]);
  const f64 beta0 = co[kTabBeta0], gamma0 = co[kTabGamma0], inv_h = 1.0 / co[kTabStep];
  const f64* nodes = co + kTabHeader;
  const f64* ay_nodes = nodes + kTabNode * nb * ng;
  for (int j = 0; j < k; j++) {
    f64 s, u;
    i64 i = Cell(beta[j], beta0, inv_h, nb, &s);
    i64 c = Cell(gamma[j], gamma0, inv_h, ng, &u);
    Hermite hb = HermiteAt(s), hg = HermiteAt(u);
    const f64* n00 = nodes + kTabNode * (i * ng + c);
    const f64* n10 = n00 + kTabNode * ng;
    f64 ax = Bicubic(n00, n00 + kTabNode, n10, n10 + kTabNode, hb, hg);
    f64 az = Bicubic(n00 + 4, n00 + kTabNode + 4, n10 + 4, n10 + kTabNode + 4, hb, hg);
    const f64* y = ay_nodes + 2 * i;
    f64 ay = hb.w0 * y[0] + hb.d0 * y[1] + hb.w1 * y[2] + hb.d1 * y[3];
    // docs/design.md 2.8: F = zeta d dA [-f1 ay sign(v^.e1) e1 - f23 ax e2 + f23 az z].
    f64 a1 = g1[j] * ay;
    f64 gx = -g23[j] * ax;
    fx[j] = std::fma(a1, ey[j], gx * ex[j]);
    fy[j] = std::fma(-a1, ex[j], gx * ey[j]);
    fz[j] = g23[j] * az;
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
    f64 an = -(gx * nx + gy * ny + gz * nz);                      // alpha . (-n)
    f64 ux = gx + an * nx, uy = gy + an * ny, uz = gz + an * nz;  // tangential part
    bool turn = ux * vx + uy * vy + uz * vz > 0.0;                // turned to oppose the motion
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
  switch (FormOf(co, ncoef)) {
    case Form::kAgarwal:
      EvaluateAgarwal(buf, k, co);
      break;
    case Form::kTabulated:
      EvaluateTabulated(buf, k, co, zeta);
      break;
    case Form::kTreers:
      EvaluateTreers(buf, k, co, ay, zeta);
      break;
  }
}

}  // namespace mjrft::law
