"""bb_friction_ros.paper: every checked number has a unit, a source, a tolerance and a reason."""

import ast
import math
import pathlib

import pytest

from bb_friction_ros import paper

VALUES = {name: v for name, v in vars(paper).items() if isinstance(v, paper.PaperValue)}
TEST_DIR = pathlib.Path(__file__).resolve().parent
PACKAGE = TEST_DIR.parent / "bb_friction_ros"


@pytest.mark.parametrize("name", sorted(VALUES))
def test_each_value_is_documented(name):
    v = VALUES[name]
    assert v.key and v.unit and v.source and v.reason, name
    assert v.value is None or math.isfinite(v.value)
    if v.target:
        # exactly one way to check it, and a tolerance that can fail
        assert (v.band is not None) + (v.rel is not None or v.abs is not None) == 1, name


def test_keys_are_unique():
    assert len({v.key for v in VALUES.values()}) == len(VALUES)


def test_holds_is_the_stated_tolerance():
    assert paper.F_B2B_AN.holds(3.74 * 1.0099) and not paper.F_B2B_AN.holds(3.74 * 1.0101)
    assert paper.EPS1_NUM.holds(0.899) and not paper.EPS1_NUM.holds(0.901)
    assert paper.B2B_PEAK_SHARE.holds(20.0) and not paper.B2B_PEAK_SHARE.holds(60.1)
    assert paper.F_B2B_B.holds(0.0) and not paper.F_B2B_B.holds(1e-300)
    assert not paper.PSI.holds(math.nan)
    with pytest.raises(ValueError, match="not a target"):
        paper.SCREW_F_B2B_A.holds(1.92)
    assert paper.SCREW_F_B2B_A.within(1.039) is False       # the known gap, reported
    assert paper.T_NUM.within(0.01) is None


def test_tolerance_in_words():
    assert paper.F_B2B_NUM.tolerance_text() == "+-2 %"
    assert paper.EPS1_NUM.tolerance_text() == "+-0.03 pt"
    assert paper.K_F.tolerance_text() == "+-0.01"
    assert paper.B2B_GROUPS.tolerance_text() == "+-0"
    assert paper.B2B_PEAK_SHARE.tolerance_text() == "20 to 60 %"
    assert paper.T_NUM.tolerance_text() == ""


def test_paper_module_imports_nothing_of_the_package():
    tree = ast.parse((PACKAGE / "paper.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) \
                else [node.module or ""]
            assert not any(n.startswith("bb_friction_ros") for n in names)


def test_every_value_is_used():
    """No dead entry: each value is read by a test or by the reproduce report."""
    sources = "".join(p.read_text() for p in list(TEST_DIR.rglob("*.py"))
                      + [PACKAGE / "reproduce.py", PACKAGE / "ball_screw" / "reproduce.py"]
                      if p.name != "test_paper.py")
    unused = [n for n in VALUES if f"paper.{n}" not in sources
              and not any(v is VALUES[n] for v in paper.LINEAR_BEARING)]
    assert not unused
