"""Applications on the field: simulation runs, the command line, reports, recordings, demos.

Nothing in ``mjrft.core`` or ``mjrft.field`` imports this package.
"""
