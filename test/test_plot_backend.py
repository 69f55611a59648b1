"""Library plotting functions leave the caller's matplotlib backend and pyplot state alone."""

import ast
import pathlib
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

from bb_friction_ros.ball_screw.simulation import plot_fig20, plot_fig21
from bb_friction_ros.replay import plot_replay, _Series
from bb_friction_ros.runner import Prediction, prediction_values

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "bb_friction_ros"


@pytest.fixture
def caller_backend():
    """Switch to a backend a caller might have chosen (not Agg); restore it afterwards."""
    before = matplotlib.get_backend()
    matplotlib.use("svg")
    yield "svg"
    matplotlib.use(before)


def _steps(n=5, balls=4):
    return [SimpleNamespace(nut_angle_rad=0.1 * k, azimuth_rad=np.linspace(0.0, 3.0, balls)
                            + 0.01 * k, b2b_forces_n=np.array([0.0, 1.0, 0.0, 0.0]),
                            torque_total_nm=0.02, torque_b2g_nm=0.015, torque_b2b_nm=0.005)
            for k in range(n)]


def _predictions(n=5):
    # replay's series reads every field of the runner's answer
    return [Prediction(stamp_s=0.01 * k, nut_angle_rad=0.06 * k, nut_velocity_rad_s=6.0,
                       axial_load_n=1500.0, torque_total_nm=0.02, torque_b2g_nm=0.015,
                       torque_b2b_nm=0.005, torque_empirical_nm=0.0, converged=True,
                       model_age_s=0.0, groups=(((0, 1), (1.0,)),), n_balls=4, stepped=True)
            for k in range(n)]


def test_plotting_keeps_the_callers_backend(caller_backend, tmp_path):
    plot_fig20(_steps(), 0.2, 4.0, tmp_path / "fig20.png")
    plot_fig21(_steps(), tmp_path / "fig21.png")
    series = _Series(measured=True)        # replay's streamed columns
    series.add_rows([(prediction_values(pred), 0.021) for pred in _predictions()])
    plot_replay(tmp_path, series)
    assert matplotlib.get_backend() == caller_backend
    for name in ("fig20.png", "fig21.png", "replay_torque_and_groups.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"


def test_no_library_module_selects_a_backend_or_uses_pyplot():
    """pyplot keeps global figures and a backend: library code builds Figure objects only."""
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", None) == "use" \
                    and getattr(node.func.value, "id", None) == "matplotlib":
                offenders.append(f"{path.name}:{node.lineno} matplotlib.use")
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] + [getattr(node, "module", "") or ""]
                if any("pyplot" in n for n in names):
                    offenders.append(f"{path.name}:{node.lineno} imports pyplot")
    assert not offenders
