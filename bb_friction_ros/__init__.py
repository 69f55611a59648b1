"""
bb_friction_ros: ball-to-ball contact friction in linear ball bearings and ball screws.

The physics core (everything but ``node.py``) is pure numpy/scipy and imports no rclpy.
Model: Lin, Duan, Okwudire, ASME J. Tribol. 141(8), 2019, DOI 10.1115/1.4043630.
"""

__version__ = "0.1.0"
