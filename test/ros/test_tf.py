"""/tf of sim_node over real DDS (crawler_sim/ros/sim/tf.py): odom -> base_link at every publish
tick, equal to ``odom``'s pose; distinct frames for a namespaced robot.

Expected values: the transform must be ``odom``'s pose, field for field, at the same stamp (the
two messages are compared with each other, and the centre of mass with sum m_i x_i / M computed
here from ``body_states``)."""
from __future__ import annotations

import json
from pathlib import Path
import sys

from ament_index_python.packages import get_package_share_directory
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage

from crawler_sim.ros.messages import ns_from_stamp
from crawler_sim.ros.sim_node import SimNode
from test.support.ros import THREE_BODY, cmd, ticks

TICK = 1_000_000        # ns (integration_rate 1 kHz); publish ticks every 10 ticks


def test_tf_is_odoms_pose_at_every_publish_tick(ros):
    sim = ros.sim(masses=[0.5, 1.0, 2.0])
    tfs = ros.listen(TFMessage, '/tf')
    odoms = ros.listen(Odometry, 'odom')
    bodies = ros.listen(JointState, 'body_states')
    pub = ros.publisher(Float64MultiArray, 'linkage_cmd')
    ros.send(pub, cmd(0.2, 0.05), sim, 'commands_accepted')
    ticks(sim, 300)
    stamps = [k * 10 * TICK for k in range(1, 31)]
    ros.until(lambda: len(tfs) >= 30 and len(odoms) >= 30 and len(bodies) >= 30,
              'the 30 publish ticks')
    by_stamp = {}
    for msg in tfs:
        assert len(msg.transforms) == 1
        tr = msg.transforms[0]
        by_stamp[ns_from_stamp(tr.header.stamp)] = tr
    assert sorted(by_stamp)[-30:] == stamps        # one transform at each publish tick
    com = {ns_from_stamp(b.header.stamp):
           (0.5 * b.position[0] + 1.0 * b.position[1] + 2.0 * b.position[2]) / 3.5
           for b in bodies}
    moved = False
    for odom in odoms:
        t_ns = ns_from_stamp(odom.header.stamp)
        tr = by_stamp[t_ns]
        assert (tr.header.frame_id, tr.child_frame_id) == (odom.header.frame_id,
                                                           odom.child_frame_id) \
            == ('odom', 'base_link')
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        v, r = tr.transform.translation, tr.transform.rotation
        assert (v.x, v.y, v.z) == (p.x, p.y, p.z)
        assert (r.x, r.y, r.z, r.w) == (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
        assert abs(v.x - com[t_ns]) <= 1e-15
        moved |= v.x != odoms[0].pose.pose.position.x
    assert moved                                    # the crawler moved: not a constant


def test_a_namespaced_robot_has_its_own_frames(ros):
    node = SimNode(context=ros.ctx, namespace='/r1', parameter_overrides=[
        Parameter(k, value=v) for k, v in THREE_BODY.items()])
    ros.ex.add_node(node)
    ros.nodes.append(node)
    tfs = ros.listen(TFMessage, '/tf')
    ticks(node, 10)
    ros.until(lambda: tfs, 'a transform')
    tr = tfs[-1].transforms[0]
    assert (tr.header.frame_id, tr.child_frame_id) == ('r1/odom', 'r1/base_link')
    assert ns_from_stamp(tr.header.stamp) == 10 * TICK


def test_a_paused_node_does_not_repeat_a_stamp_to_the_same_subscriber(ros):
    """tf2 listeners warn on every repeated stamp (TF_REPEATED_DATA): the paused node's
    republication of its state sends the transform only to a subscriber that joined since."""
    sim = ros.sim()
    first = ros.listen(TFMessage, '/tf')
    ticks(sim, 10)
    ros.until(lambda: first, 'the transform at 10 ms')
    sim.republish()                                # what the loop does while paused
    sim.republish()
    late = []
    sub = ros.obs.create_subscription(TFMessage, '/tf', late.append, 100)
    ros.until(lambda: sim.outputs.tf._pub.get_subscription_count() == 2, 'the late subscriber')
    sim.republish()
    ros.until(lambda: late, 'the transform for the late subscriber')
    ticks(sim, 10)
    ros.until(lambda: len(late) >= 2, 'the next publish tick')
    assert [ns_from_stamp(m.transforms[0].header.stamp) for m in late] == [10 * TICK, 20 * TICK]
    assert 10 * TICK in [ns_from_stamp(m.transforms[0].header.stamp) for m in first]
    ros.obs.destroy_subscription(sub)


def test_without_tf2_msgs_the_node_runs_without_tf(ros, monkeypatch):
    for name in [m for m in sys.modules if m.startswith('tf2_msgs')]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, 'tf2_msgs', None)     # import fails
    sim = ros.sim()
    assert sim.outputs.tf is None and 'tf2_msgs' in sim.outputs.tf_missing
    ticks(sim, 10)
    assert sim.sim_time_ns == 10 * TICK
    assert ros.obs.count_publishers('/tf') == 0


def test_tfmessage_has_the_type_hash_of_jazzys_tf2_msgs():
    """The installed TFMessage (ours or the real one) against rosbags' Jazzy type store, an
    independent RIHS01 implementation over the real definition."""
    from rosbags.typesys import Stores, get_typestore
    share = Path(get_package_share_directory('tf2_msgs'))
    hashes = {h['type_name']: h['hash_string'] for h in
              json.loads((share / 'msg' / 'TFMessage.json').read_text())['type_hashes']}
    expected = get_typestore(Stores.ROS2_JAZZY).hash_rihs01('tf2_msgs/msg/TFMessage')
    assert hashes['tf2_msgs/msg/TFMessage'] == expected


def test_a_namespaced_robots_odom_names_the_frames_of_its_tf(ros):
    """In /r1, /tf says r1/odom -> r1/base_link: ``odom`` must name the same frames (it said
    odom/base_link, so RViz with fixed frame r1/odom could not place the odometry)."""
    node = SimNode(context=ros.ctx, namespace='/r1', parameter_overrides=[
        Parameter(k, value=v) for k, v in THREE_BODY.items()])
    ros.ex.add_node(node)
    ros.nodes.append(node)
    tfs = ros.listen(TFMessage, '/tf')
    odoms = ros.listen(Odometry, '/r1/odom')
    ticks(node, 20)
    ros.until(lambda: len(tfs) >= 2 and len(odoms) >= 2, 'two publish ticks')
    tr, odom = tfs[-1].transforms[0], odoms[-1]
    assert (odom.header.frame_id, odom.child_frame_id) == (tr.header.frame_id,
                                                           tr.child_frame_id) \
        == ('r1/odom', 'r1/base_link')
    assert ns_from_stamp(odom.header.stamp) == ns_from_stamp(tr.header.stamp) == 20 * TICK
    assert odom.pose.pose.position.x == tr.transform.translation.x


def test_publish_tf_switches_tf_like_the_other_outputs(ros):
    sim = ros.sim(publish_tf=False)
    assert sim.outputs.tf is None
    ticks(sim, 10)
    assert ros.obs.count_publishers('/tf') == 0
    # (a parameter change takes effect at the next tick)
    assert sim.set_parameters([Parameter('publish_tf', value=True)])[0].successful
    ticks(sim, 1)
    tfs = ros.listen(TFMessage, '/tf')
    ticks(sim, 9)
    ros.until(lambda: tfs, 'a transform once switched on')
    assert ns_from_stamp(tfs[-1].transforms[0].header.stamp) == 20 * TICK
    assert sim.set_parameters([Parameter('publish_tf', value=False)])[0].successful
    ticks(sim, 1)
    assert sim.outputs.tf is None
    ros.until(lambda: ros.obs.count_publishers('/tf') == 0, 'the /tf publisher gone')


def test_tf_is_published_but_not_recorded(ros, tmp_path):
    """The output table's rule: a session records its switched-on grid outputs
    (``bag.topics.OUTPUTS``); /tf is outside it (``odom`` holds its numbers), so a bag of the
    default node is what it was before /tf existed."""
    from mcap.reader import make_reader
    sim = ros.sim(record=True, record_dir=str(tmp_path), record_name='tf')
    tfs = ros.listen(TFMessage, '/tf')
    ticks(sim, 30)
    ros.until(lambda: tfs, 'a transform')
    sim.close()
    bag = next(tmp_path.rglob('*.mcap'))
    with bag.open('rb') as f:
        topics = {ch.topic for ch in make_reader(f).get_summary().channels.values()}
    assert '/odom' in topics and '/body_states' in topics
    assert '/tf' not in topics


def test_the_raw_transform_is_the_serialised_message(ros):
    """/tf goes out as CDR bytes packed into a template: they are ``serialize_message`` of the
    TFMessage with those numbers (padding zeroed), stamps and awkward x included."""
    from geometry_msgs.msg import TransformStamped
    import numpy as np
    from rclpy.serialization import serialize_message
    from crawler_sim.bag.cdr import zero_padding
    from crawler_sim.bag.topics import TF
    node = SimNode(context=ros.ctx, namespace='/r2', parameter_overrides=[
        Parameter(k, value=v) for k, v in THREE_BODY.items()])
    ros.ex.add_node(node)
    ros.nodes.append(node)
    tf = node.outputs.tf
    assert tf.encode is not None
    rng = np.random.default_rng(5)
    for t_ns, x in [(0, 0.0), (10 * TICK, -0.0), (2**31 * 10**9 - 1, 1e-300),
                    *((int(rng.integers(0, 2**40)), float(rng.normal())) for _ in range(20))]:
        tr = TransformStamped()
        tr.header.frame_id, tr.child_frame_id = tf.parent, tf.child
        tr.transform.rotation.w = 1.0
        msg = TFMessage(transforms=[tr])
        tr.header.stamp.sec, tr.header.stamp.nanosec = divmod(t_ns, 10**9)
        tr.transform.translation.x = x
        assert tf.encode(t_ns, x) == zero_padding(serialize_message(msg), TF.type)
    assert (tr.header.frame_id, tr.child_frame_id) == ('r2/odom', 'r2/base_link')
