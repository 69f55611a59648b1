"""Small generated recordings shared by the replay and node tests."""

from bb_friction_ros.config import bundled_config
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.replay import run_events
from bb_friction_ros.runner import build_runner, InputAssembler
from bb_friction_ros.trajectories import DemoRecording, make_demo_events


def model_friction(events):
    """Return the bundled model's friction on the nut-state samples (the replay path)."""
    settings = NodeParameters()
    runner = build_runner(bundled_config("ball_screw.yaml"), settings.model_rate_hz)
    assembler = InputAssembler(settings.nut_joint, settings.max_axial_load_n)
    return [p.torque_total_nm for p in run_events(events, runner, assembler)]


def short_recording(state_rate_hz=100.0, segment_s=0.25, measured=None):
    """
    A short reversing run; measured torque = ``measured(events)`` + synthetic effects.

    ``measured`` None: a zero model, so the measured torque is the synthetic effects alone (a
    quarter of the model's friction: fitting it would give a model of the wrong sign; pass
    ``model_friction`` for a recording to analyse).
    """
    cfg = DemoRecording(state_rate_hz=state_rate_hz, load_rate_hz=20.0,
                        segments_rev_s=(1.0, -1.0), segment_duration_s=segment_s)
    predict = measured or (lambda events: [0.0] * sum(e.kind == "nut_state" for e in events))
    return make_demo_events(cfg, predict)


def averaged_feedforward(pred):
    """
    Return the feedforward of a converged prediction of the bundled model (message or object).

    Its fitted terms plus the physics' torque averaged over the balls' arrangements (the
    node's default ``b2b_feedforward``).
    """
    from bb_friction_ros.ball_screw.arrangement import mean_b2b
    from bb_friction_ros.model_file import load_ball_screw
    mean = mean_b2b(load_ball_screw(bundled_config("ball_screw.yaml")))
    return pred.torque_empirical_nm + mean.total_at(pred.axial_load_n,
                                                    pred.nut_velocity_rad_s)
