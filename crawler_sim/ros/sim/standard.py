"""The simulation_interfaces standard (ros-simulation/simulation_interfaces 1.5.1) in sim_node.

Served under the node's name, as Gazebo serves it under ``/gzserver/``:
``~/get_simulator_features``, ``~/get_simulation_state``, ``~/set_simulation_state``,
``~/step_simulation``, ``~/reset_simulation``, ``~/get_entities``, ``~/get_entity_state``,
``~/get_entities_states``, ``~/set_entity_state`` and the action ``~/simulate_steps``.
:data:`FEATURES` lists the standard's feature codes of exactly these.

What the standard's words mean for one crawler:

- **a step** is one integration tick (``integration_rate``); steps run only while paused (the
  standard's rule) and as fast as the machine goes. Outputs go out on the publish grid as in a
  run, and once more at the last step when it ends off the grid (/clock and the state at that
  time), so a caller sees where the steps ended. A sim that follows another's /clock does not
  step (its time is that clock's).
- **states**: PLAYING and PAUSED are ``~/pause``; STOPPED is paused and reset to rest (reported
  as long as no tick ran since); QUITTING, NO_WORLD and LOADING_WORLD are not served.
- **reset scopes**: SCOPE_STATE puts the crawler back at rest in its initial configuration
  (``~/reset``). Sim time never goes back (one /clock for every robot of the domain, and the
  bag's log times), so SCOPE_TIME is refused; SCOPE_DEFAULT and SCOPE_ALL reset everything that
  can be, the state, and say that time goes on. Nothing is ever spawned: SCOPE_SPAWNED is refused.
- **entities** are the bodies ``body_0`` ... (frame ``odom``, prefixed in a namespace as /tf
  is): pose x = body position [m], twist linear x = velocity [m/s], at the last publish tick (a
  read never cuts the integration off its grid, which would change the rounding of the run);
  acceleration is not reported (zero). Name filters are regular expressions (Python's ``re``,
  which reads the POSIX extended patterns tools send); sphere bounds select the bodies inside;
  categories, tags and other bounds are not served.
- **set_entity_state** changes nothing: a body's position is the state of the friction
  dynamics, tied to its neighbours by linkage lengths the actuator imposes, and its velocity
  follows from friction and the imposed rates; moving one body alone would break an imposed
  length. A request equal to the current state answers OK (nothing to do); anything else is
  refused with the reason (INVALID_POSE for a pose off the crawler's line or a quaternion that
  is not the identity, OPERATION_FAILED otherwise; ``reset_simulation`` is the way back to
  rest).

Without the simulation_interfaces package (a plain pip install: ``make build`` builds it) sim_node
runs without these and says so in one line (:func:`attach`).
"""
from __future__ import annotations

import math
import re
import threading
from typing import TYPE_CHECKING, Any, Callable, Protocol

from crawler_sim.bag.msgs import body_names
from crawler_sim.core.simtime import to_seconds
from crawler_sim.ros.messages import stamp_from_ns
from .loop import Loopable
from .tf import frame_prefix

if TYPE_CHECKING:
    from crawler_sim.core.trajectory import State
    from .outputs import Outputs

__all__ = ['attach', 'Standard', 'Simulated', 'MAX_SERVICE_STEPS', 'MAX_ACTION_STEPS',
           'SERVICES', 'ACTION']

#: steps one ``~/step_simulation`` call may ask for: the service holds the node's callbacks
#: until it answers (100 s of sim time at 1 kHz; more goes through the action, which does not)
MAX_SERVICE_STEPS = 100_000
MAX_ACTION_STEPS = 10**12
FEEDBACK_DEPTH = 100    # history of the action's feedback publisher
#: service name -> type name in simulation_interfaces.srv
SERVICES = {
    '~/get_simulator_features': 'GetSimulatorFeatures',
    '~/get_simulation_state': 'GetSimulationState',
    '~/set_simulation_state': 'SetSimulationState',
    '~/step_simulation': 'StepSimulation',
    '~/reset_simulation': 'ResetSimulation',
    '~/get_entities': 'GetEntities',
    '~/get_entity_state': 'GetEntityState',
    '~/get_entities_states': 'GetEntitiesStates',
    '~/set_entity_state': 'SetEntityState',
}
ACTION = '~/simulate_steps'
#: SimulatorFeatures constants of what is served (the list the features service answers)
FEATURES = ('SIMULATION_STATE_GETTING', 'SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE',
            'STEP_SIMULATION_SINGLE', 'STEP_SIMULATION_MULTIPLE', 'STEP_SIMULATION_ACTION',
            'SIMULATION_RESET', 'SIMULATION_RESET_STATE', 'ENTITY_STATE_GETTING',
            'ENTITY_STATE_SETTING')


class Simulated(Loopable, Protocol):
    """What this module uses of ``SimNode``: what the loop uses (lock, config, sim time,
    paused, tick_locked, publish_state, clock), these, and rclpy's Node API (create_service,
    get_logger, get_namespace, executor)."""

    outputs: Outputs

    @property
    def state(self) -> State: ...
    @property
    def last_published(self) -> tuple[State | None, int]: ...
    def set_paused(self, paused: bool) -> str: ...
    def reset(self) -> None: ...


def attach(node: Any) -> Standard | None:
    """Serve the standard on ``node`` if simulation_interfaces is installed; otherwise log one
    line saying why not and return None (the line names a missing tf2_msgs too: /tf)."""
    try:
        import simulation_interfaces.msg as msg
        import simulation_interfaces.srv as srv
        from simulation_interfaces.action import SimulateSteps
    except ImportError as exc:
        missing = node.outputs.tf_missing
        extra = f'; /tf not published: {missing}' if missing else ''
        node.get_logger().info(
            f'simulation_interfaces services not available: the package is not installed '
            f'({exc}; `make build` builds it, tools/build_interfaces.py){extra}')
        return None
    if node.outputs.tf_missing:
        node.get_logger().info(f'/tf not published: {node.outputs.tf_missing} (`make build` '
                               'builds it, tools/build_interfaces.py)')
    return Standard(node, msg, srv, SimulateSteps)


class Standard:
    """The services and the action of the standard on one node (see the module docstring)."""

    def __init__(self, node: Simulated, msg: Any, srv: Any, simulate_steps: type) -> None:
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        from rclpy.qos import QoSProfile
        self._node = node
        self._msg, self._srv, self._action_type = msg, srv, simulate_steps
        self._frame = frame_prefix(node.get_namespace()) + 'odom'
        self._stopped_at: int | None = None     # sim time of the latest STOPPED (None: not)
        self.services = [node.create_service(getattr(srv, type_name), name,
                                             getattr(self, '_' + name[2:]))
                         for name, type_name in SERVICES.items()]
        # feedback comes once per tick, faster than a client may take it: a deeper history than
        # the default 10 keeps a burst (a reader with depth 10 still sees the latest ones)
        self.action = ActionServer(
            node, simulate_steps, ACTION, execute_callback=self._execute,
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            cancel_callback=lambda goal_handle: CancelResponse.ACCEPT,
            feedback_pub_qos_profile=QoSProfile(depth=FEEDBACK_DEPTH))

    # ------------------------------------------------------------------ helpers
    def _result(self, code: str = 'RESULT_OK', message: str = '') -> Any:
        Result = self._msg.Result
        return Result(result=getattr(Result, code) if isinstance(code, str) else code,
                      error_message=message)

    def _entity_state(self, i: int, state: State, t_ns: int) -> Any:
        out = self._msg.EntityState()
        out.header.stamp = stamp_from_ns(t_ns)
        out.header.frame_id = self._frame
        out.pose.position.x = float(state.x[i])
        out.pose.orientation.w = 1.0
        out.twist.linear.x = float(state.v[i])
        return out

    def _published(self) -> tuple[State, int]:
        state, t_ns = self._node.last_published
        if state is None:           # nothing published yet: the state at the current tick
            node = self._node
            with node.lock:
                return node.state, node.sim_time_ns
        return state, t_ns

    def _select(self, filters: Any, p: int, state: State) -> tuple[list[int] | None, Any]:
        """Indices of the bodies that pass ``filters`` (None and a refusal Result if a filter
        is not served or not valid)."""
        if len(filters.categories):
            return None, self._result('RESULT_FEATURE_UNSUPPORTED',
                                      'entity categories are not served')
        if len(filters.tags.tags):
            return None, self._result('RESULT_FEATURE_UNSUPPORTED', 'entity tags are not served')
        try:
            pattern = re.compile(filters.filter) if filters.filter else None
        except re.error as exc:
            return None, self._result('RESULT_OPERATION_FAILED',
                                      f'filters.filter is not a valid regular expression: {exc}')
        names = body_names(p)
        chosen = [i for i in range(p) if pattern is None or pattern.search(names[i])]
        bounds = filters.bounds
        if bounds.type == bounds.TYPE_EMPTY:
            return chosen, None
        if bounds.type != bounds.TYPE_SPHERE:
            return None, self._result('RESULT_FEATURE_UNSUPPORTED',
                                      'of filters.bounds, only TYPE_SPHERE is served')
        if len(bounds.points) != 2 or not bounds.points[1].x >= 0.0:
            return None, self._result('RESULT_OPERATION_FAILED',
                                      'filters.bounds of TYPE_SPHERE takes 2 points: the '
                                      'centre, then the radius >= 0 in x')
        c, r = bounds.points[0], bounds.points[1].x
        # a body is a point of the odom x axis (y = z = 0)
        return [i for i in chosen
                if math.hypot(float(state.x[i]) - c.x, c.y, c.z) <= r], None

    # ------------------------------------------------------------------ services
    def _get_simulator_features(self, request: Any, response: Any) -> Any:
        features = response.features
        features.features = [getattr(self._msg.SimulatorFeatures, name) for name in FEATURES]
        features.custom_info = ('crawler_sim sim_node: entities are the bodies body_i; a step '
                                'is one integration tick; sim time never goes back '
                                '(SCOPE_TIME refused); set_entity_state refuses changes to '
                                'a crawler with imposed linkage lengths (docs/node.md)')
        return response

    def _state_code(self) -> int:
        SS = self._msg.SimulationState
        node = self._node
        if not node.paused:
            return SS.STATE_PLAYING
        if self._stopped_at is not None and self._stopped_at == node.sim_time_ns:
            return SS.STATE_STOPPED
        return SS.STATE_PAUSED

    def _get_simulation_state(self, request: Any, response: Any) -> Any:
        with self._node.lock:
            response.state.state = self._state_code()
        response.result = self._result()
        return response

    def _set_simulation_state(self, request: Any, response: Any) -> Any:
        SS = self._msg.SimulationState
        node = self._node
        target = request.state.state
        with node.lock:
            now = self._state_code()
            if target not in (SS.STATE_PLAYING, SS.STATE_PAUSED, SS.STATE_STOPPED):
                response.result = self._result(
                    'RESULT_FEATURE_UNSUPPORTED',
                    f'state.state {target} is not served: PLAYING (1), PAUSED (2) and '
                    'STOPPED (0) are (quitting: stop the node; worlds: none)')
            elif target == now:
                response.result = self._result(response.ALREADY_IN_TARGET_STATE,
                                               'already in that state')
            elif target == SS.STATE_PAUSED and now == SS.STATE_STOPPED:
                response.result = self._result(response.INCORRECT_TRANSITION,
                                               'stopped: play it, or step it')
            elif target == SS.STATE_STOPPED:
                node.set_paused(True)
                node.reset()
                self._stopped_at = node.sim_time_ns
                response.result = self._result(
                    message=f'stopped: paused and at rest at t = '
                            f'{to_seconds(node.sim_time_ns):.9f} s (sim time goes on)')
            else:
                self._stopped_at = None
                response.result = self._result(
                    message=node.set_paused(target == SS.STATE_PAUSED))
        return response

    def _step_refusal(self, steps: int, most: int, field: str) -> Any:
        """A Result refusing ``steps`` steps now, or None if they can run."""
        node = self._node
        if not 1 <= steps <= most:
            return self._result('RESULT_OPERATION_FAILED',
                                f'{field} must be in [1, {most}], got {steps}')
        if not node.paused:
            return self._result('RESULT_OPERATION_FAILED',
                                'not paused: the standard steps a paused simulation '
                                '(set_simulation_state to STATE_PAUSED first)')
        if node.clock.following:
            return self._result('RESULT_OPERATION_FAILED',
                                f'this sim follows the /clock of {node.clock.owner}: its '
                                'time is that clock\'s; step the owner')
        return None

    def _advance(self, steps: int, stop: Callable[[], bool] | None = None,
                 feedback: Callable[[int], None] | None = None) -> tuple[int, str]:
        """Run up to ``steps`` ticks while paused (the lock taken per tick or per run of ticks
        to the publish grid, so the node's other callbacks and the loop get in between);
        return how many ran and why it stopped early ('' if it did not). ``stop`` is asked
        before each tick, ``feedback`` gets the count after each (then ticks go one by one)."""
        node = self._node
        done = 0
        why = ''
        while done < steps:
            if stop is not None and stop():
                why = 'cancelled'
                break
            if node.stopped:                # the node is shutting down
                why = 'the node stopped'
                break
            with node.lock:
                if not node.paused:
                    why = 'resumed during the steps'
                    break
                cfg = node.config
                t0 = node.sim_time_ns
                to_grid = cfg.publish_every - (t0 // cfg.dt_ns) % cfg.publish_every
                # a run of ticks up to the publish grid is the same ticks, bit for bit, in
                # one call (Engine.tick_to_grid)
                node.tick_locked(to_grid=feedback is None and to_grid <= steps - done)
                done += (node.sim_time_ns - t0) // cfg.dt_ns
            if feedback is not None:
                feedback(done)
        with node.lock:
            cfg = node.config
            if done and (node.sim_time_ns // cfg.dt_ns) % cfg.publish_every:
                node.publish_state()    # /clock and the state where the steps ended
            if done:
                self._stopped_at = None
        return done, why

    def _step_simulation(self, request: Any, response: Any) -> Any:
        node = self._node
        with node.lock:
            refusal = self._step_refusal(request.steps, MAX_SERVICE_STEPS, 'steps')
        if refusal is not None:
            response.result = refusal
            return response
        done, why = self._advance(request.steps)
        response.result = (
            self._result(message=f'stepped to t = {to_seconds(node.sim_time_ns):.9f} s')
            if not why else
            self._result('RESULT_INCORRECT_STATE', f'{why} after {done} of {request.steps} steps'))
        return response

    def _reset_simulation(self, request: Any, response: Any) -> Any:
        R = self._srv.ResetSimulation.Request
        scope = request.scope
        node = self._node
        if scope in (R.SCOPE_DEFAULT, R.SCOPE_ALL):
            note = '; sim time goes on (it never goes back: one /clock for every robot)'
        elif scope & R.SCOPE_TIME:
            response.result = self._result(
                'RESULT_FEATURE_UNSUPPORTED',
                'scope SCOPE_TIME is not served: sim time never goes back (one /clock for '
                'every robot of the domain, and the bag); SCOPE_STATE resets the crawler')
            return response
        elif scope != R.SCOPE_STATE:
            response.result = self._result(
                'RESULT_FEATURE_UNSUPPORTED',
                f'scope {scope} is not served: SCOPE_STATE (2), SCOPE_ALL (255) and '
                'SCOPE_DEFAULT (0) are (nothing is ever spawned)')
            return response
        else:
            note = ''
        with node.lock:
            stopped = self._state_code() == self._msg.SimulationState.STATE_STOPPED
            node.reset()
            if stopped:
                self._stopped_at = node.sim_time_ns
            response.result = self._result(
                message=f'at rest in the initial configuration at t = '
                        f'{to_seconds(node.sim_time_ns):.9f} s' + note)
        return response

    def _get_entities(self, request: Any, response: Any, states: bool = False) -> Any:
        state, t_ns = self._published()
        chosen, refusal = self._select(request.filters, len(state.x), state)
        if refusal is not None:
            response.result = refusal
            return response
        names = body_names(len(state.x))
        response.entities = [names[i] for i in chosen]
        if states:
            response.states = [self._entity_state(i, state, t_ns) for i in chosen]
        response.result = self._result()
        return response

    def _get_entities_states(self, request: Any, response: Any) -> Any:
        return self._get_entities(request, response, states=True)

    def _find(self, name: str, p: int) -> tuple[int | None, Any]:
        """The index of body ``name`` among ``p``, or None and a NOT_FOUND Result."""
        names = body_names(p)
        if name in names:
            return names.index(name), None
        return None, self._result('RESULT_NOT_FOUND', f'entity {name!r} is not a body of this '
                                                      f'crawler (body_0 ... body_{p - 1})')

    def _get_entity_state(self, request: Any, response: Any) -> Any:
        state, t_ns = self._published()
        i, refusal = self._find(request.entity, len(state.x))
        if refusal is not None:
            response.result = refusal
            return response
        response.state = self._entity_state(i, state, t_ns)
        response.result = self._result()
        return response

    def _set_entity_state(self, request: Any, response: Any) -> Any:
        state, _ = self._published()
        i, refusal = self._find(request.entity, len(state.x))
        if refusal is not None:
            response.result = refusal
            return response
        s = request.state
        pos, q = s.pose.position, s.pose.orientation
        if pos.y != 0.0 or pos.z != 0.0 or (q.x, q.y, q.z, abs(q.w)) != (0.0, 0.0, 0.0, 1.0):
            response.result = self._result(
                response.INVALID_POSE,
                'state.pose: the bodies move on the odom x axis (y = z = 0, identity '
                'orientation)')
            return response
        tw, ac = s.twist, s.acceleration
        moving = [tw.linear.x - float(state.v[i]), tw.linear.y, tw.linear.z, tw.angular.x,
                  tw.angular.y, tw.angular.z, ac.linear.x, ac.linear.y, ac.linear.z,
                  ac.angular.x, ac.angular.y, ac.angular.z]
        if pos.x == float(state.x[i]) and not any(moving):
            response.result = self._result(message='the current state: nothing to change')
            return response
        response.result = self._result(
            'RESULT_OPERATION_FAILED',
            f'{request.entity} cannot be set: its position is the state of the friction '
            'dynamics, tied to its neighbours by linkage lengths the actuator imposes, and its '
            'velocity follows from friction and the imposed length rates; moving one body '
            'alone would break an imposed length (reset_simulation puts the crawler back at '
            'rest; linkage_cmd moves it)')
        return response

    # ------------------------------------------------------------------ the action
    async def _execute(self, goal_handle: Any) -> Any:
        """SimulateSteps: the steps run in a worker thread (this coroutine waits on a future it
        completes), so the node's executor stays free for cancel requests and the services;
        feedback after each step, cancel between two steps."""
        from rclpy.task import Future
        node = self._node
        steps = goal_handle.request.steps
        result = self._action_type.Result()
        with node.lock:
            result.result = self._step_refusal(steps, MAX_ACTION_STEPS, 'steps') or \
                self._result()
        if result.result.result != result.result.RESULT_OK:
            goal_handle.abort()
            return result
        feedback = self._action_type.Feedback()

        def send(done: int) -> None:
            feedback.completed_steps, feedback.remaining_steps = done, steps - done
            goal_handle.publish_feedback(feedback)

        finished = Future(executor=node.executor)
        # (with a callback, setting the future wakes the executor)
        finished.add_done_callback(lambda _f: None)

        def work() -> None:
            try:
                finished.set_result(self._advance(steps, lambda: goal_handle.is_cancel_requested,
                                                  send))
            except Exception as exc:     # noqa: BLE001 - handed to the coroutine
                finished.set_exception(exc)

        threading.Thread(target=work, name='simulate_steps', daemon=True).start()
        done, why = await finished
        line = f'{done} of {steps} steps, t = {to_seconds(node.sim_time_ns):.9f} s'
        if why == 'cancelled':
            goal_handle.canceled()
            result.result = self._result(message=f'cancelled after {line}')
        elif why:
            goal_handle.abort()
            result.result = self._result('RESULT_INCORRECT_STATE', f'{why}: {line}')
        else:
            goal_handle.succeed()
            result.result = self._result(message=line)
        return result
