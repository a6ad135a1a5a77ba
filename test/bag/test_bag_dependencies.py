"""The bag layer uses its libraries (mcap, rosbags, zstandard, lz4) through their public API only:
no name-mangled attribute, no private attribute of an object that is not ours, no private
module or name imported, no class of a library subclassed (reaching into its state is what a
subclass of ``mcap.writer.Writer`` did). And MCAP files are read in one place, the scanner."""
from __future__ import annotations

import ast
from pathlib import Path
import re
import sys

BAG = Path(__file__).resolve().parents[2] / 'crawler_sim' / 'bag'
MANGLED = re.compile(r'^_[A-Za-z0-9]+__\w+')


def _trees() -> dict[Path, ast.Module]:
    return {path: ast.parse(path.read_text()) for path in sorted(BAG.glob('*.py'))}


def _own_private_names(trees) -> set[str]:
    """Private names the bag package defines itself: functions, methods, classes, attributes
    assigned anywhere, ``__slots__`` entries."""
    names = set()
    for tree in trees.values():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names.add(node.name)
            elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                names.add(node.attr)
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                names.add(node.id)
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                names.add(node.target.id)
    return {n for n in names if n.startswith('_')}


def _third_party(module: str) -> bool:
    root = module.split('.')[0]
    return root not in sys.stdlib_module_names and root != 'crawler_sim'


def _foreign(trees) -> set[str]:
    """Names bound by imports of third-party modules (not the standard library, not ours)."""
    names = set()
    for tree in trees.values():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and not node.level and _third_party(
                    node.module or ''):
                names |= {a.asname or a.name for a in node.names}
            elif isinstance(node, ast.Import):
                names |= {(a.asname or a.name).split('.')[0] for a in node.names
                          if _third_party(a.name)}
    return names


def private_accesses(trees) -> list[str]:
    """Name-mangled attributes, and private attributes the package does not define itself
    (read, written, or named in getattr/hasattr/setattr)."""
    own = _own_private_names(trees)
    found = []
    for path, tree in trees.items():
        for node in ast.walk(tree):
            where = f'{path.name}:{getattr(node, "lineno", "?")}'
            if isinstance(node, ast.Attribute):
                name = node.attr
            elif (isinstance(node, ast.Call) and getattr(node.func, 'id', '') in (
                    'getattr', 'hasattr', 'setattr') and len(node.args) >= 2
                    and isinstance(node.args[1], ast.Constant)
                    and isinstance(node.args[1].value, str)):
                name = node.args[1].value
            else:
                continue
            if name.startswith('_') and not name.endswith('__') and (
                    MANGLED.match(name) or name not in own):
                found.append(f'{where} {name}')
    return sorted(found)


def private_imports(trees) -> list[str]:
    """Private modules or names imported from a third-party package, and classes derived
    from a third-party class."""
    foreign = _foreign(trees)
    found = []
    for path, tree in trees.items():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and not node.level and _third_party(
                    node.module or ''):
                if any(part.startswith('_') for part in node.module.split('.')):
                    found.append(f'{path.name}: from {node.module}')
                found += [f'{path.name}: {node.module}.{a.name}' for a in node.names
                          if a.name.startswith('_')]
            elif isinstance(node, ast.Import):
                found += [f'{path.name}: import {a.name}' for a in node.names
                          if _third_party(a.name)
                          and any(p.startswith('_') for p in a.name.split('.'))]
            elif isinstance(node, ast.ClassDef):
                for base in node.bases:
                    root = base
                    while isinstance(root, ast.Attribute):
                        root = root.value
                    if isinstance(root, ast.Name) and root.id in foreign:
                        found.append(f'{path.name}: class {node.name}({ast.unparse(base)})')
    return found


def test_the_bag_layer_reads_no_private_attribute_of_a_dependency():
    assert private_accesses(_trees()) == []


def test_the_bag_layer_imports_no_private_module_or_name_and_subclasses_no_library_class():
    assert private_imports(_trees()) == []


def test_the_checks_catch_what_the_former_writer_subclass_did():
    sample = {Path('lean.py'): ast.parse(
        'from mcap.writer import Writer\n'
        'from mcap._chunk_builder import ChunkBuilder\n'
        'class LeanWriter(Writer):\n'
        '    def f(self):\n'
        '        builder = self._Writer__chunk_builder\n'
        '        builder.record_writer._buffer.tell()\n'
        '        return getattr(self, "_Writer__statistics")\n')}
    assert private_accesses(sample) == ['lean.py:5 _Writer__chunk_builder', 'lean.py:6 _buffer',
                                        'lean.py:7 _Writer__statistics']
    assert private_imports(sample) == ['lean.py: from mcap._chunk_builder',
                                       'lean.py: class LeanWriter(Writer)']


READING = re.compile(r'\\x89MCAP|ReadDataStream|StreamReader\(|make_reader\(|SeekingReader\(')


def mcap_readers(root: Path) -> set[str]:
    """Modules under ``root`` that read MCAP structure themselves (magic bytes, mcap's
    record streams or readers)."""
    return {str(path.relative_to(root)) for path in root.rglob('*.py')
            if READING.search(path.read_text())}


def test_one_record_walk_the_scanner_reads_every_mcap_file():
    """recover, load, info and the replay node read files through mcapfile.scan (the search
    after damage, resync.py, is part of it); the writer writes, it reads nothing back."""
    assert mcap_readers(BAG.parent) == {'bag/mcapfile.py', 'bag/resync.py'}


def test_no_module_of_the_package_reads_a_private_attribute_of_a_dependency():
    """The same check over the whole package (rclpy's privates were read by gait_node and the
    argument checks). Two names pass it knowingly: ``os._exit`` is public (documented in the
    standard library despite its underscore) and ``_alloc`` is the actuator's own method,
    defined in the compiled ``core/_actuator.pyx`` that the AST walk does not read."""
    package = BAG.parent
    trees = {path: ast.parse(path.read_text()) for path in sorted(package.rglob('*.py'))}
    assert 'def _alloc' in (package / 'core' / '_actuator.pyx').read_text()
    allowed = {'_exit', '_alloc'}
    found = [f for f in private_accesses(trees) if f.rsplit(' ', 1)[-1] not in allowed]
    assert found == []


# ----------------------------------------------------------------------- bags without ROS
# Issue 43: a bag is a file format (MCAP holding CDR), not a ROS process. Without rclpy and the
# message packages the layouts come from rosbags' Jazzy typestore (crawler_sim.bag.rosmsg).

ROS_MODULES = ('rclpy', 'rosidl_runtime_py', 'builtin_interfaces', 'std_msgs', 'sensor_msgs',
               'nav_msgs', 'geometry_msgs', 'visualization_msgs', 'diagnostic_msgs',
               'rosgraph_msgs', 'trajectory_msgs', 'std_srvs', 'rcl_interfaces',
               'ament_index_python')

WITHOUT_ROS = '''
import sys
class _Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {blocked!r}:
            raise ImportError('blocked: ' + name)
        return None
sys.meta_path.insert(0, _Block())
import numpy as np
from crawler_sim import Crawler, gaits, simulate
from crawler_sim.bag import info, load, plot, recover, record_trajectory
crawler = Crawler([0.5, 1.0, 0.7], mu=0.3)
run = simulate(crawler, gaits.Sinusoid([0.1, 0.12], [0.02, 0.01], 1.5, [0.0, 1.0]), 2.0)
commands = (np.array([0.0, 0.5, 1.7]), np.array([[0.1, 0.12], [0.11, 0.12], [0.1, 0.13]]))
record_trajectory({out!r}, run, commands=commands, scene={{'name': 'no_ros'}}, chunk_size=8192)
back = load({out!r})
assert np.array_equal(back.x, run.x) and np.array_equal(back.contact, run.contact)
assert len(back.events.t) == len(run.events) > 0 and back.bodies[0] == 'body_0'
assert 'status:    complete' in info({out!r})
plot({out!r}, {png!r})
data = open({out!r} + '/{name}_0.mcap', 'rb').read()
open({cut!r}, 'wb').write(data[:len(data) * 2 // 3])
recover({cut!r}, {fixed!r})
bad = sorted(m for m in sys.modules if m.split('.')[0] in {blocked!r})
assert not bad, bad
print(len(back.t))
'''


def _messages(path: Path) -> list[tuple[str, int, bytes]]:
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f).iter_messages(
            log_time_order=False)]


def test_bags_are_written_and_read_without_any_ros_module_byte_identical(tmp_path):
    """With rclpy and every message package unimportable, an offline run is recorded, loaded,
    summarised, plotted and recovered; its messages are byte for byte those the same run
    recorded with ROS gives (and those the node encodes: test_bag_roundtrip), the channels
    carry the same type hashes, and rosbags reads every message."""
    import subprocess

    import numpy as np

    from crawler_sim import Crawler, gaits, simulate
    from crawler_sim.bag import record_trajectory

    out, png = tmp_path / 'no_ros', tmp_path / 'no_ros.png'
    code = WITHOUT_ROS.format(blocked=set(ROS_MODULES), out=str(out), png=str(png),
                              name='no_ros', cut=str(tmp_path / 'cut.mcap'),
                              fixed=str(tmp_path / 'fixed'))
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          cwd=BAG.parents[1], timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert png.stat().st_size > 10_000 and (tmp_path / 'fixed' / 'metadata.yaml').is_file()
    # the same run and commands recorded here, with ROS
    run = simulate(Crawler([0.5, 1.0, 0.7], mu=0.3),
                   gaits.Sinusoid([0.1, 0.12], [0.02, 0.01], 1.5, [0.0, 1.0]), 2.0)
    commands = (np.array([0.0, 0.5, 1.7]), np.array([[0.1, 0.12], [0.11, 0.12], [0.1, 0.13]]))
    ros = tmp_path / 'ros'
    record_trajectory(ros, run, commands=commands, scene={'name': 'no_ros'}, chunk_size=8192)
    without, with_ros = _messages(out / 'no_ros_0.mcap'), _messages(ros / 'ros_0.mcap')
    assert len(without) == len(with_ros) == int(proc.stdout) * 4 + len(run.events) + 3 + 1
    assert without == with_ros
    from rosbags.highlevel import AnyReader
    hashes = []
    for bag in (out, ros):
        with AnyReader([bag]) as reader:
            assert sum(1 for conn, _, raw in reader.messages()
                       if reader.deserialize(raw, conn.msgtype) is not None) == len(without)
            hashes.append(sorted((c.topic, c.digest) for c in reader.connections))
    assert hashes[0] == hashes[1]


def _types() -> list[str]:
    """Every type the node and offline recording write, and every type inside them."""
    from crawler_sim.bag import rosmsg, topics
    todo = [t.type for t in topics.ALL_TOPICS] + ['builtin_interfaces/msg/Time']
    seen: list[str] = []
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.append(name)
        for sub in rosmsg.store_field_types(name).values():
            inner = sub.split('<')[-1].rstrip('>').split('[')[0]
            if '/' in inner:
                pkg, typ = inner.split('/')
                todo.append(f'{pkg}/msg/{typ}')
    return sorted(seen)


def test_the_typestore_gives_the_field_lists_and_empty_messages_of_the_ros_classes():
    """The two backends of crawler_sim.bag.rosmsg agree on every type the package records:
    the typestore's field list is rclpy's, spelt alike, and an empty message of each
    serialises to the same bytes as recorded (padding zeroed: Fast CDR leaves it
    uninitialised; its surplus tail cut, as the writer cuts it), .msg default values
    included (``Quaternion.w`` = 1, which rosbags' typestore does not keep)."""
    from crawler_sim.bag import rosmsg
    from crawler_sim.bag.cdr import Trimmer, zero_padding

    types = _types()
    assert len(types) >= 25 and 'geometry_msgs/msg/PoseWithCovariance' in types
    for name in types:
        cls = rosmsg.ros_class(name)
        assert cls is not None, name
        assert rosmsg.store_field_types(name) == cls.get_fields_and_field_types(), name
        ros_bytes = Trimmer(name).trim(zero_padding(rosmsg.serialize(cls(), name), name))
        assert rosmsg.serialize(rosmsg.store_new(name), name) == ros_bytes, name


def test_export_without_pandas_names_the_pip_command_and_exits_2(tmp_path):
    """pandas is not in ``pip install .``: ``crawler-sim export`` says so in one line with the
    exact pip command, exit 2 (it said 'a part of crawler_sim ... is missing', exit 1), and
    ``Trajectory.to_pandas`` names the same command."""
    import subprocess

    from crawler_sim import Crawler, gaits, simulate
    from crawler_sim.bag import record_trajectory

    run = simulate(Crawler([0.5, 1.0], mu=0.3), gaits.Scallop(0.1, 0.02, 2.0, 0.2), 1.0)
    record_trajectory(tmp_path / 'run', run)
    code = ('import sys; sys.modules["pandas"] = None\n'
            'from crawler_sim.cli import main\n'
            f'code = main(["export", {str(tmp_path / "run")!r}, "--csv", '
            f'{str(tmp_path / "out.csv")!r}])\n'
            'from crawler_sim import Crawler, gaits, simulate\n'
            'run = simulate(Crawler([0.5, 1.0], mu=0.3), gaits.Scallop(0.1, 0.02, 2.0, 0.2), 1.0)\n'
            'try:\n    run.to_pandas()\nexcept ImportError as exc:\n    print(exc)\n'
            'sys.exit(code)\n')
    proc = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          cwd=BAG.parents[1], timeout=300)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count('\n') == 1 and proc.stderr.startswith('crawler-sim: error: ')
    assert 'needs pandas' in proc.stderr and 'pip install pandas' in proc.stderr
    assert 'pip install pandas' in proc.stdout
    assert not (tmp_path / 'out.csv').exists()
