"""rclpy messages of a recording, built from plain numbers (no rclpy.init needed).

They are the node's own builders (``crawler_sim/messages.py``): JointState names ``body_i`` /
``linkage_j`` with an empty frame id, Int8MultiArray / Float64MultiArray without layout, Odometry
of the centre of mass in frame ``odom`` with child ``base_link`` and identity orientation. All
times are integer nanoseconds of sim time (see :mod:`crawler_sim.bag.clock`).
"""
from __future__ import annotations

from typing import Any

from std_msgs.msg import String
import yaml

# One set of builders for the node and for offline recording (same messages in both bags).
from ..messages import (  # noqa: F401  (re-exported for the recorder)
    BASE_FRAME, body_names, body_states, contact_states, joint_state, joint_states,
    linkage_names, ODOM_FRAME, odometry)
from ..messages import event_msg as event  # noqa: F401
from ..messages import float64_array_msg as float64_array  # noqa: F401


def scene_string(scene: dict[str, Any]) -> String:
    """``crawler_sim/scene``: the scene as YAML text."""
    return String(data=yaml.safe_dump(scene, sort_keys=False, default_flow_style=None))
