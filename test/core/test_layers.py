"""The layers of docs/ARCHITECTURE.md: the core imports no ROS, and no layer imports upwards.

Both checks read the real import graph: the first imports the core in a fresh interpreter in
which rclpy and every message package are made unimportable; the second parses every module's
imports (module level and inside functions) and fails on an edge against the layer order.
"""
import ast
from pathlib import Path
import subprocess
import sys

import pytest

PKG = Path(__file__).resolve().parents[2] / 'crawler_sim'

# Allowed imports between layers: cli/ros/sweep -> bag -> core. A layer may always import
# itself.
ALLOWED = {
    'core': {'core'},
    'bag': {'bag', 'core'},
    'ros': {'ros', 'bag', 'core'},
    'sweep': {'sweep', 'bag', 'core'},
    'cli': {'cli', 'bag', 'core', 'ros', 'sweep'},
    'envs': {'envs', 'core'},       # Gymnasium environments over the core's plant (no ROS)
}
ROS_MODULES = ('rclpy', 'rosidl_runtime_py', 'builtin_interfaces', 'std_msgs', 'sensor_msgs',
               'nav_msgs', 'geometry_msgs', 'visualization_msgs', 'diagnostic_msgs',
               'rosgraph_msgs', 'trajectory_msgs', 'std_srvs', 'rcl_interfaces',
               'ament_index_python', 'mcap', 'mcap_ros2')

BLOCKER = '''
import sys
class _Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {blocked!r}:
            raise ImportError('blocked for the layer test: ' + name)
        return None
sys.meta_path.insert(0, _Block())
import crawler_sim, crawler_sim.core
import crawler_sim.core.solvers.exact, crawler_sim.core.plant, crawler_sim.core.scene
import crawler_sim.core.plant.replay, crawler_sim.core.plant.config
import crawler_sim.core.actuator
from crawler_sim import Crawler, simulate, gaits, verify, Stepper
run = simulate(Crawler([1.0, 1.0], [1.0, 2.0]), gaits.Sinusoid(1.0, 0.2, 1.0), 2.0)
assert abs(run.x[-1, 0] - run.x[0, 0]) > 0.0
bad = sorted(m for m in sys.modules if m.split('.')[0] in {blocked!r})
assert not bad, bad
print('ok')
'''


def test_the_core_imports_and_runs_with_every_ros_module_unimportable():
    code = BLOCKER.format(blocked=set(ROS_MODULES))
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=PKG.parent, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'ok'


def _layer(module: str) -> str | None:
    parts = module.split('.')
    if parts[0] != 'crawler_sim' or len(parts) < 2:
        return None
    return parts[1] if parts[1] in ALLOWED else None


def _imports(path: Path) -> list[tuple[str, int]]:
    """Absolute names of every crawler_sim module imported by ``path`` (with line numbers)."""
    rel = path.relative_to(PKG.parent).with_suffix('')
    package = list(rel.parts[:-1]) if rel.name != '__init__' else list(rel.parts[:-1])
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1]
                name = '.'.join(base + ([node.module] if node.module else []))
            else:
                name = node.module or ''
            out.append((name, node.lineno))
            out += [(f'{name}.{a.name}', node.lineno) for a in node.names]
    return [(n, line) for n, line in out if n.startswith('crawler_sim')]


MODULES = sorted(p for p in PKG.rglob('*.py'))


@pytest.mark.parametrize('path', MODULES, ids=lambda p: str(p.relative_to(PKG)))
def test_no_module_imports_against_the_layer_order(path):
    own = _layer('.'.join(path.relative_to(PKG.parent).with_suffix('').parts))
    if own is None:
        return   # crawler_sim/__init__.py re-exports the core: it is the public face, not a layer
    bad = [(name, line) for name, line in _imports(path)
           if _layer(name) is not None and _layer(name) not in ALLOWED[own]]
    assert not bad, f'{path.relative_to(PKG)} ({own}) imports {bad}'


def test_the_layer_checker_flags_an_upward_import(tmp_path):
    # the checker itself must be able to fail: a core module importing crawler_sim.ros
    fake = PKG / 'core' / '_layer_probe_tmp.py'
    fake.write_text('from ..ros import messages\n')
    try:
        names = [n for n, _ in _imports(fake)]
    finally:
        fake.unlink()
    assert 'crawler_sim.ros' in names and _layer('crawler_sim.ros') not in ALLOWED['core']


def _every_import(path: Path) -> set[str]:
    """Top-level names of every module ``path`` imports (absolute imports only)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name.split('.')[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module.split('.')[0])
    return names


@pytest.mark.parametrize('path', MODULES, ids=lambda p: str(p.relative_to(PKG)))
def test_the_package_imports_nothing_from_the_tests_or_the_benchmarks(path):
    """Issue 27: what is installed must work installed: scaffolding lives in test/ and
    benchmarks/, outside the package."""
    assert not _every_import(path) & {'test', 'tests', 'benchmarks', 'tools'}
