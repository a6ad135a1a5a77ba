"""The parameter names the command line gives a node, read from the arguments themselves
(``crawler_sim.ros.args.given_names``; rclpy has no public accessor for its overrides), so a
misspelt name is reported whichever way it was given."""
from __future__ import annotations

from crawler_sim.ros.args import _wildcard_names, given_names, ros_sections


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
