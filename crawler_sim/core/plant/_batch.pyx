# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False
"""The plant's compiled step: ``Engine``'s run of ticks up to the publish grid and its sync in
one compiled pass, for one crawler (``PlantStep.run``) or N (``step_plants``), issue 41.

``Engine.tick_to_grid`` and ``Engine.run_to`` take this path when nothing is queued and the
plant integrates with the exact method (``plant_step`` says when); the vector environment
steps its N engines through the same function. It is not a second plant: the actuator's tick
loop (``_actuator.servo_run``), the table of the run's pieces (``_gait.run_table``), the
gait switch and the integration (``_exact.core_switch``, ``core_drive``) are the very
functions the Python path calls, reached without a Python call, a ``Pieces``, a
``PiecewiseCubic`` or a table copy in between: the actuator writes its pieces into the
table the solver reads. The Python layers' bookkeeping is repeated here on the same objects
(``Engine.t_ns``, the solver's ``gait``, ``n_segments``, the core's periodic check), and
whatever this path does not handle goes back to them at the point it arises:

- a run wholly at rest or of one tick (``Engine._gait`` then hands the solver a ``Cubic``
  object), or a gait not finite at the start (``Stepper.advance`` refuses it): the pieces as
  ``Pieces`` through ``Engine._gait`` and ``Engine._integrate``;
- stiction choices of a call: ``ExactSolver._store`` and ``Stepper.pop_events`` (contact
  events alone go to the engine's list as those two would hand them, packed as records
  until ``Engine.pop_events``);
- a failed integration: ``Engine._integrate`` with its status (the solver's message, the
  implicit fallback, containment).

So every state, event, journal entry and failure is the Python path's, bit for bit
(test/core/plant/test_compiled_paths.py, test/envs).
"""
from crawler_sim.core._actuator cimport servo_run, servo_target
from crawler_sim.core.solvers._gait cimport CompiledGait, gait_eval, run_table, run_table_fill
from crawler_sim.core.solvers._exact cimport (core_drive, core_event_records, core_forget,
                                              core_read, core_settle, core_switch, core_time)
from cpython.ref cimport Py_REFCNT
from libc.math cimport isfinite

import numpy as np

from crawler_sim.core.actuator import Pieces
from crawler_sim.core.solvers._gait import run_arrays
from crawler_sim.core.solvers.exact import ExactSolver, _run_gait
from crawler_sim.core.solvers import _exact
from crawler_sim.core.stepper import Stepper

#: the Python methods the compiled step stands for (``PlantStep.current``)
_STEPPER_ADVANCE = Stepper.advance
_EXACT_ADVANCE = ExactSolver.advance

__all__ = ['PlantStep', 'plant_step', 'step_plants']

cdef int REACHED = _exact.REACHED
cdef int FULL = _exact.FULL

cdef enum:
    MAX_LINKS = 16      # the compiled switch of gait (``ExactCore.switch_gait``) takes fewer


cdef class PlantStep:
    """One ``Engine``'s objects as the compiled step reads them (``plant_step`` makes it and
    the engine keeps it until its stepper, actuator or configuration changes)."""
    cdef readonly object engine
    cdef object servo, stepper, solver, core
    cdef long long dt_ns, every
    cdef Py_ssize_t nl, p
    cdef bint skip
    cdef double tscale, cap
    # tables of past steps, refilled in place once nothing else holds them (``_table``)
    cdef object ring0, ring1, ring2
    # the last ``run_grid`` ended in the core, on the compiled path throughout (no Python
    # path took over: the engine's stepper is still this one and holds the state)
    cdef bint compiled

    def __init__(self, engine):
        stepper = engine.stepper
        solver = stepper._solver
        self.engine = engine
        self.servo = engine.actuator
        self.stepper = stepper
        self.solver = solver
        self.core = solver._core
        self.dt_ns = engine.cfg.dt_ns
        self.every = engine.cfg.publish_every
        self.nl = engine.actuator.n_links
        self.p = self.nl + 1
        # ``ExactSolver.advance``'s settings for a gait with no period and no max_step (a
        # ``PiecewiseCubic``): the solver's max_step is None (``plant_step``), so the time
        # scale is 1 s and the grid step cap 0 (an eighth of each segment)
        self.skip = solver._skip
        self.tscale = 1.0
        self.cap = 0.0

    def run(self) -> int:
        """``Engine.tick_to_grid()`` with nothing queued: the ticks up to and including the
        next one on the publish grid, integrated; returns how many ran."""
        return run_grid(self)

    cpdef bint current(self):
        """Whether the engine still has the objects this was made from, and they still run
        the methods this step stands for (``Stepper.advance``, ``ExactSolver.advance``: one
        replaced, as a test does to make a failure, runs through Python)."""
        eng = self.engine
        return (eng.stepper is self.stepper and eng.actuator is self.servo
                and type(self.stepper).advance is _STEPPER_ADVANCE
                and type(self.solver).advance is _EXACT_ADVANCE)


def plant_step(engine) -> PlantStep | None:
    """The compiled step of ``engine`` (an ``Engine``), or None where only the Python path
    runs: an engine that does not integrate, a method other than "exact", a solver that keeps
    its segments or has a max_step, 16 linkages or more."""
    if not engine.integrate:
        return None
    solver = engine.stepper._solver
    if (type(solver) is not ExactSolver or solver.keep_segments or solver.max_step is not None
            or engine.actuator.n_links >= MAX_LINKS):
        return None
    return PlantStep(engine)


cdef int finite_at(CompiledGait g, double t, Py_ssize_t nl) except -1:
    """``CompiledGait.finite_at(t)`` of a TABLE gait (l, l', l'' all finite at t [s])."""
    cdef double w[4 * MAX_LINKS]
    cdef Py_ssize_t j
    gait_eval(&g.d, t, w, w + nl, w + 2 * nl, w + 3 * nl)
    for j in range(3 * nl):
        if not isfinite(w[j]):
            return 0
    return 1


cdef CompiledGait _table(PlantStep s, Py_ssize_t n):
    """A table of n pieces to write: one of the step's past tables that nothing else holds
    any more (the solver and its core hold the last two: the gait and the one ``restore``
    would put back; a gait made for Python holds its own), else a new one
    (``_gait.run_table``). Its contents are all written again (``servo_run``,
    ``run_table_fill``), so a refilled table is a new one to the bit, without an allocation
    or the cyclic collector's count of one."""
    cdef CompiledGait g
    # free: a reference count of 2, the ring's and this local variable's
    if s.ring0 is not None:
        g = s.ring0
        if Py_REFCNT(g) == 2 and g.d.n == n:
            return g
    if s.ring1 is not None:
        g = s.ring1
        if Py_REFCNT(g) == 2 and g.d.n == n:
            return g
    if s.ring2 is not None:
        g = s.ring2
        if Py_REFCNT(g) == 2 and g.d.n == n:
            return g
    g = run_table(n, s.nl)
    s.ring0, s.ring1, s.ring2 = g, s.ring0, s.ring1
    return g


cdef long long run_grid(PlantStep s) except -1:
    """``Engine._run(k)`` + ``Engine.sync()`` of the k ticks up to the publish grid, the queue
    empty (module doc); returns k."""
    cdef object eng = s.engine, solver = s.solver, core = s.core
    cdef long long t0_ns = eng.t_ns
    cdef long long n = s.every - (t0_ns // s.dt_ns) % s.every
    cdef long long t1_ns = t0_ns + n * s.dt_ns
    cdef CompiledGait g = _table(s, n)
    cdef Py_ssize_t rest_from
    cdef double t1
    cdef long counts[3]
    cdef long ev_base = 0
    cdef int status
    cdef bint stored = False
    s.compiled = False
    rest_from = servo_run(s.servo, t0_ns, s.dt_ns, n, g.d.starts, g.d.anchors, g.d.coef)
    eng.t_ns = t1_ns
    # ``to_seconds``: the int converted to the nearest double, then divided
    t1 = <double>t1_ns / 1e9
    if rest_from == 0 or n == 1:
        # the solver is handed a Cubic object (the rest piece, or the one tick's piece):
        # ``Engine._gait``'s rule on the run as ``Actuator.run`` returns it
        starts, anchors, coef = run_arrays(g)
        run = Pieces(starts, anchors, coef, rest_from,
                     s.servo._rest_piece if rest_from < n else None)
        eng._integrate(t1, eng._gait([run]))
        return n
    run_table_fill(g)
    # ``Stepper.advance``'s check of the gait at the current time (t1 > t on the tick grid),
    # then ``ExactSolver.advance``: the switch to the new gait
    if not finite_at(g, core_time(core), s.nl) or not core_switch(core, solver._cg, g):
        eng._integrate(t1, _run_gait(g))
        return n
    solver._gait = None                  # made from the table if asked (``ExactSolver.gait``)
    solver._cg = g
    core_settle(core, s.skip, s.tscale, s.cap)
    solver.status = 'ok'
    solver.message = ''
    while core_time(core) < t1:
        status = core_drive(core, g, t1, ev_base, counts)
        if status != REACHED and status != FULL:
            eng._integrate(t1, solver.gait, status)
            return n
        if counts[2] or stored:
            # Rule S choices (and, after them, all of the call): kept by the solver as
            # objects (``_store``), popped by the engine below
            solver._store(counts[0], counts[1])
            ev_base += counts[1]
            stored = True
            continue
        if counts[1]:
            # the contact events straight to the engine's list, what ``_store`` then
            # ``Stepper.pop_events`` hand it (in order; the solver's log stays empty), as one
            # bytes of records that ``Engine.pop_events`` makes Events
            eng._events.append(core_event_records(core, counts[1]))
            eng._packed = True
            ev_base += counts[1]
        if counts[0]:
            solver.n_segments += counts[0]
            solver._last_gait = None
    if stored:
        eng._events.extend(s.stepper.pop_events())
    else:
        # ``Stepper.pop_events`` with nothing to pop: its ``forget_history`` (the solver's
        # choices list is empty: only ``_store`` fills it)
        core_forget(core)
    s.compiled = True
    return n


def step_plants(list engines, const double[:, ::1] targets, long long span_ns,
                double[:, ::1] x, double[:, ::1] v, signed char[:, ::1] contact) -> None:
    """For each i: ``Engine.command(targets[i])``, ``Engine.run_to(t_ns + span_ns)`` (from
    its own time t_ns [ns]) and ``Engine.read_state`` into row i of ``x`` [m], ``v`` [m/s]
    and ``contact`` for the ``Engine`` ``engines[i]`` (None: row i is skipped), in one
    compiled loop (``step_engine``)."""
    cdef Py_ssize_t i, n = len(engines), nl = targets.shape[1], p = x.shape[1]
    if targets.shape[0] < n or x.shape[0] < n or v.shape[0] < n or contact.shape[0] < n \
            or v.shape[1] != p or contact.shape[1] != p:
        raise ValueError(f'step_plants: {n} rows of targets, x, v and contact needed')
    for i in range(n):
        if engines[i] is not None:
            step_engine(engines[i], &targets[i, 0], nl, span_ns, &x[i, 0], &v[i, 0],
                        &contact[i, 0], p)


cdef int step_engine(object eng, const double* targets, Py_ssize_t nl, long long span_ns,
                     double* x, double* v, signed char* contact, Py_ssize_t p) except -1:
    """``Engine.command`` of ``nl`` targets [m], ``Engine.run_to(t_ns + span_ns)`` and
    ``Engine.read_state`` into the (p,) rows: the engine's compiled step where it has one
    (``Engine._fast``), else its Python methods (the same states)."""
    cdef Py_ssize_t j
    cdef PlantStep s
    obj = eng._step
    if obj is None:
        obj = eng._fast()
    if obj is not False:
        s = <PlantStep>obj
        if s.nl != nl or s.p != p:
            raise ValueError(f'step_plants: {nl} targets and {p} bodies for a crawler of '
                             f'{s.nl} linkages')
    if obj is False or not s.current():
        eng.command([targets[j] for j in range(nl)])
        eng.run_to(eng.t_ns + span_ns)
        _read(eng, x, v, contact, p)
        return 0
    plant_command(s, targets)
    # the core's state is the engine's when the compiled run ended the span (nothing queued)
    # on the compiled path throughout (the stepper the same)
    if not (plant_run_to(s, eng.t_ns + span_ns) and s.compiled
            and core_read(s.core, x, v, contact)):
        _read(eng, x, v, contact, p)
    return 0


cdef int _read(object eng, double* x, double* v, signed char* contact,
               Py_ssize_t p) except -1:
    """``Engine.read_state`` into the (p,) rows."""
    eng.read_state(np.asarray(<double[:p]>x), np.asarray(<double[:p]>v),
                   np.asarray(<signed char[:p]>contact))
    return 0


cdef int plant_command(PlantStep s, const double* targets) except -1:
    """``Engine.command`` of n_links targets [m]: the actuator's step command, journalled."""
    cdef Py_ssize_t j
    eng = s.engine
    servo_target(s.servo, targets)
    if eng.journal is not None:
        eng._note('command', [targets[j] for j in range(s.nl)])
    return 0


cdef int plant_run_to(PlantStep s, long long t_ns) except -1:
    """``Engine.run_to(t_ns)`` [ns]: the compiled run when the span ends on the next grid
    tick with nothing queued (returns 1), else the engine's own (which takes it where it
    can; returns 0)."""
    eng = s.engine
    cdef long long now = eng.t_ns
    if (t_ns - now == (s.every - (now // s.dt_ns) % s.every) * s.dt_ns
            and not eng._pieces and not eng._blocks):
        run_grid(s)
        return 1
    eng.run_to(t_ns)
    return 0
