"""The scene options: one home for the choices a user may make on top of the MJCF.

Every way in (``mjrft.load_model``, ``GranularField``, ``scene_from_model``, ``WarpField``, the
CLI, the environments, sweeps) takes a ``SceneOptions`` or its fields as keywords; ``None``
leaves the MJCF's value (``mjrft:`` custom fields, docs/mjcf.md) in force.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class SceneOptions:
    """Overrides of the MJCF's ``mjrft:`` section (None: the MJCF's value, or its default).

    Attributes:
      material: a ``mjrft.Material`` or a preset's name (``mjrft:material``, ``mjrft:zeta``).
      n_triangles: triangle count of every primitive geom (MJCF ``prm``, ``mjrft:triangles``);
        mesh geoms keep their own.
      tolerance: instead of n_triangles, the relative RMS force error wanted per primitive
        geom; the count comes from ``mjrft.geometry.triangles_for_tolerance``.
      low_speed: "stick", "free" or "off" (``mjrft:low_speed``; docs/stability.md).
      stick_reach: the low-speed treatment's reach (``mjrft:stick_reach``).
      deform_cell: the deforming ground's cell [m], "auto" (``mjrft.core.soil.CELLS_ACROSS``
        cells across the narrowest intruder), 0 off (``mjrft:deform_cell``).
      repose: its angle of repose [deg] (``mjrft:repose``).
      deform_every: steps between its updates (``mjrft:deform_every``, default 1), or
        deform_travel: the cells the intruders travel between its updates
        (``mjrft:deform_travel``; 0: every step).
      dynamic: the dynamic RFT term's rho_c [kg/m^3] or (rho_c, lambda), 0 off
        (``mjrft:dynamic``).
      intruders: the geoms that feel the medium, instead of the MJCF's ``mjrft:intruders``
        tuple and ``mjrft:intruders_*`` texts: a dict of selections, each a list of names or
        one string of space-separated names, their union taken: ``geoms``, ``bodies`` (all
        their geoms), ``subtree`` (a body's and its descendants' geoms; "world": every body's),
        ``match`` (glob patterns on geom names) and ``collision`` (the collision geoms of
        subtrees), e.g. ``{"match": "*foot* *calf*"}`` (docs/mjcf.md).
      watch_sinking: False: no ``mjrft.SinkingWarning`` for collision geoms of moving bodies
        that are below the surface without being intruders (``mjrft:watch_sinking``).
    """

    material: Any = None
    n_triangles: int | None = None
    tolerance: float | None = None
    low_speed: str | None = None
    stick_reach: float | None = None
    deform_cell: float | str | None = None
    repose: float | None = None
    deform_every: int | None = None
    deform_travel: float | None = None
    dynamic: float | tuple[float, float] | None = None
    intruders: dict[str, Any] | None = None
    watch_sinking: bool | None = None

    @classmethod
    def of(cls, options: SceneOptions | None = None, **overrides: Any) -> SceneOptions:
        """options with keyword overrides (names of SceneOptions' fields; a misspelt name is
        refused with the valid ones)."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise TypeError(
                f"unknown scene option(s) {', '.join(unknown)}; valid: {', '.join(sorted(names))}"
            )
        base = {f.name: getattr(options, f.name) for f in fields(cls)} if options else {}
        base.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**base)

    def given(self) -> dict[str, Any]:
        """The options that override the MJCF (not None), by name."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return {k: v for k, v in values.items() if v is not None}
