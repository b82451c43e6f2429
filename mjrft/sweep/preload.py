"""Imported once by the local backend's forkserver: it imports what a run needs (mujoco, mjrft's
field and sweep code) and loads the engine library, so every worker forked from that server
starts ready to run."""

import mjrft.sweep.executor  # noqa: F401 (imported for the workers forked from this server)
from mjrft.field import plugin

plugin.library()
