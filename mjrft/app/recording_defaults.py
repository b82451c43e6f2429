"""Defaults of rerun recordings, in a module of their own so that the CLI can show them in
``mjrft run --help`` without importing rerun (``mjrft.app.viz`` imports it)."""

#: Default frame period [s] of simulated time: 100 frames per simulated second (``every`` = 10
#: steps at dt = 1 ms). A 10 s run of models/ellipsoid_pitch.xml then takes about 15 MB.
DEFAULT_FRAME_PERIOD_S = 0.01
#: Default maximum number of force arrows per body and frame.
DEFAULT_MAX_ARROWS = 400
#: Default top of the stress colour scale [Pa] (10 kPa = 1 N/cm^2). In 0.33 N/cm^3 glass beads
#: the ellipsoid and root rigs stay mostly below it (median 2-3 kPa, 99th percentile 8-15 kPa in
#: their runs); the plate rig reaches it about 3 cm deep (use a larger stress_max there).
DEFAULT_STRESS_MAX_PA = 1.0e4
#: gRPC address used by ``connect`` when none is given (rerun's default viewer port).
DEFAULT_CONNECT_URL = "rerun+http://127.0.0.1:9876/proxy"
