"""Every command of the docs runs as written, or is checked as far as it can be here (issue 43:
"every config file and docs command runs as written (test them)").

Pages: README.md and every ``docs/*.md`` but the changelog (history), found anew at each run,
so a new page is checked without being listed here.

Fenced ``bash``/``sh``/``python`` blocks of the docs pages (the README's are run by
test/test_readme.py) run as written, each in a fresh directory holding the repository's
``.venv``, ``install`` and ``config`` (bash with ``-e``; python with this interpreter), unless
the line before the fence marks them:

- ``<!-- ci: run -->`` (the same as no mark);
- ``<!-- ci: jazzy -->``: needs a ROS 2 Jazzy install (the ``ros2`` command, not in the
  wheels set-up): skipped with that reason. A block that calls ``ros2`` must carry this mark;
- ``<!-- ci: excerpt ... -->``: code shown, not a command to run as is (a contract's
  signatures, a fragment of a run a README block runs whole): skipped with that reason.

A block that starts the nodes (``$BIN/``, ``install/setup.bash``) runs on the colcon install of
``make build`` (skipped without it), in this session's ROS domain.

Inline commands (a code span starting with ``crawler-sim ``, ``python -m ``, ``make `` or
``pip install``):

- a ``crawler-sim`` line naming a real scene (``config/...``) and no placeholder runs in a
  fresh directory (exit 0);
- one with a placeholder (``SCENE.yaml``, ``BAG``, ``OUT``, ``[--flag ...]``) or without its
  input is a synopsis: its subcommand exists and every ``--flag`` it names is in that
  subcommand's ``--help``;
- ``python -m benchmarks.X`` (minutes each, on 2 cores) or another module: the module exists
  and its ``--help`` names every flag given;
- ``make TARGET``: ``make -n TARGET`` succeeds; ``pip install``: the extras and requirement
  files it names exist (the installs themselves: test/test_fresh_install.py);
- ``ros2 ...``: needs a Jazzy install, skipped with that reason.
"""
from __future__ import annotations

from dataclasses import dataclass
import functools
import os
from pathlib import Path
import re
import shlex
import shutil
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[2]
FENCE = re.compile(r'(?:<!--\s*ci:\s*(?P<mark>[^>]*?)\s*-->\s*\n)?^```(?P<lang>[\w.-]*)[ \t]*\n'
                   r'(?P<code>.*?)^```', re.S | re.M)
RUN_LANGS = {'bash': 'bash', 'sh': 'bash', 'shell': 'bash', 'python': 'python'}
KINDS = {'run', 'jazzy', 'excerpt', '.ci/run'}
#: a word standing for something the reader supplies (SCENE.yaml, BAG, OUT, RESULTS.parquet)
PLACEHOLDER = re.compile(r'(^|[\s=/])[A-Z][A-Z_]{1,}(\.\w+)?(\s|$)|\.\.\.|[\[\]|]')
JAZZY = 'needs a ROS 2 Jazzy install (the ros2 command; not in the wheels set-up)'


def pages() -> list[Path]:
    docs = sorted(p for p in (REPO / 'docs').glob('*.md') if p.name.lower() != 'changelog.md')
    return [REPO / 'README.md', *docs]


@dataclass(frozen=True)
class Block:
    page: str
    line: int
    lang: str
    kind: str        # run, jazzy, excerpt, .ci/run
    code: str

    @property
    def id(self) -> str:
        return f'{self.page}:{self.line}'


def blocks() -> list[Block]:
    """The fenced bash/python blocks of every page, with their marks."""
    out = []
    for page in pages():
        text = page.read_text(encoding='utf-8')
        for m in FENCE.finditer(text):
            lang = RUN_LANGS.get(m['lang'])
            if lang is None:
                continue
            kind = (m['mark'] or 'run').split()[0]
            line = text.count('\n', 0, m.start('code'))
            out.append(Block(page.relative_to(REPO).as_posix(), line, lang, kind, m['code']))
    return out


def inline_commands() -> list[tuple[str, str]]:
    """(page:line, command) of every inline code span that is a command, outside fences."""
    out = []
    for page in pages():
        text = FENCE.sub(lambda m: '\n' * m[0].count('\n'), page.read_text(encoding='utf-8'))
        for m in re.finditer(r'`([^`]+)`', text):
            command = ' '.join(m[1].split())
            if re.match(r'(crawler-sim |python3? -m |make |pip install|ros2 )', command):
                line = text.count('\n', 0, m.start()) + 1
                out.append((f'{page.relative_to(REPO).as_posix()}:{line}', command))
    return out


def _env(tmp: Path) -> dict[str, str]:
    env = dict(os.environ)
    env['PATH'] = os.pathsep.join([str(REPO / 'install' / 'crawler_sim' / 'bin'),
                                   str(Path(sys.executable).parent), env.get('PATH', '')])
    env['PYTHONPATH'] = str(REPO)
    env['MPLBACKEND'] = 'Agg'
    env.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    return env


def _workdir(tmp: Path) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    for name in ('.venv', 'install', 'config'):
        if (REPO / name).exists():
            (tmp / name).symlink_to(REPO / name)
    return tmp


def _output_folders(cwd: Path, tokens: list[str]) -> None:
    """Create the folders of the relative output paths a command names (``docs/x.png``,
    ``runs/climb``), as they exist in the checkout the page is read from."""
    for t in tokens:
        t = t.split('=')[-1]
        if '/' in t and not t.startswith(('config/', '.venv', 'install', '-', '$', '/', '~')):
            (cwd / t).parent.mkdir(parents=True, exist_ok=True)


def _needs_nodes(code: str) -> bool:
    return '$BIN/' in code or 'install/setup.bash' in code


# ---------------------------------------------------------------------------- fenced blocks

def test_the_pages_are_found_and_every_block_is_marked_for_what_it_needs():
    names = [p.name for p in pages()]
    assert 'README.md' in names and 'solvers.md' in names and 'CHANGELOG.md' not in names
    found = blocks()
    assert any(b.page.startswith('docs/') and b.kind == 'run' for b in found)
    for b in found:
        assert b.kind in KINDS, f'{b.id}: unknown mark ci: {b.kind} (one of {sorted(KINDS)})'
        calls_ros2 = any(line.split('#')[0].strip().startswith('ros2 ')
                         for line in b.code.splitlines())
        if calls_ros2 and b.kind not in ('jazzy', 'excerpt'):
            pytest.fail(f'{b.id}: calls ros2: mark it <!-- ci: jazzy --> (not in the wheels '
                        'set-up), or make it run with the executables of install/')


DOC_BLOCKS = [b for b in blocks() if not b.page == 'README.md']   # the README's: test_readme


@pytest.mark.parametrize('block', DOC_BLOCKS, ids=[b.id for b in DOC_BLOCKS])
def test_a_docs_block_runs_as_written(block, tmp_path):
    if block.kind == 'jazzy':
        pytest.skip(JAZZY)
    if block.kind == 'excerpt':
        pytest.skip('an excerpt, not a command to run as is (marked in the page)')
    if _needs_nodes(block.code) and not (REPO / 'install' / 'crawler_sim').is_dir():
        pytest.skip('needs `make build` (the colcon install the page names)')
    cwd = _workdir(tmp_path)
    if block.lang == 'bash':
        _output_folders(cwd, block.code.split())
    cmd = (['bash', '-e', '-c', block.code] if block.lang == 'bash'
           else [sys.executable, '-c', block.code])
    proc = subprocess.run(cmd, cwd=cwd, env=_env(cwd), capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, f'{block.id}:\n{block.code}\n{proc.stdout}\n{proc.stderr}'


# ---------------------------------------------------------------------------- inline commands

@functools.lru_cache(maxsize=None)
def _help(*command: str) -> str:
    proc = subprocess.run([*command, '--help'], cwd=REPO, env=_env(REPO), capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, f'{" ".join(command)} --help: {proc.stderr[-2000:]}'
    return proc.stdout


def _flags(tokens: list[str]) -> list[str]:
    return [t.split('=')[0] for t in tokens if t.startswith('--') and t != '--help']


def _subcommands() -> set[str]:
    from crawler_sim.cli import build_parser
    import argparse
    parser = build_parser()
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return set(actions[0].choices)


def _extras() -> set[str]:
    from test.test_packaging import setup_kwargs
    return set(setup_kwargs()['extras_require'])


def check_cli(command: str, tmp: Path) -> str:
    tokens = shlex.split(command)
    sub = tokens[1] if len(tokens) > 1 else ''
    if sub in ('COMMAND', '--help'):
        return 'the command line\'s help'
    assert sub in _subcommands(), f'{command}: no subcommand {sub!r}'
    inputs = [t for t in tokens[2:] if t.startswith('config/')]
    if inputs and not PLACEHOLDER.search(command):
        for t in inputs:
            assert (REPO / t).exists(), f'{command}: {t} does not exist'
        cwd = _workdir(tmp)
        _output_folders(cwd, tokens[2:])
        proc = subprocess.run([sys.executable, '-m', 'crawler_sim.cli', *tokens[1:]], cwd=cwd,
                              env=_env(cwd), capture_output=True, text=True, timeout=900)
        assert proc.returncode == 0, f'{command}:\n{proc.stdout}\n{proc.stderr}'
        return 'ran'
    text = _help(sys.executable, '-m', 'crawler_sim.cli', sub)
    for flag in _flags(tokens):
        assert flag in text, f'{command}: {flag} is not an option of crawler-sim {sub}'
    return 'synopsis: flags checked'


def check_module(command: str) -> str:
    tokens = shlex.split(command)
    module = tokens[2]
    path = REPO / Path(*module.split('.'))
    assert path.with_suffix('.py').is_file() or (path / '__main__.py').is_file(), \
        f'{command}: no module {module} in the checkout'
    text = _help(sys.executable, '-m', module)
    for flag in _flags(tokens[3:]):
        assert flag in text, f'{command}: {flag} is not an option of {module}'
    return 'module and flags checked'


def check_make(command: str) -> str:
    target = shlex.split(command)[1]
    proc = subprocess.run(['make', '-n', target], cwd=REPO, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, f'{command}: {proc.stderr}'
    return 'make -n'


def check_pip(command: str) -> str:
    tokens = shlex.split(command)
    for i, t in enumerate(tokens):
        if t == '-r':
            assert (REPO / tokens[i + 1]).is_file(), f'{command}: no file {tokens[i + 1]}'
        m = re.fullmatch(r'\.\[([\w,]+)\]', t)
        if m:
            for extra in m[1].split(','):
                assert extra in _extras(), f'{command}: setup.py has no extra {extra!r}'
    return 'extras and files checked'


INLINE = inline_commands()


@pytest.mark.parametrize('where, command', INLINE, ids=[w for w, _ in INLINE])
def test_an_inline_command_runs_or_names_what_exists(where, command, tmp_path):
    if command.startswith('ros2 '):
        pytest.skip(JAZZY)
    if command.startswith('crawler-sim '):
        check_cli(command, tmp_path)
    elif command.startswith(('python -m ', 'python3 -m ')):
        check_module(command)
    elif command.startswith('make '):
        if shutil.which('make') is None:
            pytest.skip('needs make')
        check_make(command)
    else:
        check_pip(command)


def test_the_checks_refuse_a_wrong_command(tmp_path):
    """The inline checks can fail: a flag, subcommand, module or extra that does not exist, and
    a scene command that exits non-zero; and some inline commands do run (not only synopses)."""
    with pytest.raises(AssertionError, match='--bogus'):
        check_cli('crawler-sim simulate SCENE.yaml --bogus', tmp_path)
    with pytest.raises(AssertionError, match='no subcommand'):
        check_cli('crawler-sim simulat SCENE.yaml', tmp_path)
    with pytest.raises(AssertionError, match='t-end'):
        check_cli('crawler-sim simulate config/scenes/scallop_2body.yaml --t-end -1',
                  tmp_path / 'a')
    with pytest.raises(AssertionError, match='no module'):
        check_module('python -m benchmarks.nothing_here')
    with pytest.raises(AssertionError, match='--bogus'):
        check_module('python -m benchmarks.dense --bogus')
    with pytest.raises(AssertionError, match='no extra'):
        check_pip('pip install ".[nothing]"')
    runnable = [c for _, c in INLINE if c.startswith('crawler-sim ') and 'config/' in c
                and not PLACEHOLDER.search(c)]
    assert len(runnable) >= 2, runnable
