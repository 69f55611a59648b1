"""
bb_friction_ros: ball-to-ball contact friction in linear ball bearings and ball screws.

The physics core (everything but ``node.py``) is numpy/scipy and imports no rclpy.  The
ball-screw solver's Newton kernel (``ball_screw/kernel.py``) is compiled with numba when numba
imports; without it the solver runs its numpy path, with the same answers, more slowly.
Model: Lin, Duan, Okwudire, ASME J. Tribol. 141(8), 2019, DOI 10.1115/1.4043630.
"""

__version__ = "0.1.0"
