// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.

#include "lowspeed.h"

#include <cmath>

#include "evaluate.h"

namespace mjrft::lowspeed {

f64 MDot(const f64* a, const f64* b, f64 mass, const f64* iw) {
  f64 s = mass * (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) s += a[3 + r] * iw[3 * r + c] * b[3 + c];
  }
  return s;
}

void Solve6(f64* a, f64* rhs, f64* x) {
  const int n = 6;
  for (int k = 0; k < n; k++) {
    int p = k;
    for (int r = k + 1; r < n; r++) {
      if (std::fabs(a[n * r + k]) > std::fabs(a[n * p + k])) p = r;
    }
    if (p != k) {
      for (int c = 0; c < n; c++) {
        f64 tmp = a[n * k + c];
        a[n * k + c] = a[n * p + c];
        a[n * p + c] = tmp;
      }
      f64 tmp = rhs[k];
      rhs[k] = rhs[p];
      rhs[p] = tmp;
    }
    for (int r = k + 1; r < n; r++) {
      f64 f = a[n * r + k] / a[n * k + k];
      for (int c = k; c < n; c++) a[n * r + c] -= f * a[n * k + c];
      rhs[r] -= f * rhs[k];
    }
  }
  for (int k = n - 1; k >= 0; k--) {
    f64 s = rhs[k];
    for (int c = k + 1; c < n; c++) s -= a[n * k + c] * x[c];
    x[k] = s / a[n * k + k];
  }
}

void Mv(const f64* a, int rows, int cols, const f64* x, f64* y) {
  for (int r = 0; r < rows; r++) {
    f64 acc = 0.0;
    for (int c = 0; c < cols; c++) acc += a[cols * r + c] * x[c];
    y[r] = acc;
  }
}

f64 Dot(const f64* x, const f64* y, int n) {
  f64 acc = 0.0;
  for (int c = 0; c < n; c++) acc += x[c] * y[c];
  return acc;
}

f64 StepWork(const f64* w, const f64* twist, const f64* end, const f64* other, f64 mass, f64 dt,
             bool semi) {
  f64 p = 0.0;
  for (int c = 0; c < 6; c++) p += w[c] * (twist[c] + end[c]);
  if (semi) {
    f64 q = 0.0;
    for (int c = 0; c < 3; c++) q += other[c] * (other[c] + w[c]);
    p -= dt * q / mass;
  }
  return p;
}

f64 StickFraction(const f64* stick, const f64* twist, const f64* other, f64 mass, f64 n2, f64 dt,
                  bool semi) {
  // The balance's terms cancel: rounding counts as zero (kRounding).
  f64 size = 0.0;
  for (int c = 0; c < 6; c++) size += std::fabs(stick[c] * twist[c]);
  if (semi) {
    for (int c = 0; c < 3; c++) {
      size += dt * std::fabs(other[c]) * (std::fabs(other[c]) + std::fabs(stick[c])) / mass;
    }
  }
  const f64 zero[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  if (StepWork(stick, twist, zero, other, mass, dt, semi) <= kRounding * size) return 1.0;
  f64 a2 = n2 / dt;
  f64 b1 = -a2;
  f64 c0 = 0.0;
  for (int c = 0; c < 6; c++) b1 += stick[c] * twist[c];
  if (semi) {
    for (int c = 0; c < 3; c++) {
      b1 -= dt * other[c] * stick[c] / mass;
      c0 -= dt * other[c] * other[c] / mass;
    }
  }
  f64 root = std::sqrt(b1 * b1 - 4.0 * a2 * c0);
  f64 lam = b1 > 0.0 ? -2.0 * c0 / (b1 + root) : (root - b1) / (2.0 * a2);
  // Python's max(lam, 0.0) and min(., 1.0): a NaN passes through.
  lam = 0.0 > lam ? 0.0 : lam;
  return 1.0 < lam ? 1.0 : lam;
}

void TransverseBasis(const f64* twist, f64 mass, const f64* iw, const f64* mm, f64 n, f64* basis) {
  for (int c = 0; c < 6; c++) basis[c] = twist[c] / n;
  // best stays 0 only if every remainder is NaN (the reference leaves it unset then).
  f64 axis[6], res[6], best[6] = {0.0};
  for (int k = 1; k < 6; k++) {
    f64 best_n = -1.0;
    for (int j = 0; j < 6; j++) {
      for (int c = 0; c < 6; c++) axis[c] = 0.0;
      axis[j] = 1.0 / std::sqrt(mm[6 * j + j]);
      for (int c = 0; c < 6; c++) res[c] = axis[c];
      for (int q = 0; q < k; q++) {
        f64 proj = MDot(basis + 6 * q, axis, mass, iw);
        for (int c = 0; c < 6; c++) res[c] -= proj * basis[6 * q + c];
      }
      f64 rn2 = MDot(res, res, mass, iw);
      f64 rn = std::sqrt(0.0 > rn2 ? 0.0 : rn2);
      if (rn > best_n) {
        best_n = rn;
        for (int c = 0; c < 6; c++) best[c] = res[c];
      }
    }
    for (int c = 0; c < 6; c++) basis[6 * k + c] = best[c] / best_n;
  }
}

void WorldInertia(const f64* x, const f64* inertia, f64* iw, f64* ii) {
  for (int r = 0; r < 3; r++) {
    for (int c = 0; c < 3; c++) {
      f64 a = 0.0;
      f64 ai = 0.0;
      for (int q = 0; q < 3; q++) {
        a += x[3 * r + q] * inertia[q] * x[3 * c + q];
        ai += x[3 * r + q] * x[3 * c + q] / inertia[q];
      }
      iw[3 * r + c] = a;
      ii[3 * r + c] = ai;
    }
  }
}

void PointVelocity(const mjData* d, const Tables& t, int k, const f64* p, f64* v) {
  const f64* cvel = d->cvel + 6 * t.tbody_bodyid[k];
  const f64* om = cvel;
  const f64* c0 = d->subtree_com + 3 * t.tbody_rootid[k];
  f64 rx = p[0] - c0[0], ry = p[1] - c0[1], rz = p[2] - c0[2];
  v[0] = cvel[3] + om[1] * rz - om[2] * ry;
  v[1] = cvel[4] + om[2] * rx - om[0] * rz;
  v[2] = cvel[5] + om[0] * ry - om[1] * rx;
}

void ComVelocity(const mjData* d, const Tables& t, int k, f64* v) {
  PointVelocity(d, t, k, d->xipos + 3 * t.tbody_bodyid[k], v);
}

void Gravity(const mjModel* m, int b, f64* g) {
  for (int c = 0; c < 3; c++) g[c] = 0.0;
  if (m->opt.disableflags & mjDSBL_GRAVITY) return;
  f64 comp = m->body_gravcomp[b];
  for (int c = 0; c < 3; c++) g[c] = m->opt.gravity[c] * (1.0 - comp);
}

bool HasInertia(const mjModel* m, int b) {
  const f64* inertia = m->body_inertia + 3 * b;
  return m->body_mass[b] > 0.0 && inertia[0] > 0.0 && inertia[1] > 0.0 && inertia[2] > 0.0;
}

void FreeBodyTerms(const mjModel* m, const mjData* d, const Tables& t, int k, const f64* user,
                   Body* body, f64* gvec) {
  int b = static_cast<int>(t.tbody_bodyid[k]);
  f64 mass = m->body_mass[b];
  Gravity(m, b, gvec);
  WorldInertia(d->ximat + 9 * b, m->body_inertia + 3 * b, body->iw, body->ii);
  const f64* om = d->cvel + 6 * b;
  f64 v[3], iom[3];
  ComVelocity(d, t, k, v);
  Mv(body->iw, 3, 3, om, iom);
  for (int c = 0; c < 3; c++) {
    body->twist[c] = v[c];
    body->twist[3 + c] = om[c];
    body->other[c] = mass * gvec[c] + user[c];
  }
  // The gyroscopic torque -omega x I omega.
  body->other[3] = user[3] - (om[1] * iom[2] - om[2] * iom[1]);
  body->other[4] = user[4] - (om[2] * iom[0] - om[0] * iom[2]);
  body->other[5] = user[5] - (om[0] * iom[1] - om[1] * iom[0]);
  body->mass = mass;
}

// end (6) = twist + dt M^-1 (other + w): the explicit step's end twist with the wrench w (6).
static void EndTwist(const Body& body, const f64* w, f64 dt, f64* end) {
  f64 tau[3], ang[3];
  for (int c = 0; c < 3; c++) tau[c] = body.other[3 + c] + w[3 + c];
  Mv(body.ii, 3, 3, tau, ang);
  for (int c = 0; c < 3; c++) {
    end[c] = body.twist[c] + dt * (body.other[c] + w[c]) / body.mass;
    end[3 + c] = body.twist[3 + c] + dt * ang[c];
  }
}

bool AddsNoEnergy(const f64* w, const Body& body, f64 dt, bool semi) {
  f64 end[6];
  EndTwist(body, w, dt, end);
  f64 size = 0.0;
  for (int c = 0; c < 6; c++) {
    size += std::fabs(w[c]) * (std::fabs(body.twist[c]) + std::fabs(end[c]));
  }
  if (semi) {
    for (int c = 0; c < 3; c++) {
      const f64 o = std::fabs(body.other[c]);
      size += dt * o * (o + std::fabs(w[c])) / body.mass;
    }
  }
  return StepWork(w, body.twist, end, body.other, body.mass, dt, semi) <= kRounding * size;
}

bool ImplicitWrench(const mjModel* m, const mjData* d, const Tables& t, State& s, int k,
                    const Body& body, f64 dt, bool semi, f64* w) {
  const f64* twist = body.twist;
  const f64 mass = body.mass;
  const f64* iw = body.iw;
  // The body's 6x6 inertia M.
  f64 mm[36] = {0.0};
  for (int c = 0; c < 3; c++) {
    mm[6 * c + c] = mass;
    for (int r = 0; r < 3; r++) mm[6 * (3 + r) + 3 + c] = iw[3 * r + c];
  }
  f64 n = std::sqrt(MDot(twist, twist, mass, iw));
  f64 basis[36];
  TransverseBasis(twist, mass, iw, mm, n, basis);

  // J from secants along the transverse directions: J = sum_q (W(xi + h e_q) - W(xi)) / h
  // (M e_q)^T, the e_q M-orthonormal.
  f64 h = t.jacobian_step * n;
  f64 jac[36] = {0.0};
  f64 probe[6], pw[6], mu[6];
  for (int q = 1; q < 6; q++) {
    for (int c = 0; c < 6; c++) probe[c] = twist[c] + h * basis[6 * q + c];
    TwistWrench(m, d, t, s, k, probe, probe + 3, pw, nullptr);
    Mv(mm, 6, 6, basis + 6 * q, mu);
    for (int r = 0; r < 6; r++) {
      f64 dw = (pw[r] - w[r]) / h;
      for (int c = 0; c < 6; c++) jac[6 * r + c] += dw * mu[c];
    }
  }

  // Linearise at c xi, c = |xi_e|_M / |xi|_M with xi_e the explicit step's end.
  f64 end_pure[6];
  EndTwist(body, w, dt, end_pure);
  f64 e2 = MDot(end_pure, end_pure, mass, iw);
  f64 cs = std::sqrt(0.0 > e2 ? 0.0 : e2) / n;
  if (!(cs > 0.0)) return false;
  for (int i = 0; i < 36; i++) jac[i] /= cs;

  // (M - dt J') d = M (xi_e - c xi); f = W(xi) + J' d.
  f64 a[36], diff[6], rhs[6], d_xi[6], jd[6], f[6];
  for (int i = 0; i < 36; i++) a[i] = mm[i] - dt * jac[i];
  for (int c = 0; c < 6; c++) diff[c] = end_pure[c] - cs * twist[c];
  Mv(mm, 6, 6, diff, rhs);
  Solve6(a, rhs, d_xi);
  Mv(jac, 6, 6, d_xi, jd);
  for (int c = 0; c < 6; c++) {
    f[c] = w[c] + jd[c];
    if (!std::isfinite(f[c])) return false;
  }

  // Guards: the motion keeps its sense, no energy added over the step.
  f64 end[6];
  EndTwist(body, f, dt, end);
  if (MDot(end, twist, mass, iw) <= 0.0) return false;
  if (StepWork(f, twist, end, body.other, mass, dt, semi) > 0.0) return false;
  for (int c = 0; c < 6; c++) w[c] = f[c];
  return true;
}

i64 StickOrSlip(const mjModel* m, const mjData* d, const Tables& t, State& s, int k,
                const Body& body, const f64* v_free, const f64* om_free, f64 dt, bool semi, f64* w,
                bool keeps) {
  const f64 mass = body.mass;
  f64 iomf[3];
  Mv(body.iw, 3, 3, om_free, iomf);
  f64 n2 = mass * Dot(v_free, v_free, 3) + Dot(om_free, iomf, 3);
  if (n2 > 0.0) {
    // R = W(xi_free): slip on it if it cannot stop the free motion within the step.
    f64 rw[6];
    TwistWrench(m, d, t, s, k, v_free, om_free, rw, nullptr);
    f64 diss = -(rw[0] * v_free[0] + rw[1] * v_free[1] + rw[2] * v_free[2]);
    diss -= rw[3] * om_free[0] + rw[4] * om_free[1] + rw[5] * om_free[2];
    if (dt * diss < n2) {
      f64 dom[3], end[6];
      Mv(body.ii, 3, 3, rw + 3, dom);
      for (int c = 0; c < 3; c++) {
        end[c] = v_free[c] + dt * rw[c] / mass;
        end[3 + c] = om_free[c] + dt * dom[c];
      }
      if (StepWork(rw, body.twist, end, body.other, mass, dt, semi) <= 0.0) {
        for (int c = 0; c < 6; c++) w[c] = rw[c];
        return kSlip;
      }
      if (keeps && AddsNoEnergy(w, body, dt, semi)) return kPure;
    }
  }
  // Stick: the body ends the step at rest (or the largest fraction of that adding no energy).
  for (int c = 0; c < 3; c++) {
    w[c] = -mass * v_free[c] / dt;
    w[3 + c] = -iomf[c] / dt;
  }
  f64 lam = StickFraction(w, body.twist, body.other, mass, n2, dt, semi);
  for (int c = 0; c < 6; c++) w[c] *= lam;
  return kStick;
}

i64 TreatBody(const mjModel* m, const mjData* d, const Tables& t, State& s, int k, const f64* user,
              f64 dt, bool semi, f64* w, f64* ab, f64* tw) {
  int b = static_cast<int>(t.tbody_bodyid[k]);
  if (!HasInertia(m, b)) return kPure;
  const f64 reach = t.reach;
  Body body;
  f64 gvec[3];
  FreeBodyTerms(m, d, t, k, user, &body, gvec);
  const f64 mass = body.mass;
  const f64* v = body.twist;
  const f64* om = body.twist + 3;
  for (int c = 0; c < 6; c++) tw[c] = body.twist[c];

  // The free motion's end twist and the pure wrench's angular change over the step.
  f64 iom[3], itau[3], iw_ang[3], v_free[3], om_free[3], dom_pure[3];
  Mv(body.iw, 3, 3, om, iom);
  Mv(body.ii, 3, 3, body.other + 3, itau);
  Mv(body.ii, 3, 3, w + 3, iw_ang);
  for (int c = 0; c < 3; c++) {
    v_free[c] = v[c] + dt * (gvec[c] + user[c] / mass);
    om_free[c] = om[c] + dt * itau[c];
    dom_pure[c] = dt * iw_ang[c];
  }

  // <probe, xi>_M = |xi|^2_M + reach <d_xi, xi>_M, d_xi the predicted change over the step.
  f64 sq = mass * Dot(v, v, 3) + Dot(om, iom, 3);
  f64 dxi = 0.0;
  for (int c = 0; c < 3; c++) dxi += (v_free[c] - v[c] + dt * w[c] / mass) * mass * v[c];
  f64 dom[3];
  for (int c = 0; c < 3; c++) dom[c] = om_free[c] - om[c] + dom_pure[c];
  dxi += Dot(dom, iom, 3);
  ab[0] = sq;
  ab[1] = dxi;

  if (sq + reach * dxi > 0.0) {
    // Stiff across the motion: (reach dt)^2 |M^-1 W|^2_M >= |xi|^2_M.
    f64 wn2 = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) / mass + Dot(w + 3, iw_ang, 3);
    f64 rdt = reach * dt;
    bool fast = rdt * rdt * wn2 < sq;
    if ((fast || !(t.jacobian_step > 0.0)) && AddsNoEnergy(w, body, dt, semi)) return kPure;
    if (t.jacobian_step > 0.0 && ImplicitWrench(m, d, t, s, k, body, dt, semi, w)) {
      return kImplicit;
    }
    // Implicitly the motion would reverse within the step (or gain work): decide below.
  }
  return StickOrSlip(m, d, t, s, k, body, v_free, om_free, dt, semi, w, sq + dxi > 0.0);
}

void TreatAll(const mjModel* m, const mjData* d, const Tables& t, State& s, const f64* user) {
  const f64 dt = m->opt.timestep;
  const bool semi = m->opt.integrator != mjINT_RK4;
  for (int k = 0; k < t.ntbody; k++) {
    i64 b = t.tbody_bodyid[k];
    s.slow[k] = 0;
    if (!t.tbody_treat[k] || !(dt > 0.0)) continue;
    // Nothing of the body can touch the medium: nothing to treat.
    if (!InPlay(t, s, k)) continue;
    f64 ab[2] = {0.0, 0.0};
    f64* w = s.wrench + 6 * b;
    f64* frozen = s.frozen + 12 * k;
    f64 pure[6];
    for (int c = 0; c < 6; c++) pure[c] = w[c];
    i64 dec = TreatBody(m, d, t, s, k, user + 6 * b, dt, semi, w, ab, frozen);
    // Only a body moved by the implicit step keeps a record.
    for (int c = 0; c < 6; c++) {
      frozen[6 + c] = dec == kImplicit ? w[c] - pure[c] : 0.0;
      if (dec != kImplicit) frozen[c] = 0.0;
    }
    s.decision[k] = dec;
    s.slow[k] = dec != kPure || ab[0] + t.rk4_hold_steps * ab[1] <= 0.0;
    if (dec != kPure) s.stats[kStatOf[dec]] += 1;
  }
}

}  // namespace mjrft::lowspeed
