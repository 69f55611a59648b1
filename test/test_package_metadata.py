"""package.xml, setup.py and the code agree: name, version, dependencies, installed files."""

import ast
import importlib
import os
import pathlib
import runpy
import sys
import xml.etree.ElementTree as ET
from unittest import mock

import pytest

import bb_friction_ros

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = 'bb_friction_ros'

# Top-level Python module -> rosdep key that provides it. An import of a module missing here
# fails test_package_xml_declares_runtime_deps: add the module and its rosdep key, and declare the
# key as <exec_depend> in package.xml.
ROSDEP_KEYS = {
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'matplotlib': 'python3-matplotlib',
    'yaml': 'python3-yaml',
    'tqdm': 'python3-tqdm',
    'dask': 'python3-dask',
    'distributed': 'python3-distributed',
    'pyarrow': 'python3-pyarrow-pip',
    'rosbags': 'python3-rosbags-pip',
    'numba': 'python3-numba',
    'llvmlite': 'python3-llvmlite',
    'pytest': 'python3-pytest',
    'rclpy': 'rclpy',
    'rcl_interfaces': 'rcl_interfaces',
    'ament_index_python': 'ament_index_python',
    'builtin_interfaces': 'builtin_interfaces',
    'std_msgs': 'std_msgs',
    'geometry_msgs': 'geometry_msgs',
    'sensor_msgs': 'sensor_msgs',
    'trajectory_msgs': 'trajectory_msgs',
    'diagnostic_msgs': 'diagnostic_msgs',
    'bb_friction_msgs': 'bb_friction_msgs',
}


def read_package_xml(path):
    """Return the root element of a package.xml."""
    return ET.parse(path).getroot()


def depends(root, *tags):
    """Return the dependency names declared with any of tags (depend counts for all)."""
    return {e.text.strip() for tag in tags + ('depend',) for e in root.findall(tag)}


@pytest.fixture(scope='module')
def package_xml():
    return read_package_xml(ROOT / 'package.xml')


@pytest.fixture(scope='module')
def setup_kwargs():
    """Run setup.py as colcon and pip do (from the repository root), capturing setup()'s kwargs."""
    captured = {}
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        with mock.patch('setuptools.setup', side_effect=captured.update):
            runpy.run_path(str(ROOT / 'setup.py'), run_name='__main__')
    finally:
        os.chdir(cwd)
    return captured


def console_scripts(setup_kwargs):
    """Return {script name: 'module:function'} of setup.py's console_scripts."""
    scripts = {}
    for spec in setup_kwargs['entry_points']['console_scripts']:
        name, target = (s.strip() for s in spec.split('='))
        scripts[name] = target
    return scripts


def test_package_xml_is_ament_python_format_3(package_xml):
    assert package_xml.tag == 'package'
    assert package_xml.get('format') == '3'
    assert package_xml.findtext('name') == PACKAGE
    assert package_xml.findtext('export/build_type') == 'ament_python'
    assert package_xml.findtext('license') == 'Apache-2.0'
    assert (ROOT / 'LICENSE').is_file()


def test_name_and_version_agree(package_xml, setup_kwargs):
    assert setup_kwargs['name'] == package_xml.findtext('name') == PACKAGE
    version = package_xml.findtext('version')
    assert setup_kwargs['version'] == version == bb_friction_ros.__version__


def test_console_scripts_exist(setup_kwargs):
    scripts = console_scripts(setup_kwargs)
    assert scripts['bb-friction'] == 'bb_friction_ros.cli:main'
    for name, target in scripts.items():
        module, function = target.split(':')
        assert callable(getattr(importlib.import_module(module), function)), name


# Modules loaded only by pytest (the pytest11 plugin): their imports are
# test dependencies, not runtime ones.
TEST_TIME_MODULES = {'pytest_plugin.py'}


def imported_top_level_modules(directory, skip=()):
    """Return {top-level module: first file importing it} over all .py files under directory."""
    found = {}
    for path in sorted(directory.rglob('*.py')):
        if path.relative_to(directory).as_posix() in skip:
            continue
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module]
            else:
                continue
            for name in names:
                found.setdefault(name.split('.')[0], path.relative_to(ROOT))
    return found


def test_package_xml_declares_runtime_deps(package_xml, setup_kwargs):
    # The console scripts (and the node) run code from anywhere in the package: every
    # third-party module it imports must be an exec_depend of package.xml.
    for target in console_scripts(setup_kwargs).values():
        assert target.split('.')[0] == PACKAGE
    declared = depends(package_xml, 'exec_depend')
    problems = []
    for module, where in sorted(imported_top_level_modules(ROOT / PACKAGE,
                                                           TEST_TIME_MODULES).items()):
        if module == PACKAGE or module in sys.stdlib_module_names:
            continue
        key = ROSDEP_KEYS.get(module)
        if key is None:
            problems.append(f'{where} imports {module!r}: add its rosdep key to ROSDEP_KEYS '
                            'in this test and an <exec_depend> to package.xml')
        elif key not in declared:
            problems.append(f'{where} imports {module!r}: package.xml lacks '
                            f'<exec_depend>{key}</exec_depend>')
    assert not problems, '\n'.join(problems)
    # The ROS interfaces the node uses, declared from the start.
    assert {'rclpy', 'std_msgs', 'geometry_msgs', 'sensor_msgs', 'diagnostic_msgs',
            'bb_friction_msgs'} <= declared


def test_data_files(setup_kwargs):
    data_files = {dest: set(files) for dest, files in setup_kwargs['data_files']}
    assert data_files['share/ament_index/resource_index/packages'] == {f'resource/{PACKAGE}'}
    assert (ROOT / 'resource' / PACKAGE).is_file()
    assert 'package.xml' in data_files[f'share/{PACKAGE}']
    configs = {str(p.relative_to(ROOT)) for p in (ROOT / 'config').glob('*.yaml')}
    assert data_files[f'share/{PACKAGE}/config'] == configs


def test_interface_package(package_xml):
    msgs_xml = read_package_xml(ROOT / 'msg_defs' / 'bb_friction_msgs' / 'package.xml')
    assert msgs_xml.get('format') == '3'
    assert msgs_xml.findtext('name') == 'bb_friction_msgs'
    assert msgs_xml.findtext('export/build_type') == 'ament_cmake'
    assert msgs_xml.findtext('member_of_group') == 'rosidl_interface_packages'
    assert 'std_msgs' in depends(msgs_xml, 'build_depend', 'exec_depend')
    # Every .msg file is generated.
    cmake = (ROOT / 'msg_defs' / 'bb_friction_msgs' / 'CMakeLists.txt').read_text()
    for msg in (ROOT / 'msg_defs' / 'bb_friction_msgs' / 'msg').glob('*.msg'):
        assert f'"msg/{msg.name}"' in cmake


def test_pytest_is_a_test_dependency_only(package_xml, setup_kwargs):
    """pytest is no runtime dependency: the harness, the demo and the CLI run without it."""
    import subprocess
    assert 'python3-pytest' not in depends(package_xml, 'exec_depend')
    assert 'python3-pytest' in depends(package_xml, 'test_depend')
    plugins = setup_kwargs['entry_points']['pytest11']
    assert plugins == ['bb_friction_ros = bb_friction_ros.pytest_plugin']
    # pytest made unimportable, as on a robot without it
    code = ("import sys; sys.modules['pytest'] = None\n"
            "import bb_friction_ros.harness, bb_friction_ros.demo, bb_friction_ros.cli, "
            "bb_friction_ros.node\n"
            "from bb_friction_ros.cli import main; main(['demo', '--help'])\n")
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0 and 'usage' in run.stdout, run.stderr
    check = subprocess.run([sys.executable, '-c', code.replace('bb_friction_ros.node',
                            'bb_friction_ros.pytest_plugin')], capture_output=True,
                           text=True, timeout=120)
    assert check.returncode != 0 and 'pytest' in check.stderr   # the check can fail
