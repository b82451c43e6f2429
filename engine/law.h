// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The RFT element law on gathered elements (docs/design.md section 2; mjrft.core.agarwal for the
// 3D-RFT parameters): the force
// per element of a chunk whose elements were written, structure of arrays, into the rows of a
// scratch buffer (Gather). Three coefficient forms (FormOf): Treers, Cao & Stuart 2021 on the 18
// combined Fourier coefficients of Li 2013's media (docs/design.md section 2) and the 3D-RFT of
// Agarwal, Goldman & Kamrin 2023 (kAgarwalSize parameters), told apart by their lengths; and
// Treers et al.'s law on a medium given by Python callables (Material.from_callables), carried
// as a table of its alphas (kTabulatedTag first, then the layout below). Each may carry the
// dynamic (inertial) term's lambda rho_c as one extra coefficient, last.
//
// EvaluateTreers is one branch-free loop the compiler vectorises: beta and gamma are never
// formed (their sines and cosines are normalised vector components), the Fourier sums follow by
// angle addition, and tanh / atanh of f1 / f23 come from exp and log polynomials on their
// bounded arguments (libm's exp and log are scalar calls). Per element: 3 square roots and 2
// divisions, the rest multiply-adds. Each multiply-add written std::fma is fused and no other
// is (-ffp-contract=off), so results do not depend on the compiler's choices nor on an
// element's slot in a chunk.

#ifndef MJRFT_ENGINE_LAW_H_
#define MJRFT_ENGINE_LAW_H_

#include <cmath>

#include "tables.h"

namespace mjrft::law {

// Elements per chunk: the scratch rows stay in L1 cache.
constexpr int kChunk = 256;

// Rows of the scratch buffer (f64[kBufRows][kChunk]): the law's inputs 0-8, written by Gather:
// unit normal n (3); horizontal direction h of the frame's e2, unnormalised (2); velocity w, any
// scale with |w|^2 in [kW2Min, kW2Max] (3); depth x area [m^3]. Its outputs 9-11: force [N].
// Then the kernel's own: point [m] (3) and the acting area [m^2] (for the dynamic term). World
// frame.
enum Row { kNx = 0, kHx = 3, kWx = 5, kDepthArea = 8, kFx = 9, kPx = 12, kArea = 15 };
constexpr int kBufRows = 16;
using Buf = f64[kBufRows][kChunk];

// |n_z| at or above this marks a nearly horizontal plate (docs/design.md 2.2): its frame comes
// from the velocity.
constexpr f64 kHorizontalPlateNz = 1.0 - 1.0e-3;

// An element leads iff n . v > kLeadingSlack |v| (unit n; docs/design.md 2.1): a face parallel
// to the motion gets n . v of a few epsilons times |v| from the rotation and twist that give
// its normal and velocity, not 0. Mirrors mjrft.core.law.LEADING_SLACK (16 float64 epsilons).
constexpr f64 kLeadingSlack = 16.0 * 2.220446049250313e-16;

// Fitted scaling functions of the 3D decomposition (Treers et al. 2021, docs/design.md 2.7),
// f1 = gain (tanh(slope |v1| - shift) + tanh(shift)) / norm, f23 likewise with atanh.
constexpr f64 kF1Gain = 0.440850096954369, kF1Slope = 3.62263982880971, kF1Shift = 1.60910808139526,
              kF1Norm = 0.832324700111401;
constexpr f64 kF23Gain = 1.99392673405210, kF23Slope = 1.61146827229181,
              kF23Shift = 0.973746396532650, kF23Norm = 5.81083560370960;
// Velocities are rescaled in Gather when |w|^2 leaves this range, so that the products of up to
// three speed-scaled factors in EvaluateTreers neither overflow nor underflow.
constexpr f64 kW2Min = 1e-60, kW2Max = 1e60;
// Length of the Treers model's coefficients (Material.kernel_coefficients).
constexpr int kNCombined = 18;
// Agarwal's model: parameter vector xi_n [N/m^3], mu_surf, then the cubics C1, C2, C3 (20
// monomials each); a unit vector's horizontal part shorter than kAgarwalHorizontalEps counts as
// none (the source's threshold).
constexpr int kAgarwalXi = 0, kAgarwalMu = 1, kAgarwalCoef0 = 2, kAgarwalTerms = 20;
constexpr int kAgarwalSize = kAgarwalCoef0 + 3 * kAgarwalTerms;
constexpr f64 kAgarwalHorizontalEps = 1e-10;

// A medium given by callables (Material.from_callables, Material.tabulated): its generic
// alpha_x(beta, gamma) and alpha_z(beta, gamma) sampled at load on a grid of step h [rad] in both
// angles, nodes beta_i = beta0 + i h (i < nb), gamma_j = gamma0 + j h (j < ng), with the
// derivatives that make the interpolation bicubic Hermite (C1), and alpha_y(beta) on the same
// beta nodes (cubic Hermite). Layout: the header (kTabHeader entries: tag, nb, ng, beta0,
// gamma0, h), then node (i, j) at kTabHeader + kTabNode (i ng + j): alpha_x, h d/dbeta,
// h d/dgamma, h^2 d2/dbeta dgamma, then the same four of alpha_z; then alpha_y node i at
// kTabHeader + kTabNode nb ng + 2 i: alpha_y, h d/dbeta. The derivatives are scaled by h so the
// interpolation needs no step. The grid covers the angles the frame produces (docs/design.md
// 2.2, 2.4): gamma in [-pi, pi], beta in [0, pi] and, on nearly horizontal plates, up to
// asin(sqrt(1 - kHorizontalPlateNz^2)) = 0.0447 rad beyond; callables need not be periodic, so
// neither angle is wrapped (an angle off the grid, from round-off, extrapolates its edge cell).
constexpr f64 kTabulatedTag = 3.0;
enum TabHeader { kTabTag = 0, kTabNb = 1, kTabNg = 2, kTabBeta0 = 3, kTabGamma0 = 4, kTabStep = 5 };
constexpr int kTabHeader = 8;
constexpr int kTabNode = 8;
constexpr int kTabMinNodes = 4;  // per angle: at least three cells

// Length of a tabulated medium's coefficients without the dynamic term, nb x ng nodes.
inline i64 TabulatedSize(i64 nb, i64 ng) { return kTabHeader + kTabNode * nb * ng + 2 * nb; }

// The coefficient forms (Material.kernel_coefficients).
enum class Form { kTreers, kAgarwal, kTabulated };

// The form of coefficients co (ncoef,): Agarwal's by its lengths (kAgarwalSize, +1 with the
// dynamic term), a table by its tag and a length that matches its header, else Treers'.
inline Form FormOf(const f64* co, i64 ncoef) {
  if (ncoef == kAgarwalSize || ncoef == kAgarwalSize + 1) return Form::kAgarwal;
  if (ncoef > kAgarwalSize + 1 && co[kTabTag] == kTabulatedTag) {
    f64 nb = co[kTabNb], ng = co[kTabNg];
    if (nb >= kTabMinNodes && ng >= kTabMinNodes && nb * ng < 1e12) {  // sizes, not garbage
      i64 size = TabulatedSize(static_cast<i64>(nb), static_cast<i64>(ng));
      if (ncoef == size || ncoef == size + 1) return Form::kTabulated;
    }
  }
  return Form::kTreers;
}

// max(a, b) and min(a, b) as the reference's compiled Python evaluates them: b if b > a (b < a)
// else a, so a NaN argument is treated alike.
inline f64 Max(f64 a, f64 b) { return b > a ? b : a; }
inline f64 Min(f64 a, f64 b) { return b < a ? b : a; }

// Writes element i at slot k of the chunk (rows 0-8 of buf, idx); returns k + 1 if it acts
// (depth > 0, inside, leading: n . w > kLeadingSlack |w|), else k, so the slot is reused
// (branch-free compaction). n: unit normal, w: velocity [m/s] (any scale), depth [m], area [m^2]
// (or depth 1 and the depth integral W [m^3] as area); world frame. The velocity is rescaled only
// when |w|^2 leaves [kW2Min, kW2Max], and h is normalised here only for nearly horizontal plates
// (rare), whose frame comes from the horizontal velocity, or world x if there is none.
inline int Gather(Buf& buf, i64* idx, int k, i64 i, f64 nx, f64 ny, f64 nz, f64 wx, f64 wy, f64 wz,
                  f64 depth, f64 area, bool inside) {
  f64 s2 = wx * wx + wy * wy + wz * wz;
  if (!(kW2Min <= s2 && s2 <= kW2Max)) {
    f64 m = Max(Max(std::fabs(wx), std::fabs(wy)), std::fabs(wz));
    if (m > 0.0) {
      wx = wx / m;
      wy = wy / m;
      wz = wz / m;
    }
  }
  // Not above kLeadingSlack |w|: trailing, moving in the plate (up to rounding), or at rest.
  f64 dot = nx * wx + ny * wy + nz * wz;
  bool lead =
      (dot > 0.0) & (dot * dot > kLeadingSlack * kLeadingSlack * (wx * wx + wy * wy + wz * wz));
  f64 hx = nx, hy = ny;
  if (std::fabs(nz) >= kHorizontalPlateNz) {
    f64 m = Max(std::fabs(wx), std::fabs(wy));
    if (m == 0.0) {
      hx = 1.0;
      hy = 0.0;
    } else {
      hx = wx / m;
      hy = wy / m;
      f64 inv = 1.0 / std::sqrt(hx * hx + hy * hy);
      hx = hx * inv;
      hy = hy * inv;
    }
  }
  buf[kNx][k] = nx;
  buf[kNx + 1][k] = ny;
  buf[kNx + 2][k] = nz;
  buf[kHx][k] = hx;
  buf[kHx + 1][k] = hy;
  buf[kWx][k] = wx;
  buf[kWx + 1][k] = wy;
  buf[kWx + 2][k] = wz;
  buf[kDepthArea][k] = depth * area;
  idx[k] = i;
  return k + ((depth > 0.0) & inside & lead);
}

// Forces (rows 9-11) on the k gathered elements of buf under Treers et al.'s law: co (18,) the
// combined generic coefficients (az: co[0..8], ax: co[9..17]), ay the generic alpha_y, zeta
// [N/m^3]. docs/design.md 2.8: F = zeta d dA [-f1 ay sign(v.e1) e1 - f23 ax e2 + f23 az z].
void EvaluateTreers(Buf& buf, int k, const f64* co, f64 ay, f64 zeta);

// Forces (rows 9-11) on the k gathered elements of buf under Agarwal et al.'s 3D-RFT
// (mjrft.core.agarwal): p (kAgarwalSize,) its parameters. Every gathered element leads.
void EvaluateAgarwal(Buf& buf, int k, const f64* p);

// Forces (rows 9-11) on the k gathered elements of buf under Treers et al.'s law for a medium
// given by callables: co its table (layout above), zeta [N/m^3]. The frame, f1 and f23 are
// EvaluateTreers'; beta = atan2(n . z, n . e2) + pi/2 and gamma = -atan2(v^ . z, v^ . e2) as the
// NumPy evaluation of callables forms them (mjrft.core.rft), and alpha_x, alpha_z, alpha_y
// interpolated there. Interpolation error: at most h^4 / 384 (max |d4 alpha / d beta4| + max
// |d4 alpha / d gamma4|) plus O(h^5) from the sampled derivatives (fourth-order differences);
// for Li's generic medium on the default grid (h = pi / 64) 1.2e-7 of the largest |alpha|
// (tests/test_tabulated.py). Two loops per chunk: the frame, f1, f23 and the angles (by an
// atan2 without libm) in one the compiler vectorises, then a scalar one that reads each
// element's table cells; about 2.5 times EvaluateTreers' time on random angles.
void EvaluateTabulated(Buf& buf, int k, const f64* co, f64 zeta);

// The force model the coefficients co (ncoef,) are for (FormOf): Agarwal's, a table, or Treers'
// (ay: its constant alpha_y).
void EvaluateModel(Buf& buf, int k, const f64* co, i64 ncoef, f64 ay, f64 zeta);

// lambda rho_c [kg/m^3] of the dynamic term the coefficients carry, 0 if none: one entry after
// any form's own (kNCombined + 1, kAgarwalSize + 1, TabulatedSize + 1 entries).
inline f64 DynamicCoefficient(const f64* co, i64 ncoef) {
  bool dyn = ncoef == kNCombined + 1 || ncoef == kAgarwalSize + 1;
  if (!dyn && FormOf(co, ncoef) == Form::kTabulated) {
    dyn = ncoef == TabulatedSize(static_cast<i64>(co[kTabNb]), static_cast<i64>(co[kTabNg])) + 1;
  }
  return dyn ? co[ncoef - 1] : 0.0;
}

// Adds the dynamic RFT inertial term to the force (rows 9-11) of gathered element j:
// -lambda rho_c (n.v)^2 A n on its acting part of area A [m^2], unit normal n (rows 0-2), moving
// at v [m/s]; world frame. The momentum flux of the grains a leading face sets moving at its
// normal speed (docs/models.md, "Dynamic RFT"): F.v = -lambda rho_c (n.v)^3 A <= 0.
inline void Dynamic(Buf& buf, int j, f64 lam_rho, f64 area, f64 vx, f64 vy, f64 vz) {
  f64 nx = buf[kNx][j], ny = buf[kNx + 1][j], nz = buf[kNx + 2][j];
  f64 vn = Max(0.0, nx * vx + ny * vy + nz * vz);
  f64 g = lam_rho * area * vn * vn;
  buf[kFx][j] -= g * nx;
  buf[kFx + 1][j] -= g * ny;
  buf[kFx + 2][j] -= g * nz;
}

}  // namespace mjrft::law

#endif  // MJRFT_ENGINE_LAW_H_
