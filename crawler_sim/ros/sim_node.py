"""``sim_node``: the crawler as a ROS 2 node driven by commanded linkage lengths.

The node is a thin layer around ``crawler_sim.core.engine.Engine`` (the actuator model and the
core's exact ``Stepper``, no ROS). Interface (relative names unless they start with ``/``):

- subscribes ``linkage_cmd`` (std_msgs/Float64MultiArray): target length of each linkage [m];
  ``linkage_trajectory`` (trajectory_msgs/JointTrajectory, joints ``linkage_0``...);
- publishes ``joint_states``, ``body_states`` (sensor_msgs/JointState), ``contact_states``
  (std_msgs/Int8MultiArray), ``odom`` (nav_msgs/Odometry), ``markers``
  (visualization_msgs/MarkerArray), ``~/applied_command`` (sensor_msgs/JointState: the target that
  took effect, stamped with the sim time of the tick it took effect at), ``/diagnostics``
  (diagnostic_msgs/DiagnosticArray, every ``diagnostics_period`` wall seconds) and ``/clock``
  (rosgraph_msgs/Clock, when ``publish_clock``, at every publish tick);
- services ``~/reset`` (std_srvs/Trigger) and ``~/pause`` (std_srvs/SetBool).

Timing. Sim time is an integer number of nanoseconds that advances by ``dt = 1/integration_rate``
per tick, so a run is deterministic: the same commands taking effect at the same ticks give
bit-identical states. A tick: apply pending parameter changes, then the pending command
(commands and trajectories take effect at the next tick boundary after they arrive), ask the
actuator for one constant-jerk piece on [t, t + dt] (l is C2 across ticks), and every
``N = round(integration_rate / publish_rate)`` ticks integrate the N queued pieces exactly in one
``Stepper.advance`` and publish ``/clock`` and the outputs. Queuing changes no physics (the
solution of the same l(t) is the same), only where the exact solver cuts its segments, which the
publish grid fixes; ``crawler-sim replay`` runs the same engine and reproduces a run bit for bit.

One loop (:meth:`SimNode.run`) drives the ticks in both clock modes. It takes the
``linkage_cmd`` and ``linkage_trajectory`` messages itself at the start of every tick
(:meth:`SimNode.take_inputs`; the executor never runs those subscriptions, see
:class:`LoopTakenGroup`); services and parameter callbacks run in an executor thread and only
take a lock to store what they received, so every change lands between two ticks.
``real_time_factor`` paces the loop against the wall clock (1 = real time,
10 = ten times faster, 0 = as fast as possible). A tick that starts more than one tick period
after its wall deadline is counted as late, and the loop catches up by running the due ticks
back to back (beyond 0.5 s of lag it gives up on the lost time and re-anchors).

Parameters are declared with descriptions and ranges (see :data:`PARAMETERS`); a set that fails
validation (range, type, list lengths against ``masses``, the core's own checks) is rejected
with a reason and the simulation keeps running on its previous values. Accepted changes take
effect at the next tick: the crawler (same number of bodies) and the method are swapped in at
the current state; a new number of bodies resets the simulation; ``initial_lengths`` and
``initial_position`` are used at the next reset; ``record*`` are read-only.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import os
import signal
import sys
import threading
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
import rclpy
from rclpy.callback_groups import CallbackGroup
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Int8MultiArray
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import MarkerArray

from crawler_sim.ros import messages as M
from crawler_sim.core.actuator import ActuatorLimits, TrajectoryReference
from crawler_sim.core.engine import Engine, EngineConfig
from crawler_sim.core.model import Crawler
from crawler_sim.core.stepper import METHODS

__all__ = ['SimNode', 'SimConfig', 'PARAMETERS', 'main', 'validate_command', 'LoopTakenGroup']

NODE_NAME = 'crawler_sim'
MAX_LAG = 0.5            # wall s of lag after which the real-time loop re-anchors
WARN_THROTTLE = 1.0      # s between two warnings about rejected input


def _rng(lo: float, hi: float) -> list[FloatingPointRange]:
    return [FloatingPointRange(from_value=float(lo), to_value=float(hi), step=0.0)]


#: name -> (default, description, range or None, read_only)
PARAMETERS: dict[str, tuple[Any, str, tuple[float, float] | None, bool]] = {
    'masses': ([1.0, 1.0, 1.0], 'Body masses [kg], p >= 2 entries, each > 0; p sets the number '
               'of bodies (a change of p resets the simulation)', None, False),
    'friction': ([3.0], 'Friction force resisting forward sliding [N], one entry for all bodies '
                 'or one per body, each >= 0', None, False),
    'friction_backward': ([3.0], 'Friction force resisting backward sliding [N], one entry for '
                          'all bodies or one per body, each >= 0', None, False),
    'slope': (0.0, 'Incline [rad], uphill is +x', (-1.5, 1.5), False),
    'gravity': (9.81, 'Gravitational acceleration [m/s^2] (acts through the slope)',
                (0.0, 100.0), False),
    'initial_lengths': ([0.1, 0.1], 'Linkage lengths at start and after reset [m], one entry for '
                        'all linkages or p-1 entries, within [min_length, max_length]',
                        None, False),
    'initial_position': (0.0, 'Position of body 0 at start and after reset [m]',
                         (-1e6, 1e6), False),
    'integration_rate': (1000.0, 'Ticks per simulated second [Hz]; dt = 1/integration_rate',
                         (1.0, 100000.0), False),
    'publish_rate': (100.0, 'Output (and /clock) rate [Hz] in sim time, <= integration_rate; '
                     'outputs go out every round(integration_rate/publish_rate) ticks',
                     (0.1, 100000.0), False),
    'method': ('exact', 'Solver: exact (event driven), implicit (Moreau-Jean) or penalty',
               None, False),
    'penalty': ([10000.0], 'Method penalty only: the regularisation n [N s/m] of the seed, one '
                'entry for all bodies or one per body, each > 0 (error ~ sqrt(t f^2 / (M n)))',
                None, False),
    'actuator_bandwidth': (5.0, 'Actuator -3 dB bandwidth [Hz] (critically damped 3rd order)',
                           (0.01, 1000.0), False),
    'actuator_max_speed': (0.5, 'Largest |l\'| of a linkage [m/s]', (1e-6, 100.0), False),
    'actuator_max_acceleration': (5.0, 'Largest |l\'\'| of a linkage [m/s^2]',
                                  (1e-6, 1e5), False),
    'min_length': (0.02, 'Shortest commandable linkage length [m]', (0.0, 100.0), False),
    'max_length': (0.5, 'Longest commandable linkage length [m]', (0.0, 100.0), False),
    'real_time_factor': (1.0, 'Sim seconds per wall second: 1 real time, 10 ten times faster, '
                         '0 as fast as possible', (0.0, 1000.0), False),
    'publish_clock': (False, 'Publish /clock (sim time) so other nodes can use_sim_time',
                      None, False),
    'publish_joint_states': (True, 'Publish joint_states', None, False),
    'publish_body_states': (True, 'Publish body_states', None, False),
    'publish_contact_states': (True, 'Publish contact_states', None, False),
    'publish_odom': (True, 'Publish odom', None, False),
    'publish_markers': (True, 'Publish markers', None, False),
    'publish_diagnostics': (True, 'Publish /diagnostics', None, False),
    'diagnostics_period': (1.0, 'Wall seconds between /diagnostics messages',
                           (0.05, 3600.0), False),
    'start_paused': (False, 'Start paused (~/pause false starts the clock), so that controllers '
                     'and recorders can connect first', None, True),
    'record': (False, 'Record inputs and outputs to an MCAP bag (crawler_sim.bag)', None, True),
    'record_dir': ('runs', 'Directory for new bags', None, True),
    'record_name': ('', 'Bag name under record_dir (empty: crawler_sim_<date>-<time>)',
                    None, True),
}
OUTPUTS = ('joint_states', 'body_states', 'contact_states', 'odom', 'markers', 'diagnostics')


@dataclass(frozen=True)
class SimConfig:
    """The node's parameters, validated and turned into core objects (the one place that reads
    parameter values)."""

    values: dict
    crawler: Crawler
    initial_lengths: tuple[float, ...]
    limits: ActuatorLimits
    dt_ns: int
    publish_every: int

    @property
    def p(self) -> int:
        return self.crawler.p

    @property
    def n_links(self) -> int:
        return self.crawler.p - 1

    def engine_config(self) -> EngineConfig:
        """The part of the configuration the integration loop (``engine.Engine``) uses."""
        return EngineConfig(self.crawler, self.method, self.dt_ns, self.publish_every,
                            self.initial_lengths, self.initial_position, self.limits,
                            self.penalty_n)

    @property
    def penalty_n(self) -> list[float] | None:
        """The ``penalty`` argument of ``Stepper`` (None unless method is penalty)."""
        return [float(n) for n in self.values['penalty']] if self.method == 'penalty' else None

    def __post_init__(self) -> None:
        # every parameter value is also a plain attribute (cfg.real_time_factor is read at every
        # loop iteration), unless a field or property has that name
        for name, value in self.values.items():
            if name not in self.__dict__ and not hasattr(type(self), name):
                object.__setattr__(self, name, value)

    @classmethod
    def from_values(cls, values: dict) -> SimConfig:
        """Validate a full set of parameter values; raise ValueError naming the problem."""
        v = dict(values)
        for name, (default, _, rng, _) in PARAMETERS.items():
            if name not in v:
                raise ValueError(f'missing parameter {name}')
            if rng is not None:
                x = v[name]
                if not (isinstance(x, float) and math.isfinite(x) and rng[0] <= x <= rng[1]):
                    raise ValueError(f'{name} must be a float in [{rng[0]}, {rng[1]}], got {x!r}')
        masses = [float(m) for m in v['masses']]
        p = len(masses)
        if p < 2:
            raise ValueError(f'masses must list p >= 2 bodies, got {p}')
        for key in ('friction', 'friction_backward'):
            if len(v[key]) not in (1, p):
                raise ValueError(f'{key} must have 1 or {p} entries (one per body, p = {p} '
                                 f'from masses), got {len(v[key])}')
        crawler = Crawler(masses, list(v['friction']), list(v['friction_backward']),
                          v['slope'], v['gravity'])
        if len(v['penalty']) not in (1, p) or not all(
                math.isfinite(n) and n > 0 for n in v['penalty']):
            raise ValueError(f'penalty must have 1 or {p} entries, each finite and > 0 N s/m, '
                             f'got {list(v["penalty"])}')
        if v['method'] not in METHODS:
            raise ValueError(f'method must be one of {", ".join(METHODS)}, got {v["method"]!r}')
        lo, hi = v['min_length'], v['max_length']
        if not lo < hi:
            raise ValueError(f'min_length ({lo}) must be < max_length ({hi})')
        lengths = [float(x) for x in v['initial_lengths']]
        if len(lengths) == 1:
            lengths = lengths * (p - 1)
        if len(lengths) != p - 1:
            raise ValueError(f'initial_lengths must have 1 or {p - 1} entries (p-1 linkages), '
                             f'got {len(lengths)}')
        for j, x in enumerate(lengths):
            if not (math.isfinite(x) and lo <= x <= hi):
                raise ValueError(f'initial_lengths[{j}] = {x} outside [min_length, max_length]'
                                 f' = [{lo}, {hi}]')
        rate, pub = v['integration_rate'], v['publish_rate']
        if pub > rate:
            raise ValueError(f'publish_rate ({pub} Hz) must be <= integration_rate ({rate} Hz)')
        limits = ActuatorLimits(v['actuator_bandwidth'], v['actuator_max_speed'],
                                v['actuator_max_acceleration'])
        return cls(v, crawler, tuple(lengths), limits, max(1, round(1e9 / rate)),
                   max(1, round(rate / pub)))


def validate_command(data, n_links: int, lo: float, hi: float) -> str | None:
    """forward_command_controller rules for ``linkage_cmd``: the reason it is rejected, or None.

    An all-NaN message ("no command yet") is not an error here; the caller ignores it.
    """
    if len(data) != n_links:
        return f'expected {n_links} lengths (linkage_0..linkage_{n_links - 1}), got {len(data)}'
    for j, x in enumerate(data):
        if not math.isfinite(x):
            return f'linkage_{j} length is not finite ({x})'
        if not lo <= x <= hi:
            return f'linkage_{j} length {x} outside [min_length, max_length] = [{lo}, {hi}]'
    return None


class LoopTakenGroup(CallbackGroup):
    """Callback group of subscriptions whose messages the simulation loop takes itself.

    An executor never waits on nor runs anything of this group (``can_execute`` is always
    False), so an incoming message does not wake the executor thread: each wake-up rebuilds a
    wait set in Python (a few hundred microseconds) and takes the GIL from the simulation loop.
    The loop takes the messages between ticks instead, with the call the executor itself uses
    (:meth:`SimNode.take_inputs`). This includes the subscriptions' QoS event handlers: under
    Fast DDS a reader's event handle wakes a wait set whenever data is waiting, so leaving them
    to the executor would make it spin until the loop took the message. The cost is that an
    incompatible-QoS publisher on these topics is not warned about (it is still not matched,
    and the diagnostics count only matched publishers).
    """

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        pass


def _count(query) -> int:
    """A graph count, or -1 once the context is shut down (e.g. in the final diagnostics)."""
    try:
        return int(query())
    except Exception:  # rclpy raises RCLError for an invalid context
        return -1


def _duration_s(d) -> float:
    return d.sec + d.nanosec * 1e-9


class SimNode(Node):
    """The simulator node. ``tick()`` advances one integration step; ``run()`` is the loop."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        for name, (default, desc, rng, ro) in PARAMETERS.items():
            d = ParameterDescriptor(description=desc, read_only=ro)
            if rng is not None:
                d.floating_point_range = _rng(*rng)
            if name == 'method':
                d.additional_constraints = 'one of: ' + ', '.join(METHODS)
            self.declare_parameter(name, default, d)
        self._cfg = SimConfig.from_values(self._param_values())
        self._pending_cfg: SimConfig | None = None
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._parameters_set)

        self._lock = threading.RLock()
        self._log = self.get_logger()
        self._pubs: dict[str, Any] = {}
        self._clock_pub = None
        self._outputs = M.OutputEncoder()
        self._applied_pub = self.create_publisher(JointState, '~/applied_command', 10)
        self._sync_publishers()
        # commands are taken by the simulation loop (take_inputs), not by the executor
        loop_group = LoopTakenGroup()
        self._cmd_sub = self.create_subscription(Float64MultiArray, 'linkage_cmd',
                                                 self._on_command, 10,
                                                 callback_group=loop_group)
        self._traj_sub = self.create_subscription(JointTrajectory, 'linkage_trajectory',
                                                  self._on_trajectory, 10,
                                                  callback_group=loop_group)
        self._inputs = ((self._cmd_sub, self._on_command), (self._traj_sub, self._on_trajectory))
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/pause', self._on_pause)

        self.counters = dict.fromkeys(
            ('ticks', 'late_ticks', 'commands_accepted', 'commands_rejected', 'commands_no_value',
             'trajectories_accepted', 'trajectories_rejected', 'solver_events', 'resets',
             'lag_resets', 'solver_failures'), 0)
        self._solver_error = ''
        self._last_rejection = ''
        self._lateness: list[float] = []
        self._pending_cmd: list[float] | None = None
        self._pending_traj: JointTrajectory | None = None
        self.paused = bool(self._cfg.start_paused)
        self._anchor_needed = True
        self._diag_prev = (0, time.perf_counter(), dict(self.counters))

        self._last_state = None
        self._stop = False        # set by stop() (signals); run() returns at the next tick
        self._bag = None
        self._bag_topics: dict[str, str] = {}     # topic as written in the code -> recorded name
        self.bag_path = ''
        self._recording_error = ''
        self._build(self._cfg, t_ns=0)
        if self._cfg.record:      # last: nothing below can fail and leave the bag open
            self._open_bag()

    # ------------------------------------------------------------------ configuration
    def _param_values(self) -> dict:
        return {name: self.get_parameter(name).value for name in PARAMETERS}

    def _validate_parameters(self, params: list[Parameter]) -> SetParametersResult:
        values = self._param_values()
        for prm in params:
            if prm.name not in PARAMETERS:
                continue
            value = prm.value
            if isinstance(PARAMETERS[prm.name][0], list) and value is not None:
                value = list(value)
            values[prm.name] = value
        try:
            SimConfig.from_values(values)
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _parameters_set(self, params: list[Parameter]) -> None:
        cfg = SimConfig.from_values(self._param_values())
        with self._lock:
            self._pending_cfg = cfg

    def _build(self, cfg: SimConfig, t_ns: int) -> None:
        """(Re)build actuator and stepper at rest in the initial configuration at sim time t_ns."""
        self._cfg = cfg
        self._t_ns = t_ns
        self._engine = Engine(cfg.engine_config(), t_ns)
        self._pending_cmd = None
        self._pending_traj = None
        self._anchor_needed = True

    def _apply_config(self, new: SimConfig) -> None:
        old = self._cfg
        if new.p != old.p:
            self._log.info(f'number of bodies changed {old.p} -> {new.p}: resetting')
            self._build(new, self._t_ns)
            self.counters['resets'] += 1
            self._sync_publishers()
            return
        self._cfg = new
        if (new.crawler.to_dict() != old.crawler.to_dict() or new.method != old.method
                or new.dt_ns != old.dt_ns or new.penalty_n != old.penalty_n):
            self._engine.restart_stepper(new.engine_config())
        else:
            self._engine.sync()
            self._engine.cfg = new.engine_config()
            if new.limits != old.limits:
                self._engine.actuator.configure(limits=new.limits)
        self._sync_publishers()
        self._anchor_needed = True

    def _sync_publishers(self) -> None:
        """Create the publishers of switched-on outputs, destroy those switched off."""
        types = {'joint_states': JointState, 'body_states': JointState,
                 'contact_states': Int8MultiArray, 'odom': Odometry, 'markers': MarkerArray,
                 'diagnostics': DiagnosticArray}
        for name in OUTPUTS:
            on = bool(getattr(self._cfg, 'publish_' + name))
            if on and name not in self._pubs:
                topic = '/diagnostics' if name == 'diagnostics' else name
                self._pubs[name] = self.create_publisher(types[name], topic, 10)
            elif not on and name in self._pubs:
                self.destroy_publisher(self._pubs.pop(name))
        # the outputs in interface order, as _publish_outputs sends them (not diagnostics)
        self._output_pubs = [(name, self._pubs[name]) for name in OUTPUTS[:-1]
                             if name in self._pubs]
        if self._cfg.publish_clock and self._clock_pub is None:
            self._clock_pub = self.create_publisher(Clock, '/clock', 10)
        elif not self._cfg.publish_clock and self._clock_pub is not None:
            self.destroy_publisher(self._clock_pub)
            self._clock_pub = None

    # ------------------------------------------------------------------ inputs
    def _reject(self, kind: str, reason: str) -> None:
        self.counters[kind + '_rejected'] += 1
        self._last_rejection = f'{kind}: {reason}'
        n = self.counters[kind + '_rejected']
        # two call sites: rclpy throttles per call site, so neither input hides the other
        if kind == 'commands':
            self._log.warning(f'linkage_cmd rejected: {reason} ({n} rejected so far)',
                              throttle_duration_sec=WARN_THROTTLE)
        else:
            self._log.warning(f'linkage_trajectory rejected: {reason} ({n} rejected so far)',
                              throttle_duration_sec=WARN_THROTTLE)

    def take_inputs(self) -> int:
        """Take every ``linkage_cmd`` and ``linkage_trajectory`` message waiting in the
        middleware and validate it (:meth:`_on_command`, :meth:`_on_trajectory`), in order of
        arrival across both topics; return how many were taken.

        The loop calls this at the start of every tick (and while paused), so a message takes
        effect at the first tick after it arrived. Taking from an empty subscription costs about
        1 us; the executor never runs these subscriptions (:class:`LoopTakenGroup`).
        """
        taken = []
        with self._lock:
            for sub, handler in self._inputs:
                handle = sub.handle
                while True:
                    with handle:
                        got = handle.take_message(sub.msg_type, sub.raw)
                    if got is None:
                        break
                    # (received time [ns], taking order) sorts both topics into arrival order
                    taken.append((got[1].get('received_timestamp', 0), len(taken), handler,
                                  got[0]))
            if len(taken) > 1:
                taken.sort(key=lambda item: item[:2])
            for _, _, handler, msg in taken:
                handler(msg)
        return len(taken)

    def _on_command(self, msg: Float64MultiArray) -> None:
        data = list(msg.data)
        with self._lock:
            if data and all(math.isnan(x) for x in data):
                self.counters['commands_no_value'] += 1
                return
            reason = validate_command(data, self._cfg.n_links, self._cfg.min_length,
                                      self._cfg.max_length)
            if reason is not None:
                self._reject('commands', reason)
                return
            self.counters['commands_accepted'] += 1
            self._pending_cmd = data
            self._pending_traj = None

    def _check_trajectory(self, msg: JointTrajectory) -> str | None:
        """joint_trajectory_controller's validate_trajectory_msg, plus finiteness and limits."""
        n = self._cfg.n_links
        names = list(msg.joint_names)
        if not names:
            return 'empty joint_names'
        if len(set(names)) != len(names):
            return f'duplicate joint names {names}'
        known = M.linkage_names(n)
        for name in names:
            if name not in known:
                return f'unknown joint {name!r} (expected {", ".join(known)})'
        if len(names) != n:
            return f'joint_names must list all {n} linkages, got {len(names)}'
        if not msg.points:
            return None                           # empty trajectory: cancel, hold position
        stamp_ns = M.ns_from_stamp(msg.header.stamp)
        if stamp_ns != 0:
            end_ns = stamp_ns + round(_duration_s(msg.points[-1].time_from_start) * 1e9)
            if end_ns < self._t_ns:
                return (f'trajectory with start time {stamp_ns / 1e9} s ends at {end_ns / 1e9}'
                        f' s, before the current sim time {self._t_ns / 1e9} s')
        prev = -1.0
        lo, hi = self._cfg.min_length, self._cfg.max_length
        for k, pt in enumerate(msg.points):
            tfs = _duration_s(pt.time_from_start)
            if tfs < 0 or (k > 0 and tfs <= prev):
                return f'time_from_start not strictly increasing at point {k} ({prev} -> {tfs})'
            prev = tfs
            if len(pt.positions) != len(names):
                return (f'mismatch between joint_names size ({len(names)}) and positions '
                        f'({len(pt.positions)}) at point #{k}')
            for field in ('velocities', 'accelerations'):
                arr = getattr(pt, field)
                if len(arr) not in (0, len(names)):
                    return (f'mismatch between joint_names size ({len(names)}) and {field} '
                            f'({len(arr)}) at point #{k}')
                if not all(math.isfinite(x) for x in arr):
                    return f'non-finite {field} at point #{k}'
            if len(pt.effort):
                return 'trajectories with effort fields are not supported'
            for j, x in enumerate(pt.positions):
                if not (math.isfinite(x) and lo <= x <= hi):
                    return (f'position {x} of {names[j]} at point #{k} outside [min_length, '
                            f'max_length] = [{lo}, {hi}]')
        last = msg.points[-1]
        if any(x != 0.0 for x in last.velocities):
            return 'velocity of the last trajectory point is not zero'
        return None

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        with self._lock:
            reason = self._check_trajectory(msg)
            if reason is not None:
                self._reject('trajectories', reason)
                return
            self.counters['trajectories_accepted'] += 1
            self._pending_traj = msg
            self._pending_cmd = None

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            self.reset()
            response.success = True
            response.message = f'reset to the initial state at t = {self._t_ns / 1e9:.9f} s'
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        with self._lock:
            self.paused = bool(request.data)
            self._anchor_needed = True
            response.success = True
            response.message = (f'{"paused" if self.paused else "running"} at '
                                f't = {self._t_ns / 1e9:.9f} s')
        return response

    def reset(self) -> None:
        """Back to the initial state (pending parameter changes applied); sim time goes on.

        Commands that arrived before the reset are taken (counted) and dropped with it."""
        with self._lock:
            self.take_inputs()
            cfg = self._pending_cfg or self._cfg
            self._pending_cfg = None
            self._build(cfg, self._t_ns)
            self._sync_publishers()
            self.counters['resets'] += 1
            self._publish_outputs()

    # ------------------------------------------------------------------ the tick
    @property
    def sim_time_ns(self) -> int:
        """Current sim time [ns]."""
        return self._t_ns

    @property
    def state(self):
        """The core ``State`` now."""
        return self._engine.state

    @property
    def config(self) -> SimConfig:
        return self._cfg

    def tick(self) -> None:
        """Advance one integration step (also callable directly, e.g. from tests): take the
        commands that arrived, apply pending parameters, then the pending command, then step."""
        with self._lock:
            self.take_inputs()
            if self._pending_cfg is not None:
                cfg, self._pending_cfg = self._pending_cfg, None
                self._apply_config(cfg)
            t0_ns = self._t_ns
            if self._pending_cmd is not None:
                self._apply_command(t0_ns)
            elif self._pending_traj is not None:
                self._apply_trajectory(t0_ns)
            engine = self._engine
            synced = engine.tick()     # integrates the queued ticks on the publish grid
            self._t_ns = engine.t_ns
            self.counters['ticks'] += 1
            if not synced:
                return
            if engine.failures:
                # the engine redid the interval with method implicit and goes on with it
                self.counters['solver_failures'] += len(engine.failures)
                self._solver_error = engine.failures[-1] + '; continuing with method implicit'
                self._log.error(self._solver_error, throttle_duration_sec=WARN_THROTTLE)
                engine.failures.clear()
            events = engine.pop_events()
            if events:
                self.counters['solver_events'] += len(events)
                if self._bag is not None:
                    for ev in events:
                        self._record('events', 'std_msgs/msg/Int32MultiArray',
                                     M.event_msg(ev.body, ev.old, ev.new), round(ev.time * 1e9))
            self._publish_outputs()        # on the sim-time grid of the publish period

    def _apply_command(self, t_ns: int) -> None:
        cmd, self._pending_cmd = self._pending_cmd, None
        self._engine.actuator.set_target(cmd)
        recording = self._bag is not None
        if not recording and self._applied_pub.get_subscription_count() == 0:
            return
        data = self._outputs.applied_command(cmd, t_ns)
        self._applied_pub.publish(data)
        if recording:
            self._record('linkage_cmd', M.OUTPUT_TYPES['linkage_cmd'],
                         self._outputs.linkage_cmd(cmd), t_ns)
            self._record('~/applied_command', M.OUTPUT_TYPES['applied_command'], data, t_ns)

    def _apply_trajectory(self, t_ns: int) -> None:
        msg, self._pending_traj = self._pending_traj, None
        if not msg.points:
            self._engine.actuator.set_trajectory(None)
            return
        t_a = t_ns / 1e9
        stamp_ns = M.ns_from_stamp(msg.header.stamp)
        offset = (stamp_ns - t_ns) / 1e9 if stamp_ns else 0.0
        order = [list(msg.joint_names).index(name) for name in M.linkage_names(self._cfg.n_links)]
        keep = [pt for pt in msg.points if offset + _duration_s(pt.time_from_start) >= 0.0]
        if not keep:
            self._reject('trajectories', 'trajectory ended before it could be applied')
            return
        times = [offset + _duration_s(pt.time_from_start) for pt in keep]
        pos = [[pt.positions[i] for i in order] for pt in keep]
        has_v = all(len(pt.velocities) for pt in keep)
        has_a = has_v and all(len(pt.accelerations) for pt in keep)
        vel = [[pt.velocities[i] for i in order] for pt in keep] if has_v else None
        acc = [[pt.accelerations[i] for i in order] for pt in keep] if has_a else None
        self._engine.actuator.set_trajectory(TrajectoryReference(t_a, self._engine.actuator.state(), times,
                                                          pos, vel, acc))
        if self._bag is not None:        # the trajectory as applied: stamp = t_a, times from t_a
            out = JointTrajectory()
            out.header.stamp = M.stamp_from_ns(t_ns)
            out.joint_names = list(M.linkage_names(self._cfg.n_links))
            for k, tk in enumerate(times):
                pt = JointTrajectoryPoint(positions=pos[k])
                if vel is not None:
                    pt.velocities = vel[k]
                if acc is not None:
                    pt.accelerations = acc[k]
                pt.time_from_start.sec, pt.time_from_start.nanosec = divmod(round(tk * 1e9),
                                                                            1_000_000_000)
                out.points.append(pt)
            self._record('linkage_trajectory', 'trajectory_msgs/msg/JointTrajectory', out, t_ns)

    # ------------------------------------------------------------------ outputs
    def _publish_outputs(self) -> None:
        t_ns = self._t_ns
        if self._clock_pub is not None:
            self._clock_pub.publish(M.clock_cdr(t_ns))  # bytes: ~1.7 us instead of ~6 us
        # An output is built only when it is switched on and someone takes it: a subscriber,
        # or the bag. Nobody listening costs nothing (a late subscriber gets the next one).
        recording = self._bag is not None
        pubs = [(name, pub) for name, pub in self._output_pubs
                if recording or pub.get_subscription_count() > 0]
        if not pubs:
            return
        st = self._last_state = self._engine.state
        masses = self._cfg.crawler.masses
        for name, pub in pubs:
            # CDR bytes from a per-shape template (messages.OutputEncoder): one serialisation
            # for the bag and the publisher, without building an rclpy message
            data = self._outputs.encode(name, st, t_ns, masses)
            if recording:       # the bag first: what a subscriber has seen is in the bag
                self._record(name, M.OUTPUT_TYPES[name], data, t_ns)
            pub.publish(data)

    def diagnostics(self, wall_now: float | None = None) -> DiagnosticArray:
        """Build the /diagnostics message (figures since the previous call)."""
        wall_now = time.perf_counter() if wall_now is None else wall_now
        with self._lock:
            t_prev, wall_prev, c_prev = self._diag_prev
            c = dict(self.counters)
            rtf = (self._t_ns - t_prev) / 1e9 / max(wall_now - wall_prev, 1e-9)
            late = sorted(self._lateness)
            self._lateness = []
            self._diag_prev = (self._t_ns, wall_now, c)
            p99 = late[min(len(late) - 1, int(0.99 * len(late)))] * 1e3 if late else 0.0
            values = {
                'sim_time': self._t_ns / 1e9, 'paused': self.paused, 'method': self._cfg.method,
                'bodies': self._cfg.p, 'real_time_factor': rtf,
                'real_time_factor_target': self._cfg.real_time_factor,
                'tick_lateness_p99_ms': p99,
                'tick_lateness_max_ms': late[-1] * 1e3 if late else 0.0,
                **c,
                'last_rejection': self._last_rejection,
                'indeterminate': bool(getattr(self._last_state, 'indeterminate', False)),
                'solver_method_now': self._engine.stepper.method,
                'solver_error': self._solver_error,
                'linkage_cmd_publishers': _count(self._cmd_sub.get_publisher_count),
                'linkage_trajectory_publishers': _count(self._traj_sub.get_publisher_count),
                'clock_subscribers': (_count(self._clock_pub.get_subscription_count)
                                      if self._clock_pub is not None else 0),
                'recording': self.bag_path,
                'recording_error': self._recording_error,
            }
            warn = []
            if c['late_ticks'] > c_prev['late_ticks']:
                warn.append(f'{c["late_ticks"] - c_prev["late_ticks"]} late ticks')
            for kind in ('commands', 'trajectories'):
                k = kind + '_rejected'
                if c[k] > c_prev[k]:
                    warn.append(f'{c[k] - c_prev[k]} {kind} rejected')
            if self._recording_error:
                warn.append('recording failed')
            if c['solver_failures'] > c_prev['solver_failures']:
                warn.append('solver failed, fell back to implicit')
            return M.diagnostics_msg(self._t_ns, values, warn=warn)

    def _publish_diagnostics(self, wall_now: float) -> None:
        msg = self.diagnostics(wall_now)
        pub = self._pubs.get('diagnostics')
        if pub is not None:
            pub.publish(msg)
            self._record('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', msg, self._t_ns)

    # ------------------------------------------------------------------ recording
    def _open_bag(self) -> None:
        cfg = self._cfg
        name = cfg.record_name or time.strftime('crawler_sim_%Y%m%d-%H%M%S')
        path = os.path.join(cfg.record_dir, name)
        try:
            from crawler_sim.bag import BagWriter
            scene = {k: (list(v) if isinstance(v, (list, tuple)) else v)
                     for k, v in cfg.values.items()}
            scene['crawler'] = cfg.crawler.to_dict()
            os.makedirs(cfg.record_dir, exist_ok=True)
            self._bag = BagWriter(path, scene=scene)
            self.bag_path = path
            self._last_flush = time.monotonic()
            self._log.info(f'recording to {path}')
        except Exception as exc:  # recording must never stop the simulation
            self._recording_error = f'{type(exc).__name__}: {exc}'
            self._log.error(f'cannot record to {path}: {self._recording_error}')
            self._bag = None

    def _record(self, topic: str, type_name: str, msg: Any, t_ns: int) -> None:
        bag = self._bag
        if bag is None:
            return
        name = self._bag_topics.get(topic)
        if name is None:
            name = self._bag_topics[topic] = self._absolute_topic(topic)
        try:
            bag.write(name, type_name, msg, t_ns)
            if getattr(bag, 'error', None):
                raise RuntimeError(bag.error)
            now = time.monotonic()
            if now - self._last_flush > 2.0:
                bag.flush()
                self._last_flush = now
        except Exception as exc:
            self._recording_error = f'{type(exc).__name__}: {exc}'
            self._log.error(f'recording stopped: {self._recording_error}')
            self._close_bag()

    def _absolute_topic(self, topic: str) -> str:
        """The recorded name of ``topic``: ``~/x`` and relative names resolved as ROS does."""
        if topic.startswith('~/'):
            return self.get_fully_qualified_name() + topic[1:]
        if topic.startswith('/'):
            return topic
        return f'{self.get_namespace().rstrip("/")}/{topic}'

    def _close_bag(self) -> None:
        bag, self._bag = self._bag, None
        if bag is not None:
            try:
                bag.close()
            except Exception as exc:
                self._recording_error = f'{type(exc).__name__}: {exc}'
                self._log.error(f'closing the bag failed: {self._recording_error}')

    def close(self) -> None:
        """Close the bag (idempotent); call before destroy_node."""
        with self._lock:
            if self._bag is not None:
                self._record('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
                             self.diagnostics(), self._t_ns)
            self._close_bag()

    # ------------------------------------------------------------------ the loop
    def run(self) -> None:
        """Tick until the context shuts down, paced by ``real_time_factor`` (0: flat out)."""
        try:
            self._loop()
        except Exception:
            if self.context.ok():
                raise
            # a signal shut the context down in the middle of a tick (e.g. while publishing)

    def _loop(self) -> None:
        now = time.perf_counter
        anchor_wall = now()
        anchor_tick = 0
        next_diag = anchor_wall + self._cfg.diagnostics_period
        ok = self.context.ok
        if self.counters['ticks'] == 0:
            with self._lock:
                self._publish_outputs()       # the initial state at t = 0 (a bag starts there)
        checks = 0
        while not self._stop:
            # context.ok() costs ~1 us: flat out, ask every 16th iteration (a tick on a context
            # shut down meanwhile fails in publish, which run() treats as the end)
            checks = (checks + 1) & 15
            if checks == 0 and not ok():
                break
            t = now()
            if t >= next_diag:
                self._publish_diagnostics(t)
                next_diag = t + self._cfg.diagnostics_period
            if self.paused:
                self.take_inputs()        # count (and warn about) commands while paused too
                time.sleep(0.01)
                continue
            if self._anchor_needed:
                self._anchor_needed = False
                anchor_wall, anchor_tick = t, self.counters['ticks']
            rtf = self._cfg.real_time_factor
            if rtf > 0.0:
                period = self._cfg.dt_ns * 1e-9 / rtf
                deadline = anchor_wall + (self.counters['ticks'] - anchor_tick) * period
                if t < deadline:
                    time.sleep(min(deadline - t, 0.05))
                    continue
                lateness = t - deadline
                self._lateness.append(lateness)
                if lateness > period:
                    self.counters['late_ticks'] += 1
                if lateness > MAX_LAG:
                    self.counters['lag_resets'] += 1
                    self._anchor_needed = True
            with self._lock:              # a pause that arrived meanwhile wins
                if not self.paused:
                    self.tick()
            # No explicit GIL yield: commands are taken by this loop, and the executor thread
            # (services, parameters) gets the GIL through the interpreter's switch interval
            # (pause/reset answered in ~2-4 ms flat out, as with a yield once per publish period).

    def stop(self) -> None:
        """Make :meth:`run` return after the current tick (thread-safe)."""
        self._stop = True


def main(args: list[str] | None = None) -> None:
    """Entry point of ``ros2 run crawler_sim sim_node``.

    The simulation loop runs in the main thread; ROS callbacks in an executor thread. On
    SIGINT/SIGTERM (rclpy shuts the context down) both stop; the executor thread is joined
    before anything is destroyed, then the bag is closed, the node destroyed and rclpy shut down.
    """
    rclpy.init(args=args)
    node = None
    executor = None
    spin_thread = None
    stop_spin = threading.Event()
    try:
        executor = SingleThreadedExecutor()
        node = SimNode()
        executor.add_node(node)
        # From here a signal only asks the loop to stop between two ticks: an exception raised
        # at an arbitrary point (e.g. inside a bag write) could leave the MCAP file inconsistent.
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, lambda signum, frame, n=node: n.stop())
        failure: list[BaseException] = []
        spin_thread = threading.Thread(target=_spin, args=(executor, stop_spin, node, failure),
                                       daemon=True)
        spin_thread.start()
        node.run()
        if failure:
            raise failure[0]
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception as exc:
        if not rclpy.ok():
            pass                  # a signal shut ROS down while starting: a clean exit
        elif node is None:        # e.g. invalid parameter overrides: one clear line, exit 1
            print(f'[crawler_sim] cannot start: {exc}', file=sys.stderr, flush=True)
            raise SystemExit(1) from None
        else:
            raise
    finally:
        stop_spin.set()
        if spin_thread is not None:
            spin_thread.join(timeout=5.0)
        if node is not None:
            node.close()
        if executor is not None and not (spin_thread is not None and spin_thread.is_alive()):
            # (rclpy 7.1's Executor.shutdown destroys its guard conditions without waiting
            # for a spinning thread, so it is called only once that thread has ended)
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def _spin(executor: SingleThreadedExecutor, stop: threading.Event, node: SimNode,
          failure: list[BaseException]) -> None:
    """Run callbacks until ``stop`` is set or the context shuts down; a callback that raises
    (a bug) stops the node and is re-raised by ``main``."""
    try:
        while not stop.is_set() and executor.context.ok():
            executor.spin_once(timeout_sec=0.1)
    except (ExternalShutdownException, KeyboardInterrupt):
        pass
    except Exception as exc:
        if executor.context.ok():
            failure.append(exc)
            node.stop()


if __name__ == '__main__':
    main()
