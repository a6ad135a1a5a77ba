#!/usr/bin/env python3
"""Build the interface packages of ``interfaces/`` into the venv when the environment lacks them.

sim_node serves simulation_interfaces and publishes tf2_msgs/TFMessage; neither package is on
PyPI. In a Jazzy install (``/opt/ros/jazzy`` sourced) both are there and this does nothing. In
the ros-jazzy wheels set-up (``make build``) it:

1. installs the build-only wheels of ``requirements-interfaces.txt`` (the rosidl generators and
   the ament_cmake pieces their dependency chain misses) with the venv's pip;
2. rewrites, in the exported CMake files of the installed message wheels, the include
   directories of the machine that built the wheels (``/opt/python/cp311-cp311/include/...``
   and numpy's include under the same root) to this interpreter's: ``sysconfig``'s include and
   ``numpy.get_include()`` (rosidl_generator_py's targets export them; without the rewrite
   CMake stops on a missing directory). Only paths that do not exist are rewritten, so it is
   idempotent and leaves a correct install alone;
3. builds ``interfaces/*`` with colcon (merged install into the venv prefix: the venv is on
   ``AMENT_PREFIX_PATH`` and its ``lib/`` on the library path the wheels set up, so rclpy finds
   the new types with no other environment change).

Usage: ``python tools/build_interfaces.py [--force]`` from the checkout (the Makefile runs it
with the venv's python; it keeps its own stamp, so an unchanged tree is not rebuilt). Exit code
0 when the packages are importable afterwards (or were there already), 1 otherwise.
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import sysconfig
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
INTERFACES = ROOT / 'interfaces'
REQUIREMENTS = ROOT / 'requirements-interfaces.txt'
#: the packages, and one module of each whose import proves the package usable from rclpy
PACKAGES = {'simulation_interfaces': 'simulation_interfaces.srv', 'tf2_msgs': 'tf2_msgs.msg'}
#: what the wheels' exported CMake files name (the wheel builder's interpreter)
_BUILDER_PYTHON_INCLUDE = re.compile(r'/opt/python/[^/;"\s]+/include/python3\.\d+')
_BUILDER_NUMPY_INCLUDE = re.compile(
    r'/opt/python/[^;"\s]*?/site-packages/numpy/(?:_core|core)/include')


def _log(line: str) -> None:
    print(f'[interfaces] {line}', flush=True)


def provided_elsewhere(prefix: Path) -> list[str]:
    """The packages that something other than ``prefix`` (the venv, where this script builds
    them) provides: an ament prefix on ``AMENT_PREFIX_PATH`` (a Jazzy install, another
    workspace), or a module this interpreter imports from outside ``prefix``."""
    found = []
    for entry in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if not entry or Path(entry).resolve() == prefix.resolve():
            continue
        index = Path(entry) / 'share' / 'ament_index' / 'resource_index' / 'packages'
        found += [name for name in PACKAGES if (index / name).is_file()]
    for name, module in PACKAGES.items():
        done = subprocess.run([sys.executable, '-c', f'import {module} as m; print(m.__file__)'],
                              capture_output=True, text=True, check=False)
        where = done.stdout.strip()
        if done.returncode == 0 and where and not Path(where).resolve().is_relative_to(
                prefix.resolve()):
            found.append(name)
    return sorted(set(found))


def importable() -> list[str]:
    """The packages whose Python module a fresh interpreter imports (a new process: the
    library path of the wheels is set at interpreter start)."""
    ok = []
    for name, module in PACKAGES.items():
        done = subprocess.run([sys.executable, '-c', f'import {module}'],
                              capture_output=True, check=False)
        if done.returncode == 0:
            ok.append(name)
    return ok


def fix_exported_paths(prefix: Path) -> int:
    """Rewrite the wheel builder's Python and numpy include directories in the exported CMake
    files under ``prefix/share`` to this interpreter's; return the number of files changed."""
    python_include = sysconfig.get_paths()['include']
    try:
        import numpy
        numpy_include = numpy.get_include()
    except ImportError:          # rosidl_generator_py needs numpy: colcon will say so
        numpy_include = None
    changed = 0
    for path in sorted((prefix / 'share').glob('*/cmake/*.cmake')):
        text = path.read_text(encoding='utf-8')
        if '/opt/python/' not in text:
            continue
        new = _BUILDER_PYTHON_INCLUDE.sub(
            lambda m: m.group(0) if Path(m.group(0)).is_dir() else python_include, text)
        if numpy_include is not None:
            new = _BUILDER_NUMPY_INCLUDE.sub(
                lambda m: m.group(0) if Path(m.group(0)).is_dir() else numpy_include, new)
        if new != text:
            path.write_text(new, encoding='utf-8')
            changed += 1
    return changed


def build(prefix: Path) -> None:
    """pip install the build wheels, fix their CMake exports, colcon build into ``prefix``."""
    subprocess.run([sys.executable, '-m', 'pip', 'install', '-q', '-r', str(REQUIREMENTS)],
                   check=True)
    _log(f'exported CMake paths rewritten in {fix_exported_paths(prefix)} file(s)')
    colcon = Path(sys.executable).parent / 'colcon'
    cmd = [str(colcon), '--log-base', str(ROOT / 'log' / 'interfaces'), 'build',
           '--base-paths', str(INTERFACES), '--build-base', str(ROOT / 'build' / 'interfaces'),
           '--install-base', str(prefix), '--merge-install',
           '--cmake-args', '-DBUILD_TESTING=OFF', f'-DPython3_EXECUTABLE={sys.executable}',
           '-DCMAKE_BUILD_TYPE=Release']
    subprocess.run(cmd, check=True, cwd=ROOT)


def main(argv: list[str] | None = None) -> int:
    """Build when needed; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--force', action='store_true',
                        help='build even if another prefix provides the packages')
    args = parser.parse_args(argv)
    prefix = Path(sys.prefix)
    elsewhere = provided_elsewhere(prefix)
    if not args.force and len(elsewhere) == len(PACKAGES):
        _log(f'{", ".join(elsewhere)} provided by the environment: not built')
        return 0
    build(prefix)
    missing = sorted(set(PACKAGES) - set(importable()))
    if missing:
        _log(f'built, but {", ".join(missing)} cannot be imported by {sys.executable}')
        return 1
    _log(f'{", ".join(PACKAGES)} built into {prefix}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
