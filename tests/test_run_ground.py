"""`mjrft run` reports the deforming ground's volume lost at the edge of mjrft:region."""

import json

import mujoco
import pytest

from mjrft.app import cli, simulate

# A blade 1 cm deep and 4 cm wide dragged along +x at 0.1 m/s (the keyframe's control) towards
# the edge of a region that ends at x = 4 cm, 1 cm beside each of its sides: 0.9 s takes it 9 cm,
# past the edge.
BLADE = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.05 -0.03 -0.1 {x_max} 0.03 0.05"/>
<numeric name="mjrft:deform_cell" data="0.0025"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="blade" prm="400"/></tuple></custom>
<worldbody><body name="blade"><joint name="x" type="slide" axis="1 0 0"/>
<geom name="blade" type="box" size="0.006 0.02 0.02" pos="0 0 0.01" mass="1"/></body>
</worldbody><actuator><velocity joint="x" kv="2000"/></actuator>
<keyframe><key ctrl="0.1"/></keyframe></mujoco>"""
DURATION = 0.9  # [s]


@pytest.mark.parametrize("x_max", [0.04, 0.15])
def test_the_volume_lost_at_the_regions_edge_is_reported(tmp_path, capsys, x_max):
    xml = tmp_path / "blade.xml"
    xml.write_text(BLADE.format(x_max=x_max))
    out = tmp_path / "out"
    assert cli.main(["run", str(xml), "--duration", str(DURATION), "--out", str(out)]) == 0
    reported = json.loads((out / cli.RUN_JSON).read_text())["ground"]
    text = capsys.readouterr()
    # The same run again, reading the engine's counter and the grid itself.
    model = simulate.load_model(xml)
    fld = simulate.GranularField(model)
    data, _ = simulate.run(model, DURATION, fld=fld, data=mujoco.MjData(model))
    soil = fld.soil(data)
    assert reported["lost_m3"] == soil.counters["unplaced"]
    assert reported["updates"] == soil.counters["updates"] > 0
    assert reported["unrelaxed_updates"] == soil.counters["unrelaxed"]
    assert reported["relaxed"] == soil.relaxed
    assert reported["cell_m"] == pytest.approx(0.0025)  # mjrft:deform_cell
    assert reported["grid"] == list(soil.height.shape)
    assert reported["excavated_m3"] == soil.counters["excavated"] > 0
    # What the counter says is lost is what the grid misses (every move conserves the rest).
    assert soil.volume() == pytest.approx(-reported["lost_m3"], abs=1e-9 * reported["excavated_m3"])
    lost = f"{reported['lost_m3']:.4g} m^3 lost at the region's edge"
    assert lost in text.out
    if x_max == 0.04:  # past the edge: a measurable part of the cut volume is gone, and said
        assert reported["lost_fraction"] > 0.01
        assert "is lost from the ground" in text.err
    else:  # the blade stays inside: nothing lost, no warning
        assert reported["lost_m3"] == 0.0 and "is lost" not in text.err


def test_a_ground_that_does_not_deform_has_no_account(tmp_path, capsys):
    out = tmp_path / "out"
    args = ["run", "sphere_drop", "--duration", "0.01", "--out", str(out), "--no-plots"]
    assert cli.main(args) == 0
    assert json.loads((out / cli.RUN_JSON).read_text())["ground"] is None
    assert "deforming ground" not in capsys.readouterr().out
