"""What the package declares against what it imports (issue 27: ``pip install .`` installed
none of the dependencies), and the rosdep keys of package.xml (issue 12).

- every third-party module the package imports is brought by ``install_requires`` or an extra
  (``ros`` for ROS 2, ``sweep`` for the tables and Dask), and nothing is declared that nothing
  imports (``mcap-ros2-support`` was);
- package.xml names only rosdep keys that exist for the bag dependencies: checked by hand against
  ros/rosdistro rosdep/python.yaml: ``mcap-ros2-support`` (pip; pulls mcap, zstandard, lz4) and
  ``python3-rosbags-pip`` exist; ``python3-mcap``, ``python3-mcap-ros2-support`` and
  ``python3-rosbags`` do not. mcap has no key of its own, so mcap-ros2-support stays there for it.
"""
from __future__ import annotations

import ast
from pathlib import Path
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

REPO = Path(__file__).resolve().parents[1]
NOT_IN_ROSDISTRO = {'python3-mcap', 'python3-mcap-ros2-support', 'python3-rosbags'}
#: import name -> distribution name, where they differ
DISTRIBUTION = {'yaml': 'PyYAML', 'distributed': 'dask'}
#: modules that come with ROS 2 (a Jazzy install, or the `ros` extra's wheels)
ROS = {'rclpy', 'rcl_interfaces', 'ament_index_python', 'builtin_interfaces', 'std_msgs',
       'std_srvs', 'sensor_msgs', 'geometry_msgs', 'nav_msgs', 'trajectory_msgs',
       'visualization_msgs', 'diagnostic_msgs', 'rosgraph_msgs', 'rosidl_parser',
       # the simulator-standard interfaces: a Jazzy install's, or built into install/ by
       # `make build` from interfaces/ (requirements-interfaces.txt)
       'simulation_interfaces', 'tf2_msgs'}
#: modules only the sweep extra brings (imported by crawler_sim.sweep and its CLI commands)
SWEEP = {'pandas', 'pyarrow', 'distributed', 'dask'}   # dask[distributed]: both modules


def imported() -> set[str]:
    names = set()
    for path in (REPO / 'crawler_sim').rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names |= {a.name.split('.')[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names.add(node.module.split('.')[0])
    return {n for n in names if n not in sys.stdlib_module_names and n != 'crawler_sim'}


def setup_kwargs() -> dict:
    """install_requires and extras_require of setup.py, read from its source."""
    tree = ast.parse((REPO / 'setup.py').read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'setup')
    return {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords
            if kw.arg in ('install_requires', 'extras_require')}


def _name(requirement: str) -> str:
    return re.split(r'[<>=\[ ;]', requirement, maxsplit=1)[0].lower()


def test_install_requires_brings_what_the_package_imports_and_nothing_else():
    kw = setup_kwargs()
    core = {_name(r) for r in kw['install_requires']}
    sweep = {_name(r) for r in kw['extras_require']['sweep']}
    ros = {_name(r) for r in kw['extras_require']['ros']}
    needed = {DISTRIBUTION.get(m, m).lower() for m in imported() - ROS - SWEEP}
    assert needed == core, (needed ^ core)
    assert {DISTRIBUTION.get(m, m).lower() for m in SWEEP} == sweep
    assert ros == {'ros-jazzy-rclpy', 'ros-jazzy-common-interfaces'}
    assert imported() & ROS            # the ROS modules the extra brings are really imported


def test_mcap_ros2_support_is_a_test_dependency_only():
    assert 'mcap_ros2' not in imported()
    kw = setup_kwargs()
    assert 'mcap-ros2-support' not in {_name(r) for r in kw['install_requires']}
    assert 'mcap-ros2-support' in {_name(r) for r in kw['extras_require']['test']}


def depends() -> set[str]:
    root = ET.parse(REPO / 'package.xml').getroot()
    tags = ('depend', 'exec_depend', 'test_depend', 'build_depend')
    return {el.text.strip() for tag in tags for el in root.iter(tag)}


def test_no_bag_dependency_uses_a_key_missing_from_rosdistro():
    assert not depends() & NOT_IN_ROSDISTRO


#: what `make run` installs besides the package's requirements: the build (colcon, Cython)
BUILD = {'cython', 'colcon-common-extensions', 'ros-jazzy-ament-package'}


def requirement_lines(name: str) -> dict[str, str]:
    """name -> requirement (comments and spaces cut) of one requirements file, without the
    files it includes (``-r``)."""
    out = {}
    for line in (REPO / name).read_text().splitlines():
        req = line.split('#')[0].replace(' ', '')
        if req and not req.startswith('-'):
            out[_name(req)] = req
    return out


def test_the_requirement_files_are_setup_pys_lists_split_as_make_installs_them():
    """``make run`` installs requirements.txt (install_requires, the ros extra, the build) and
    no test or lint tool; ``make test`` adds requirements-test.txt (requirements-sweep.txt, the
    test and lint extras). The same specifiers in both places (issue 43: a lean run venv)."""
    kw = setup_kwargs()
    extras = kw['extras_require']

    def spec(reqs: list[str]) -> dict[str, str]:
        return {_name(r): r.replace(' ', '') for r in reqs}

    run = requirement_lines('requirements.txt')
    assert {k: v for k, v in run.items() if k not in BUILD} == spec(
        kw['install_requires'] + extras['ros'])
    assert BUILD <= set(run)
    assert requirement_lines('requirements-sweep.txt') == spec(extras['sweep'])
    assert requirement_lines('requirements-test.txt') == spec(extras['test'] + extras['lint'])
    assert '-r requirements-sweep.txt' in (REPO / 'requirements-test.txt').read_text()
    tools = {'pytest', 'hypothesis', 'ruff', 'yourdfpy', 'trimesh', 'mcap-ros2-support'}
    assert not tools & set(run), 'a test or lint tool in make run\'s requirements'


def _make_dry_run(target: str) -> str:
    """The commands ``make TARGET`` would run with every target out of date (``-B -n``: nothing
    runs)."""
    proc = subprocess.run(['make', '-B', '-n', target], cwd=REPO, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


@pytest.mark.skipif(shutil.which('make') is None, reason='needs make')
def test_make_run_installs_no_test_tool_and_make_test_adds_them_without_rebuilding():
    run = _make_dry_run('run')
    assert 'pip install --no-compile -r requirements.txt' in run
    assert 'requirements-test.txt' not in run
    test = _make_dry_run('test')
    assert 'pip install --no-compile -r requirements-test.txt' in test
    # the compiled build does not wait for the test tools: adding them leaves it up to date
    prereqs = subprocess.run(['make', '-p', '-n', '-q', 'build'], cwd=REPO, capture_output=True,
                             text=True, timeout=120).stdout
    built = next(line for line in prereqs.splitlines() if line.startswith('install/.built:'))
    assert '.installed-test' not in built and 'requirements-test' not in built, built


def test_the_bag_libraries_are_declared_with_their_rosdistro_keys():
    assert {'mcap-ros2-support', 'python3-rosbags-pip'} <= depends()
    requirements = (REPO / 'requirements.txt').read_text()
    for pip_name in ('mcap', 'rosbags'):
        assert any(_name(line) == pip_name for line in requirements.splitlines()), pip_name
