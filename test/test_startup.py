"""
What friction_node's start-up imports: never a timing, only the modules.

Launch to "ready" is measured in bench/bench_startup.py (docs/node_latency.md).  What can be
tested is what start-up must not load: each of these cost tens to hundreds of milliseconds
and none is needed to answer an input once the caches are warm (the numba cache and the
friction maps' table cache, filled by the first build).
"""

import os
import subprocess
import sys

from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import build_runner

# scipy.optimize/special: the Hertz constants and the B2B separation come from the table
# cache; scipy.linalg and coverage: imported by numba's own modules unless hidden
# (compiled._import_numba; 0.14-0.2 s and 58 ms); the rest: workflows, plotting, the bag
# reader and the test tool
NOT_AT_START = ("scipy.optimize", "scipy.special", "scipy.interpolate", "scipy.linalg",
                "coverage", "matplotlib", "dask", "pyarrow", "pandas", "rosbags", "pytest")

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
    # without pytest-cov's start-up hook, which imports coverage in every subprocess
    env = {k: v for k, v in os.environ.items() if not k.startswith("COV_CORE_")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [], f"imported at start-up: {out.stdout.strip()}"


def test_the_check_sees_an_import():
    """The same check in a process that imports one of them reports it (it can fail)."""
    code = "import scipy.special\n" + CODE.format(top={"scipy"}, names=("scipy.special",))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    assert "scipy.special" in out.stdout.split()


LOADED = """
import math, sys
from bb_friction_ros.config import bundled_config
from bb_friction_ros.runner import InputSample, build_runner

def loaded():
    # every numba dispatcher of the package, with the signatures it has compiled or loaded
    out = set()
    for name, mod in list(sys.modules.items()):
        if not name.startswith("bb_friction_ros"):
            continue
        for attr, obj in vars(mod).items():
            if hasattr(obj, "py_func") and hasattr(obj, "signatures"):
                out.update((name, attr, str(sig)) for sig in obj.signatures)
    return out

runner = build_runner(bundled_config("ball_screw.yaml"), 100.0)
ready = loaded()
w = 2.0 * math.pi
angle, stamp = 0.0, 0.0
for k in range(60):                       # forward, then a reversal: warm steps both ways
    v = w if k < 30 else -w
    angle += v * 0.001
    stamp += 0.001
    runner.process(InputSample(stamp, angle, v, 1500.0))
assert runner.stats.model_steps > 10, runner.stats.model_steps
print(len(ready))
print("\\n".join(sorted(" ".join(x) for x in loaded() - ready)))
"""


def test_nothing_compiles_or_loads_after_ready():
    """
    The model built as the node builds it has loaded every compiled call a step makes.

    numba loads a kernel at its first call (67 ms from its cache for ``kernel.warm_step``,
    seconds to compile): one loaded after "ready" stalled the node's first warm step and
    made it fall ~70 inputs behind at 1 kHz.  Checked in a fresh process by the kernels'
    signatures before and after steps both ways; the first line shows the check sees some.
    """
    out = subprocess.run([sys.executable, "-c", LOADED], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    first, *new = out.stdout.strip().split("\n")
    assert int(first) > 0, "no compiled call seen at ready: the check sees nothing"
    assert [n for n in new if n] == [], f"loaded after ready: {new}"
