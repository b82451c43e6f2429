// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Every array of the engine, declared once: name, element type, shape and meaning. The structs
// of tables.h and state.h are generated from these lists, and so are the plugin's allocation of
// them (granular.cc) and the Python bridge of the tests (tests/engine_bridge.py parses this
// file), so a new array is one line here.
//
// Shapes are row-major, in the sizes of Tables (nelem, ntgeom, ntbody, ...) and of mjModel
// (nbody, nv, nu). Element types: f64 (mjtNum) and i64 (int64_t).
//
// World frame unless a line says "body frame"; wrenches are force [N] then torque [N m] about
// the body's centre of mass (xipos).

#ifndef MJRFT_ENGINE_FIELDS_H_
#define MJRFT_ENGINE_FIELDS_H_

// Sizes of the static tables (int64).
#define MJRFT_TABLE_SIZES(X)                                                      \
  X(nelem)        /* surface triangles (elements) of all tagged geoms */          \
  X(ntgeom)       /* tagged geoms */                                              \
  X(ntbody)       /* tagged bodies (bodies with at least one tagged geom) */      \
  X(surface_nrow) /* rows of surface_grid (1 for a flat or plane surface) */      \
  X(surface_ncol) /* columns of surface_grid */                                   \
  X(ncoef)        /* length of coef (18 Treers, 19 with the dynamic term, ...) */ \
  X(nvert)        /* rows of elem_vert: nelem with a deforming ground, else 1 */  \
  X(nsoil)        /* size of the soil block (1 without a deforming ground) */     \
  X(nwatch)       /* geoms checked for sinking without being intruders (watch.h) */

// Scalars of the static tables: X(type, name, meaning).
#define MJRFT_TABLE_SCALARS(X)                                        \
  X(f64, surface_z, "free-surface height [m], world frame")           \
  X(i64, use_region, "1 if region bounds the medium")                 \
  X(f64, zeta, "scale of the medium [N/m^3]")                         \
  X(f64, alpha_y, "generic out-of-plane coefficient")                 \
  X(i64, treat, "1 if the low-speed treatment is on")                 \
  X(f64, reach, "the treatment's reach")                              \
  X(f64, jacobian_step, "the treatment's finite-difference step")     \
  X(f64, rk4_hold_steps, "RK4 hold length (lowspeed.RK4_HOLD_STEPS)") \
  X(i64, mech, "1 if the treatment acts on bodies in mechanisms")     \
  X(i64, soil, "1 if the surface deforms (kind SOIL)")

// Arrays of the static tables: X(type, name, shape, meaning).
#define MJRFT_TABLE_ARRAYS(X)                                                          \
  X(f64, elem_pos, nelem * 3, "triangle centroids [m], body frame")                    \
  X(f64, elem_normal, nelem * 3, "outward unit normals, body frame")                   \
  X(f64, elem_area, nelem, "areas [m^2]")                                              \
  X(i64, tgeom_geomid, ntgeom, "MuJoCo geom id of each tagged geom")                   \
  X(i64, tgeom_tbody, ntgeom, "its tagged body (index into tbody_*)")                  \
  X(i64, tgeom_elemadr, ntgeom, "first element")                                       \
  X(i64, tgeom_elemnum, ntgeom, "number of elements")                                  \
  X(f64, tgeom_rbound, ntgeom, "bounding-sphere radius [m] (0: never culled)")         \
  X(i64, tbody_bodyid, ntbody, "MuJoCo body id of each tagged body")                   \
  X(i64, tbody_rootid, ntbody, "its root body (cvel's reference point)")               \
  X(i64, tbody_geomadr, ntbody, "first tagged geom")                                   \
  X(i64, tbody_geomnum, ntbody, "number of tagged geoms")                              \
  X(i64, tbody_treat, ntbody, "1 if the low-speed treatment may act on it")            \
  X(f64, region, 2 * 3, "world box [m]: min corner, max corner")                       \
  X(f64, coef, ncoef, "kernel coefficients (Material.kernel_coefficients)")            \
  X(i64, tbody_mech, ntbody, "1 if it is a body in a mechanism")                       \
  X(i64, tbody_dofmask, ntbody* nv, "1 where dof j moves tagged body k")               \
  X(i64, actuator_affine, nu, "1: gain fixed/affine, bias none/affine, not actearly")  \
  X(i64, actuator_gainaffine, nu, "1 if its gain is affine (else fixed)")              \
  X(i64, actuator_biasaffine, nu, "1 if its bias is affine (else none)")               \
  X(i64, actuator_actadr, nu, "its activation's address in act (-1: input is ctrl)")   \
  X(i64, actuator_ctrllimited, nu, "1 if its control is clamped")                      \
  X(i64, actuator_forcelimited, nu, "1 if its force is clamped")                       \
  X(f64, surface_prm, kPrmSize, "the free surface (surface.h)")                        \
  X(f64, surface_grid, surface_nrow* surface_ncol, "grid heights [m], world frame")    \
  X(f64, elem_vert, nvert * 9, "triangle vertices [m], body frame (deforming ground)") \
  X(f64, elem_reach, nelem, "largest centroid-corner distance [m]")                    \
  X(f64, elem_patch, nelem* kPatchSize, "corner offsets and normals, body frame")      \
  X(i64, watch_geomid, nwatch, "MuJoCo geom id of each geom checked for sinking")

// The engine's state for one mjData: X(type, name, size, meaning); size is an expression in nbody,
// nv, nu (mjModel), nelem, ng = ntgeom, nk = ntbody, nsoil (Tables), and soil_nrow, soil_ncol
// (surface_nrow and surface_ncol with a deforming ground, else 1). Persistent arrays carry from
// pass to pass and live in mjData.plugin_state (so mj_copyData, mj_resetData, mj_getState and
// mj_setState carry them; i64 values are stored bit for bit in their 8-byte slots); work arrays
// live in the instance's plugin_data.
#define MJRFT_STATE_PERSISTENT(X)                                                              \
  X(f64, user, nbody * 6, "user part of each tagged row of xfrc_applied")                      \
  X(f64, written, nbody * 6, "what the last installed pass wrote there")                       \
  X(f64, wrench, nbody * 6, "this pass's RFT wrench (held rows: stage 1's)")                   \
  X(f64, rk4, kRk4Head + kRk4Body * nk, "the RK4 stage record (rk4.h)")                        \
  X(i64, geom_dirty, ng, "1 where elem_force may be nonzero")                                  \
  X(i64, decision, nk, "the treatment's decisions (lowspeed.h)")                               \
  X(i64, stats, kNStats, "work counters: calls, evaluated, acting, stuck, slipping, implicit") \
  X(i64, status, 1, "status of the last pass (forward.h)")                                     \
  X(f64, mech_tau, nv, "generalized force the last pass applied to mechanism bodies")          \
  X(f64, mech_time, 3, "time of the last installed pass, 1 once seen, 1 if predictor ok")      \
  X(f64, mech_prev, nk * 6, "wrench of each body held in the last pass")                       \
  X(i64, mech_held, nk, "1 if held in the last pass")                                          \
  X(f64, mech_in, 2 * nv, "qacc and mech_tau as the first pass at this time read them")        \
  X(f64, mech_in_prev, nk * 6, "mech_prev as that pass read it")                               \
  X(f64, mech_in_force, nu, "actuator_force as that pass read it")                             \
  X(i64, mech_in_held, nk, "mech_held as that pass read it")                                   \
  X(f64, mech_R, nk * 6, "the medium's resistance last evaluated for a hold")                  \
  X(f64, mech_key, nk * 19, "where R was evaluated: CoM, inertial frame, direction, valid")    \
  X(f64, soil_stats, kNSoilStats, "ground counters (soil.h)")                                  \
  X(f64, soil, nsoil, "the deforming ground's block (surface.h)")

#define MJRFT_STATE_WORK(X)                                                                 \
  X(f64, user_in, nbody * 6, "other applied wrenches for the explicit path")                \
  X(f64, xfrc_last, nbody * 6, "what the last installed pass wrote into this xfrc_applied") \
  X(f64, elem_force, nelem * 3, "element forces of this pass's pure model [N]")             \
  X(i64, cull, ng, "1 where the geom cannot touch the medium this pass")                    \
  X(i64, keep, nk, "1: keeps its RK4 step's first-stage wrench")                            \
  X(i64, frz, nk, "1: feels the model with stage 1's twist")                                \
  X(i64, slow, nk, "1: later RK4 stages must not evaluate the pure model")                  \
  X(i64, lazy, nk, "1: its pure model deferred this pass (mechanism::HeldBefore)")          \
  X(f64, frozen, nk * 12, "stage 1's twist and implicit correction")                        \
  X(f64, mech_M, nv* nv, "cache: M of the configuration the factors belong to")             \
  X(f64, mech_cfg, 1 + nk + 6 * nv + 6 * nk, "cache: that configuration (-1: none)")        \
  X(i64, mech_hkey, 1 + 6 * nk, "cache: held rows of mech_S (-1 none, -2 no mech_A)")       \
  X(f64, mech_L, nv* nv, "work: M, then its Cholesky factor")                               \
  X(f64, mech_J, 6 * nk * nv, "work: Jacobians of the bodies in play")                      \
  X(f64, mech_X, 6 * nk * nv, "work: rows of L^-1 J^T")                                     \
  X(f64, mech_A, 36 * nk * nk, "work: J M^-1 J^T")                                          \
  X(f64, mech_S, 36 * nk * nk, "work: the held bodies' block, factored")                    \
  X(f64, mech_vec, 3 * (nv > 6 * nk ? nv : 6 * nk), "work vectors (3 rows)")                \
  X(f64, soil_floor, soil_nrow* soil_ncol, "work: intruders' lowest point per vertex [m]")  \
  X(i64, soil_owner, soil_nrow* soil_ncol, "work: the tagged body over it, -1 none")        \
  X(i64, soil_queue, soil_nrow* soil_ncol, "work: the relaxation's queue of vertices")      \
  X(f64, soil_box, (3 * nk + 4) * 4, "work: vertex boxes of footprints, the relaxation's")  \
  X(i64, watch_told, nwatch, "1 once the geom's sinking was reported (watch.h)")            \
  X(f64, geom_pure, ng * 6, "work: pure wrench per geom about its body's CoM (sensor.h)")   \
  X(i64, geom_pure_pass, ng, "work: the pass (pass[0]) geom_pure[g] was computed in")       \
  X(i64, pass, 1, "work: passes run on this mjData (the clock of elem_depth)")              \
  X(f64, elem_depth, nelem * 4, "work: depth of each centroid, then its corners [m]")       \
  X(i64, elem_depth_pass, nelem * 2, "work: the pass they hold (centroid, corners; -1 none)")

#define MJRFT_STATE_ARRAYS(X) MJRFT_STATE_PERSISTENT(X) MJRFT_STATE_WORK(X)

#endif  // MJRFT_ENGINE_FIELDS_H_
