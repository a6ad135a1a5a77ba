"""``gait_node``: a small topic-driven controller that plays one of the core's gaits.

Time is ROS time: sim time with ``use_sim_time:=true`` (``sim_node`` with ``publish_clock:=true``);
the gait's t is measured from the first tick of the timer. Default gait: the seed's asymmetric
``Scallop`` stroke of ONE linkage (extension in 20 % of the period, contraction in 80 %) at
2 Hz, 0.08-0.12 m, which makes sim_node's default two-body crawler move forward (about
+4 mm/s, although it asks more of the default actuator than it gives: |l'| up to
0.77 m/s and |l''| up to 22 m/s^2). With ``n_links`` > 1 linkage j+1 leads linkage j
by ``phase_lag``: a travelling wave for chains. Two modes:

- ``command`` (default): every ``1/rate`` s it samples the lengths l(t) and publishes them on
  ``linkage_cmd`` (std_msgs/Float64MultiArray), the sim's step-command input; the sim's
  actuator model makes them smooth. Simple, but a command lands when it arrives, so a sim
  running much faster than real time sees it late (by the wall latency times the speed-up).
- ``trajectory``: every ``horizon/4`` s it publishes on ``linkage_trajectory`` a JointTrajectory
  stamped with absolute sim times, holding the next ``horizon`` s of the gait sampled at
  ``rate`` with positions, velocities and accelerations (quintic interpolation in the sim), plus
  a final point at rest as joint_trajectory_controller requires. Each one replaces the previous
  one long before its end, so the stroke is played exactly on sim time whatever the latency.

Parameters: ``gait`` (scallop | sinusoid), ``n_links``, ``mean`` [m], ``amplitude`` [m],
``frequency`` [Hz], ``asymmetry`` (scallop: fraction of the period spent extending),
``phase_lag`` [rad] between neighbouring linkages, ``rate`` [Hz], ``mode``, ``horizon`` [s],
``duration`` [s] of ROS time after which it stops publishing (0: forever), ``preload``
(trajectory mode: one trajectory of the whole duration, stamped 0, sent once a subscriber is
matched: the demo's deterministic command stream; the node then has no use for ROS time left
and stops taking /clock, which would otherwise wake it at every publish tick of a flat-out sim).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crawler_sim.core import gaits
from crawler_sim.ros.messages import float64_array_msg, linkage_names, stamp_from_ns

__all__ = ['GaitNode', 'make_gait', 'main']

GAITS = ('scallop', 'sinusoid')
MODES = ('command', 'trajectory')


def make_gait(name: str, n_links: int, mean: float, amplitude: float, frequency: float,
              asymmetry: float, phase_lag: float) -> gaits.Gait:
    """The named gait with linkage j lagging by ``j * phase_lag`` [rad]."""
    phase = [-j * phase_lag for j in range(n_links)]
    if name == 'scallop':
        return gaits.Scallop(mean, amplitude, frequency, asymmetry, phase, n_links=n_links)
    if name == 'sinusoid':
        return gaits.Sinusoid(mean, amplitude, frequency, phase, n_links=n_links)
    raise ValueError(f'gait must be one of {", ".join(GAITS)}, got {name!r}')


def gait_from_file(path: str) -> gaits.Gait:
    """The gait of the scene file ``path``; ValueError naming gait_file when it cannot be read
    or is not a valid scene."""
    from crawler_sim.core.scene import load_scene, SceneError
    try:
        return load_scene(path).gait
    except (OSError, SceneError) as exc:
        raise ValueError(f'gait_file: {exc}') from None


def _desc(text: str, lo: float | None = None, hi: float | None = None,
          integer: bool = False) -> ParameterDescriptor:
    d = ParameterDescriptor(description=text, read_only=True)
    if lo is not None:
        if integer:
            d.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi), step=1)]
        else:
            d.floating_point_range = [FloatingPointRange(from_value=lo, to_value=hi, step=0.0)]
    return d


class GaitNode(Node):
    """Publishes ``gait(t)`` lengths on ``linkage_cmd`` at ``rate`` Hz of ROS time."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('gait_node', **kwargs)
        p = {
            'gait': self.declare_parameter('gait', 'scallop', _desc(
                'Gait: ' + ' | '.join(GAITS))).value,
            'n_links': self.declare_parameter('n_links', 1, _desc(
                'Number of linkages (bodies - 1)', 1, 100, integer=True)).value,
            'mean': self.declare_parameter('mean', 0.1, _desc(
                'Mean length [m]', 0.0, 100.0)).value,
            'amplitude': self.declare_parameter('amplitude', 0.02, _desc(
                'Half stroke [m]', 0.0, 100.0)).value,
            'frequency': self.declare_parameter('frequency', 2.0, _desc(
                'Stroke frequency [Hz]', 1e-3, 100.0)).value,
            'asymmetry': self.declare_parameter('asymmetry', 0.2, _desc(
                'Scallop: fraction of the period spent extending', 0.01, 0.99)).value,
            'phase_lag': self.declare_parameter('phase_lag', -math.pi / 2, _desc(
                'Phase lag of linkage j+1 behind linkage j [rad] (negative: it leads)',
                -10.0, 10.0)).value,
        }
        rate = self.declare_parameter('rate', 50.0, _desc(
            'Command rate [Hz] of ROS time', 0.1, 10000.0)).value
        self._duration = self.declare_parameter('duration', 0.0, _desc(
            'Stop publishing after this much ROS time [s] (0: never)', 0.0, 1e9)).value
        self.mode = self.declare_parameter('mode', 'command', _desc(
            'command (lengths on linkage_cmd) | trajectory (on linkage_trajectory)')).value
        self._horizon = self.declare_parameter('horizon', 4.0, _desc(
            'Trajectory mode: seconds of gait per trajectory', 0.1, 3600.0)).value
        self._preload = self.declare_parameter('preload', False, _desc(
            'Trajectory mode: publish ONE trajectory of the whole duration, stamped 0 (start at '
            'the tick it is applied), as soon as a subscriber is matched; then nothing. The '
            'same command stream whatever the timing: a deterministic run')).value
        if self._preload and not (self.mode == 'trajectory' and self._duration > 0):
            raise ValueError('preload needs mode trajectory and a duration > 0')
        if self.mode not in MODES:
            raise ValueError(f'mode must be one of {", ".join(MODES)}, got {self.mode!r}')
        gait_file = self.declare_parameter('gait_file', '', _desc(
            'A scene YAML file (top-level "scene:", e.g. the OUT_scene.yaml of crawler-sim '
            'optimize): play its gait, of any family, instead of the gait parameters above')).value
        self.gait = (gait_from_file(gait_file) if gait_file else
                     make_gait(p['gait'], p['n_links'], p['mean'], p['amplitude'],
                               p['frequency'], p['asymmetry'], p['phase_lag']))
        if gait_file:
            p = {'gait_file': gait_file, 'n_links': self.gait.n_links}
        self._rate = rate
        if self.mode == 'command':
            self._pub = self.create_publisher(Float64MultiArray, 'linkage_cmd', 10)
        else:
            self._pub = self.create_publisher(JointTrajectory, 'linkage_trajectory', 10)
        self._t0_ns: int | None = None
        self._next_ns = 0
        self.sent = 0
        if self._preload:
            from rclpy.clock import Clock, ClockType
            self._preload_timer = self.create_timer(
                0.05, self._on_preload, clock=Clock(clock_type=ClockType.STEADY_TIME))
        else:
            self.create_timer(1.0 / rate, self._on_timer)
        topic = 'linkage_cmd' if self.mode == 'command' else 'linkage_trajectory'
        what = p.get('gait_file') or p['gait']
        self.get_logger().info(f'playing {what} on {topic} at {rate} Hz: {p}')

    def _on_timer(self) -> None:
        now = self.get_clock().now().nanoseconds
        if self._t0_ns is None:
            self._t0_ns = now
        t = (now - self._t0_ns) / 1e9
        if self._duration and t > self._duration:
            return
        if self.mode == 'command':
            self._pub.publish(float64_array_msg(self.gait.length(t).tolist()))
            self.sent += 1
        elif now >= self._next_ns:
            self._pub.publish(self.trajectory(now))
            self._next_ns = now + round(self._horizon / 4 * 1e9)
            self.sent += 1

    def _on_preload(self) -> None:
        if self.sent or self._pub.get_subscription_count() == 0:
            return
        self._t0_ns = 0
        msg = self.trajectory(0, horizon=self._duration)
        msg.header.stamp = stamp_from_ns(0)       # 0: start at the tick it is applied
        self._pub.publish(msg)
        self.sent += 1
        self._preload_timer.cancel()
        self.get_logger().info(f'preloaded one trajectory of {len(msg.points)} points')
        self._stop_taking_clock()

    def _stop_taking_clock(self) -> None:
        """Destroy the /clock subscription of use_sim_time (preload: nothing reads ROS time
        after the one trajectory, stamped 0 and sent on a steady timer). Each /clock message
        is otherwise a Python callback: a quarter of a core next to a flat-out sim_node."""
        source = getattr(self, '_time_source', None)
        sub = getattr(source, '_clock_sub', None)
        if sub is not None:
            self.destroy_subscription(sub)
            source._clock_sub = None

    def trajectory(self, now_ns: int, horizon: float | None = None) -> JointTrajectory:
        """The next ``horizon`` seconds of the gait from ROS time ``now_ns``, stamped
        absolutely."""
        n = max(2, round((self._horizon if horizon is None else horizon) * self._rate))
        step = 1.0 / self._rate
        tau = np.arange(n) * step
        gait_t = (now_ns - self._t0_ns) / 1e9 + tau
        if self._duration:
            keep = gait_t <= self._duration
            tau, gait_t = tau[keep], gait_t[keep]
        l, ld, ldd = self.gait(gait_t)
        msg = JointTrajectory()
        msg.header.stamp = stamp_from_ns(now_ns)
        msg.joint_names = list(linkage_names(self.gait.n_links))
        zeros = [0.0] * self.gait.n_links
        rows = [(tk, l[k].tolist(), ld[k].tolist(), ldd[k].tolist()) for k, tk in enumerate(tau)]
        last = rows[-1][0] if rows else 0.0
        end_l = rows[-1][1] if rows else self.gait.length(gait_t[0] if len(gait_t) else 0.0)
        rows.append((last + step, list(end_l), zeros, zeros))     # at rest, as JTC requires
        for tk, pos, vel, acc in rows:
            pt = JointTrajectoryPoint(positions=pos, velocities=vel, accelerations=acc)
            pt.time_from_start.sec, pt.time_from_start.nanosec = divmod(round(tk * 1e9),
                                                                        1_000_000_000)
            msg.points.append(pt)
        return msg


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run crawler_sim gait_node``."""
    rclpy.init(args=args)
    node = None
    try:
        node = GaitNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():
            raise
        # a signal shut ROS down while the node was starting: a clean exit
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
