"""
What friction_node's start-up imports (issue 22, item 5): never a timing, only the modules.

Launch to "ready" is measured in bench/bench_startup.py (docs/node_latency.md).  What can be
tested is what start-up must not load: each of these cost tens to hundreds of milliseconds
and none is needed to answer an input once the caches are warm (the numba cache and the
friction maps' table cache, filled by the first build).
"""

import subprocess
import sys

from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import build_runner

# scipy.optimize/special: the Hertz constants and the B2B separation come from the table
# cache; the rest: workflows, plotting, the bag reader and the test tool
NOT_AT_START = ("scipy.optimize", "scipy.special", "scipy.interpolate", "matplotlib",
                "dask", "pyarrow", "pandas", "rosbags", "pytest")

CODE = """
import sys
from bb_friction_ros import node
from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import build_runner
build_runner(bundled_config("ball_screw.yaml"), 100.0)
print(" ".join(sorted(m for m in sys.modules if m.split(".")[0] in {top}
                      and m.startswith({names}))))
"""


def test_a_warm_start_imports_no_workflow_or_fitting_module():
    """Build the node's model as the node does, in a fresh process, caches warm."""
    build_runner(bundled_config("ball_screw.yaml"), 100.0)      # fills the caches if empty
    names = tuple(NOT_AT_START)
    code = CODE.format(top={n.split(".")[0] for n in names}, names=names)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [], f"imported at start-up: {out.stdout.strip()}"


def test_the_check_sees_an_import():
    """The same check in a process that imports one of them reports it (it can fail)."""
    code = "import scipy.special\n" + CODE.format(top={"scipy"}, names=("scipy.special",))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    assert "scipy.special" in out.stdout.split()
