"""Imported once by the local backend's forkserver: it imports mjrft and loads the compiled code
(from numba's on-disk cache), so every worker forked from that server starts ready to run."""

from mjrft.field.warmup import warm_up

warm_up()
