"""Golden trajectories (tests/golden_runs.py): every production path reproduces its pinned run.

These pin behaviour across refactors; they are not physics references. On the machine and
versions that generated a file the comparison is bit for bit (``array_equal``). numba compiles
for the host CPU, so on another CPU the same code may round differently: there the runs are
compared to ``OTHER_MACHINE_RTOL`` instead, and the test says so.
"""

import warnings

import golden_runs
import numpy as np
import pytest

# Relative tolerance on another machine: a few thousand steps of round-off differences (1e-16
# per step) that the low-speed treatment's discrete decisions may amplify.
OTHER_MACHINE_RTOL = 1e-6


@pytest.mark.parametrize("name", sorted(golden_runs.SCENARIOS))
def test_golden_run_is_reproduced(name):
    path = golden_runs.GOLDEN / f"{name}.npz"
    with np.load(path) as f:
        stored = {k: f[k] for k in f.files}
    fingerprint = str(stored.pop("fingerprint"))
    got = golden_runs.SCENARIOS[name]()
    assert sorted(got) == sorted(stored)
    same_machine = fingerprint == golden_runs.fingerprint()
    for key, want in stored.items():
        if same_machine:
            np.testing.assert_array_equal(got[key], want, err_msg=f"{name}: {key}")
        else:
            scale = np.abs(want).max(axis=0, keepdims=True) if want.ndim > 1 else np.abs(want)
            np.testing.assert_allclose(
                got[key], want, rtol=0, atol=OTHER_MACHINE_RTOL * (scale + 1e-12),
                err_msg=f"{name}: {key}",
            )  # fmt: skip
    if not same_machine:
        warnings.warn(
            f"{name}: generated on {fingerprint!r}, compared to {OTHER_MACHINE_RTOL:g} here "
            f"({golden_runs.fingerprint()!r})",
            stacklevel=1,
        )
