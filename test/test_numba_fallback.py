"""
numba is optional: without it the ball-screw solver runs its numpy path, with the same answers.

The README and the package docstring promise this; the test runs the model in a child
process in which ``import numba`` fails.
"""

import json
import subprocess
import sys

import pytest

from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.module import solve_two_ball_module
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.ball_screw.screw_model import ScrewModel
from bb_friction_ros.ball_screw.simulation import run_whole_screw

STEPS = 6

CHILD = f"""
import json, sys
sys.modules["numba"] = None          # makes "import numba" raise ImportError
from bb_friction_ros.ball_screw import kernel
from bb_friction_ros.ball_screw.module import solve_two_ball_module
from bb_friction_ros.model_file import load_ball_screw
from bb_friction_ros.ball_screw.screw_model import ScrewModel
from bb_friction_ros.ball_screw.simulation import run_whole_screw
cfg = load_ball_screw()
model = ScrewModel(cfg)
m = solve_two_ball_module(model, 0.0, cfg.operation.module_theta2_rad,
                          cfg.operation.module_axial_load_n)
steps = run_whole_screw(cfg, n_steps={STEPS})[0]
print(json.dumps({{"have_numba": kernel.HAVE_NUMBA, "use_kernel": model.solver.use_kernel,
                  "f_b2b_n": m.f_b2b_n, "friction_increase": m.friction_increase,
                  "torque_nm": [r.torque_total_nm for r in steps],
                  "converged": all(r.converged for r in steps)}}))
"""


@pytest.mark.skipif(not kernel.HAVE_NUMBA, reason="compares against the numba path")
def test_without_numba_the_numpy_path_gives_the_same_answers():
    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                         timeout=600, check=True)
    child = json.loads(out.stdout.strip().splitlines()[-1])
    assert child["have_numba"] is False and child["use_kernel"] is False
    cfg = load_ball_screw()
    ref = solve_two_ball_module(ScrewModel(cfg), 0.0, cfg.operation.module_theta2_rad,
                                cfg.operation.module_axial_load_n)
    # tolerances of test/ball_screw/test_fast_solver.py (kernel vs numpy path)
    assert child["f_b2b_n"] == pytest.approx(ref.f_b2b_n, rel=1e-8)
    assert child["friction_increase"] == pytest.approx(ref.friction_increase, rel=1e-8)
    steps = run_whole_screw(cfg, n_steps=STEPS)[0]
    scale = max(abs(r.torque_total_nm) for r in steps)
    assert child["converged"]
    assert child["torque_nm"] == pytest.approx([r.torque_total_nm for r in steps],
                                               abs=1e-8 * scale)
