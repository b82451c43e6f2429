// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The sensor plugin mjrft.sensor: per intruder geom, what the medium did to it in this forward
// pass, as MuJoCo sensor data, so controllers, observations, recordings and mj_getState users
// read it like any sensor. One sensor per geom:
//
//   <extension><plugin plugin="mjrft.sensor"/></extension>
//   <sensor><plugin name="FL_rft" plugin="mjrft.sensor" objtype="geom" objname="FL"/></sensor>
//
// Its 7 values (kReadingSize): the RFT force [N] and the torque [N m] about the geom's centre
// (geom_xpos) applied to the geom, world frame, then its sinkage [m]: the local surface's
// height above the geom's lowest point (lowest.h; negative while the geom is above the surface).
// The force and torque are those the low-speed treatment applied: a body's applied wrench is
// shared among its geoms as the pure model's forces on them are (evenly among its geoms below
// the surface where no pure force acts: a body held at rest), so the readings of a body's
// geoms add up to the wrench its xfrc_applied row received (docs/mjcf.md, "Sensors").
//
// The readings are computed after the passive stage (needstage mjSTAGE_VEL), from the
// mjrft.granular instance of the same model, which every mjrft.sensor requires.

#ifndef MJRFT_ENGINE_SENSOR_H_
#define MJRFT_ENGINE_SENSOR_H_

#include "state.h"

namespace mjrft {

constexpr char kSensorPluginName[] = "mjrft.sensor";
constexpr int kReadingSize = 7;

// Sets out (kReadingSize) to the reading of tagged geom g (an index into tgeom_*) from the
// state of the last pass on d: each geom's pure wrench is what the pass's pure model added to
// its body's sum (s.geom_pure, written by PureWrenches), or, for a geom the pass did not
// evaluate (a body an RK4 stage keeps, or one the mechanism treatment held again without its
// pure model: mechanism.h), the sum of its element forces, computed here once.
void GeomReading(const mjModel* m, const mjData* d, const Tables& t, State& s, int g,
                 f64 out[kReadingSize]);

// Registers mjrft.sensor with MuJoCo (once per process).
void RegisterSensor();

}  // namespace mjrft

#endif  // MJRFT_ENGINE_SENSOR_H_
