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
