"""``gait_node``: a small topic-driven controller that plays one of the core's gaits.

Time is ROS time: sim time with ``use_sim_time:=true`` (``sim_node`` with ``publish_clock:=true``);
the gait's t is measured from the first tick of the timer. Default gait: the seed's asymmetric
``Scallop`` stroke of ONE linkage (extension in 20 % of the period, contraction in 80 %) at
2 Hz, 0.08-0.12 m, which makes sim_node's default two-body crawler move forward (about
+4 mm/s, although it asks more of the default actuator than it gives: |l'| up to
0.77 m/s and |l''| up to 22 m/s^2). With more than one linkage linkage j+1 leads linkage j
by ``phase_lag``: a travelling wave for chains. How the gait is sent (``mode``, ``rate``,
``horizon``, ``preload``, ``duration``) is a ``crawler_sim.core.plant.streams.Stream``, the
same description ``crawler-sim optimize`` scores with (one sampler of a gait into trajectory
points, ``streams.trajectory_points``):

- ``command`` (default): every ``1/rate`` s it samples the lengths l(t) and publishes them on
  ``linkage_cmd`` (std_msgs/Float64MultiArray), the sim's step-command input; the sim's
  actuator model makes them smooth. Simple, but a command lands when it arrives, so a sim
  running much faster than real time sees it late (by the wall latency times the speed-up).
- ``trajectory``: every ``horizon/4`` s it publishes on ``linkage_trajectory`` a JointTrajectory
  stamped with absolute sim times, holding the next ``horizon`` s of the gait sampled at
  ``rate`` with positions, velocities and accelerations (quintic interpolation in the sim), plus
  a final point at rest as joint_trajectory_controller requires.
- ``preload`` (trajectory mode): one trajectory of the whole ``duration``, stamped 0 (start at
  the tick it is applied), sent once a subscriber is matched: the same command stream whatever
  the timing, hence a deterministic run (the demo's, and what an optimised gait file asks for).
  The node then has no use for ROS time left and stops taking /clock, which would otherwise wake
  it at every publish tick of a flat-out sim.

``n_links`` 0 (the default) asks the running sim_node (``sim_node`` names it, in this node's
namespace) for its number of linkages and length limits, waiting up to ``wait_for_sim`` s, and
then follows the sim's parameter events: when its ``masses`` change the number of bodies at run
time, the next command has the new number of lengths (the sim would reject every command of
the old size). A ``gait_file`` gives its own number, which stays. ``--help`` lists the
parameters (``crawler_sim.ros.args.help_text``). Every parameter is checked at start: a bad
value, a parameter the node does not have (``-p frequncy:=1.0``) or an argument outside
``--ros-args`` ends the node with one line naming it and its allowed range (exit code 1, 2 for
arguments).

A message it cannot read (a /clock message or a parameter request rclpy fails to convert) is
skipped, counted and reported (a WARN line and a ``/diagnostics`` status ``<node>: input`` at
most once per second), and SIGINT/SIGTERM stop it between two callbacks, exit code 0
(``crawler_sim.ros.rejections``).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import sys
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from crawler_sim.bag import topics as T
from crawler_sim.core import gaits
from crawler_sim.core.plant.config import MAX_BODIES
from crawler_sim.core.plant.streams import MODES, Stream, trajectory_points
from crawler_sim.ros.messages import float64_array_msg, linkage_names, stamp_from_ns
from crawler_sim.ros.rejections import spin, stop_on_signals, UnreadableInput
from crawler_sim.core.simtime import to_seconds

__all__ = ['GaitNode', 'GaitSettings', 'PARAMETERS', 'make_gait', 'main']

GAITS = ('scallop', 'sinusoid')
MAX_LINKS = MAX_BODIES - 1

#: name -> (default, description with unit and allowed values, (lo, hi) of a number or None)
PARAMETERS: dict[str, tuple[Any, str, tuple[float, float] | None]] = {
    'gait': ('scallop', 'Gait: ' + ' | '.join(GAITS), None),
    'n_links': (0, f'Number of linkages (bodies - 1), 0 to {MAX_LINKS}; 0: ask the running '
                'sim_node (a gait_file gives its own)', (0, MAX_LINKS)),
    'mean': (0.1, 'Mean length [m], in (0, 100]', (0.0, 100.0)),
    'amplitude': (0.02, 'Half stroke [m], in [0, 100] and below mean', (0.0, 100.0)),
    'frequency': (2.0, 'Stroke frequency [Hz], in [0.001, 100]', (1e-3, 100.0)),
    'asymmetry': (0.2, 'Scallop: fraction of the period spent extending, in [0.01, 0.99]',
                  (0.01, 0.99)),
    'phase_lag': (-math.pi / 2, 'Phase lag of linkage j+1 behind linkage j [rad], in '
                  '[-10, 10] (negative: it leads)', (-10.0, 10.0)),
    'rate': (50.0, 'Command rate [Hz] of ROS time (trajectory mode: samples per second), in '
             '[0.1, 10000]', (0.1, 10000.0)),
    'duration': (0.0, 'Stop publishing after this much ROS time [s], in [0, 1e9] (0: never)',
                 (0.0, 1e9)),
    'mode': ('command', 'command (lengths on linkage_cmd) | trajectory (on linkage_trajectory)',
             None),
    'horizon': (4.0, 'Trajectory mode: seconds of gait per trajectory, in [0.1, 3600]',
                (0.1, 3600.0)),
    'preload': (False, 'Trajectory mode: publish ONE trajectory of the whole duration, stamped '
                '0 (start at the tick it is applied), as soon as a subscriber is matched; then '
                'nothing. The same command stream whatever the timing: a deterministic run',
                None),
    'gait_file': ('', 'A scene YAML file (top-level "scene:", e.g. the OUT_scene.yaml of '
                  'crawler-sim optimize): play its gait, of any family, instead of the gait '
                  'parameters above', None),
    'sim_node': ('crawler_sim', 'Name of the sim_node to ask for the number of linkages when '
                 'n_links is 0 (relative: in this node\'s namespace)', None),
    'wait_for_sim': (10.0, 'Seconds to wait for that sim_node, in [0, 3600]', (0.0, 3600.0)),
}
#: the first paragraph of ``gait_node --help``
HELP_SUMMARY = ('Plays a gait of the core on linkage_cmd (or as trajectories on '
                'linkage_trajectory) at rate Hz of ROS time (sim time with use_sim_time:=true). '
                'Without n_links it asks the running sim_node for its number of linkages and '
                'follows a change of its masses at run time. Parameters are read at start.')
_GAIT_PARAMETERS = ('gait', 'mean', 'amplitude', 'frequency', 'asymmetry', 'phase_lag')
_UNITS = {'mean': ' m', 'amplitude': ' m', 'frequency': ' Hz', 'phase_lag': ' rad',
          'rate': ' Hz', 'duration': ' s', 'horizon': ' s', 'wait_for_sim': ' s'}


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


def _number(name: str, value: Any, integer: bool = False) -> float:
    """``value`` as a number in the range of ``PARAMETERS[name]`` (an int is a number; an
    integral float is an integer); ValueError naming the field and the range."""
    lo, hi = PARAMETERS[name][2]
    unit = _UNITS.get(name, '')
    kind = 'an integer' if integer else 'a number'
    ok_type = isinstance(value, (int, float)) and not isinstance(value, bool)
    if ok_type and integer and isinstance(value, float):
        ok_type = value.is_integer()
    if not ok_type:
        raise ValueError(f'{name} must be {kind} in [{lo:g}, {hi:g}]{unit}, got {value!r}')
    x = float(value)
    if not (math.isfinite(x) and lo <= x <= hi):
        raise ValueError(f'{name} must be in [{lo:g}, {hi:g}]{unit}, got {value!r}')
    return int(x) if integer else x


@dataclass(frozen=True)
class GaitSettings:
    """gait_node's parameters validated (no ROS): the gait (None while n_links is still to be
    asked from the sim), its number of linkages (0: ask) and how it is sent."""

    values: dict
    n_links: int
    stream: Stream
    gait: gaits.Gait | None

    @classmethod
    def from_values(cls, values: dict) -> GaitSettings:
        """Validate gait_node's parameter values; ValueError naming the field and the
        allowed range."""
        v = dict(values)
        for name in ('gait', 'mode', 'gait_file', 'sim_node'):
            if not isinstance(v[name], str):
                raise ValueError(f'{name} must be a string ({PARAMETERS[name][1]}), got '
                                 f'{v[name]!r}')
        if v['gait'] not in GAITS:
            raise ValueError(f'gait must be one of {", ".join(GAITS)}, got {v["gait"]!r}')
        if v['mode'] not in MODES:
            raise ValueError(f'mode must be one of {", ".join(MODES)}, got {v["mode"]!r}')
        if not isinstance(v['preload'], bool):
            raise ValueError(f'preload must be true or false, got {v["preload"]!r}')
        n_links = _number('n_links', v['n_links'], integer=True)
        for name, (_, _, rng) in PARAMETERS.items():
            if rng is not None and name != 'n_links':
                v[name] = _number(name, v[name])
        if not v['mean'] > 0:
            raise ValueError(f'mean must be in (0, 100] m, got {v["mean"]!r}')
        if not v['amplitude'] < v['mean']:
            raise ValueError(f'amplitude ({v["amplitude"]} m) must be below mean '
                             f'({v["mean"]} m): a linkage length stays > 0')
        try:
            stream = Stream(v['mode'], v['rate'], v['horizon'], v['preload'], v['duration'])
        except ValueError as exc:
            raise ValueError(str(exc)) from None
        gait = None
        if v['gait_file']:
            gait = gait_from_file(v['gait_file'])
            if n_links and n_links != gait.n_links:
                raise ValueError(f'n_links = {n_links}, but gait_file {v["gait_file"]} drives '
                                 f'{gait.n_links} linkages')
            n_links = gait.n_links
        elif n_links:
            gait = cls._gait(v, n_links)
        return cls(v, n_links, stream, gait)

    @staticmethod
    def _gait(v: dict, n_links: int) -> gaits.Gait:
        return make_gait(v['gait'], n_links, v['mean'], v['amplitude'], v['frequency'],
                         v['asymmetry'], v['phase_lag'])

    def with_links(self, n_links: int) -> GaitSettings:
        """The settings with the number of linkages the sim reported."""
        return GaitSettings(self.values, n_links, self.stream, self._gait(self.values, n_links))


def _descriptor(name: str) -> ParameterDescriptor:
    # dynamic typing: `-p amplitude:=1` (an integer) is a number too, and every value goes
    # through GaitSettings, which names the field and its range in one line (rclpy's own type
    # and range errors are tracebacks); read-only: the gait is fixed at start
    return ParameterDescriptor(description=PARAMETERS[name][1], read_only=True,
                               dynamic_typing=True)


class GaitNode(Node):
    """Publishes ``gait(t)`` lengths on ``linkage_cmd`` (or trajectories) at ``rate`` Hz of
    ROS time. Raises ValueError (one line) for a parameter it cannot use."""

    def __init__(self, argv: list[str] | None = None, **kwargs: Any) -> None:
        super().__init__('gait_node', **kwargs)
        from crawler_sim.ros.args import unknown_parameters
        values = {name: self.declare_parameter(name, default, _descriptor(name)).value
                  for name, (default, _, _) in PARAMETERS.items()}
        unknown = unknown_parameters(self, argv or [])
        if unknown:
            raise ValueError('; '.join(unknown))
        settings = GaitSettings.from_values(values)
        #: the sim's number of linkages as its latest parameter event gives it (None: none
        #: seen); only followed when the node asked the sim for it (no n_links, no gait_file)
        self._sim_links: int | None = None
        self._sim_events = None
        if settings.gait is None:
            # listen before asking: a change of masses between the answer and a later
            # subscription would otherwise go unnoticed, and an event is never older than
            # the answer it arrives after (it is sent once the change is accepted)
            self._sim_events = self._follow_sim_bodies(settings.values)
            settings = settings.with_links(self._ask_sim(settings.values))
        self.settings = settings
        self.gait = settings.gait
        self.mode = settings.stream.mode
        self._stream = settings.stream
        self._rate = settings.stream.rate
        self._horizon = settings.stream.horizon
        self._duration = settings.stream.duration
        self._preload = settings.stream.preload
        if self.mode == 'command':
            self._pub = self.create_publisher(Float64MultiArray, T.LINKAGE_CMD.node_name, 10)
        else:
            self._pub = self.create_publisher(JointTrajectory, T.LINKAGE_TRAJECTORY.node_name,
                                              10)
        self._t0_ns: int | None = None
        self._next_ns = 0
        self.sent = 0
        if self._preload:
            from rclpy.clock import Clock, ClockType
            self._preload_timer = self.create_timer(
                0.05, self._on_preload, clock=Clock(clock_type=ClockType.STEADY_TIME))
        else:
            self.create_timer(1.0 / self._rate, self._on_timer)
        topic = (T.LINKAGE_CMD if self.mode == 'command' else T.LINKAGE_TRAJECTORY).node_name
        v = settings.values
        what = v['gait_file'] or {k: v[k] for k in _GAIT_PARAMETERS}
        self.get_logger().info(f'playing {what} on {self.gait.n_links} linkage(s), {topic} at '
                               f'{self._rate} Hz ({"preloaded" if self._preload else self.mode})')
        # last: _ask_sim spins the node in an executor of its own for a while
        self.unreadable = UnreadableInput(self)

    @property
    def t0_ns(self) -> int | None:
        """The ROS time [ns] the gait's t = 0 is at (None before the first timer tick)."""
        return self._t0_ns

    def _ask_sim(self, v: dict) -> int:
        """The number of linkages of the running sim_node (and a check of the gait against its
        length limits); ValueError when it does not answer within ``wait_for_sim``."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.executors import SingleThreadedExecutor
        name = self.resolve_service_name(f'{v["sim_node"]}/get_parameters')
        client = self.create_client(GetParameters, name)
        executor = SingleThreadedExecutor(context=self.context)
        executor.add_node(self)
        try:
            wait = v['wait_for_sim']
            if not client.wait_for_service(timeout_sec=wait):
                raise ValueError(f'n_links is 0 (ask the sim) but no sim_node answers at '
                                 f'{client.srv_name} within wait_for_sim = {wait:g} s: start '
                                 'sim_node first or give -p n_links:=N')
            future = client.call_async(GetParameters.Request(
                names=['masses', 'min_length', 'max_length']))
            executor.spin_until_future_complete(future, timeout_sec=max(wait, 1.0))
            if not future.done() or future.result() is None:
                raise ValueError(f'{client.srv_name} did not answer within {wait:g} s')
            masses, lo, hi = future.result().values
        finally:
            executor.remove_node(self)
            executor.shutdown()
            self.destroy_client(client)
        n_links = len(masses.double_array_value) - 1
        if not 1 <= n_links <= MAX_LINKS:
            raise ValueError(f'the sim_node at {client.srv_name} reports {n_links} linkages')
        low = v['mean'] - v['amplitude']
        high = v['mean'] + v['amplitude']
        if low < lo.double_value or high > hi.double_value:
            raise ValueError(f'the gait spans [{low:g}, {high:g}] m, outside the sim\'s '
                             f'[min_length, max_length] = [{lo.double_value:g}, '
                             f'{hi.double_value:g}] m: every command would be rejected')
        self.get_logger().info(f'{client.srv_name}: {n_links} linkage(s)')
        return n_links

    def _follow_sim_bodies(self, v: dict) -> Any:
        """Follow the sim's ``masses`` through its parameter events (rclpy's
        ParameterEventHandler, on /parameter_events filtered on the sim's node name): a change
        of the number of bodies at run time (``ros2 param set /crawler_sim masses ...``) would
        otherwise leave this node sending lengths of the old size, every one rejected by the
        sim. The handler only notes the new count; the timer switches the gait (one thread
        owns the gait). Returns the handler (kept: dropping it ends the subscription)."""
        from rclpy.parameter_event_handler import ParameterEventHandler
        sim = self.resolve_service_name(v['sim_node'])
        handler = ParameterEventHandler(self)

        def on_masses(param: Any) -> None:
            value = param.value
            # dynamic typing: masses:=[1,1,1] comes as integers
            entries = list(value.double_array_value) or list(value.integer_array_value)
            if 1 <= len(entries) - 1 <= MAX_LINKS:
                self._sim_links = len(entries) - 1
        self._masses_handle = handler.add_parameter_callback('masses', sim, on_masses)
        return handler

    def _follow_sim(self) -> None:
        """Switch to the number of linkages the sim last reported, if it changed."""
        n = self._sim_links
        if n is None or n == self.gait.n_links:
            return
        old = self.gait.n_links
        self.settings = self.settings.with_links(n)
        self.gait = self.settings.gait
        self.get_logger().info(f'the sim now has {n + 1} bodies: playing the gait on {n} '
                               f'linkage(s) (was {old})')

    def _on_timer(self) -> None:
        self._follow_sim()
        now = self.get_clock().now().nanoseconds
        if self._t0_ns is None:
            self._t0_ns = now
        t = to_seconds(now - self._t0_ns)
        if self._duration and t > self._duration:
            return
        if self.mode == 'command':
            self._pub.publish(float64_array_msg(self.gait.length(t).tolist()))
            self.sent += 1
        elif now >= self._next_ns:
            self._pub.publish(self.trajectory(now))
            self._next_ns = now + self._stream.period_ns
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
        """Stop following /clock (preload: nothing reads ROS time after the one trajectory,
        stamped 0 and sent on a steady timer). Each /clock message is otherwise a Python
        callback: a quarter of a core next to a flat-out sim_node. Setting ``use_sim_time``
        false is rclpy's public way to drop its /clock subscription."""
        if self.get_parameter('use_sim_time').value:
            self.set_parameters([Parameter('use_sim_time', Parameter.Type.BOOL, False)])
            self.get_logger().info('preload sent: /clock no longer followed '
                                   '(use_sim_time set to false)')

    def trajectory(self, now_ns: int, horizon: float | None = None) -> JointTrajectory:
        """The next ``horizon`` seconds of the gait from ROS time ``now_ns``, stamped
        absolutely (``streams.trajectory_points``)."""
        tfs, pos, vel, acc = trajectory_points(
            self.gait, to_seconds(now_ns - self._t0_ns),
            self._horizon if horizon is None else horizon, self._rate, self._duration)
        msg = JointTrajectory()
        msg.header.stamp = stamp_from_ns(now_ns)
        msg.joint_names = list(linkage_names(self.gait.n_links))
        for k in range(len(tfs)):
            pt = JointTrajectoryPoint(positions=pos[k].tolist(), velocities=vel[k].tolist(),
                                      accelerations=acc[k].tolist())
            pt.time_from_start.sec, pt.time_from_start.nanosec = divmod(int(tfs[k]),
                                                                        1_000_000_000)
            msg.points.append(pt)
        return msg


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run crawler_sim gait_node``."""
    from crawler_sim.ros.args import ArgsError, check_args, print_help_and_exit
    argv = list(sys.argv if args is None else args)
    print_help_and_exit(argv, 'gait_node', 'gait_node', HELP_SUMMARY, PARAMETERS)
    try:
        check_args(argv, 'gait_node')
    except ArgsError as exc:
        print(f'[gait_node] cannot start: {exc}', file=sys.stderr, flush=True)
        raise SystemExit(2) from None
    rclpy.init(args=argv)
    node = None
    try:
        node = GaitNode(argv)
        spin(node.unreadable.executor, stop_on_signals())
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        if not rclpy.ok():
            pass            # a signal shut ROS down while the node was starting: a clean exit
        elif node is None:  # a parameter or a name it cannot use: one line, exit 1
            print(f'[gait_node] cannot start: {exc}', file=sys.stderr, flush=True)
            raise SystemExit(1) from None
        else:
            raise
    finally:
        if node is not None:
            node.unreadable.executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
