"""
tools/import_epos.py refuses flags that would write wrong numbers.

A negative nominal torque flips every torque's sign, zero erases them, NaN poisons every row;
a NaN axial load does the same to ``axial_load_n``.  Each is refused by argparse naming the
flag (exit 2), before any file is written.
"""

import importlib.util
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parents[1] / "tools" / "import_epos.py"
EXCERPT = Path(__file__).resolve().parent / "discrepancy" / "data" / \
    "epos_driveNo3_steady_1rpm_excerpt.csv"


def _importer():
    spec = importlib.util.spec_from_file_location("import_epos_flags", TOOLS)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


epos = _importer()


@pytest.mark.parametrize("flag,value", [
    ("--nominal-torque-nm", "-9.84e-3"), ("--nominal-torque-nm", "0"),
    ("--nominal-torque-nm", "nan"), ("--nominal-torque-nm", "inf"),
    ("--axial-load-n", "nan"), ("--axial-load-n", "-inf"),
])
def test_bad_scale_flags_are_refused_by_name(tmp_path, capsys, flag, value):
    out = tmp_path / "x.csv"
    with pytest.raises(SystemExit) as exc:
        epos.main([str(EXCERPT), "--out", str(out), f"{flag}={value}"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {flag}" in err and "finite" in err
    assert not out.exists()


def test_good_flags_still_import(tmp_path):
    out = tmp_path / "x.csv"
    assert epos.main([str(EXCERPT), "--out", str(out), "--nominal-torque-nm", "0.02",
                      "--axial-load-n", "-3.5"]) == 0
    assert out.exists()


@pytest.mark.parametrize("kwargs,name", [
    ({"nominal_torque_nm": -1.0}, "nominal_torque_nm"),
    ({"nominal_torque_nm": float("nan")}, "nominal_torque_nm"),
    ({"axial_load_n": float("nan")}, "axial_load_n"),
])
def test_to_si_refuses_bad_scales(kwargs, name):
    t, rpm, pct, _ = epos.read_epos(EXCERPT)
    with pytest.raises(ValueError, match=name):
        epos.to_si(t, rpm, pct, **kwargs)
