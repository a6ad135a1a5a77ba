"""sim_node --help names every interface it serves (issue 42: the simulation_interfaces services
and action, and /tf, were missing from it)."""
from __future__ import annotations

import pytest

from crawler_sim.ros.sim.main import main
from crawler_sim.ros.sim.standard import ACTION, SERVICES


def test_help_names_the_standards_services_the_action_and_tf(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(['sim_node', '--help'])
    assert exit_.value.code == 0
    text = ' '.join(capsys.readouterr().out.split())      # the summary is wrapped
    for name in [*SERVICES, ACTION, '/tf', 'robot_description', 'Parameter name: publish_tf']:
        assert name in text, name
