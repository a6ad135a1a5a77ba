"""`pip install .` in a fresh venv brings what the package needs, and the README's Python
example then runs (issue 27: the install installed none of the dependencies; `import
crawler_sim` failed on numpy), and so does every offline command of the README, without ROS
(issue 43: `simulate --plot`, `--out`, `plot`, `export`... failed on `builtin_interfaces`).

Real: a new venv (no system site-packages), pip's own isolated build of this checkout (the
compiled core included) with its dependencies from the index, then the README's Python block
run by that venv's interpreter from an empty directory without PYTHONPATH, so only the
installed package can be imported."""
from __future__ import annotations

import os
from pathlib import Path
import re
import shlex
import shutil
import subprocess
import sys
import venv

REPO = Path(__file__).resolve().parents[1]


def readme_python() -> str:
    text = (REPO / 'README.md').read_text(encoding='utf-8')
    blocks = re.findall(r'<!-- ci: run -->\s*```python\n(.*?)```', text, flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


def readme_commands() -> list[str]:
    """The README's ``crawler-sim`` lines of the command-line block (comments cut off)."""
    text = (REPO / 'README.md').read_text(encoding='utf-8')
    blocks = [b for b in re.findall(r'<!-- ci: run -->\s*```bash\n(.*?)```', text, flags=re.S)
              if 'crawler-sim simulate' in b]
    assert len(blocks) == 1
    lines = [line.split('#')[0].strip() for line in blocks[0].splitlines()]
    return [line for line in lines if line.startswith('crawler-sim ')]


def run_offline_commands(env_dir: Path, env: dict, run_dir: Path) -> None:
    """The README's offline commands, then info, replay and recover of the recorded run, in
    ``run_dir`` (outside the checkout: the scenes copied there) with the venv's crawler-sim;
    no ROS module exists in that venv. ``export`` needs pandas, which ``pip install .`` does
    not bring: one line naming the pip command, exit 2, and after that command, exit 0."""
    shutil.copytree(REPO / 'config' / 'scenes', run_dir / 'config' / 'scenes')
    bin_dir = env_dir / 'bin'
    env = {**env, 'PATH': f'{bin_dir}{os.pathsep}{env.get("PATH", "")}', 'MPLBACKEND': 'Agg'}

    def run(line: str) -> subprocess.CompletedProcess:
        return subprocess.run(shlex.split(line), env=env, cwd=run_dir, capture_output=True,
                              text=True, timeout=600)

    no_ros = subprocess.run([str(bin_dir / 'python'), '-c', 'import rclpy'], env=env,
                            capture_output=True, text=True, timeout=60)
    assert no_ros.returncode != 0
    commands = readme_commands()
    assert any('--plot' in c for c in commands) and any('--out' in c for c in commands)
    assert any(c.startswith('crawler-sim export') for c in commands)
    for line in commands:
        proc = run(line)
        if line.startswith('crawler-sim export'):
            assert proc.returncode == 2, (line, proc.stderr)
            assert proc.stderr.count('\n') == 1 and 'pip install pandas' in proc.stderr
            pip = subprocess.run([str(bin_dir / 'python'), '-m', 'pip', 'install', '-q',
                                  'pandas'], env=env, capture_output=True, text=True,
                                 timeout=600)
            assert pip.returncode == 0, pip.stderr[-2000:]
            proc = run(line)
        assert proc.returncode == 0, (line, proc.stderr)
    bags = [c.split('--out')[1].split()[0] for c in commands if '--out' in c]
    bag = bags[0]
    name = Path(bag).name
    for line in (f'crawler-sim info {bag}', f'crawler-sim replay {bag}',
                 f'crawler-sim recover {bag}/{name}_0.mcap -o recovered'):
        proc = run(line)
        assert proc.returncode == 0, (line, proc.stderr)
    assert (run_dir / 'recovered' / 'metadata.yaml').is_file()
    assert (run_dir / 'crawl.png').stat().st_size > 10_000


def test_pip_install_in_a_fresh_venv_then_the_readme_example(tmp_path):
    env_dir = tmp_path / 'venv'
    venv.create(env_dir, with_pip=True)
    python = env_dir / 'bin' / 'python'
    env = {k: v for k, v in os.environ.items()
           if k not in ('PYTHONPATH', 'VIRTUAL_ENV', 'AMENT_PREFIX_PATH', 'PYTHONHOME')}
    proc = subprocess.run([str(python), '-m', 'pip', 'install', '-q', str(REPO)], env=env,
                          cwd=tmp_path, capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    run_dir = tmp_path / 'empty'
    run_dir.mkdir()
    proc = subprocess.run([str(python), '-c', readme_python()], env=env, cwd=run_dir,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    # the example prints displacement, steady speed and stick fractions first, the events on
    # a line of their own and the worst verify residual last: a crawl forward, events found,
    # residuals at rounding level
    displacement = float(lines[0].split()[0])
    assert displacement > 0.01 and any('Event(time=' in line for line in lines[1:-1])
    assert float(lines[-1]) < 1e-9
    # it is the installed copy that ran, not this checkout
    where = subprocess.run([str(python), '-c', 'import crawler_sim; print(crawler_sim.__file__)'],
                           env=env, cwd=run_dir, capture_output=True, text=True, timeout=120)
    assert str(env_dir) in where.stdout and sys.prefix not in where.stdout
    # the README's offline commands, without ROS, from a directory outside the checkout
    offline = tmp_path / 'offline'
    offline.mkdir()
    run_offline_commands(env_dir, env, offline)
    add_the_sweep_extra_without_rebuilding(env_dir, env, run_dir)


def add_the_sweep_extra_without_rebuilding(env_dir: Path, env: dict, run_dir: Path) -> None:
    """The README's way to add sweeps after ``pip install .``, ``pip install -r
    requirements-sweep.txt``, brings pandas, pyarrow and Dask and builds nothing: the compiled
    core installed before is the same file (issue 43: ``pip install ".[sweep]"`` compiled it
    again, +250 s on a loaded machine)."""
    python = str(env_dir / 'bin' / 'python')
    where = 'import crawler_sim.core.solvers._exact as m; print(m.__file__)'
    core = Path(subprocess.run([python, '-c', where], env=env, cwd=run_dir, capture_output=True,
                               text=True, timeout=120).stdout.strip())
    before = core.stat().st_mtime_ns
    pip = subprocess.run([python, '-m', 'pip', 'install', '-r',
                          str(REPO / 'requirements-sweep.txt')], env=env, cwd=run_dir,
                         capture_output=True, text=True, timeout=1200)
    assert pip.returncode == 0, pip.stderr[-2000:]
    assert 'crawler_sim' not in pip.stdout and 'Building wheel' not in pip.stdout, pip.stdout
    assert core.stat().st_mtime_ns == before
    imports = subprocess.run([python, '-c', 'import pandas, pyarrow, distributed; '
                              'import crawler_sim.sweep'], env=env, cwd=run_dir,
                             capture_output=True, text=True, timeout=300)
    assert imports.returncode == 0, imports.stderr


def test_importing_from_a_checkout_nobody_built_names_the_fix(tmp_path):
    """`import crawler_sim` from the root of a source checkout whose compiled core was never
    built (Python puts the current directory first) said `cannot import name '_stepping'`."""
    source = tmp_path / 'source'
    shutil.copytree(REPO / 'crawler_sim', source / 'crawler_sim',
                    ignore=shutil.ignore_patterns('*.so', '*.c', '__pycache__'))
    env = {k: v for k, v in os.environ.items() if k not in ('PYTHONPATH', 'PYTHONHOME')}
    proc = subprocess.run([sys.executable, '-c', 'import crawler_sim'], env=env, cwd=source,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith('ImportError: crawler_sim is imported from the source checkout '
                           f'{source}'), last
    assert '_stepping' in last and 'pip install -e .' in last and 'make build' in last, last
