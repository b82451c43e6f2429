"""The C++ deforming ground (engine/soil.cc, engine/deform.cc) against the numba one
(mjrft.core.soil, mjrft.field.deform): bit for bit, on real scenes and on random grids.

Along a run of each scene, before every step, the ground is brought to the step's configuration
as the numba pass would (``deform.due`` at the step's first pass, never in a held RK4 stage): the
numba ``deform.update`` runs on the field's own state and the C++ ``deform::Update`` on a
Bridge copy taken just before, and the soil block, the counters, the footprint boxes, floors and
owners and the returned body must be equal. The field's installed pass then takes the step (its
own update finds the ground already done at that time).
"""

import ctypes

import mujoco
import numpy as np
import pytest
from engine_bridge import Bridge, library

import mjrft
from mjrft.core import soil, surface
from mjrft.field import deform
from mjrft.field.numba_field import GranularField, load_plain

F8P = np.ctypeslib.ndpointer(np.float64, flags="C_CONTIGUOUS")
I8P = np.ctypeslib.ndpointer(np.int64, flags="C_CONTIGUOUS")
#: The work arrays compared after an update. soil_queue is left out: the C++ deposition keeps
#: the rim's weights there (numba allocates them), and the relaxation reads only what it wrote.
COMPARED = ("soil", "soil_stats", "soil_box", "soil_floor", "soil_owner")


@pytest.fixture(scope="module")
def lib():
    out = library()
    ptrs = [ctypes.c_void_p] * 4
    out.mjrft_test_deform_due.argtypes = ptrs
    out.mjrft_test_deform_update.argtypes = ptrs
    i8, f8 = ctypes.c_int64, ctypes.c_double
    out.mjrft_test_soil_excavate.argtypes = [F8P, F8P, F8P, F8P, I8P, F8P, i8, F8P, f8, F8P, F8P]
    out.mjrft_test_soil_excavate.restype = None
    out.mjrft_test_soil_deposit.argtypes = [F8P, F8P, F8P, F8P, I8P, F8P, i8, f8, f8, f8, F8P,
                                            F8P, I8P]  # fmt: skip
    out.mjrft_test_soil_deposit.restype = None
    out.mjrft_test_soil_relax.argtypes = [F8P, F8P, F8P, F8P, I8P, I8P, F8P, F8P, F8P]
    out.mjrft_test_soil_footprint.argtypes = [F8P, F8P, i8, i8, F8P, F8P, i8, F8P, I8P, F8P, f8]
    out.mjrft_test_soil_finish.argtypes = [F8P, F8P, F8P, F8P, I8P, F8P, f8]
    out.mjrft_test_soil_finish.restype = None
    return out


def due(field, d, block) -> bool:
    """mjrft.field.deform.due, read in Python (it is inlined into the numba pass)."""
    t, last = d.time, block[surface.SOIL_TIME]
    if block[surface.SOIL_DONE] == 0.0 or t < last:
        return True
    every = field._tables.arrays.surface_prm[surface.EVERY]
    if every <= 1.0:
        return last != t
    return t - last > (every - 0.5) * field.model.opt.timestep


class Checker:
    """Runs both updates before each step and counts what was compared."""

    def __init__(self, lib, m, f, d) -> None:
        self.lib, self.m, self.f, self.d = lib, m, f, d
        self.updates = 0
        self.bad = []

    def check(self) -> None:
        m, f, d = self.m, self.f, self.d
        # The step's first pass sees the kinematics of its configuration (what mj_step's
        # forward computes before the field's pass), without running the field's pass.
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_comVel(m, d)
        st = f._states.of(d)
        br = Bridge(f, d)
        expect = due(f, d, st.userdata)
        assert bool(self.lib.mjrft_test_deform_due(*br.pointers(m, d))) == expect
        if not expect:
            return
        got = self.lib.mjrft_test_deform_update(*br.pointers(m, d))
        want = deform.update(f._tables.address, st.address)
        assert got == want
        for name in COMPARED:
            ref = st.userdata if name == "soil" else getattr(st.arrays, name)
            np.testing.assert_array_equal(br.arrays[name], ref, err_msg=f"{name} at t={d.time}")
        self.updates += 1
        if want >= 0:
            self.bad.append(want)

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            self.check()
            mujoco.mj_step(self.m, self.d)


def load(xml: str, **kw):
    m = load_plain(mujoco.MjSpec.from_string(xml))
    f = GranularField(m, **kw)
    return m, f, mujoco.MjData(m)


FOOT = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.06 -0.06 {zmin} 0.06 0.06 0.05"/>
<numeric name="mjrft:deform_cell" data="0.0025"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="foot" prm="300"/></tuple></custom>
<worldbody><body name="foot" pos="0.0013 -0.0007 0.005" euler="0 4 7">
<joint name="z" type="slide" axis="0 0 1"/>
<geom name="foot" type="box" size="0.025 0.02 0.005" mass="1"/></body></worldbody>
<actuator><position joint="z" kp="1e5" kv="2000"/></actuator></mujoco>"""


def drive(c: Checker, targets, steps: int = 2) -> None:
    with c.f.installed():
        for tgt in targets:
            c.d.ctrl[0] = tgt
            c.step(steps)


@pytest.mark.parametrize("every", [1, 3])
def test_a_foot_pressed_lifted_and_pressed_again(lib, every):
    """A tilted box foot pressed 1 cm, lifted 5 mm, pressed again to 1.2 cm: excavation, its
    memory, an even rim, the hole's slopes relaxing (pending boxes over several updates)."""
    m, f, d = load(FOOT.format(zmin=-0.1), deform_every=every)
    c = Checker(lib, m, f, d)
    drive(c, np.linspace(0.0, -0.01, 120))
    drive(c, np.linspace(-0.01, -0.005, 30))
    drive(c, np.linspace(-0.005, -0.012, 120))
    stats = dict(zip(soil.SOIL_STATS, f._states.of(d).arrays.soil_stats, strict=True))
    assert c.updates == pytest.approx(540 / every, abs=2)
    assert stats["excavated"] > 0.8 * 0.05 * 0.04 * 0.01
    assert stats["rasterised"] > 0 and not c.bad


def test_a_foot_below_the_bottom_is_returned(lib):
    """The medium's bottom 3 mm down: both return the foot once its floor lies below it."""
    m, f, d = load(FOOT.format(zmin=-0.003))
    c = Checker(lib, m, f, d)
    with f.installed():
        for tgt in np.linspace(0.0, -0.01, 100):
            d.ctrl[0] = tgt
            for _ in range(2):
                c.check()
                if c.bad:
                    break
                mujoco.mj_step(m, d)
            if c.bad:
                break
    assert c.bad == [0]


BLADE = """<mujoco><option timestep="0.002" integrator="{integrator}" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.05 -0.04 -0.1 0.15 0.04 0.05"/>
<numeric name="mjrft:deform_cell" data="0.0025"/><numeric name="mjrft:repose" data="27"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="blade" prm="400"/></tuple></custom>
<worldbody><body name="blade" pos="0 0 0" euler="0 0 10"><joint name="x" type="slide" axis="1 0 0"/>
<geom name="blade" type="box" size="0.006 0.02 0.02" pos="0 0 0.01" mass="1"/></body>
</worldbody><actuator><velocity joint="x" kv="{kv}"/></actuator></mujoco>"""


@pytest.mark.parametrize(("integrator", "kv"), [("implicitfast", 2000), ("RK4", 200)])
def test_a_blade_dragged_at_depth(lib, integrator, kv):
    """A blade 1 cm deep dragged 5 cm: bulldozing ahead of it, the trench behind, the relaxation
    running out of budget and carrying its box to the next update. RK4 (its explicit velocity
    servo softer): the ground moves at each step's first stage only."""
    m, f, d = load(BLADE.format(integrator=integrator, kv=kv))
    c = Checker(lib, m, f, d)
    with f.installed():
        d.ctrl[0] = 0.1  # [m/s]
        while d.qpos[0] < 0.05:
            c.step()
    stats = dict(zip(soil.SOIL_STATS, f._states.of(d).arrays.soil_stats, strict=True))
    assert stats["excavated"] > 0.0 and stats["unrelaxed"] > 0 and c.updates > 200


ROD = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.04 -0.04 -0.1 0.04 0.04 0.05"/>
<numeric name="mjrft:deform_cell" data="0.002"/><numeric name="mjrft:repose" data="30"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="rod" prm="400"/></tuple></custom>
<worldbody><body name="rod" pos="0.003 0 0.03"><joint name="z" type="slide" axis="0 0 1"/>
<joint name="y" type="slide" axis="0 1 0"/>
<geom name="rod" type="cylinder" size="0.006 0.03" mass="0.2"/></body></worldbody>
<actuator><position joint="z" kp="2e4" kv="400"/><position joint="y" kp="2e3" kv="100"/>
</actuator></mujoco>"""


def test_a_rod_pushed_sideways_and_withdrawn(lib):
    """A rod pushed in, moved sideways and pulled out: the hole under a hovering intruder fills
    only up to its floor, then slumps to the angle of repose once it is out."""
    m, f, d = load(ROD)
    c = Checker(lib, m, f, d)
    drive(c, np.linspace(0.0, -0.02, 80))
    with f.installed():
        d.ctrl[1] = 0.006
    drive(c, np.full(20, -0.02))
    drive(c, np.linspace(-0.02, 0.05, 60))
    drive(c, np.full(30, 0.05))
    assert c.updates == 380 and not c.bad
    assert f._states.of(d).arrays.soil_stats[3] > 0  # relaxation carried over


def test_the_walking_hexapod_on_a_coarse_grid(lib):
    """The hexapod's gait on a 1 cm cell for 0.3 s: six legs, several footprints per update."""
    from mjrft.envs import hexapod_sand

    env = hexapod_sand.make(seed=0, time_limit=float("inf"), deform_cell=0.01)
    try:
        env.reset()
        physics = env.physics
        m, d = physics.model.ptr, physics.data.ptr
        c = Checker(lib, m, physics.field, d)
        substeps = round(env.control_timestep() / m.opt.timestep)
        for _ in range(15):  # the field stays installed while the physics lives
            env._task.before_step(np.array([1.0, np.pi]), physics)
            c.step(substeps)
        stats = physics.field._states.of(d).arrays.soil_stats
        # reset()'s forward already followed t = 0.
        assert c.updates == 15 * substeps - 1 and stats[1] > 0.0 and not c.bad
    finally:
        env.close()


@pytest.mark.parametrize("seed", [0, 1])
def test_a_rod_on_random_rough_ground(lib, seed):
    """The rod on seeded random ground (h, c <= h and p per vertex, everything pending
    relaxation): the first updates relax slopes everywhere under the budget, the rod hovers over
    and presses into a rough surface, moves sideways and leaves."""
    m, f, d = load(ROD)
    block = f._states.of(d).userdata
    prm = f._tables.arrays.surface_prm
    nrow, ncol = int(prm[surface.NROW]), int(prm[surface.NCOL])
    h, cl, p = soil.block_views(prm, block)
    rng = np.random.default_rng(seed)
    h[1:-1, 1:-1] = rng.uniform(-0.004, 0.004, (nrow - 2, ncol - 2))
    cl[:] = h - rng.uniform(0.0, 0.002, h.shape) * (rng.random(h.shape) < 0.5)
    p[:] = rng.uniform(0.0, 0.003, h.shape)
    block[surface.SOIL_ZOFF] = h.max() - prm[surface.ZMAX]
    block[surface.SOIL_PENDING : surface.SOIL_PENDING + 4] = (0, nrow, 0, ncol)
    c = Checker(lib, m, f, d)
    drive(c, np.linspace(0.0, -0.015, 60))
    with f.installed():
        d.ctrl[1] = -0.008
    drive(c, np.full(20, -0.015))
    drive(c, np.linspace(-0.015, 0.05, 40))
    stats = f._states.of(d).arrays.soil_stats
    assert c.updates == 240 and not c.bad and stats[1] > 0.0 and stats[3] > 0


# Unit level: each function of soil.h against its numba original on seeded random grids. The
# numba functions are compiled here for plain arrays, in memory only (their cache left alone:
# the shared cache holds them only inlined into deform.update).
NROW, NCOL = 23, 31


@pytest.fixture(scope="module")
def nb():
    from numba.core.caching import NullCache

    for name in ("footprint", "excavate", "deposit", "relax", "finish"):
        getattr(soil, name)._cache = NullCache()
    return soil


def random_ground(rng, tan_repose=0.6):
    """prm, grid and a soil block of an NROW x NCOL grid with rough heights, c <= h, p >= 0."""
    prm = np.zeros(surface.PRM_SIZE)
    prm[surface.KIND] = surface.SOIL
    prm[[surface.X0, surface.Y0, surface.DX, surface.DY]] = -0.031, -0.02, 0.002, 0.0017
    prm[surface.NCOL], prm[surface.NROW] = NCOL, NROW
    prm[surface.TAN_REPOSE], prm[surface.EVERY] = tan_repose, 1
    grid = rng.uniform(-0.002, 0.002, (NROW, NCOL))
    prm[surface.ZMAX] = grid.max()
    block = np.zeros(surface.soil_block(NROW, NCOL))
    h, c, p = soil.block_views(prm, block)
    h[:] = rng.uniform(-0.005, 0.005, h.shape)
    c[:] = h - rng.uniform(0.0, 0.002, h.shape) * (rng.random(h.shape) < 0.5)
    p[:] = rng.uniform(0.0, 0.003, h.shape)
    return prm, grid, block


def random_floor(rng, prm, grid, block):
    """Floors over a few patches: pressing (below h), touching, hovering (above h), none."""
    h = grid + soil.block_views(prm, block)[0]
    floor = np.full((NROW, NCOL), np.inf)
    owner = np.full((NROW, NCOL), -1, np.int64)
    for k in range(3):
        r0, c0 = rng.integers(0, NROW - 4), rng.integers(0, NCOL - 4)
        r1, c1 = r0 + rng.integers(2, 8), c0 + rng.integers(2, 10)
        patch = (slice(r0, r1), slice(c0, c1))
        shape = h[patch].shape
        kind = rng.integers(0, 4, shape)
        f = np.where(kind == 0, h[patch] - rng.uniform(0, 0.004, shape), h[patch])
        f = np.where(kind == 2, h[patch] + rng.uniform(2e-7, 0.003, shape), f)
        f = np.where(kind == 3, h[patch] + rng.uniform(0, 2e-7, shape), f)
        better = f < floor[patch]
        floor[patch] = np.where(better, f, floor[patch])
        owner[patch] = np.where(better, k, owner[patch])
    return floor, owner


def boxes_of(owner, nk=3):
    out = np.tile([2147483647.0, -1.0, 2147483647.0, -1.0], (nk, 1))
    for k in range(nk):
        r, c = np.nonzero(owner == k)
        if len(r):
            out[k] = r.min(), r.max(), c.min(), c.max()
    return out


@pytest.mark.parametrize("seed", range(6))
def test_relax_on_random_grids(lib, nb, seed):
    rng = np.random.default_rng(seed)
    prm, grid, block = random_ground(rng, tan_repose=rng.uniform(0.3, 0.8))
    floor, _ = random_floor(rng, prm, grid, block)
    r0, c0 = rng.integers(-1, NROW // 2), rng.integers(-1, NCOL // 2)
    box = np.array([r0, r0 + rng.integers(0, NROW), c0, c0 + rng.integers(0, NCOL)], float)
    args = [block, np.full((NROW, NCOL), -1, np.int64), np.zeros(NROW * NCOL, np.int64), box,
            box.copy(), np.zeros(soil.N_SOIL_STATS)]  # fmt: skip
    mine = [a.copy() for a in args]
    want = nb.relax(prm, grid, args[0], floor, *args[1:])
    got = lib.mjrft_test_soil_relax(prm, grid, mine[0], floor, mine[1].ravel(), *mine[2:])
    assert bool(got) == want
    for a, b in zip(mine, args, strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.any(block != random_ground(np.random.default_rng(seed))[2])  # material moved


@pytest.mark.parametrize("seed", range(6))
def test_excavate_and_deposit_on_random_grids(lib, nb, seed):
    rng = np.random.default_rng(seed)
    prm, grid, block = random_ground(rng)
    floor, owner = random_floor(rng, prm, grid, block)
    boxes = boxes_of(owner)
    zlo = -0.006 if seed == 5 else -1.0  # seed 5: a floor below the bottom
    mine, stats, my_stats = block.copy(), np.zeros(soil.N_SOIL_STATS), np.zeros(soil.N_SOIL_STATS)
    work = np.zeros(NROW * NCOL, np.int64)
    cut = np.zeros(6)
    bottom = False
    for k in range(3):
        if boxes[k, 0] > boxes[k, 1]:
            continue
        twist = rng.normal(size=9) * [0.1, 0.1, 0.1, 2.0, 2.0, 2.0, 0.01, 0.01, 0.01]
        want = nb.excavate(prm, grid, block, floor, owner, boxes[k], k, twist, zlo, stats)
        lib.mjrft_test_soil_excavate(prm, grid, mine, floor, owner.ravel(), boxes[k], k, twist,
                                     zlo, my_stats, cut)  # fmt: skip
        np.testing.assert_array_equal(cut, want)
        np.testing.assert_array_equal(mine, block)
        bottom |= want[0] < 0.0
        if want[0] > 0.0:
            v = np.array(want[3:])
            if k == 1:
                v[:2] = 0.0  # straight down: an even rim
            nb.deposit(prm, grid, block, floor, owner, boxes[k], k, want[0], want[1], want[2], v,
                       stats)  # fmt: skip
            lib.mjrft_test_soil_deposit(prm, grid, mine, floor, owner.ravel(), boxes[k], k,
                                        want[0], want[1], want[2], v, my_stats, work)  # fmt: skip
            np.testing.assert_array_equal(mine, block)
        np.testing.assert_array_equal(my_stats, stats)
    assert stats[1] > 0.0 and bottom == (seed == 5)


@pytest.mark.parametrize("seed", range(4))
def test_footprint_and_finish_on_random_grids(lib, nb, seed):
    rng = np.random.default_rng(seed)
    prm, grid, block = random_ground(rng)
    # Triangles of random orientation and size around the grid, some crossing its edge.
    n = 400
    centre = rng.uniform([-0.035, -0.024, -0.004], [0.035, 0.024, 0.004], (n, 1, 3))
    vert = (centre + rng.normal(scale=0.004, size=(n, 3, 3))).reshape(n, 9)
    quat = rng.normal(size=4)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, quat / np.linalg.norm(quat))
    rot = rot.reshape(3, 3)
    pos = rng.normal(scale=0.003, size=3)
    floor = np.full((NROW, NCOL), np.inf)
    owner = np.full((NROW, NCOL), -1, np.int64)
    box = np.array([2147483647.0, -1.0, 2147483647.0, -1.0])
    mine = [floor.copy(), owner.copy(), box.copy()]
    top = 0.003 if seed % 2 else np.inf
    for k, (start, stop) in enumerate(((0, 150), (150, 400))):
        want = nb.footprint(prm, vert, start, stop, rot, pos, k, floor, owner, box, top)
        got = lib.mjrft_test_soil_footprint(prm, vert, start, stop, rot.ravel(), pos, k,
                                            mine[0], mine[1], mine[2], top)  # fmt: skip
        assert got == want > 0
        for a, b in zip(mine, (floor, owner, box), strict=True):
            np.testing.assert_array_equal(a, b)
    assert np.isfinite(floor).sum() > 50
    mine_block = block.copy()
    nb.finish(prm, grid, block, floor, owner, box, 0.25)
    lib.mjrft_test_soil_finish(prm, grid, mine_block, mine[0], mine[1], box, 0.25)
    np.testing.assert_array_equal(mine_block, block)
    np.testing.assert_array_equal(mine[0], floor)
    np.testing.assert_array_equal(mine[1], owner)
