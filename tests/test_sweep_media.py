"""What a study may change in the model's medium (a preset replaced by zeta and back), and what
the results say about each run's regime: the Froude number, the quasi-static flag, and the
warnings, summarised once per sweep."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from mjrft.app import cli
from mjrft.sweep import Study, StudyError, load_results, run_study

# A 1 cm steel sphere on a free joint, released from `height` [m] above a flat surface at z = 0;
# `medium` is the <custom> line that names the medium.
SPHERE = """
<mujoco>
  <option timestep="0.001"><flag contact="disable"/></option>
  <custom>
    {medium}
    <tuple name="mjrft:intruders"><element objtype="geom" objname="ball" prm="200"/></tuple>
  </custom>
  <worldbody>
    <body name="ball" pos="0 0 {height}">
      <freejoint/>
      <geom name="ball" type="sphere" size="0.01" density="7850"/>
    </body>
  </worldbody>
</mujoco>
"""
PRESET = '<text name="mjrft:material" data="glass_beads"/>'
ZETA = '<numeric name="mjrft:zeta" data="500000"/>'
# The glass beads preset is Li's generic set scaled by zeta = 0.33 N/cm^3 = 330000 N/m^3.
GLASS_BEADS_ZETA = 330000.0
# The two ways of naming that medium differ by the rounding of 0.33 N/cm^3 into N/m^3.
SAME_MEDIUM_REL = 1e-9


def study(tmp_path: Path, medium: str, parameter: str, *, height: float = 0.011,
          duration: float = 0.1, extra: str = "") -> Path:  # fmt: skip
    (tmp_path / "ball.xml").write_text(SPHERE.format(medium=medium, height=height))
    path = tmp_path / "study.toml"
    path.write_text(f"""
[study]
model = "ball.xml"
duration = {duration}
{parameter}
{extra}
[metrics]
depth_m = {{ kind = "final_depth", body = "ball" }}
""")
    return path


def test_a_study_replaces_a_preset_by_zeta_and_zeta_by_a_preset(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    zeta = f"""
[parameters.zeta]
path = "mjrft:zeta"
values = [{GLASS_BEADS_ZETA}, {2 * GLASS_BEADS_ZETA}]"""
    run_study(Study.load(study(tmp_path / "a", PRESET, zeta)), tmp_path / "a" / "out",
              backend="serial", plots=False)  # fmt: skip
    depth = {r["zeta"]: r["depth_m"] for r in load_results(tmp_path / "a" / "out")}
    preset = """
[parameters.material]
path = "mjrft:material"
values = ["glass_beads"]"""
    run_study(Study.load(study(tmp_path / "b", ZETA, preset)), tmp_path / "b" / "out",
              backend="serial", plots=False)  # fmt: skip
    (beads,) = load_results(tmp_path / "b" / "out")
    assert beads["status"] == "ok" and beads["depth_m"] > 0
    assert depth[GLASS_BEADS_ZETA] == pytest.approx(beads["depth_m"], rel=SAME_MEDIUM_REL)
    assert depth[2 * GLASS_BEADS_ZETA] < depth[GLASS_BEADS_ZETA]  # a stronger medium


def test_two_values_that_replace_each_other_are_refused_naming_both(tmp_path):
    path = study(
        tmp_path,
        PRESET,
        """
[parameters.zeta]
path = "mjrft:zeta"
values = [300000.0, 600000.0]""",
        extra='[set]\n"mjrft:material" = "poppy_seeds_lp"',
    )
    with pytest.raises(
        StudyError,
        match=r"\[set\] 'mjrft:material' writes mjrft:material and parameter 'zeta' writes "
        r"mjrft:zeta, which replace each other in a model",
    ):
        Study.load(path)


def test_the_results_say_which_runs_left_the_quasi_static_regime_and_warn_once(tmp_path, capsys):
    """Released 1 mm above the surface the sphere sinks slowly; from 8 cm it enters at about
    1.2 m/s: Fr = v^2 / (g L) = 1.2^2 / (9.81 * 0.02) ~ 7, beyond the quasi-static regime."""
    path = study(
        tmp_path,
        PRESET,
        """
[parameters.z]
path = "body.ball.pos[2]"
values = [0.011, 0.08, 0.09]""",
        duration=0.15,
    )
    out = tmp_path / "out"
    assert cli.main(["sweep", str(path), "--out", str(out), "--workers", "2"]) == 0
    rows = {r["z"]: r for r in load_results(out)}
    assert rows[0.011]["quasi_static"] is True and rows[0.011]["max_froude"] < 1
    for z in (0.08, 0.09):
        assert rows[z]["quasi_static"] is False and rows[z]["max_froude"] > 1
        assert rows[z]["warnings"].startswith("QuasiStaticWarning: body 'ball' moves")
    assert rows[0.011]["warnings"] == ""
    err = capsys.readouterr().err
    assert err.count("QuasiStaticWarning") == 1, err  # one summary line, no line per run
    assert "warning: QuasiStaticWarning in 2 of 3 runs (the first: body 'ball'" in err
    assert "regime.py" not in err  # no internal source line
    assert not math.isnan(rows[0.08]["max_froude"])


def test_a_run_keeps_its_first_ten_distinct_warnings_and_counts_the_rest(tmp_path):
    """A metric that raises 500 messages twice each: the row keeps the first ten and counts the
    raises of the others, so the run's memory and the row's length stay bounded."""
    (tmp_path / "noisy.py").write_text(
        "import warnings\n"
        "def depth(outcome):\n"
        "    for i in range(1000):\n"
        "        warnings.warn(f'warning {i % 500}', UserWarning)\n"
        "    return outcome.metrics['depth_m']\n"
    )
    path = study(tmp_path, PRESET, '[parameters.z]\npath = "body.ball.pos[2]"\nvalues = [0.011]',
                 duration=0.01)  # fmt: skip
    path.write_text(path.read_text() + 'noisy = { kind = "custom", function = "noisy.py:depth" }\n')
    summary = run_study(Study.load(path), tmp_path / "out", backend="serial", plots=False)
    (row,) = load_results(tmp_path / "out")
    kept = [f"UserWarning: warning {i}" for i in range(10)]
    others = 1000 - 2 * len(kept)  # each message is raised twice (i % 500)
    assert row["warnings"] == " | ".join([*kept, f"and {others} more"])
    assert summary.warning_lines() == ["UserWarning in 1 of 1 runs; the first: warning 0"]


def test_a_warning_of_the_study_is_shown_once_before_the_runs_and_counted_after(tmp_path, capsys):
    path = study(tmp_path, PRESET, '[parameters.z]\npath = "body.ball.pos[2]"\nvalues = [0.011, '
                 '0.012]', duration=0.01, extra='[set]\n"mjrft:repose" = 30')  # fmt: skip
    assert cli.main(["sweep", str(path), "--out", str(tmp_path / "out"), "--workers", "2"]) == 0
    err = capsys.readouterr().err
    assert err.count("does nothing: there is no deforming ground") == 1, err
    assert "mjrft sweep: warning: SceneWarning: <numeric name='mjrft:repose'> does nothing" in err
    assert "SceneWarning in 2 of 2 runs (above)" in err
    assert ".py:" not in err  # no source line
