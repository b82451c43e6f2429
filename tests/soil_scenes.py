"""Scenes of the deforming-ground tests (tests/test_soil.py, test_warp_soil.py, test_batch.py):
a plate on a position servo pressed into glass beads, and a blade on a velocity servo dragged
through them, both on a grid over the region around them."""

#: A foot of the given shape and size on a vertical slide, its servo's target the depth [m];
#: mjrft:deform_cell = cell.
FOOT = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.06 -0.06 -0.1 0.06 0.06 0.05"/>
<numeric name="mjrft:deform_cell" data="{cell}"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="foot" prm="300"/></tuple></custom>
<worldbody><body name="foot" pos="0 0 0.005"><joint name="z" type="slide" axis="0 0 1"/>
<geom name="foot" type="{shape}" size="{size}" mass="1"/></body></worldbody>
<actuator><position joint="z" kp="1e5" kv="2000"/></actuator></mujoco>"""
#: The foot as a 5 x 5 x 1 cm plate.
BOX = {"shape": "box", "size": "0.025 0.025 0.005"}
#: The plate on a 2.5 mm grid.
PLATE = FOOT.format(cell=0.0025, **BOX)
#: A blade 4 cm wide and 1.2 cm thick on a horizontal slide, its servo's target the speed
#: [m/s], on a 2.5 mm grid.
BLADE = """<mujoco><option timestep="0.002" integrator="implicitfast" gravity="0 0 0"/>
<custom><text name="mjrft:material" data="glass_beads"/>
<numeric name="mjrft:region" data="-0.05 -0.04 -0.1 0.15 0.04 0.05"/>
<numeric name="mjrft:deform_cell" data="0.0025"/>
<tuple name="mjrft:intruders"><element objtype="geom" objname="blade" prm="400"/></tuple></custom>
<worldbody><body name="blade" pos="0 0 0"><joint name="x" type="slide" axis="1 0 0"/>
<geom name="blade" type="box" size="0.006 0.02 0.02" pos="0 0 0.01" mass="1"/></body>
</worldbody><actuator><velocity joint="x" kv="2000"/></actuator></mujoco>"""
