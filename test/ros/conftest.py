"""Fixtures of the ROS tests (the helpers they use: test/support/ros.py)."""
from __future__ import annotations

import pytest

from test.support.ros import Harness, Peer


@pytest.fixture
def ros():
    """An in-process sim_node harness: its own context and domain, discovery off."""
    h = Harness()
    yield h
    h.close()


@pytest.fixture
def ament_env(installed_env, monkeypatch):
    """This process sees the temporary install first in the ament index, as `ros2 run` would."""
    monkeypatch.setenv('AMENT_PREFIX_PATH', installed_env['AMENT_PREFIX_PATH'])
    return installed_env


@pytest.fixture
def peer():
    """The test's own node in the session's domain, host-wide discovery."""
    p = Peer()
    yield p
    p.close()
