"""``SimNode``: the crawler as a ROS 2 node driven by commanded linkage lengths.

The node glues the pieces of this package around ``crawler_sim.core.plant.Engine`` (the
actuator model and the core's exact ``Stepper``, no ROS): :mod:`.params` (parameters to a
:class:`~.params.SimConfig`), :mod:`.intake` (commands and trajectories), :mod:`.outputs`
(publishers and encoders), :mod:`.recording` (the bag), :mod:`.diagnostics` and :mod:`.loop`
(the real-time loop). Interface (relative names unless they start with ``/``):

- subscribes ``linkage_cmd`` (std_msgs/Float64MultiArray): target length of each linkage [m]
  (the seed's two bodies: ONE length); ``linkage_trajectory`` (trajectory_msgs/JointTrajectory,
  joints ``linkage_0``...);
- publishes ``joint_states``, ``body_states`` (sensor_msgs/JointState), ``contact_states``
  (std_msgs/Int8MultiArray), ``contacts`` (sensor_msgs/JointState: the stamped alternative),
  ``odom`` (nav_msgs/Odometry), ``markers`` (visualization_msgs/MarkerArray),
  ``~/applied_command`` (sensor_msgs/JointState: the target that took effect, stamped with the
  tick it took effect at), ``/diagnostics``, ``/clock`` (by default, at every publish tick;
  one node owns it when several run, ``choose_clock``) and ``robot_description``
  (std_msgs/String, transient local: the URDF of :mod:`.model`);
- services ``~/reset`` (std_srvs/Trigger), ``~/pause`` (std_srvs/SetBool) and ``~/step``
  (std_srvs/Trigger: one publish period while paused).

Timing. Sim time is an integer number of nanoseconds that advances by ``dt`` per tick, so a run
is deterministic: the same commands taking effect at the same ticks give bit-identical states.
A tick: take the inputs that arrived, apply pending parameter changes, then the pending command
or trajectory, then one actuator piece; every ``publish_every`` ticks the engine integrates the
queued pieces exactly and the outputs go out (flat out, the loop runs a publish period's ticks in
one call and takes the inputs at its first tick, see :mod:`.loop`). A state that is not finite
is never published
(it is counted in ``nonfinite_outputs`` and the simulation resets).

Module size: about 430 lines, just over the ~400 guide: ``SimNode`` is where the pieces of
``ros/sim`` meet (services, parameter callbacks, tick, shutdown); every responsibility it
delegates lives in its own module.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger
from trajectory_msgs.msg import JointTrajectory

from crawler_sim.bag import journal, topics as T
from crawler_sim.core.plant import Engine
from crawler_sim.core.trajectory import State
from crawler_sim.ros import messages as M
from . import intake, loop, standard
from .clock import SharedClock
from .diagnostics import COUNTERS, Diagnostics, graph_count
from .outputs import Outputs
from .params import NODE_NAME, PARAMETERS, SimConfig, declare_all
from .recording import applied_trajectory, SessionBag
from .taken import LoopTakenGroup
from crawler_sim.core.simtime import to_ns, to_seconds

__all__ = ['SimNode', 'LoopTakenGroup', 'NODE_NAME']


class SimNode(Node):
    """The simulator node. ``tick()`` advances one integration step; ``run()`` is the loop."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._cfg = SimConfig.from_values(declare_all(self))
        self._pending_cfg: SimConfig | None = None
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._parameters_set)

        self._lock = threading.RLock()
        self._log = self.get_logger()
        self.counters = dict.fromkeys(COUNTERS, 0)
        self._rejections = intake.RejectionLog(self.counters, self._log.warning)
        self._diag = Diagnostics(self.counters, f'{self.get_fully_qualified_name()}: simulation')
        #: wall s of lateness of each paced tick since the last report (the loop appends)
        self.lateness = self._diag.lateness
        self.outputs = Outputs(self)
        self._applied_pub = self.create_publisher(JointState, T.APPLIED_COMMAND.node_name, 10)
        self.outputs.sync(self._cfg)
        group = LoopTakenGroup()
        self._cmd_sub = self.create_subscription(Float64MultiArray, T.LINKAGE_CMD.node_name,
                                                 self._on_command, 10, callback_group=group)
        self._traj_sub = self.create_subscription(JointTrajectory,
                                                  T.LINKAGE_TRAJECTORY.node_name,
                                                  self._on_trajectory, 10, callback_group=group,
                                                  raw=True)
        self._takes = [(sub.handle.take_message, sub.msg_type, sub.raw, handler)
                       for sub, handler in ((self._cmd_sub, self._on_command),
                                            (self._traj_sub, self._on_trajectory))]
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(SetBool, '~/pause', self._on_pause)
        self.create_service(Trigger, '~/step', self._on_step)

        self._solver_error = ''
        self._traj_intake = (0.0, 0)          # (wall s, bytes) of the latest trajectory
        self._pending_cmd: list[float] | None = None
        self._pending_traj: intake.PreparedTrajectory | None = None
        self._anchor_needed = True
        self._last_state = None
        self._last_row = None
        self._last_row_ns = 0
        #: the /clock role of this sim among the sims of the domain (owner or follower)
        self.clock = SharedClock(self, self._log_line)
        self._stop = False        # set by stop() (signals); run() returns at the next tick
        self.recorder = SessionBag(self._absolute_topic, self._log)
        self._journal_seq = 0
        self._same_name_logged = False
        # the one owner of the plant: every input goes through it and into its journal
        self._engine = Engine(self._cfg.engine_config(), 0, journal=self._journal)
        if self._cfg.start_paused:
            self._engine.pause()
        if self._cfg.record:      # last: nothing below can fail and leave the bag open
            scene = {k: (list(v) if isinstance(v, (list, tuple)) else v)
                     for k, v in self._cfg.values.items()}
            scene['crawler'] = self._cfg.crawler.to_dict()
            # every topic the run records, so the bag holds their schemas and channels from its
            # first millisecond (a run killed before its first chunk is still readable)
            recorded = [*self.outputs.topics(), T.LINKAGE_CMD, T.APPLIED_COMMAND,
                        T.LINKAGE_TRAJECTORY, T.PLANT_INPUTS, T.ROBOT_DESCRIPTION, T.EVENTS,
                        T.DIAGNOSTICS]
            self.recorder.open(self._cfg.record_dir, self._cfg.record_name, scene,
                               dict.fromkeys(recorded))
            self._record_description()
        # simulation_interfaces services and action, when the package is installed (.standard)
        self.standard = standard.attach(self)

    # ------------------------------------------------------------------ read-only views
    @property
    def bag_path(self) -> str:
        """Where the bag is ('' when not recording)."""
        return self.recorder.path

    @property
    def engine(self) -> Engine:
        """The plant's engine (read it; every input goes through the node's topics,
        parameters and services)."""
        return self._engine

    @property
    def last_rejection(self) -> str:
        """Why the latest rejected input was rejected ('' if none): the diagnostics'
        ``last_rejection``."""
        return self._rejections.last

    # ------------------------------------------------------------------ configuration
    def _param_values(self) -> dict:
        return {name: self.get_parameter_or(name).value for name in PARAMETERS}

    def _validate_parameters(self, params: list[Parameter]) -> SetParametersResult:
        values = self._param_values()
        for prm in params:
            if prm.name not in PARAMETERS:
                continue
            value = prm.value
            if (isinstance(PARAMETERS[prm.name][0], (list, tuple)) and value is not None
                    and not isinstance(value, (int, float, str))):
                value = list(value)           # an array (a scalar is one entry for all)
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

    def _apply_config(self, new: SimConfig) -> None:
        old = self._cfg
        self._cfg = new
        if self._engine.reconfigure(new.engine_config()):
            self._log.info(f'number of bodies changed {old.p} -> {new.p}: resetting')
            self.counters['resets'] += 1
            self._drop_pending()
        self._anchor_needed = True
        self._sync_outputs(self._cfg)

    def _sync_outputs(self, cfg: SimConfig) -> None:
        """Publishers as ``cfg`` says; a new robot model (p, masses, limits) is recorded too."""
        if self.outputs.sync(cfg):
            self._record_description()

    def _record_description(self) -> None:
        if self.recorder.on and self.outputs.description:
            self.recorder.write(T.ROBOT_DESCRIPTION,
                                String(data=self.outputs.description), self._t_ns)

    def _drop_pending(self) -> None:
        self._pending_cmd = None
        self._pending_traj = None

    def _journal(self, kind: str, t_ns: int, payload: Any) -> None:
        """The engine's journal: every plant input, in order, on ``~/plant_inputs`` (JSON, at
        the sim time it took effect), so that ``crawler-sim replay`` repeats the run bit for
        bit (``crawler_sim.core.plant.replay``). A trajectory's points go on
        ``linkage_trajectory`` at the same time (stamp 0 made absolute)."""
        rec = self.recorder
        if not rec.on:
            return
        self._journal_seq += 1
        if kind == 'trajectory':
            raw = getattr(payload, 'raw', None)
            if raw is not None:
                rec.write(T.LINKAGE_TRAJECTORY,
                          applied_trajectory(raw, payload.stamp_ns, t_ns), t_ns)
            # a trajectory given in Python (or None) has no message: not recorded
            payload = len(payload.tfs_ns) if raw is not None else journal.NOT_RECORDED
        rec.write(T.PLANT_INPUTS, String(data=journal.encode(self._journal_seq, kind, payload)),
                  t_ns)

    # ------------------------------------------------------------------ inputs
    def take_inputs(self) -> int:
        """Take every ``linkage_cmd`` and ``linkage_trajectory`` message waiting in the
        middleware and validate it, in order of arrival across both topics; return how many
        were taken. The loop calls this at the start of every tick (and while paused).

        The subscription handles are used without their ``with`` guard (2.3 us each, every
        tick): it only defers destruction, and they are destroyed only with the node, after
        the loop has stopped.
        """
        with self._lock:
            return self._take_inputs()

    def _take_inputs(self) -> int:
        """:meth:`take_inputs` for a caller that holds the lock (the tick)."""
        taken = None
        for take, msg_type, raw, handler in self._takes:
            got = take(msg_type, raw)
            while got is not None:
                if taken is None:
                    taken = []
                taken.append((got[1].get('received_timestamp', 0), len(taken), handler,
                              got[0]))
                got = take(msg_type, raw)
        if taken is None:
            return 0
        if len(taken) > 1:
            taken.sort(key=lambda item: item[:2])
        for _, _, handler, msg in taken:
            handler(msg)
        return len(taken)

    def _on_command(self, msg: Float64MultiArray) -> None:
        data = msg.data
        cfg = self._cfg
        reason = intake.check_command(data, cfg.n_links, cfg.min_length, cfg.max_length)
        if reason is not None:
            self._rejections.note('commands', T.LINKAGE_CMD.suffix, reason)
            return
        if all(math.isnan(x) for x in data):
            self.counters['commands_no_value'] += 1
            return
        self.counters['commands_accepted'] += 1
        self._pending_cmd = list(data)
        self._pending_traj = None

    def _on_trajectory(self, msg: bytes | JointTrajectory) -> None:
        if not isinstance(msg, (bytes, bytearray)):
            from rclpy.serialization import serialize_message
            msg = serialize_message(msg)
        cfg = self._cfg
        start = time.perf_counter()
        reason, prepared = intake.prepare(msg, cfg.n_links, cfg.min_length, cfg.max_length,
                                          self._t_ns, cfg.max_trajectory_lead)
        if prepared is not None and len(prepared.tfs_ns):
            try:                 # the interpolation too, from the actuator's state now
                self._engine.check_trajectory(prepared)
            except ValueError as exc:
                reason, prepared = str(exc), None
        # wall time of the intake (parse + checks) of the latest trajectory: a figure for the
        # diagnostics (a 100k-point trajectory must not stall the loop)
        self._traj_intake = (time.perf_counter() - start, len(msg))
        if reason is not None:
            self._rejections.note('trajectories', T.LINKAGE_TRAJECTORY.suffix, reason)
            return
        self.counters['trajectories_accepted'] += 1
        self._pending_traj = prepared
        self._pending_cmd = None

    # ------------------------------------------------------------------ services
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            self.reset()
            response.success = True
            response.message = f'reset to the initial state at t = {to_seconds(self._t_ns):.9f} s'
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        response.success = True
        response.message = self.set_paused(request.data)
        return response

    def set_paused(self, paused: bool) -> str:
        """Pause or resume (logged); return the line that says so (``~/pause`` and the
        standard's set_simulation_state)."""
        with self._lock:
            if paused:
                self._engine.pause()
            else:
                self._engine.resume()
            self._anchor_needed = True
            line = (f'{"paused" if self.paused else "running"} at '
                    f't = {to_seconds(self._t_ns):.9f} s')
            self._log.info(line)
        return line

    def _on_step(self, request: Trigger.Request, response: Trigger.Response
                 ) -> Trigger.Response:
        """While paused: advance one publish period (to the next publish tick, taking the
        inputs that arrived, as the loop does) and publish it. Finer steps: a publish_rate equal
        to integration_rate makes a step one tick. (std_srvs/Trigger: common_interfaces has no
        step service with a count; Gazebo's world control steps the same way.)"""
        with self._lock:
            if not self.paused:
                response.success = False
                response.message = 'not paused: call ~/pause with true first'
                return response
            self._tick(to_grid=True)
            response.success = True
            response.message = f'stepped to t = {to_seconds(self._t_ns):.9f} s'
        return response

    def republish(self) -> None:
        """Publish the latest state and /clock again, unchanged and not recorded (the loop
        does it while paused, so a late subscriber sees the crawler)."""
        with self._lock:
            if self._last_row is not None:
                self.outputs.publish(self._last_row, self._last_row_ns,
                                     self._cfg.crawler.masses)

    def reset(self) -> None:
        """Back to the initial state (pending parameter changes applied); sim time goes on.
        Commands that arrived before the reset are taken (counted) and dropped with it."""
        with self._lock:
            self.take_inputs()
            cfg = self._pending_cfg or self._cfg
            self._pending_cfg = None
            self._cfg = cfg
            self._engine.reset(cfg.engine_config())
            self._drop_pending()
            self._anchor_needed = True
            self._sync_outputs(cfg)
            self.outputs.refresh()
            self.counters['resets'] += 1
            self._log.info(f'reset to rest at t = {to_seconds(self._t_ns):.9f} s')
            self._publish_outputs()

    # ------------------------------------------------------------------ the tick
    @property
    def _t_ns(self) -> int:
        return self._engine.t_ns

    @property
    def paused(self) -> bool:
        """True while the simulation is paused (``~/pause``)."""
        return self._engine.paused

    @property
    def sim_time_ns(self) -> int:
        """Current sim time [ns]."""
        return self._t_ns

    @property
    def state(self) -> State:
        """The core ``State`` now."""
        return self._engine.state

    @property
    def config(self) -> SimConfig:
        return self._cfg

    @property
    def last_published(self) -> tuple[State | None, int]:
        """The state last published and its sim time [ns] ((None, 0) before the first): what
        a reader gets without cutting the integration off the publish grid."""
        return self._last_state, self._last_row_ns

    def tick(self) -> None:
        """Advance one integration step (also callable directly, e.g. from tests)."""
        with self._lock:
            self._tick()

    def _tick(self, to_grid: bool = False) -> None:
        """:meth:`tick` for a caller that holds the lock (the loop). ``to_grid``: go on ticking
        up to the next publish tick (inputs are taken at the first tick only; the flat-out
        loop: the same states as single ticks with no input arriving in between).

        Never raises (the last line of defence: inputs are checked before they reach the
        engine, and the engine contains the solver's failures): anything that escapes is
        counted in ``tick_failures``, logged at ERROR level, reported in the diagnostics, and
        the plant starts again at rest at the current sim time."""
        try:
            self._tick_inner(to_grid)
        except Exception as exc:      # noqa: BLE001 - the node must keep running
            self.counters['tick_failures'] += 1
            self._solver_error = (f'tick at t = {to_seconds(self._t_ns):.9f} s failed '
                                  f'({type(exc).__name__}: {exc}); reset to rest')
            self._log.error(self._solver_error, throttle_duration_sec=1.0)
            try:
                self._engine.reset()
                self._drop_pending()
                self._publish_outputs()
            except Exception as again:  # noqa: BLE001
                self._log.error(f'reset after a failed tick failed too: {again}',
                                throttle_duration_sec=1.0)

    def _tick_inner(self, to_grid: bool) -> None:
        self._take_inputs()
        if self._pending_cfg is not None:
            cfg, self._pending_cfg = self._pending_cfg, None
            self._apply_config(cfg)
        t0_ns = self._t_ns
        if self._pending_cmd is not None:
            self._apply_command(t0_ns)
        elif self._pending_traj is not None:
            self._apply_trajectory(t0_ns)
        engine = self._engine
        if to_grid:
            self.counters['ticks'] += engine.tick_to_grid()
            synced = True
        else:
            synced = engine.tick()
            self.counters['ticks'] += 1
        if not synced:
            return
        if engine.failures:
            self.counters['solver_failures'] += len(engine.failures)
            self._solver_error = engine.failures[-1] + '; continuing with method implicit'
            self._log.error(self._solver_error, throttle_duration_sec=1.0)
            engine.failures.clear()
        events = engine.pop_events()
        if events:
            self.counters['solver_events'] += len(events)
            if self.recorder.on:
                for ev in events:
                    self.recorder.write(T.EVENTS,
                                        M.event_msg(ev.body, ev.old, ev.new),
                                        to_ns(ev.time))
        self._publish_outputs()

    def _apply_command(self, t_ns: int) -> None:
        cmd, self._pending_cmd = self._pending_cmd, None
        self._engine.command(cmd)
        recording = self.recorder.on
        if not recording and self._applied_pub.get_subscription_count() == 0:
            return
        data = self.outputs.encoder.applied_command(cmd, t_ns)
        self._applied_pub.publish(data)
        if recording:
            self.recorder.write(T.LINKAGE_CMD, self.outputs.encoder.linkage_cmd(cmd), t_ns)
            self.recorder.write(T.APPLIED_COMMAND, data, t_ns)

    def _apply_trajectory(self, t_ns: int) -> None:
        tr, self._pending_traj = self._pending_traj, None
        try:
            self._engine.trajectory(tr)
        except ValueError as exc:       # e.g. times that round together at this sim time
            self._rejections.note('trajectories', T.LINKAGE_TRAJECTORY.suffix, str(exc))

    # ------------------------------------------------------------------ outputs
    def _publish_outputs(self) -> None:
        st = self._engine.state
        row = M.Row(st)          # the numbers as floats, once for the check and every encoder
        if not row.finite():
            # never publish a non-finite value: count it, report it and start again
            self.counters['nonfinite_outputs'] += 1
            self._log.error('non-finite state: outputs withheld, resetting',
                            throttle_duration_sec=1.0)
            self._engine.reset()
            self._drop_pending()
            return
        self._last_state = st
        self._last_row, self._last_row_ns = row, self._t_ns
        self.outputs.publish(row, self._t_ns, self._cfg.crawler.masses,
                             self.recorder.write if self.recorder.on else None)

    def diagnostics(self, wall_now: float | None = None, final: bool = False
                    ) -> DiagnosticArray:
        """Build the /diagnostics message (figures since the previous call; ``final``: the
        last one, at shutdown)."""
        with self._lock:
            values, warn = self._report_values()
            same = values['same_name_nodes'] > 0
            if same and not self._same_name_logged:
                self._log.warning(next(w for w in warn if 'other node(s) named' in w))
            self._same_name_logged = same
            return self._diag.message(self._t_ns, values, wall_now, warn, final=final)

    def _report_values(self) -> tuple[dict[str, Any], list[str]]:
        """The node's own figures for its report (under the lock), and extra warnings."""
        rec = self.recorder
        cfg = self._cfg
        clock = self.outputs.clock_pub
        fqn = self.get_fully_qualified_name()
        values = {
            'paused': self.paused, 'method': cfg.method, 'bodies': cfg.p,
            'real_time_factor_target': cfg.real_time_factor,
            'last_rejection': self._rejections.last,
            'indeterminate': bool(getattr(self._last_state, 'indeterminate', False)),
            'solver_method_now': self._engine.stepper.method,
            'solver_error': self._solver_error,
            'linkage_cmd_publishers': graph_count(self._cmd_sub.get_publisher_count),
            'linkage_trajectory_publishers': graph_count(self._traj_sub.get_publisher_count),
            'clock_subscribers': (graph_count(clock.get_subscription_count)
                                  if clock is not None else 0),
            'recording': rec.path, 'recording_error': rec.error,
            'last_trajectory_intake_ms': self._traj_intake[0] * 1e3,
            'last_trajectory_bytes': self._traj_intake[1],
            'same_name_nodes': graph_count(
                lambda: self.get_fully_qualified_node_names().count(fqn) - 1),
        }
        values.update(self.clock.values())
        warn = ['recording failed'] if rec.error else []
        warn += self.clock.warnings()
        if values['same_name_nodes'] > 0:
            # two sims in one namespace interleave their outputs and share this status's name
            warn.append(f'{values["same_name_nodes"]} other node(s) named {fqn}: outputs '
                        'interleave (give each sim its own namespace, -r __ns:=/robot2)')
        return values, warn

    def publish_diagnostics(self, wall_now: float) -> None:
        """Publish (and record) the report now (the loop does, every diagnostics_period)."""
        msg = self.diagnostics(wall_now)
        pub = self.outputs.pubs.get('diagnostics')
        if pub is not None:
            pub.publish(msg)
            self.recorder.write(T.DIAGNOSTICS, msg, self._t_ns)

    def _absolute_topic(self, topic: str) -> str:
        """The recorded name of ``topic``: ``~/x`` and relative names resolved as ROS does."""
        if topic.startswith('~/'):
            return self.get_fully_qualified_name() + topic[1:]
        if topic.startswith('/'):
            return topic
        return f'{self.get_namespace().rstrip("/")}/{topic}'

    def close(self) -> None:
        """Close the bag (idempotent); call before destroy_node."""
        with self._lock:
            if self.recorder.on:
                self.recorder.write(T.DIAGNOSTICS,
                                    self.diagnostics(final=True), self._t_ns)
            self.recorder.close()

    # ------------------------------------------------------------------ the clock
    def choose_clock(self) -> None:
        """Take this sim's role on the shared ``/clock`` (:meth:`.clock.SharedClock.choose`):
        call with the executor spinning, before the loop."""
        self.clock.choose()

    def _log_line(self, level: str, line: str) -> None:
        # (one call site per severity: rclpy refuses two severities from one line)
        if level == 'warn':
            self._log.warning(line)
        else:
            self._log.info(line)

    @property
    def lock(self) -> threading.RLock:
        """The lock of the node's state (the loop ticks under it; services take it too)."""
        return self._lock

    def restart_at(self, t_ns: int) -> None:
        """Start again at rest at sim time ``t_ns`` (a follower joining the shared clock; under
        the lock). A journaled reset, so the bag replays from there."""
        self._engine.reset(self._cfg.engine_config(), t_ns=t_ns)
        self._drop_pending()
        self._anchor_needed = True

    def reanchor(self) -> None:
        """Pace from now on (the wall-clock anchor is taken again at the next tick)."""
        self._anchor_needed = True

    def log_ready(self) -> None:
        """One INFO line when the node is ready: what it simulates, how fast, where to."""
        cfg = self._cfg
        rtf = cfg.real_time_factor
        pace = 'as fast as possible' if rtf <= 0 else f'{rtf:g} x real time'
        owner = self.clock.owner if self.clock.following else ''
        clock = ('/clock published' if self.outputs.clock_pub is not None
                 else f'following the /clock of {owner}' if owner
                 else '/clock not published')
        if owner:
            pace = 'paced by that clock'
        rec = f'recording to {self.recorder.path}' if self.recorder.on else 'not recording'
        self._log.info(
            f'ready: {cfg.p} bodies ({cfg.n_links} linkage(s): linkage_cmd takes '
            f'{cfg.n_links} length(s)), method {cfg.method}, {1e9 / cfg.dt_ns:g} Hz ticks, '
            f'outputs every {cfg.publish_every} ticks, {pace}, {clock}, {rec}'
            + ('; paused: ~/pause false starts it' if self.paused else ''))

    def warm_up(self) -> None:
        """Run once what the first ticks would compile, import or build cold (the solver's first
        call, the encoders' templates) on a scratch engine, so that cold start stays out of the
        real-time loop; ``main`` calls it before the loop starts. The node's state is
        unchanged."""
        with self._lock:
            cfg = self._cfg
            scratch = Engine(cfg.engine_config(), self._t_ns)
            for _ in range(cfg.publish_every):
                scratch.tick()
            self.outputs.warm_up(scratch.state, self._t_ns, cfg.crawler.masses,
                                 list(cfg.initial_lengths))

    # ------------------------------------------------------------------ what the loop uses
    # (.loop.Loopable: the whole interface between the loop and the node)
    @property
    def stopped(self) -> bool:
        """Whether :meth:`stop` was called."""
        return self._stop

    def take_anchor(self) -> bool:
        """Whether pacing must start again from now (a pause, a reset, a new clock...); the
        request is cleared."""
        needed, self._anchor_needed = self._anchor_needed, False
        return needed

    def tick_locked(self, to_grid: bool = False) -> None:
        """:meth:`tick` for the loop, which holds the lock (``to_grid``: see :meth:`_tick`)."""
        self._tick(to_grid)

    def publish_state(self) -> None:
        """Publish (and record) the state now; the lock held (the loop's first state)."""
        self._publish_outputs()

    def run(self) -> None:
        """Tick until stopped or the context shuts down, paced by ``real_time_factor``."""
        loop.run(self)

    def stop(self) -> None:
        """Make :meth:`run` return after the current tick (thread-safe)."""
        self._stop = True
