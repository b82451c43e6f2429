"""MJCF rig models shipped with mjrft; installed as the data package ``mjrft.models``."""
