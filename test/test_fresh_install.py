"""`pip install .` in a fresh venv brings what the package needs, and the README's Python
example then runs (issue 27: the install installed none of the dependencies; `import
crawler_sim` failed on numpy).

Real: a new venv (no system site-packages), pip's own isolated build of this checkout (the
compiled core included) with its dependencies from the index, then the README's Python block
run by that venv's interpreter from an empty directory without PYTHONPATH, so only the
installed package can be imported."""
from __future__ import annotations

import os
from pathlib import Path
import re
import subprocess
import sys
import venv

REPO = Path(__file__).resolve().parents[1]


def readme_python() -> str:
    text = (REPO / 'README.md').read_text(encoding='utf-8')
    blocks = re.findall(r'<!-- ci: run -->\s*```python\n(.*?)```', text, flags=re.S)
    assert len(blocks) == 1
    return blocks[0]


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
    # the example prints displacement, steady speed and stick fractions, then events, then
    # the worst verify residual: a crawl forward, events found, residuals at rounding level
    displacement = float(lines[0].split()[0])
    assert displacement > 0.01 and 'Event(time=' in lines[1] and float(lines[2]) < 1e-9
    # it is the installed copy that ran, not this checkout
    where = subprocess.run([str(python), '-c', 'import crawler_sim; print(crawler_sim.__file__)'],
                           env=env, cwd=run_dir, capture_output=True, text=True, timeout=120)
    assert str(env_dir) in where.stdout and sys.prefix not in where.stdout
