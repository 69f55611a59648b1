"""
Public API documentation, pvlib style: numpydoc Parameters / Returns with units for the
functions a library user calls, and a References section naming the paper's equations in the
module docstring of every physics module.
"""

import importlib
import inspect
import re

import pytest

PHYSICS_MODULES = [
    "contact.hertz", "contact.friction_maps",
    "linear_bearing.numerical", "linear_bearing.analytical", "linear_bearing.case_study",
    "linear_bearing.geometry", "linear_bearing.mitigation",
    "ball_screw.geometry", "ball_screw.single_ball", "ball_screw.b2b", "ball_screw.solver",
    "ball_screw.kernel", "ball_screw.screw_model", "ball_screw.module",
    "ball_screw.whole_screw", "ball_screw.simulation",
]

PUBLIC_API = [
    "contact.hertz:HertzContact.ball_in_straight_groove", "contact.hertz:HertzContact.psi",
    "linear_bearing.analytical:velocity_deviation_eq22",
    "linear_bearing.analytical:velocity_deviation_eq33",
    "linear_bearing.analytical:b2b_force_eq30", "linear_bearing.analytical:b2b_loss_eq32",
    "linear_bearing.mitigation:matched_top_deviations",
    "linear_bearing.mitigation:two_ball_relative_motion",
    "linear_bearing.case_study:LinearPairCase.numerical",
    "linear_bearing.case_study:LinearPairCase.analytical",
    "linear_bearing.case_study:LinearPairCase.numerical_grid",
    "model_file:load_ball_screw", "model_file:load_model_file",
    "ball_screw.module:solve_two_ball_module",
    "ball_screw.whole_screw:WholeScrew.step", "ball_screw.simulation:run_whole_screw",
    "ball_screw.simulation:summarize",
]

UNIT = re.compile(r"\[[^\]]+\]")
UNIT_SUFFIX = re.compile(r"_(m|n|rad|s|pa|m_s|rad_s|w|nm|deg)$|^(eps\d?|psi|mu|k_f|rho)$")


def _section(doc, name):
    """Return the body of a numpydoc section (up to the next section or the end)."""
    m = re.search(rf"^{name}\n-+\n(.*?)(?=^\w[\w ]*\n-+\n|\Z)", doc, re.M | re.S)
    return m.group(1) if m else None


def _resolve(target):
    module, _, qual = target.partition(":")
    obj = importlib.import_module(f"bb_friction_ros.{module}")
    for part in qual.split("."):
        obj = getattr(obj, part)
    return obj


@pytest.mark.parametrize("module", PHYSICS_MODULES)
def test_physics_module_cites_the_paper(module):
    doc = importlib.import_module(f"bb_friction_ros.{module}").__doc__
    refs = _section(inspect.cleandoc(doc), "References")
    assert refs and "10.1115/1.4043630" in refs
    assert re.search(r"Eqs?\. \(|Sec\. \d", refs), "name the equations or sections used"


@pytest.mark.parametrize("target", PUBLIC_API)
def test_public_function_documents_parameters_and_units(target):
    fn = _resolve(target)
    doc = inspect.getdoc(fn)
    params = _section(doc, "Parameters")
    returns = _section(doc, "Returns")
    assert params and returns, f"{target}: numpydoc Parameters and Returns"
    names = [n for n in inspect.signature(fn).parameters if n not in ("self", "cls")]
    entries = {}          # header line of each entry -> its description
    for line in params.splitlines():
        if line and not line.startswith(" "):
            header = line.split(":")[0].strip()
            entries[header] = ""
        elif entries:
            entries[header] += line
    missing = [n for n in names if not any(n in h.split(", ") for h in entries)]
    assert not missing, f"{target}: undocumented parameters {missing}"
    # a physical quantity (named with its unit, or a bare physics symbol) states its unit
    for header, text in entries.items():
        if any(UNIT_SUFFIX.search(n) for n in header.split(", ")):
            assert UNIT.search(text), f"{target}: {header} without its unit"
    # numbers returned state their units; a returned object (a class) documents its own
    # (each named value ``name : Type`` of several is checked alike)
    heads = [line for line in returns.splitlines() if line and not line.startswith(" ")]
    for head in heads:
        kind = head.split(" : ")[-1].lstrip("(").split()[0]
        assert kind[0].isupper() or UNIT.search(returns), f"{target}: returns without units"
