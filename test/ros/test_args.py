"""The parameter names the command line gives a node, read from the arguments themselves
(``crawler_sim.ros.args.given_names``; rclpy has no public accessor for its overrides), so a
misspelt name is reported whichever way it was given."""
from __future__ import annotations

from crawler_sim.ros.args import (_wildcard_names, given_names, help_requested, help_text,
                                  ros_sections)


def test_only_arguments_inside_ros_args_sections_count():
    argv = ['prog', '-p', 'x:=1', '--ros-args', '-p', 'a:=1', '--', '-p', 'b:=2',
            '--ros-args', '--param', 'c:=3', '-r', '__ns:=/r1']
    assert ros_sections(argv) == ['-p', 'a:=1', '--param', 'c:=3', '-r', '__ns:=/r1']
    assert given_names(argv, 'gait_node', '/r1/gait_node') == ['a', 'c']


def test_a_params_file_gives_the_names_of_this_nodes_sections(tmp_path):
    f = tmp_path / 'p.yaml'
    f.write_text(
        'gait_node:\n  ros__parameters:\n    frequncy: 1.0\n    gait: {amplitude: 0.1}\n'
        '/r1/gait_node:\n  ros__parameters:\n    mode: command\n'
        '/r1:\n  gait_node:\n    ros__parameters:\n      rate: 50.0\n'
        '/r2/gait_node:\n  ros__parameters:\n    other: 1\n'
        'crawler_sim:\n  ros__parameters:\n    masses: [1.0, 1.0]\n'
        '/**:\n  ros__parameters:\n    use_sim_time: true\n')
    argv = ['prog', '--ros-args', '--params-file', str(f)]
    got = given_names(argv, 'gait_node', '/r1/gait_node')
    # its own sections (by name, by full name, nested under its namespace); not another
    # namespace's node, not another node, not the wildcard section (checked separately)
    assert sorted(got) == ['frequncy', 'gait.amplitude', 'mode', 'rate']
    assert sorted(given_names(argv, 'gait_node', '/gait_node')) == ['frequncy',
                                                                      'gait.amplitude']
    # the wildcard section's names go to every node: not reported as typos of this one
    assert _wildcard_names(argv) == {'use_sim_time'}


def test_an_unreadable_params_file_gives_no_names(tmp_path):
    (tmp_path / 'bad.yaml').write_text('a: [\n')
    argv = ['prog', '--ros-args', '--params-file', str(tmp_path / 'bad.yaml'),
            '--params-file', str(tmp_path / 'missing.yaml')]
    assert given_names(argv, 'n', '/n') == []


def test_help_is_asked_outside_ros_args_only():
    assert help_requested(['sim_node', '--help'])
    assert help_requested(['gait_node', '-h', '--ros-args', '-p', 'n_links:=1'])
    assert not help_requested(['sim_node', '--ros-args', '-p', 'masses:=[1.0, 1.0]'])
    # inside a --ros-args section the word is ROS's (rcl refuses it there, in one line)
    assert not help_requested(['sim_node', '--ros-args', '--help'])
    assert help_requested(['sim_node', '--ros-args', '-p', 'a:=1', '--', '--help'])


def test_help_lists_each_parameter_with_its_type_description_range_default_and_read_only():
    table = {'masses': ([0.5, 1.0], 'Body masses [kg]', None, False),
             'slope': (0.0, 'Incline [rad]', (-1.5, 1.5), False),
             'record': (False, 'Record a bag', None, True),
             'n_links': (0, 'Number of linkages', (0, 63)),     # gait_node's shape: 3 fields
             'topics': (None, 'Topics to play', None)}
    text = help_text('sim_node', 'crawler_sim', 'Simulates a crawler.', table)
    assert text.startswith('usage: sim_node [-h] [--ros-args')
    blocks = {b.splitlines()[0]: b for b in text.split('\n\n')}
    assert blocks['Parameter name: masses'].splitlines()[1:] == [
        '  Type: double array', '  Description: Body masses [kg]', '  Default value: [0.5, 1.0]']
    assert blocks['Parameter name: slope'].splitlines()[1:] == [
        '  Type: double', '  Description: Incline [rad]', '  Default value: 0.0',
        '  Constraints:', '    Min value: -1.5', '    Max value: 1.5']
    assert '  Type: boolean' in blocks['Parameter name: record']
    assert '    Read only: true (set at start only)' in blocks['Parameter name: record']
    assert '  Type: integer' in blocks['Parameter name: n_links']
    assert '  Type: not set' in blocks['Parameter name: topics']


def test_every_node_table_is_in_its_help():
    """The tables the nodes declare from (sim_node, gait_node) and replay_node's: each name
    appears once, with its default."""
    from crawler_sim.ros.gait_node import PARAMETERS as GAIT
    from crawler_sim.ros.replay_node import HELP_PARAMETERS as REPLAY
    from crawler_sim.ros.sim.params import PARAMETERS as SIM
    for table in (SIM, GAIT, REPLAY):
        text = help_text('x', 'x', 'x', table)
        for name in table:
            assert text.count(f'Parameter name: {name}\n') == 1, name
        assert all(len(line) <= 100 for line in text.splitlines())
