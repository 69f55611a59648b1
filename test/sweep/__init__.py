"""Tests mirroring bb_friction_ros.sweep."""
