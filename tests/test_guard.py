"""MuJoCo's one passive callback, shared: chained, never lost, never left half-installed."""

import signal
import subprocess
import sys
import textwrap

import mujoco
import numpy as np
import pytest
from mujoco import set_mjcb_passive as raw_set_mjcb_passive  # taken before any install

from mjrft.field import GranularField, guard

BALL = """<mujoco><option timestep="0.001"><flag contact="disable"/></option><custom>
  <text name="mjrft:material" data="glass_beads"/>
  <tuple name="mjrft:intruders"><element objtype="geom" objname="g" prm="100"/></tuple>
  </custom><worldbody><body pos="0 0 -0.005"><freejoint/><geom name="g" size="0.01"/></body>
  </worldbody></mujoco>"""


def ball():
    m = mujoco.MjModel.from_xml_string(BALL)
    d = mujoco.MjData(m)
    d.qvel[2] = -0.05
    return m, d


def process_is_clean():
    """No field installed, no callback left, models compile, a field installs and acts."""
    assert guard.installed_models() == 0
    assert mujoco.get_mjcb_passive() is None
    m, d = ball()  # compiles
    fld = GranularField(m)
    with fld.installed():
        mujoco.mj_step(m, d)
    assert fld.last_wrench[1, 2] > 0


def test_a_callback_set_while_installed_is_chained_and_kept():
    m, d = ball()
    fld = GranularField(m)
    seen = []

    def mine(mm, dd):
        seen.append(dd.time)

    with fld.installed():
        mujoco.set_mjcb_passive(mine)
        assert mujoco.get_mjcb_passive() is mine
        for _ in range(3):
            mujoco.mj_step(m, d)
        assert len(seen) == 3 and fld.last_wrench[1, 2] > 0  # both ran
        mujoco.set_mjcb_passive(None)
        mujoco.mj_step(m, d)
        assert len(seen) == 3
        mujoco.set_mjcb_passive(mine)
    assert mujoco.get_mjcb_passive() is mine  # the user's callback outlives the field
    mujoco.set_mjcb_passive(None)
    process_is_clean()


def test_a_callback_replaced_behind_the_fields_back_is_reported():
    m, d = ball()
    fld = GranularField(m)
    with pytest.raises(RuntimeError, match="replaced while a granular field was installed"):
        with fld.installed():
            mujoco.mj_step(m, d)
            raw_set_mjcb_passive(lambda mm, dd: None)  # the field stops acting here
            mujoco.mj_step(m, d)
    raw_set_mjcb_passive(None)
    process_is_clean()


def test_interrupts_while_entering_and_leaving_leave_a_working_process():
    """Ctrl-C at many moments of installed()'s way in and out (SIGINT from a timer)."""
    m, d = ball()
    fld = GranularField(m)
    rng = np.random.default_rng(5)
    armed = [False]

    def ctrl_c(signum, frame):  # what SIGINT would do right now: record it, or raise
        if armed[0]:
            signal.getsignal(signal.SIGINT)(signal.SIGINT, frame)

    previous = signal.signal(signal.SIGALRM, ctrl_c)
    interrupted = 0
    try:
        for _ in range(300):
            try:
                armed[0] = True
                signal.setitimer(signal.ITIMER_REAL, rng.uniform(1e-6, 4e-4))
                with fld.installed():
                    mujoco.mj_step(m, d)
            except KeyboardInterrupt:
                interrupted += 1
            finally:
                armed[0] = False
                signal.setitimer(signal.ITIMER_REAL, 0)
            assert guard.installed_models() == 0 or guard.installed_handler(m) == fld.apply_passive
            if guard.installed_models():  # cut in the last bytecodes: the next entry finishes it
                with pytest.warns(RuntimeWarning, match="interrupted on its way out"):
                    with fld.installed():
                        pass
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert interrupted > 30  # the timer really did interrupt
    process_is_clean()


@pytest.mark.parametrize("delay", [0.05, 0.6])
def test_an_interrupt_while_the_guard_compiles_leaves_a_working_process(delay):
    """The first installed() of a process loads the native guard (half a second; longer when
    it compiles): Ctrl-C during it must leave nothing half-installed."""
    script = textwrap.dedent(
        f"""
        import os, signal, mujoco
        from mjrft.field import GranularField, guard
        XML = {BALL!r}
        m = mujoco.MjModel.from_xml_string(XML)
        fld = GranularField(m)
        signal.signal(signal.SIGALRM, lambda *a: os.kill(os.getpid(), signal.SIGINT))
        signal.setitimer(signal.ITIMER_REAL, {delay})
        try:
            with fld.installed():
                signal.setitimer(signal.ITIMER_REAL, 0)
                print("not interrupted")
        except KeyboardInterrupt:
            print("interrupted")
        signal.setitimer(signal.ITIMER_REAL, 0)
        assert guard.installed_models() == 0, guard.installed_models()
        assert mujoco.get_mjcb_passive() is None
        m2 = mujoco.MjModel.from_xml_string(XML)  # compilation works
        d = mujoco.MjData(m2)
        d.qvel[2] = -0.05
        f2 = GranularField(m2)
        with f2.installed():
            mujoco.mj_step(m2, d)
        assert f2.last_wrench[1, 2] > 0
        print("clean")
        """
    )
    # A fresh process loads the guard and the pass from numba's cache.
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stdout + out.stderr
    assert out.stdout.split()[-1] == "clean"
