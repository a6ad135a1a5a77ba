"""The vectorized CDR decoder agrees with rclpy message by message.

It falls back to rclpy whenever a message does not share its template's layout.
"""
from __future__ import annotations

import struct

from mcap_ros2._dynamic import serialize_dynamic
import numpy as np
from numpy.testing import assert_array_equal
import pytest
from rclpy.serialization import deserialize_message, serialize_message

from crawler_sim.bag import schema as bag_schema
from crawler_sim.bag.cdr import (Decoder, Encoder, field_value, layout, LayoutError, set_fields,
                                  zero_padding)

JOINT_FIELDS = ('header.stamp.sec', 'header.stamp.nanosec', 'position', 'velocity', 'effort')


def pack(messages: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One buffer holding the messages back to back, with their starts and lengths."""
    lengths = np.array([len(m) for m in messages], dtype=np.int64)
    starts = np.concatenate(([0], np.cumsum(lengths)[:-1])).astype(np.int64)
    return np.frombuffer(b''.join(messages), dtype=np.uint8), starts, lengths


def joint_state(i: int, *, frame: str = '', names=('body_0', 'body_1', 'body_2'),
                position=None, velocity=None, effort=None):
    from sensor_msgs.msg import JointState
    n = len(names)
    msg = JointState(name=list(names))
    msg.header.stamp.sec, msg.header.stamp.nanosec = i, 1000 * i + 7
    msg.header.frame_id = frame
    msg.position = [0.5 * i + j for j in range(n)] if position is None else position
    msg.velocity = [-1.0 * i - j for j in range(n)] if velocity is None else velocity
    msg.effort = [i / 3 + j for j in range(n)] if effort is None else effort
    return msg


def expected(messages, paths) -> dict[str, list]:
    return {p: [np.atleast_1d(np.asarray(field_value(m, p))) for m in messages] for p in paths}


def check(decoder: Decoder, messages, paths) -> None:
    columns = decoder.columns()
    want = expected(messages, paths)
    for path in paths:
        assert columns[path].shape[0] == len(messages)
        for row, value in zip(columns[path], want[path]):
            assert_array_equal(row[:len(value)], value)
            assert np.isnan(row[len(value):]).all()


def test_uniform_joint_states_are_all_decoded_by_the_fast_path():
    messages = [joint_state(i) for i in range(50)]
    decoder = Decoder('sensor_msgs/msg/JointState', JOINT_FIELDS)
    decoder.add(*pack([serialize_message(m) for m in messages]))
    assert (decoder.fast, decoder.slow) == (50, 0)
    check(decoder, messages, JOINT_FIELDS)


@pytest.mark.parametrize('frame', ['', 'a', 'abcde', 'odom_frame'])
@pytest.mark.parametrize('sizes', [(3, 3, 3), (0, 1, 1), (2, 2, 0), (0, 0, 0), (1, 0, 2)])
def test_layouts_with_empty_sequences_and_odd_strings_match_rclpy(frame, sizes):
    """Fast CDR aligns an empty float64 sequence to 8 too; the walker must do the same."""
    messages = [joint_state(i, frame=frame, position=[1.0 * i] * sizes[0],
                            velocity=[2.0 * i] * sizes[1], effort=[3.0 * i] * sizes[2])
                for i in range(5)]
    decoder = Decoder('sensor_msgs/msg/JointState', JOINT_FIELDS)
    decoder.add(*pack([serialize_message(m) for m in messages]))
    assert decoder.fast == 5
    check(decoder, messages, JOINT_FIELDS)


def test_same_length_but_different_names_go_through_rclpy():
    messages = [joint_state(i, names=('body_0', 'body_1') if i % 3 else ('left_0', 'right'))
                for i in range(9)]
    raw = [serialize_message(m) for m in messages]
    assert len({len(r) for r in raw}) == 1            # same byte length, different content
    decoder = Decoder('sensor_msgs/msg/JointState', JOINT_FIELDS)
    decoder.add(*pack(raw))
    assert decoder.fast == 3 and decoder.slow == 6      # message 0 ('left_0', ...) is the template
    check(decoder, messages, JOINT_FIELDS)


def test_mixed_lengths_are_decoded_in_order_and_nan_padded():
    messages = [joint_state(i, names=[f'body_{j}' for j in range(1 + i % 3)]) for i in range(12)]
    decoder = Decoder('sensor_msgs/msg/JointState', JOINT_FIELDS)
    buffer, starts, lengths = pack([serialize_message(m) for m in messages])
    decoder.add(buffer, starts[:5], lengths[:5])           # in two batches
    decoder.add(buffer, starts[5:], lengths[5:])
    assert decoder.fast == 12
    check(decoder, messages, JOINT_FIELDS)


def test_messages_encoded_by_mcap_ros2_decode_like_rclpy_ones():
    """mcap_ros2's encoder pads differently after empty sequences; results must not differ."""
    type_name = 'sensor_msgs/msg/JointState'
    encoder = serialize_dynamic(type_name, bag_schema.full_text(type_name))[type_name]
    messages = [joint_state(i, frame='abcde', position=[], velocity=[1.0 * i], effort=[2.0])
                for i in range(6)]
    decoder = Decoder(type_name, JOINT_FIELDS)
    decoder.add(*pack([encoder(m) for m in messages]))
    assert decoder.fast + decoder.slow == 6
    check(decoder, messages, JOINT_FIELDS)


def test_odometry_and_multiarray_fields_decode_like_rclpy():
    from nav_msgs.msg import Odometry
    from std_msgs.msg import Float64MultiArray, Int8MultiArray, MultiArrayDimension
    odoms = []
    for i in range(4):
        m = Odometry()
        m.header.frame_id, m.child_frame_id = 'odom', 'base_link'
        m.pose.pose.position.x = 0.1 * i
        m.pose.covariance = [float(k + i) for k in range(36)]
        m.twist.twist.linear.x = -0.2 * i
        odoms.append(m)
    paths = ('pose.pose.position.x', 'pose.covariance', 'twist.twist.linear.x')
    decoder = Decoder('nav_msgs/msg/Odometry', paths)
    decoder.add(*pack([serialize_message(m) for m in odoms]))
    assert decoder.fast == 4
    check(decoder, odoms, paths)

    arrays = [Float64MultiArray(data=[1.0 * i, 2.0]) for i in range(3)]
    arrays[1].layout.dim = [MultiArrayDimension(label='x', size=2, stride=2)]
    decoder = Decoder('std_msgs/msg/Float64MultiArray', ('data',))
    decoder.add(*pack([serialize_message(m) for m in arrays]))
    check(decoder, arrays, ('data',))
    contacts = [Int8MultiArray(data=[-1, 0, 1, i]) for i in range(3)]
    decoder = Decoder('std_msgs/msg/Int8MultiArray', ('data',))
    decoder.add(*pack([serialize_message(m) for m in contacts]))
    assert decoder.columns()['data'].dtype == np.int8
    check(decoder, contacts, ('data',))


def test_layout_records_fixed_bytes_and_numeric_field_offsets():
    raw = serialize_message(joint_state(3, frame='ab'))
    lay = layout(raw, 'sensor_msgs/msg/JointState')
    assert lay.length == len(raw)
    assert lay.fields['header.stamp.sec'] == (4, 1, '<i4')
    offset, n, dtype = lay.fields['position']
    assert n == 3 and dtype == '<f8' and (offset - 4) % 8 == 0
    assert np.frombuffer(raw, '<f8', count=3, offset=offset).tolist() == [1.5, 2.5, 3.5]
    assert 0 in lay.fixed and 1 in lay.fixed            # encapsulation kind is fixed
    assert 4 not in lay.fixed                           # the stamp is data


# --------------------------------------------------------------------------- encoder

@pytest.mark.parametrize('frame,sizes', [('', (3, 3, 3)), ('odom', (2, 2, 2)), ('ab', (1, 0, 0)),
                                         ('abc', (0, 0, 0)), ('a', (4, 4, 0))])
def test_the_encoder_packs_numbers_into_a_template_like_serialize_message(frame, sizes):
    n_pos, n_vel, n_eff = sizes
    names = [f'j{k}' for k in range(n_pos)]
    groups = [('header.stamp.sec', 'header.stamp.nanosec')] + [
        (f,) for f, n in zip(('position', 'velocity', 'effort'), sizes) if n]
    proto = joint_state(1, frame=frame, names=names, position=[0.1] * n_pos,
                        velocity=[0.2] * n_vel, effort=[0.3] * n_eff)
    enc = Encoder(proto, 'sensor_msgs/msg/JointState', groups)
    for i in (0, 5, 2**20):
        msg = joint_state(i, frame=frame, names=names,
                          position=[i + 0.5 * k for k in range(n_pos)],
                          velocity=[-i - 1e-300 * k for k in range(n_vel)],
                          effort=[i / 7 for _ in range(n_eff)])
        values = [(msg.header.stamp.sec, msg.header.stamp.nanosec)] + [
            list(getattr(msg, g[0])) for g in groups[1:]]
        data = enc.encode(*values)
        assert data == zero_padding(serialize_message(msg), 'sensor_msgs/msg/JointState')
        assert deserialize_message(data, type(msg)) == msg


def test_the_encoder_refuses_what_it_cannot_template():
    proto = joint_state(1)
    with pytest.raises(LayoutError, match='not a numeric field'):
        Encoder(proto, 'sensor_msgs/msg/JointState', [('name',)])
    with pytest.raises(LayoutError, match='does not follow'):
        Encoder(proto, 'sensor_msgs/msg/JointState', [('position', 'effort')])
    enc = Encoder(proto, 'sensor_msgs/msg/JointState', [('position',)])
    with pytest.raises(struct.error):
        enc.encode([1.0, 2.0])                   # one length short: never silently wrong
    with pytest.raises(TypeError):
        enc.encode([1.0, 2.0, 3.0], [4.0])       # a group too many: never silently ignored
    with pytest.raises(LayoutError, match='order of their bytes'):
        Encoder(proto, 'sensor_msgs/msg/JointState', [('velocity',), ('position',)])


def test_the_encoder_packs_float32_and_int32_fields_between_constant_strings():
    """Marker: strings (ns, frame, text, mesh resource) between the changing numbers, float32
    colours, an int32 id; the bytes are serialize_message's, padding aside."""
    from visualization_msgs.msg import Marker
    proto = Marker(ns='bodies', id=3, type=Marker.CUBE, text='a', mesh_resource='m')
    proto.header.frame_id = 'odom'
    groups = [('header.stamp.sec', 'header.stamp.nanosec'), ('id',), ('pose.position.x',),
              ('color.r', 'color.g', 'color.b', 'color.a')]
    enc = Encoder(proto, 'visualization_msgs/msg/Marker', groups)
    msg = Marker(ns='bodies', id=-7, type=Marker.CUBE, text='a', mesh_resource='m')
    msg.header.frame_id = 'odom'
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 999_999_999
    msg.pose.position.x = -1e-300
    msg.color.r, msg.color.g, msg.color.b, msg.color.a = 0.1, 0.2, 0.3, 1.0
    data = enc.encode((12, 999_999_999), (-7,), (-1e-300,), (0.1, 0.2, 0.3, 1.0))
    assert data == zero_padding(serialize_message(msg), 'visualization_msgs/msg/Marker')
    assert deserialize_message(data, Marker) == deserialize_message(serialize_message(msg), Marker)


# --------------------------------------------------------------------------- set_fields

def trajectory(points: int, stamp=(0, 0)):
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    msg = JointTrajectory(joint_names=['linkage_0', 'linkage_1'])
    msg.header.frame_id = 'odom'
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    for k in range(points):                # empty effort: rclpy's serialisation has a tail
        msg.points.append(JointTrajectoryPoint(positions=[0.1 * k, 0.2], velocities=[0.0, 1.0]))
        msg.points[-1].time_from_start.sec, msg.points[-1].time_from_start.nanosec = divmod(
            10_000_000 * k, 1_000_000_000)
    return msg


@pytest.mark.parametrize('points', [0, 1, 500])
def test_set_fields_sets_a_stamp_and_keeps_every_other_byte(points):
    from trajectory_msgs.msg import JointTrajectory
    raw = serialize_message(trajectory(points))
    out = set_fields(raw, 'trajectory_msgs/msg/JointTrajectory',
                     {'header.stamp.sec': -3, 'header.stamp.nanosec': 123_456_789})
    assert deserialize_message(out, JointTrajectory) == trajectory(points, (-3, 123_456_789))
    assert len(out) == len(raw) and out[:4] == raw[:4] and out[12:] == raw[12:]
    assert out[4:12] == struct.pack('<iI', -3, 123_456_789)


def test_set_fields_walks_the_message_only_up_to_its_fields():
    """Only the header is walked: bytes cut right after it are enough, however many points
    the message claims (a trajectory of minutes costs what an empty one does)."""
    raw = serialize_message(trajectory(100_000))
    head = layout(raw, 'trajectory_msgs/msg/JointTrajectory',
                  only=['header.stamp.sec', 'header.stamp.nanosec'])
    assert head.end == 12 and set(head.fields) == {'header.stamp.sec', 'header.stamp.nanosec'}
    cut = set_fields(raw[:12], 'trajectory_msgs/msg/JointTrajectory', {'header.stamp.sec': 9})
    assert cut == raw[:4] + struct.pack('<i', 9) + raw[8:12]


def test_set_fields_refuses_a_field_that_is_not_a_number_of_the_message():
    raw = serialize_message(trajectory(2))
    with pytest.raises(LayoutError, match='header.frame_id'):
        set_fields(raw, 'trajectory_msgs/msg/JointTrajectory', {'header.frame_id': 1})
    with pytest.raises(struct.error):
        set_fields(raw, 'trajectory_msgs/msg/JointTrajectory', {'header.stamp.sec': [1, 2]})
