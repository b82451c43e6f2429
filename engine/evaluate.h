// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The RFT model on tagged bodies: the state check, culling by bounding spheres, and wrenches at
// a twist. World frame; wrenches are force [N] then torque [N m] about the body's CoM (xipos).

#ifndef MJRFT_ENGINE_EVALUATE_H_
#define MJRFT_ENGINE_EVALUATE_H_

#include "state.h"

namespace mjrft {

// Index k of the first tagged body with a non-finite position or velocity, or -1.
int FirstBadBody(const mjModel* m, const mjData* d, const Tables& t);

// An upper bound [m] of the surface height under tagged geom g's bounding sphere.
f64 GeomTop(const mjData* d, const Tables& t, const State& s, int g);

// True if tagged geom g's bounding sphere cannot touch the medium (above the surface or
// outside the region). A radius of 0 never culls.
bool Culled(const mjData* d, const Tables& t, const State& s, int g);

// Sets out (6) to the RFT wrench on tagged body k's geoms in play (not culled this pass), the
// body moving with the twist (v (3) at the CoM [m/s], omega (3) [rad/s]); its element forces
// are not kept. Returns #evaluated; acting (if not null) gets #acting.
int TwistWrench(const mjModel* m, const mjData* d, const Tables& t, State& s, int k, const f64* v,
                const f64* omega, f64* out, int* acting);

// True if a geom of tagged body k may touch the medium this pass.
bool InPlay(const Tables& t, const State& s, int k);

// The pure model on tagged body k's geoms in play: adds it to the body's s.wrench row, and
// writes each geom's share (s.geom_pure) and its element forces (s.elem_force); clears
// s.lazy[k]. Returns #evaluated; acting (if not null) grows by #acting.
int BodyPure(const mjData* d, const Tables& t, State& s, int k, int* acting);

// The pure model on every tagged body that neither keeps nor freezes its wrench this pass:
// culls geoms (s.cull), zeroes element forces of geoms that left the medium, writes s.wrench
// rows and s.elem_force. With defer_held, a mechanism body held at the last pass
// (mechanism::HeldBefore) is left at zero and marked s.lazy: the mechanism treatment holds it
// again and evaluates it only where its pure model is needed. Returns #evaluated; acting gets
// #acting.
int PureWrenches(const mjModel* m, const mjData* d, const Tables& t, State& s, int* acting,
                 bool defer_held);

}  // namespace mjrft

#endif  // MJRFT_ENGINE_EVALUATE_H_
