"""
Building the whole-screw model with warm caches imports no scipy.optimize or scipy.special.

Why: importing them cost 0.26 s of the node's 1.3 s start-up (the target: launch to
ready <= 1 s); the Hertz and B2B constants that need them are kept in the table cache beside the
friction maps (``friction_maps.cached_arrays``).  A child process builds the model (which
fills the cache if it is empty, importing scipy), then another must build it without scipy.
scipy.linalg is not checked: numba imports it for its BLAS check when it loads a kernel.
"""

import json
import subprocess
import sys

CHILD = """
import json, sys
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
from bb_friction_ros.model_file import load_ball_screw
WholeScrew(load_ball_screw(overrides={"load_distribution": sys.argv[1]}))
print(json.dumps(sorted(m for m in ("scipy.optimize", "scipy.special", "scipy.interpolate")
                        if m in sys.modules)))
"""


def _imported(distribution):
    out = subprocess.run([sys.executable, "-c", CHILD, distribution], check=True,
                         capture_output=True, text=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_warm_table_cache_keeps_scipy_off_the_model_build():
    _imported("rigid")                       # fills the cache if it is empty
    assert _imported("rigid") == []
    assert _imported("elastic") == []
