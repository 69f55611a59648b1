"""Tests mirroring bb_friction_ros.ball_screw."""
