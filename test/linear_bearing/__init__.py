"""Tests mirroring bb_friction_ros.linear_bearing."""
