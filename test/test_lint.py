"""ament-style lint, as the tests ROS 2 generates for an ament_python package.

flake8 (pycodestyle + pyflakes, line length 99) over the Python sources, and pep257
(pydocstyle with the ament convention) over the package. They run through ament_flake8 and
ament_pep257, the ROS 2 Jazzy linters, so ``colcon test`` in a ROS workspace checks the same.
"""

import pathlib

import pytest
from ament_flake8.main import main_with_errors as flake8_main_with_errors
from ament_pep257.main import main as pep257_main

ROOT = pathlib.Path(__file__).resolve().parent.parent
# Directories and files flake8 checks; ones that do not exist (yet) are skipped.
FLAKE8_PATHS = ['bb_friction_ros', 'test', 'bench', 'tools', 'setup.py']
PEP257_PATHS = ['bb_friction_ros']
LINE_LENGTH = 99


def existing(paths):
    """Return the absolute paths of those of paths that exist under the repository root."""
    return [str(ROOT / p) for p in paths if (ROOT / p).exists()]


@pytest.mark.flake8
@pytest.mark.linter
def test_flake8(monkeypatch):
    # ament_flake8 walks the working directory for AMENT_IGNORE markers.
    monkeypatch.chdir(ROOT)
    rc, errors = flake8_main_with_errors(
        argv=['--linelength', str(LINE_LENGTH)] + existing(FLAKE8_PATHS))
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257(monkeypatch):
    monkeypatch.chdir(ROOT)
    rc = pep257_main(argv=existing(PEP257_PATHS))
    assert rc == 0, (
        'Found docstring style errors, listed in the captured stderr. The ament convention '
        'checks every pydocstyle code but D100-D107, D203, D212 and D404; so a multi-line '
        'docstring starts its summary on the line after the opening quotes (D213).')
