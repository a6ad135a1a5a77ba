"""Shared test set-up: an isolated ROS environment per session and a colcon-built install.

The ROS variables are set here, at import, before any test module imports rclpy: a
``ROS_DOMAIN_ID`` that no other test session on this host holds (claimed with a lock file held
for the session's life, test/support/domains.py: parallel runs on one host never see each
other), discovery limited to this host, and rclpy's message field checks switched on.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

from test.support.domains import session_domain_id

os.environ['ROS_DOMAIN_ID'] = str(session_domain_id())
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['ROS_PYTHON_CHECK_FIELDS'] = '1'

REPO = Path(__file__).resolve().parents[1]
VENV = Path(sys.prefix)

@pytest.fixture(scope='session')
def colcon_install(tmp_path_factory) -> Path:
    """``colcon build`` of this repository into a temporary directory; yields the install base.

    The same command a Jazzy workspace runs (without --symlink-install, so the installed copy is
    what runs).
    """
    tmp = tmp_path_factory.mktemp('colcon')
    colcon = (shutil.which('colcon', path=str(Path(sys.executable).parent))
              or shutil.which('colcon'))
    if colcon is None:
        pytest.fail('colcon is not installed in this environment (make venv installs it)')
    cmd = [colcon, '--log-base', str(tmp / 'log'), 'build', '--paths', str(REPO),
           '--build-base', str(tmp / 'build'), '--install-base', str(tmp / 'install')]
    proc = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        pytest.fail(f'colcon build failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}')
    return tmp / 'install'


@pytest.fixture(scope='session')
def installed_env(colcon_install: Path) -> dict[str, str]:
    """Environment for running the installed executables, as ``source install/setup.bash`` plus
    the venv's share/ (message definitions) would give."""
    prefix = colcon_install / 'crawler_sim'
    site = next((prefix / 'lib').glob('python3*/site-packages'))
    env = dict(os.environ)
    env['AMENT_PREFIX_PATH'] = f'{prefix}{os.pathsep}{VENV}'
    env['PYTHONPATH'] = str(site)
    env['PYTHONUNBUFFERED'] = '1'
    return env
