"""The lint configuration holds (issue 27: a lint configuration and CI running it; type hints
on public functions checked). ``make test`` (and so CI) runs this file."""
from __future__ import annotations

import ast
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / 'crawler_sim'


def test_ruff_finds_nothing():
    ruff = shutil.which('ruff', path=str(Path(sys.executable).parent)) or shutil.which('ruff')
    if ruff is None:
        pytest.fail('ruff is not installed: `pip install ".[test]"` brings it')
    proc = subprocess.run([ruff, 'check', '--output-format', 'concise', '.'], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def _public_functions(tree: ast.Module):
    """(qualified name, node, is a method) of the public functions and methods of a module;
    ``__init__`` counts, other dunders and ``_private`` ones do not."""
    def walk(body, prefix, in_class):
        for node in body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith('_'):
                yield from walk(node.body, prefix + node.name + '.', True)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                if node.name.startswith('_') and node.name != '__init__':
                    continue
                yield prefix + node.name, node, in_class
    yield from walk(tree.body, '', False)


def unannotated(root: Path) -> list[str]:
    """``file:line function(argument)`` of every argument (and return type) without a hint in
    the public functions of the modules under ``root`` (``_private`` modules are internal).
    The implementation behind ``typing.overload`` signatures is exempt: they carry the hints."""
    found = []
    for path in sorted(root.rglob('*.py')):
        rel = path.relative_to(root)
        if any(part.startswith('_') and part != '__init__.py' for part in rel.parts):
            continue
        tree = ast.parse(path.read_text(encoding='utf-8'))
        overloaded = {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)
                      and any(getattr(d, 'id', getattr(d, 'attr', '')) == 'overload'
                              for d in n.decorator_list)}
        for name, fn, in_class in _public_functions(tree):
            if fn.name in overloaded:
                continue
            args = fn.args.posonlyargs + fn.args.args + fn.args.kwonlyargs
            if in_class and args and args[0].arg in ('self', 'cls'):
                args = args[1:]
            args += [a for a in (fn.args.vararg, fn.args.kwarg) if a]
            found += [f'{rel}:{fn.lineno} {name}({a.arg})' for a in args if a.annotation is None]
            if fn.returns is None:
                found.append(f'{rel}:{fn.lineno} {name} -> ?')
    return found


def test_public_functions_have_type_hints():
    assert unannotated(PACKAGE) == []


def test_the_hint_checker_sees_a_missing_hint(tmp_path):
    (tmp_path / 'mod.py').write_text(
        'class A:\n    def f(self, x: int, y) -> None: ...\n'
        '    def _g(self, z): ...\n'
        'def h(*args) -> int: ...\n'
        'def k(a: int): ...\n')
    assert unannotated(tmp_path) == ['mod.py:2 A.f(y)', 'mod.py:4 h(args)', 'mod.py:5 k -> ?']
