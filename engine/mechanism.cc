// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "mechanism.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "evaluate.h"
#include "law.h"
#include "lowspeed.h"
#include "surface.h"

namespace mjrft::mechanism {
namespace {

using lowspeed::kPure;
using lowspeed::kRounding;
using lowspeed::kSlip;
using lowspeed::kStick;

// Length of a row of s.mech_vec.
int VecLen(const mjModel* m, const Tables& t) {
  return std::max(static_cast<int>(m->nv), static_cast<int>(6 * t.ntbody));
}

// The wrench a held body's hold starts from (W_ref, row r): its wrench in the pass that read
// the loads if it was held then, else its pure wrench.
f64 Reference(const Tables& t, const State& s, i64 k, int r) {
  if (s.mech_in_held[k]) return s.mech_in_prev[6 * k + r];
  return s.wrench[6 * t.tbody_bodyid[k] + r];
}

// Evaluates tagged body k's pure model if this pass deferred it (s.lazy; PureWrenches), counted
// in the pass's work counters.
void EnsurePure(const mjData* d, const Tables& t, State& s, int k) {
  if (!s.lazy[k]) return;
  int acting = 0;
  s.stats[1] += BodyPure(d, t, s, k, &acting);
  s.stats[2] += acting;
}

// The configuration key of SameConfiguration, entry q: the number of bodies in the medium,
// their rows (-1 padded), cdof, then per row its CoM and its root's subtree CoM (0 padded).
f64 ConfigurationKey(const mjModel* m, const mjData* d, const Tables& t, const i64* rows, int n,
                     int q) {
  int nk = t.ntbody, nv = m->nv;
  if (q == 0) return n;
  q -= 1;
  if (q < nk) return q < n ? static_cast<f64>(rows[q]) : -1.0;
  q -= nk;
  if (q < 6 * nv) return d->cdof[q];
  q -= 6 * nv;
  int a = q / 6, c = q % 6;
  if (a >= n) return 0.0;
  i64 k = rows[a];
  if (c < 3) return d->xipos[3 * t.tbody_bodyid[k] + c];
  return d->subtree_com[3 * t.tbody_rootid[k] + c - 3];
}

}  // namespace

void FullInertia(const mjModel* m, const mjData* d, f64* out) {
  int nv = m->nv;
  for (int i = 0; i < nv * nv; i++) out[i] = 0.0;
  for (int i = 0; i < nv; i++) {
    for (int a = m->M_rowadr[i]; a < m->M_rowadr[i] + m->M_rownnz[i]; a++) {
      int j = m->M_colind[a];
      out[nv * i + j] = d->M[a];
      out[nv * j + i] = d->M[a];
    }
  }
}

bool Cholesky(f64* a, int lda, int n, f64 eps) {
  for (int j = 0; j < n; j++) {
    f64 s = a[lda * j + j] + eps;
    for (int q = 0; q < j; q++) s -= a[lda * j + q] * a[lda * j + q];
    if (!(s > 0.0)) return false;
    a[lda * j + j] = std::sqrt(s);
    for (int i = j + 1; i < n; i++) {
      f64 v = a[lda * i + j];
      for (int q = 0; q < j; q++) v -= a[lda * i + q] * a[lda * j + q];
      a[lda * i + j] = v / a[lda * j + j];
    }
  }
  return true;
}

void ChoSolve(const f64* lower, int lda, int n, f64* x) {
  ForwardSolve(lower, lda, n, x);
  BackSolve(lower, lda, n, x);
}

void ForwardSolve(const f64* lower, int lda, int n, f64* x) {
  for (int i = 0; i < n; i++) {
    f64 s = x[i];
    for (int q = 0; q < i; q++) s -= lower[lda * i + q] * x[q];
    x[i] = s / lower[lda * i + i];
  }
}

void BackSolve(const f64* lower, int lda, int n, f64* x) {
  for (int i = n - 1; i >= 0; i--) {
    f64 s = x[i];
    for (int q = i + 1; q < n; q++) s -= lower[lda * q + i] * x[q];
    x[i] = s / lower[lda * i + i];
  }
}

void BodyJacobian(const mjModel* m, const mjData* d, const Tables& t, int k, int row, f64* jac) {
  int nv = m->nv;
  i64 b = t.tbody_bodyid[k];
  const f64* c0 = d->subtree_com + 3 * t.tbody_rootid[k];
  const f64* x = d->xipos + 3 * b;
  f64 rx = x[0] - c0[0], ry = x[1] - c0[1], rz = x[2] - c0[2];
  f64* out = jac + static_cast<i64>(nv) * row;
  for (int j = 0; j < nv; j++) {
    if (!t.tbody_dofmask[static_cast<i64>(nv) * k + j]) {
      for (int r = 0; r < 6; r++) out[nv * r + j] = 0.0;
      continue;
    }
    const f64* cdof = d->cdof + 6 * j;
    f64 w0 = cdof[0], w1 = cdof[1], w2 = cdof[2];
    out[nv * 0 + j] = cdof[3] + w1 * rz - w2 * ry;
    out[nv * 1 + j] = cdof[4] + w2 * rx - w0 * rz;
    out[nv * 2 + j] = cdof[5] + w0 * ry - w1 * rx;
    out[nv * 3 + j] = w0;
    out[nv * 4 + j] = w1;
    out[nv * 5 + j] = w2;
  }
}

bool PredictorValid(const mjModel* m, const mjData* d, State& s, bool same_time) {
  if (same_time) return s.mech_time[2] == 1.0;
  f64 time = d->time, dt = m->opt.timestep, t0 = s.mech_time[0];
  bool ok =
      s.mech_time[1] == 1.0 && std::fabs(time - (t0 + dt)) <= 1e-9 * dt + 1e-12 * std::fabs(time);
  s.mech_time[0] = time;
  s.mech_time[1] = 1.0;
  s.mech_time[2] = ok ? 1.0 : 0.0;
  return ok;
}

bool HeldBefore(const mjData* d, const State& s, int k) {
  bool same_time = s.mech_time[1] == 1.0 && d->time == s.mech_time[0];
  return (same_time ? s.mech_in_held[k] : s.mech_held[k]) != 0;
}

bool Submerged(const mjData* d, const Tables& t, const State& s, int k) {
  i64 b = t.tbody_bodyid[k];
  const f64* pos = d->xpos + 3 * b;
  const f64* rot = d->xmat + 9 * b;
  bool flat = t.surface_prm[surface::kKind] == surface::kFlat;
  for (i64 g = t.tbody_geomadr[k]; g < t.tbody_geomadr[k] + t.tbody_geomnum[k]; g++) {
    if (s.cull[g]) continue;
    // An element above the highest surface point near its geom is dry wherever it is: the
    // height alone (three multiply-adds an element) clears it, as it decides under a flat
    // surface, before the surface is looked up.
    f64 top = GeomTop(d, t, s, g);
    for (i64 e = t.tgeom_elemadr[g]; e < t.tgeom_elemadr[g] + t.tgeom_elemnum[g]; e++) {
      const f64* p = t.elem_pos + 3 * e;
      f64 z = pos[2];
      for (int c = 0; c < 3; c++) z += rot[6 + c] * p[c];
      if (flat || z >= top) {
        if (z < top) return true;
        continue;
      }
      f64 x = pos[0], y = pos[1];
      for (int c = 0; c < 3; c++) {
        x += rot[c] * p[c];
        y += rot[3 + c] * p[c];
      }
      if (surface::Depth(t.surface_prm, t.surface_grid, s.soil, x, y, z, k + 1.0) > 0.0)
        return true;
    }
  }
  return false;
}

int Gather(const mjData* d, const Tables& t, const State& s, i64* rows) {
  int n = 0;
  for (int k = 0; k < t.ntbody; k++) {
    if (t.tbody_mech[k] && InPlay(t, s, k) && Submerged(d, t, s, k)) rows[n++] = k;
  }
  return n;
}

f64 ActuatorForce(const mjModel* m, const mjData* d, const Tables& t, int a) {
  if (m->opt.disableflags & mjDSBL_ACTUATION) return 0.0;
  i64 adr = t.actuator_actadr[a];
  f64 x;
  if (adr >= 0) {
    x = d->act[adr];
  } else {
    x = d->ctrl[a];
    if (t.actuator_ctrllimited[a] && !(m->opt.disableflags & mjDSBL_CLAMPCTRL)) {
      x = std::min(std::max(x, m->actuator_ctrlrange[2 * a]), m->actuator_ctrlrange[2 * a + 1]);
    }
  }
  f64 length = d->actuator_length[a], velocity = d->actuator_velocity[a];
  const f64* g = m->actuator_gainprm + mjNGAIN * a;
  const f64* b = m->actuator_biasprm + mjNBIAS * a;
  f64 gain = g[0] + (t.actuator_gainaffine[a] ? g[1] * length + g[2] * velocity : 0.0);
  f64 bias = t.actuator_biasaffine[a] ? b[0] + b[1] * length + b[2] * velocity : 0.0;
  f64 f = gain * x + bias;
  if (t.actuator_forcelimited[a]) {
    f = std::min(std::max(f, m->actuator_forcerange[2 * a]), m->actuator_forcerange[2 * a + 1]);
  }
  return f;
}

void ActuatorForces(const mjModel* m, const mjData* d, const Tables& t, f64* out) {
  for (int a = 0; a < m->nu; a++) {
    out[a] =
        t.actuator_affine[a] ? ActuatorForce(m, d, t, a) : std::numeric_limits<f64>::quiet_NaN();
  }
}

void ActuatorUpdate(const mjModel* m, const mjData* d, const Tables& t, const State& s, f64* tau) {
  for (int a = 0; a < m->nu; a++) {
    if (!t.actuator_affine[a]) continue;
    f64 df = ActuatorForce(m, d, t, a) - s.mech_in_force[a];
    if (df == 0.0) continue;
    int start = d->moment_rowadr[a];
    for (int q = start; q < start + d->moment_rownnz[a]; q++) {
      tau[d->moment_colind[q]] += d->actuator_moment[q] * df;
    }
  }
}

bool SameConfiguration(const mjModel* m, const mjData* d, const Tables& t, State& s,
                       const i64* rows, int n) {
  // The key is compared entry by entry as it is computed, then written only if it changed
  // (nothing is allocated in a pass).
  f64* cfg = s.mech_cfg;
  int size = 1 + t.ntbody + 6 * m->nv + 6 * t.ntbody;
  bool same = cfg[0] >= 0.0;
  for (int q = 0; q < size && same; q++) {
    same = std::fabs(ConfigurationKey(m, d, t, rows, n, q) - cfg[q]) <= kConfigurationReuse;
  }
  if (!same) {
    for (int q = 0; q < size; q++) cfg[q] = ConfigurationKey(m, d, t, rows, n, q);
    s.mech_hkey[0] = -2;  // the hold system (and its held rows' factor) is the old one's
  }
  return same;
}

bool Setup(const mjModel* m, const mjData* d, const Tables& t, State& s, const i64* rows, int n) {
  int nv = m->nv;
  f64 dt = m->opt.timestep;
  f64* lo = s.mech_L;
  if (!SameConfiguration(m, d, t, s, rows, n)) {
    FullInertia(m, d, s.mech_M);
    for (int i = 0; i < nv * nv; i++) lo[i] = s.mech_M[i];
    if (!Cholesky(lo, nv, nv, 0.0)) {
      s.mech_cfg[0] = -1.0;
      return false;
    }
    for (int a = 0; a < n; a++) BodyJacobian(m, d, t, rows[a], 6 * a, s.mech_J);
  }
  f64* u = s.mech_vec;
  for (int i = 0; i < nv; i++) {  // tau_other = M qacc_prev - tau_field_prev
    f64 acc = -s.mech_in[nv + i];
    for (int j = 0; j < nv; j++) acc += s.mech_M[nv * i + j] * s.mech_in[j];
    u[i] = acc;
  }
  ActuatorUpdate(m, d, t, s, u);
  ChoSolve(lo, nv, nv, u);
  for (int i = 0; i < nv; i++) u[i] = d->qvel[i] + dt * u[i];
  return true;
}

void HoldSystem(const mjModel* m, const Tables& t, State& s, int n) {
  if (s.mech_hkey[0] != -2) return;
  int nv = m->nv, lda = 6 * t.ntbody;
  for (int r = 0; r < 6 * n; r++) {
    f64* x = s.mech_X + static_cast<i64>(nv) * r;
    for (int j = 0; j < nv; j++) x[j] = s.mech_J[nv * r + j];
    ForwardSolve(s.mech_L, nv, nv, x);
  }
  // A = X^T X, four entries of a row at a time: four independent sums (each in the order of
  // one) instead of one chain of dependent additions.
  const f64* x = s.mech_X;
  for (int r = 0; r < 6 * n; r++) {
    const f64* xr = x + static_cast<i64>(nv) * r;
    int c = r;
    for (; c + 4 <= 6 * n; c += 4) {
      const f64* x0 = x + static_cast<i64>(nv) * c;
      f64 a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
      for (int j = 0; j < nv; j++) {
        a0 += xr[j] * x0[j];
        a1 += xr[j] * x0[nv + j];
        a2 += xr[j] * x0[2 * nv + j];
        a3 += xr[j] * x0[3 * nv + j];
      }
      const f64 acc[4] = {a0, a1, a2, a3};
      for (int q = 0; q < 4; q++) {
        s.mech_A[lda * r + c + q] = acc[q];
        s.mech_A[lda * (c + q) + r] = acc[q];
      }
    }
    for (; c < 6 * n; c++) {
      f64 acc = 0.0;
      for (int j = 0; j < nv; j++) acc += xr[j] * x[nv * c + j];
      s.mech_A[lda * r + c] = acc;
      s.mech_A[lda * c + r] = acc;
    }
  }
  s.mech_hkey[0] = -1;
}

f64 RowDot(const f64* jac, int r, const f64* x, int nv) {
  f64 acc = 0.0;
  for (int j = 0; j < nv; j++) acc += jac[static_cast<i64>(nv) * r + j] * x[j];
  return acc;
}

void Classify(const mjModel* m, const mjData* d, const Tables& t, State& s, const i64* rows, int n,
              i64* code) {
  int nv = m->nv;
  f64 dt = m->opt.timestep;
  const f64* u = s.mech_vec;
  f64* g = s.mech_vec + VecLen(m, t);  // M^-1 sum J^T W: the medium's generalized acceleration
  for (int j = 0; j < nv; j++) g[j] = 0.0;
  for (int a = 0; a < n; a++) {
    for (int r = 0; r < 6; r++) {
      f64 w = Reference(t, s, rows[a], r);  // a body held at the last pass: its hold
      for (int j = 0; j < nv; j++) g[j] += s.mech_J[nv * (6 * a + r) + j] * w;
    }
  }
  ChoSolve(s.mech_L, nv, nv, g);
  f64 xi[6], dxi[6], pred[6], iw[9], ii[9];
  for (int a = 0; a < n; a++) {
    i64 k = rows[a];
    if (s.mech_in_held[k]) {
      code[k] = kStick;
      continue;
    }
    i64 b = t.tbody_bodyid[k];
    lowspeed::WorldInertia(d->ximat + 9 * b, m->body_inertia + 3 * b, iw, ii);
    f64 mass = m->body_mass[b];
    for (int r = 0; r < 6; r++) {
      xi[r] = RowDot(s.mech_J, 6 * a + r, d->qvel, nv);
      // the twist's change over a step under every force, the medium's pure model included
      dxi[r] = RowDot(s.mech_J, 6 * a + r, u, nv) - xi[r];
      dxi[r] += dt * RowDot(s.mech_J, 6 * a + r, g, nv);
      pred[r] = xi[r] + t.reach * dxi[r];
    }
    f64 n2 = lowspeed::MDot(xi, xi, mass, iw);
    bool keeps = lowspeed::MDot(pred, xi, mass, iw) > 0.0;
    bool fast = t.reach * t.reach * lowspeed::MDot(dxi, dxi, mass, iw) < n2;
    if (!(keeps && fast)) code[k] = kStick;
  }
}

bool SolveHolds(const mjModel* m, const Tables& t, State& s, const i64* rows, int n,
                const i64* code, f64* out) {
  int nv = m->nv, lda = 6 * t.ntbody;
  f64 dt = m->opt.timestep;
  const f64* u = s.mech_vec;
  // The held rows are those of the held bodies in order: h of them.
  int h = 0;
  for (int a = 0; a < n; a++) h += code[rows[a]] == kStick ? 6 : 0;
  if (h == 0) return true;
  // rhs = -J_S u / dt - A_S,all W (W: the reference for held rows, the given wrenches for the
  // others)
  f64* rhs = s.mech_vec + 2 * VecLen(m, t);
  int q = 0;
  for (int a = 0; a < n; a++) {
    if (code[rows[a]] != kStick) continue;
    for (int r0 = 0; r0 < 6; r0++, q++) {
      int r = 6 * a + r0;
      f64 acc = -RowDot(s.mech_J, r, u, nv) / dt;
      for (int a2 = 0; a2 < n; a2++) {
        bool held = code[rows[a2]] == kStick;
        for (int c0 = 0; c0 < 6; c0++) {
          f64 w = held ? Reference(t, s, rows[a2], c0) : out[6 * a2 + c0];
          acc -= s.mech_A[lda * r + 6 * a2 + c0] * w;
        }
      }
      rhs[q] = acc;
    }
  }
  f64* lhs = s.mech_S;
  i64* key = s.mech_hkey;
  bool same = key[0] == h;
  q = 0;
  for (int a = 0; a < n && same; a++) {
    if (code[rows[a]] != kStick) continue;
    for (int r0 = 0; r0 < 6 && same; r0++, q++) same = key[1 + q] == 6 * a + r0;
  }
  if (!same) {  // factor the held rows' block (kept while configuration and rows stay)
    int qr = 0;
    for (int a = 0; a < n; a++) {
      if (code[rows[a]] != kStick) continue;
      for (int r0 = 0; r0 < 6; r0++, qr++) {
        int qc = 0;
        for (int a2 = 0; a2 < n; a2++) {
          if (code[rows[a2]] != kStick) continue;
          for (int c0 = 0; c0 < 6; c0++, qc++) {
            lhs[lda * qr + qc] = s.mech_A[lda * (6 * a + r0) + 6 * a2 + c0];
          }
        }
      }
    }
    for (int j = 0; j < h; j++) lhs[lda * j + j] *= 1.0 + kHoldRegularisation;
    if (!Cholesky(lhs, lda, h, 1e-300)) {
      key[0] = -1;
      return false;
    }
    key[0] = h;
    qr = 0;
    for (int a = 0; a < n; a++) {
      if (code[rows[a]] != kStick) continue;
      for (int r0 = 0; r0 < 6; r0++) key[1 + qr++] = 6 * a + r0;
    }
  }
  ChoSolve(lhs, lda, h, rhs);
  q = 0;
  for (int a = 0; a < n; a++) {
    if (code[rows[a]] != kStick) continue;
    for (int r = 0; r < 6; r++) out[6 * a + r] = Reference(t, s, rows[a], r) + rhs[q++];
  }
  return true;
}

f64 HoldPower(const Tables& t, const State& s, int a, const f64* out, f64 dt, f64* xf) {
  int lda = 6 * t.ntbody;
  for (int r = 0; r < 6; r++) {
    f64 acc = 0.0;
    for (int c = 0; c < 6; c++) acc += s.mech_A[lda * (6 * a + r) + 6 * a + c] * out[6 * a + c];
    xf[r] = -dt * acc;
  }
  f64 hold = 0.0;
  for (int r = 0; r < 6; r++) hold -= out[6 * a + r] * xf[r];
  return hold;
}

int WorstHold(const mjModel* m, const mjData* d, const Tables& t, State& s, const i64* rows, int n,
              const i64* code, const f64* out, f64* slip) {
  f64 dt = m->opt.timestep;
  f64 xf[6], r_w[6];
  // 1. The hold that dissipates the most power is tested first: its shortfall bounds what the
  //    others' can be (below).
  int first = -1;
  f64 most = 0.0;
  for (int a = 0; a < n; a++) {
    if (code[rows[a]] != kStick) continue;
    f64 hold = HoldPower(t, s, a, out, dt, xf);
    if (hold > most) {
      first = a;
      most = hold;
    }
  }
  // 2. Then the others in order. A hold's shortfall is its power less the medium's, and the
  //    medium's resistance dissipates (RFT media are dissipative; mjrft warns at load of a
  //    material that is not, whose holds could then be released in another order), so a hold
  //    whose power is no more than the largest shortfall found cannot fall shorter: its
  //    resistance is not evaluated. Ties go to the lower index, as in a scan in index order.
  int worst = -1;
  f64 margin = 0.0;
  for (int i = -1; i < n; i++) {
    int a = i < 0 ? first : i;
    if (a < 0 || (i >= 0 && a == first) || code[rows[a]] != kStick) continue;
    f64 hold = HoldPower(t, s, a, out, dt, xf);
    if (!(hold > 0.0)) continue;  // the hold does nothing: nothing to supply
    if (worst >= 0 && hold <= margin) continue;
    Resistance(m, d, t, s, rows[a], xf, r_w);
    f64 medium = 0.0;
    for (int r = 0; r < 6; r++) medium -= r_w[r] * xf[r];
    f64 short_by = hold - medium - kRounding * (hold + std::fabs(medium));
    if (short_by > margin || (worst >= 0 && short_by == margin && a < worst)) {
      worst = a;
      margin = short_by;
      for (int r = 0; r < 6; r++) slip[r] = r_w[r];
    }
  }
  if (worst >= 0) {
    i64 k = rows[worst];
    i64 b = t.tbody_bodyid[k];
    f64 v[3];
    lowspeed::ComVelocity(d, t, k, v);
    f64 power = 0.0;
    for (int r = 0; r < 3; r++) power += slip[r] * v[r] + slip[3 + r] * d->cvel[6 * b + r];
    if (power > 0.0) {  // R would push along the present motion: the pure model instead
      EnsurePure(d, t, s, static_cast<int>(k));
      for (int r = 0; r < 6; r++) slip[r] = s.wrench[6 * b + r];
    }
  }
  return worst;
}

void Resistance(const mjModel* m, const mjData* d, const Tables& t, State& s, int k,
                const f64* twist, f64* out) {
  i64 b = t.tbody_bodyid[k];
  f64 size = BodySize(t, k);
  f64 key[19];
  f64 norm = 0.0;
  for (int r = 0; r < 6; r++) {
    f64 v = twist[r] * (r >= 3 ? size : 1.0);
    norm += v * v;
  }
  norm = std::sqrt(norm);
  for (int r = 0; r < 3; r++) key[r] = d->xipos[3 * b + r];
  for (int r = 0; r < 9; r++) key[3 + r] = d->ximat[9 * b + r] * size;
  for (int r = 0; r < 6; r++) key[12 + r] = twist[r] * (r >= 3 ? size : 1.0) / norm;
  key[18] = 1.0;
  f64* old = s.mech_key + 19 * k;
  bool same = old[18] == 1.0;
  for (int r = 0; r < 12 && same; r++) same = std::fabs(key[r] - old[r]) <= kResistanceReuseM;
  for (int r = 12; r < 18 && same; r++) same = std::fabs(key[r] - old[r]) <= kResistanceReuseRad;
  f64* stored = s.mech_R + 6 * k;
  if (same) {
    for (int r = 0; r < 6; r++) out[r] = stored[r];
    return;
  }
  // The resistance to starting to move: a rate-independent medium's depends on the direction
  // only; a dynamic term's (lambda rho_c (n.v)^2) is evaluated at a slow start, not at the
  // release velocity -dt A W, which a light leg's mobility makes arbitrarily fast.
  f64 slow[6];
  f64 scale =
      law::DynamicCoefficient(t.coef, t.ncoef) > 0.0 && norm > 0.0 ? kQuasiStaticSpeed / norm : 1.0;
  for (int r = 0; r < 6; r++) slow[r] = scale * twist[r];
  TwistWrench(m, d, t, s, k, slow, slow + 3, out, nullptr);
  for (int r = 0; r < 6; r++) stored[r] = out[r];
  for (int r = 0; r < 19; r++) old[r] = key[r];
}

f64 BodySize(const Tables& t, int k) {
  f64 size = 0.0;
  for (i64 g = t.tbody_geomadr[k]; g < t.tbody_geomadr[k] + t.tbody_geomnum[k]; g++) {
    size = std::max(size, t.tgeom_rbound[g]);
  }
  return size;
}

void TreatMechanisms(const mjModel* m, const mjData* d, const Tables& t, State& s) {
  int nv = m->nv, nk = t.ntbody;
  // 1. The loads: a repeated pass (mj_forward, then mj_step) reads what the first read.
  bool same_time = s.mech_time[1] == 1.0 && d->time == s.mech_time[0];
  bool valid = PredictorValid(m, d, s, same_time);
  if (!same_time) {
    for (int i = 0; i < nv; i++) {
      s.mech_in[i] = d->qacc[i];
      s.mech_in[nv + i] = s.mech_tau[i];
    }
    for (int i = 0; i < 6 * nk; i++) s.mech_in_prev[i] = s.mech_prev[i];
    for (int a = 0; a < m->nu; a++) s.mech_in_force[a] = d->actuator_force[a];
    for (int k = 0; k < nk; k++) s.mech_in_held[k] = s.mech_held[k];
  }
  // mech_held and mech_tau are dead from here to the end, where they are written: the bodies
  // in the medium (rows) live in mech_held meanwhile, and their decisions in s.decision.
  i64* rows = s.mech_held;
  i64* code = s.decision;
  int n = Gather(d, t, s, rows);
  if (n == 0 || nv == 0 || !(m->opt.timestep > 0.0) || !Setup(m, d, t, s, rows, n)) {
    for (int i = 0; i < nv; i++) s.mech_tau[i] = 0.0;
    for (int k = 0; k < nk; k++) {
      s.mech_held[k] = 0;
      EnsurePure(d, t, s, k);
    }
    return;
  }
  // 2. Which bodies keep the pure model (all of them where the loads cannot be predicted).
  for (int a = 0; a < n; a++) code[rows[a]] = kPure;
  if (valid) {
    Classify(m, d, t, s, rows, n, code);
  } else {
    for (int a = 0; a < n; a++) EnsurePure(d, t, s, static_cast<int>(rows[a]));
  }
  bool any = false;
  for (int a = 0; a < n; a++) any = any || code[rows[a]] == kStick;
  if (any) HoldSystem(m, t, s, n);
  // 3-4. Hold the others; release the worst-supplied hold on its resistance, and again.
  f64* out = s.mech_vec + VecLen(m, t);  // (n, 6): Classify is done with this row
  for (int a = 0; a < n; a++) {
    const f64* w = s.wrench + 6 * t.tbody_bodyid[rows[a]];
    for (int r = 0; r < 6; r++) out[6 * a + r] = w[r];
  }
  f64 slip[6];
  for (int iter = 0; iter < n + 1; iter++) {
    if (!SolveHolds(m, t, s, rows, n, code, out)) {
      for (int a = 0; a < n; a++) {  // not solvable: the pure model
        code[rows[a]] = kPure;
        EnsurePure(d, t, s, static_cast<int>(rows[a]));
        const f64* w = s.wrench + 6 * t.tbody_bodyid[rows[a]];
        for (int r = 0; r < 6; r++) out[6 * a + r] = w[r];
      }
      break;
    }
    int a = WorstHold(m, d, t, s, rows, n, code, out, slip);
    if (a < 0) break;
    code[rows[a]] = kSlip;
    for (int r = 0; r < 6; r++) out[6 * a + r] = slip[r];
  }
  // The bodies in the medium get out; those out of it feel their pure model.
  for (int a = 0; a < n; a++) s.lazy[rows[a]] = 0;
  for (int k = 0; k < nk; k++) EnsurePure(d, t, s, k);
  // What the field applies, in tests/field_reference.py's order of additions.
  for (int i = 0; i < nv; i++) s.mech_tau[i] = 0.0;
  for (int a = 0; a < n; a++) {
    for (int r = 0; r < 6; r++) {
      for (int j = 0; j < nv; j++) s.mech_tau[j] += s.mech_J[nv * (6 * a + r) + j] * out[6 * a + r];
    }
  }
  // The records, backwards: rows[a] >= a, so writing mech_held[rows[a]] (and clearing the slots
  // above it) never touches rows[0..a) still to be read.
  i64 above = nk;
  for (int a = n - 1; a >= 0; a--) {
    i64 k = rows[a];
    i64 b = t.tbody_bodyid[k];
    for (i64 q = k + 1; q < above; q++) s.mech_held[q] = 0;
    above = k;
    for (int r = 0; r < 6; r++) s.wrench[6 * b + r] = out[6 * a + r];
    i64 dec = code[k];
    s.slow[k] = dec != kPure;
    s.mech_held[k] = dec == kStick;
    if (dec == kStick) {
      for (int r = 0; r < 6; r++) s.mech_prev[6 * k + r] = out[6 * a + r];
      s.stats[3] += 1;
    } else if (dec == kSlip) {
      s.stats[4] += 1;
    }
  }
  for (i64 q = 0; q < above; q++) s.mech_held[q] = 0;
}

}  // namespace mjrft::mechanism
