"""Small generated recordings shared by the replay and node tests."""

from bb_friction_ros.trajectories import DemoRecording, make_demo_events


def short_recording(state_rate_hz=100.0, segment_s=0.25, measured=None):
    """A short reversing run; measured torque = zero-model + synthetic effects unless given."""
    cfg = DemoRecording(state_rate_hz=state_rate_hz, load_rate_hz=20.0,
                        segments_rev_s=(1.0, -1.0), segment_duration_s=segment_s)
    predict = measured or (lambda events: [0.0] * sum(e.kind == "nut_state" for e in events))
    return make_demo_events(cfg, predict)
