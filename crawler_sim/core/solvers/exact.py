"""Method "exact": event-driven solution in closed form between stick/slip events (MODEL.md s. 2).

Between events the motion is known exactly:

* every body slides: the centre of mass X has constant acceleration a = (F_ext + sum R_i) / M, so
  X and V = X' are a quadratic and a line in t, and x_i = X + e_i(t) with e_i from the gait;
* a body r sticks (alone, or with a group Z of bodies momentarily rigidly linked to it):
  x_r is constant, x_i = x_r + s_i(t) - s_r(t), and the group's total friction is whatever
  keeps it still: R_Z = -M e_r''(t) - F_ext - sum of the sliding bodies' R_i.

Events end a segment: a sliding body's velocity reaching zero, a stuck group's required force
reaching its friction bound, the group losing rigidity, and the gait's own breakpoints (jumps of
l''). At each segment start the contact mode is the solution of the acceleration-level inclusion;
a degenerate choice (a tie at a kink or at a bound) is decided by the same inclusion a short
look-ahead later. The contact sign of a body always comes from its actual velocity or
acceleration; V is never moved to make an event.

Stiction (static bounds above kinetic, ``Crawler.has_stiction``; STICTION.md): a stuck group
holds while its force is within its summed *static* interval (only the constants of its two
force rows change), and at each mode decision Rule S picks among the continuations the
inclusion with static bounds allows (``stiction_rule``: the incumbent group first, or the
largest static margin; ``core.friction``). The incumbent (the group stuck just before t) is
state: saved and restored with the rest, set by ``initial_stuck``, compared by the periodic
skip, reported as ``State.incumbent``; the instants where the rule chose among several
consistent continuations are ``choices``. Without stiction none of this runs: bit for bit the
convex method.

The whole segment loop is compiled (``_exact.ExactCore``), with every gait evaluated through its
compiled form (``Gait.compiled()``, ``_gait``): there is one implementation of each rule. This
module keeps what happens once per call: the periodic skip (whole periods that repeat are stored
as one ``PeriodicBlock``), the records and events of the segments, the messages of failures.

Guarantee: for every built-in gait (its compiled bounds of l''' and l'''' hold on every
interval), no contact event is missed and every event time is within ``tol`` seconds (or one
float spacing of t) of the exact one. A gait of Python functions (``Custom``, a user's ``Gait``
subclass) is sampled into Chebyshev pieces to the rounding of its values (``proxy``; a
``jerk_bound`` it gives is checked against them) and the guarantee holds for those pieces:
sampling, not a proof.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..friction import DEFAULT_RULE, check_rule
from ..gaits import Gait, PiecewiseCubic, _positive
from ..model import Crawler
from ..trajectory import EventLog, new_event
from . import _exact
from ._gait import _NO_LOCK, run_arrays as _gait_arrays
from .base import Capabilities, SolverError, register
from .segments import (PeriodicBlock, Records, Segment, SegmentChunk, SegmentList,
                       crawler_constants, evaluate_records, offset_matrices)

__all__ = ['ExactSolver', 'PeriodicBlock', 'Segment', 'offset_matrices',
           'check_finite_gait']

_EPS = np.finfo(float).eps
#: ``drive``'s statuses of a call that ended well, read as globals (one per drive, issue 41)
_REACHED, _FULL, _PERIODIC = _exact.REACHED, _exact.FULL, _exact.PERIODIC

#: ``periodic_skip=None``: a whole run skips repeated periods only if it would take more
#: segments than this without the skip (the skip's fixed cost, about 0.1 ms, is that many
#: segments' time: the break-even of 2, 3 and 8-body Scallops was at 130-170 segments,
#: ``python -m benchmarks.skip``)
SKIP_MIN_SEGMENTS = 150


def check_finite_gait(vals: Sequence[ArrayLike], t: float) -> None:
    """Raise ValueError naming the quantity and time if a gait value (l, l', l'') is not finite."""
    if all(np.isfinite(v).all() for v in vals):
        return
    for name, arr in zip(('length', 'velocity', 'acceleration'), vals):
        if not np.all(np.isfinite(arr)):
            bad = np.atleast_1d(t)[np.nonzero(~np.isfinite(np.reshape(
                arr, (np.size(t), -1))).any(axis=1))[0][0]]
            raise ValueError(f'gait {name} must be finite, got a non-finite value at t = '
                             f'{float(bad)!r} s')


def _run_gait(cg: Any) -> Gait:
    """The ``PiecewiseCubic`` of a run's table built in place (``_gait.run_table``): its
    pieces copied (``_gait.run_arrays``), its compiled form the table itself, so the solver
    reads the same struct whichever it is handed."""
    gait = PiecewiseCubic.from_arrays(*_gait_arrays(cg))
    gait.__dict__['_compiled'] = gait.__dict__['_native_kind'] = cg
    return gait


@register('exact')
class ExactSolver:
    """Event-driven integrator with a streaming interface (see ``crawler_sim.core.stepper``).

    With a periodic gait the solver also checks, at every multiple of the period, whether the
    state repeats the one a period earlier (same contact state and zero set, same centre-of-mass
    velocity to the solver's accuracy, 16 (tol * max friction acceleration + eps |V|)). From
    then on the motion is the last period translated by its displacement, so whole periods are
    skipped and stored as one ``PeriodicBlock`` (``periodic_skip=False`` turns this off).

    ``periodic_skip=None`` (the default) decides from the scene: on while streaming (each
    ``advance`` alone), and for a whole run (``simulate``) on only if the run without it would
    take more than ``SKIP_MIN_SEGMENTS`` segments, estimated from its first period. The skip's
    cost is fixed (the period checks, then sampling and events through a ``PeriodicBlock``:
    about 0.1 ms), its gain proportional to the segments it spares: a 2-body Scallop of 20
    periods was 1.2-1.7x slower with it, a 3-body one of 60 periods 1.8x faster.

    ``status`` and ``message`` describe the last ``advance``: "ok", or the failure it raised
    (``SolverError`` for a stall or an event search out of steps, see ``base``).
    """

    capabilities = Capabilities(dense_output=True, closed_form=True, streaming=True,
                                periodic_skip=True, stiction=True)

    def __init__(self, crawler: Crawler, gait: Gait, *, t0: float = 0.0, x0: float = 0.0,
                 v0: float = 0.0, tol: float = 1e-13, max_step: float | None = None,
                 keep_segments: bool = True, periodic_skip: bool | None = None,
                 stiction_rule: str = DEFAULT_RULE, initial_stuck: int | None = None) -> None:
        self.crawler = crawler
        self.stiction_rule = check_rule(stiction_rule)
        self.initial_stuck = initial_stuck
        self.gait = gait
        self._cg = gait.compiled()
        self.tol = float(tol)
        self.max_step = max_step
        self.keep_segments = keep_segments
        self.periodic_skip = periodic_skip
        # what ``advance`` does: auto is on until ``simulate`` finds the run too short for it
        self._skip = periodic_skip is None or bool(periodic_skip)
        k = self._k = crawler_constants(crawler)
        self._core = _exact.ExactCore(k.closed, self.tol)
        self._core.margin_rule = self.stiction_rule == 'margin'
        self.status, self.message = 'ok', ''
        self.reset(t0=t0, x0=x0, v0=v0, initial_stuck=initial_stuck)

    # ------------------------------------------------------------------ state
    t = property(lambda self: self._core.t)
    X = property(lambda self: self._core.X)
    V = property(lambda self: self._core.V)
    ref = property(lambda self: self._core.ref)
    K = property(lambda self: self._core.K_array)
    contact = property(lambda self: self._core.contact_array)
    zero = property(lambda self: self._core.zero_array)
    n_evals = property(lambda self: self._core.n_evals)

    def reset(self, *, t0: float = 0.0, x0: float = 0.0, v0: float = 0.0,
              initial_stuck: int | None = None) -> None:
        """Start at time t0 with body 0 at x0 [m] moving at v0 [m/s]; ``initial_stuck``: None
        (no incumbent) or a body at rest at t0 whose cluster counts as stuck just before t0
        (``Stepper`` checks it is at rest)."""
        if not self._core.reset(self._cg, float(t0), float(x0), float(v0)):
            check_finite_gait(self._cg.at(float(t0)), t0)
        if initial_stuck is not None:
            inc = np.zeros(self.crawler.p, dtype=bool)
            inc[int(initial_stuck)] = True
            self._core.incumbent_array = inc
        self.initial_stuck = initial_stuck
        self.segments = SegmentList()
        # the incumbent at t0 travels with the run's pieces (``incumbent_at``, dense output)
        self.segments.incumbent0 = self._core.incumbent_array
        self.events = EventLog()
        #: instants where Rule S chose among several consistent continuations (a crawler with
        #: stiction): (time [s], number of continuations, exact tie of margins), those of the
        #: periods integrated; ``n_choices`` counts the skipped periods' too
        self.choices: list[tuple[float, int, bool]] = []
        self.n_choices = 0
        self.n_segments = 0
        self.n_skipped_periods = 0
        self._last_gait = self.gait

    @property
    def gait(self) -> Gait:
        """The gait of the current interval. A run's table the plant's compiled step built
        (``core/plant/_batch.pyx``) is made a ``PiecewiseCubic`` only when asked for here
        (``_run_gait``: the same pieces, its compiled form that very table)."""
        g = self._gait
        if g is None:
            g = self._gait = _run_gait(self._cg)
        return g

    @gait.setter
    def gait(self, gait: Gait) -> None:
        self._gait = gait

    def forget_history(self) -> None:
        """Streaming use drops the events read: the periodic check starts anew, and the
        choice instants listed so far are dropped too (``n_choices`` keeps counting), so a
        long session does not accumulate them."""
        self._core.ck_valid = False
        self.choices.clear()

    @property
    def last(self) -> Segment | None:
        """The last segment integrated (None after a skipped period)."""
        rec = self._core.last_record()
        if rec is None:
            return None
        f, ref, contact, group, R, K0, _ = rec
        if self._last_gait is None:       # a compiled step's table (``gait``)
            cg = self._core.last_gait
            self._last_gait = self.gait if cg is self._cg else _run_gait(cg)
        return Segment(float(f[0]), float(f[1]), self._last_gait, contact, R, K0, float(f[2]),
                       float(f[3]), float(f[4]), int(ref), float(f[5]), group)

    # ------------------------------------------------------------- integration
    def advance(self, t1: float, gait: Gait | None = None) -> None:
        """Integrate exactly to t1 with ``gait`` (default: the current one) valid on [t, t1]."""
        if gait is not None and gait is not self.gait:
            self._switch_gait(gait)
        t1 = float(t1)
        core = self._core
        gp = self.gait.period
        # a periodic gait's multiples of the period end segments whether or not repeats are
        # skipped: each period runs in its own frame (``ExactCore.tl``: local time from
        # origin_k T, so an event time is known to ulp(T), not ulp(t), and the gait is read at
        # the same floats each period: a run of periods does not drift with t)
        T = gp if gp else 0.0
        core.skip = self._skip
        core.tscale = gp if gp else (self.max_step or 1.0)
        core.cap = self._cap()
        self.status, self.message = 'ok', ''
        cg = self._cg
        # the span a gait of Python functions is built in (``drive`` sets it): a call that
        # fails puts it back, or the next run's first reading (inside the failed span) would
        # build the failing window again, and the gait object would stay broken
        span = (cg.span_lo, cg.span_hi)
        while core.t < t1:
            core.seg_base = len(self.segments) if self.keep_segments else 0
            core.ev_base = len(self.events)
            core.save()
            try:
                if cg.lock is _NO_LOCK:   # a gait of its own state: no lock to enter
                    status = core.drive(cg, t1, T)
                else:
                    with cg.lock:         # a Custom gait's state is shared by its solvers
                        status = core.drive(cg, t1, T)
            except BaseException as exc:        # the user's gait raised: nothing of the call
                core.restore()
                cg.span_lo, cg.span_hi = span
                self.status, self.message = 'error', str(exc)
                raise
            if status == _REACHED or status == _FULL:
                self._store(core.n_seg, core.n_ev)
            elif status == _PERIODIC:
                self._store(core.n_seg, core.n_ev)
                self._period_boundary(core.k_at, T, t1)
            else:
                core.restore()
                cg.span_lo, cg.span_hi = span
                self._fail(status, t1)

    def _fail(self, status: int, t1: float) -> None:
        core, t = self._core, self._core.t
        if status == _exact.NONFINITE:
            tb = core.bad_time
            bad = tb if math.isfinite(tb) else t
            check_finite_gait(self._cg.values(np.array([bad])), [bad])
            msg = f'gait values must be finite (at t = {bad!r} s)'
            exc: Exception = ValueError(msg)
        elif status == _exact.STALLED:
            msg = (f'exact solver stalled after t = {t!r} s; report this scene (try '
                   'method="implicit")')
            exc = SolverError(msg, 'failed', 'exact')
        else:
            msg = (f'exact solver: the event search ran out of steps after t = {t!r} s; report '
                   'this scene (try method="implicit")')
            exc = SolverError(msg, 'failed', 'exact')
        self.status, self.message = 'failed', msg
        raise exc

    def _cap(self) -> float:
        """Largest grid step [s] while a row is watched: the user's max_step, the gait's,
        period / 8 (0: an eighth of each segment's span). Only the cost depends on it."""
        gait = self.gait
        period = gait.period
        cap = self.max_step
        step = getattr(gait, 'max_step', None)
        # the smallest of those given (min over them in this order, without building lists)
        if step is not None and (cap is None or step < cap):
            cap = step
        if period:
            eighth = period / 8.0
            if cap is None or eighth < cap:
                cap = eighth
        return 0.0 if cap is None else cap

    def _store(self, n: int, n_ev: int) -> None:
        """Keep the call's n segment records (as one ``SegmentChunk``, turned into ``Segment``
        objects only when read) and its n_ev contact changes as events."""
        core = self._core
        if core.n_choice:
            self.choices.extend(core.choices(core.n_choice))
            self.n_choices += core.n_choice
        if n_ev:
            self.events.extend(core.events(n_ev, new_event))
        if not n:
            return
        self.n_segments += n
        self._last_gait = self._gait      # None: the compiled step's table, made when read
        if self.keep_segments:
            self.segments.extend_chunk(SegmentChunk(self.gait, *core.records(n)))

    def _period_boundary(self, k: int, T: float, t1: float) -> None:
        """At t = k T the state repeats the one at (k - 1) T: skip the whole periods left."""
        core = self._core
        n = math.floor((t1 - core.t) / T * (1 + 4 * _EPS))
        t_k = core.t
        new_events = self.events[core.ck_nev:]
        template = ([sg for sg in self.segments[core.ck_nseg:] if isinstance(sg, Segment)]
                    if self.keep_segments else [])
        if self.choices:
            # the period just completed repeats its choices in each skipped one (counted)
            lo = np.searchsorted([c[0] for c in self.choices], t_k - T * (1 + 4 * _EPS))
            self.n_choices += n * (len(self.choices) - int(lo))
        D, dK = core.skip_periods(n, T, k)
        if self.keep_segments:
            self.segments.append(PeriodicBlock(t_k, n, T, D, dK, template, (k - 1) * T))
        self.events.add_periodic(new_events, n, T)     # stored once (memory)
        core.ck_nseg = len(self.segments)
        core.ck_nev = len(self.events)
        self.n_skipped_periods += n

    def _switch_gait(self, gait: Gait) -> None:
        """Continue with a new gait: keep the bodies' positions, velocities and contact state."""
        core, k = self._core, self._k
        cg = gait.compiled()
        if core.switch_gait(self._cg, cg):      # the same arithmetic, compiled (issue 41)
            self.gait = gait
            self._cg = cg
            return
        t = core.t
        # the new gait is read at absolute times (it may repeat on another period or not at all)
        core.tl, core.origin, core.origin_k = t, 0.0, 0
        l0, ld0, ldd0 = self._cg.at(t)
        l1, ld1, ldd1 = cg.at(t)
        core.ck_valid = False
        if not (l0.tolist() == l1.tolist() and ld0.tolist() == ld1.tolist()
                and ldd0.tolist() == ldd1.tolist()):
            core.forget_mode()          # not a C2 continuation: choose the mode anew
        if core.ref < 0:
            # body 0 keeps its position and velocity
            core.X += float(k.W[0] @ (l0 - l1))
            core.V += float(k.W[0] @ (ld0 - ld1))
        self.gait = gait
        self._cg = cg

    # ------------------------------------------------------------- solver contract
    @classmethod
    def options(cls, *, tol: float = 1e-13, max_step: float | None = None,
                keep_history: bool = False, periodic_skip: bool | None = None,
                stiction_rule: str = DEFAULT_RULE, initial_stuck: int | None = None,
                **_ignored: Any) -> dict:
        """The constructor's keyword arguments from ``Stepper``'s (validated;
        ``initial_stuck`` is checked against the state by ``Stepper``)."""
        return {'tol': _positive('tol', tol, 's'),
                'max_step': None if max_step is None else _positive('max_step', max_step, 's'),
                'keep_segments': bool(keep_history),
                'periodic_skip': None if periodic_skip is None else bool(periodic_skip),
                'stiction_rule': check_rule(stiction_rule), 'initial_stuck': initial_stuck}

    @staticmethod
    def check_span(gait: Gait, t_end: float, options: dict) -> None:
        """Float time resolution: event times are floats, spaced ulp(t) ~ 2.2e-16 t apart; past
        1e-6 of the gait's time scale per ulp the "exact" times would be rounding noise."""
        scale = gait.period if getattr(gait, 'period', None) else (options['max_step'] or 1.0)
        limit = 1e-6 * scale / _EPS
        if t_end > limit:
            raise ValueError(f't_end must be <= {limit:.3g} s for method "exact" with this gait '
                             f'(time resolution eps * t_end below 1e-6 of its time scale '
                             f'{scale:g} s), got {t_end!r}')

    @staticmethod
    def default_times(t_end: float, dt: float | None) -> NDArray[np.float64]:
        """1001 evenly spaced times, or one every dt (up to a million)."""
        n = int(round(t_end / dt)) + 1 if dt is not None and t_end / dt <= 1e6 else 1001
        return np.linspace(0.0, t_end, max(n, 2))

    def simulate(self, t_end: float, times: NDArray | None, include_events: bool,
                 dt: float | None = None) -> tuple:
        """(times, outputs, info) of a whole run on [t, t_end] (``stepper.simulate``): the
        closed forms at the times, the event times added to the default ones."""
        self._decide_skip(t_end)
        self.advance(t_end)
        if self.periodic_skip is None and not self._skip:
            self._merge_probe()
        if times is None:
            times = self.default_times(t_end, dt)
            if include_events and len(self.events):
                times = np.union1d(times, [e.time for e in self.events if 0 < e.time < t_end])
        return times, self.sample(times), self.info(times)

    def _decide_skip(self, t_end: float) -> None:
        """``periodic_skip=None``: run to the first multiple of the period with the skip on
        (it compares nothing before the second), then keep it only if the run's segments
        without it, that period's count per period, exceed ``SKIP_MIN_SEGMENTS``."""
        T = self.gait.period
        if self.periodic_skip is not None or not T:
            return
        t1 = (math.floor(self.t / T) + 1) * T
        if t1 >= t_end:
            self._skip = False          # not one whole period to compare: nothing to skip
            return
        n0, t0 = self.n_segments, self.t
        self.advance(t1)
        per_second = (self.n_segments - n0) / (t1 - t0)
        self._skip = per_second * (t_end - t0) > SKIP_MIN_SEGMENTS

    def _merge_probe(self) -> None:
        """The probe's period and the rest of the run as ONE ``SegmentChunk``: sampling a
        single chunk is one compiled call, two go through ``evaluate_records`` (0.03 ms more on
        a 2-body run of 10 periods, a tenth of it)."""
        parts = self.segments._parts
        if not (len(parts) == 2 and all(isinstance(c, SegmentChunk) for c in parts)
                and parts[0].gait is parts[1].gait):
            return
        a, b = parts
        merged = SegmentChunk(a.gait, *(np.concatenate((getattr(a, f), getattr(b, f)))
                                        for f in ('f', 'ref', 'contact', 'group', 'R', 'K0')))
        inc0 = getattr(self.segments, 'incumbent0', None)
        self.segments = SegmentList()
        self.segments.incumbent0 = inc0
        self.segments.extend_chunk(merged)

    def info(self, times: NDArray[np.float64]) -> dict:
        """The run's counters; with stiction also ``choices`` (the instants where Rule S
        chose, skipped periods included) and ``choice_times`` [s] (those integrated)."""
        out = {'segments': self.n_segments, 'skipped_periods': self.n_skipped_periods}
        if self.crawler.has_stiction:
            out['choices'] = self.n_choices
            out['choice_times'] = np.array([c[0] for c in self.choices])
        return out

    # ---------------------------------------------------------------- output
    def current(self) -> dict:
        """The state at the current time as one output row (left limit at an event), with
        ``incumbent`` (p,) bool: the cluster stuck just before t."""
        row = self._core.current(self._cg)
        row['incumbent'] = self._core.incumbent_array
        return row

    def sample(self, times: NDArray[np.float64]) -> dict:
        """Exact states at ``times`` (sorted, within the integrated span) from kept segments.

        Times inside a ``PeriodicBlock`` are mapped onto its template period and shifted; the
        segments' constants are gathered from their table (``SegmentList.records``).
        """
        segs = self.segments
        k = self._k
        chunk = segs.only_chunk()
        if chunk is not None:
            # the common run: one compiled call finds each time's segment and evaluates
            cg = chunk.gait.compiled()
            with cg.lock:        # a Custom gait's pieces are shared by its solvers
                x, v, R, K, lam, state, ind, l, ld = k.closed.sample(
                    cg, chunk.f, chunk.ref, chunk.group, chunk.contact, chunk.R, chunk.K0,
                    np.ascontiguousarray(times, dtype=float))
            return {'x': x, 'v': v, 'friction': R, 'impulse': K, 'linkage_force': lam,
                    'lengths': l, 'rates': ld, 'contact': state, 'indeterminate': ind}
        n_t = times.size
        table, row_of = segs.records()
        idx = np.searchsorted(segs.starts(), times, side='right') - 1
        np.maximum(idx, 0, out=idx)      # (searchsorted - 1 is at most the last item)
        owner = row_of[idx]
        local = np.array(times, dtype=float)
        blocks = (owner < 0).nonzero()[0]
        if not blocks.size:       # no skipped period among the sampled times
            return evaluate_records(self.crawler, table, owner, local)
        shift_x = np.zeros(n_t)
        shift_k = np.zeros((n_t, k.m.size))
        parts, n_rows = [table], table.ref.size
        for b in np.unique(idx[blocks]).tolist():
            sel = (idx == b).nonzero()[0]
            piece = segs[b]
            j = np.clip(np.floor((times[sel] - piece.t0) / piece.T).astype(int) + 1, 1, piece.n)
            loc = times[sel] - j * piece.T             # falls in the template period
            tpl = piece.template
            t_starts = np.array([sg.t0 for sg in tpl])
            t_ends = np.array([sg.t1 for sg in tpl])
            sub = np.clip(np.searchsorted(t_starts, loc, side='right') - 1, 0, len(tpl) - 1)
            owner[sel] = n_rows + sub
            parts.append(Records.from_segments(tpl))
            n_rows += len(tpl)
            local[sel] = np.clip(loc, t_starts[sub], t_ends[sub])
            shift_x[sel] = j * piece.D
            shift_k[sel] = np.multiply.outer(j, piece.dK)
        out = evaluate_records(self.crawler, Records.concat(parts), owner, local)
        out['x'] += shift_x[:, None]
        out['impulse'] += shift_k
        return out


def incumbent_at(segments: SegmentList, times: NDArray[np.float64], p: int) -> NDArray[np.bool_]:
    """The incumbent (N, p) bool at ``times`` [s] (shape (N,), inside the run) of a run's kept
    pieces: the cluster stuck on the segment holding t in (t0, t1], i.e. stuck just before t
    (STICTION.md s. 5; at an event, the segment that ends there), no body where that segment
    slides; at or before the first segment's start the reset's (``initial_stuck``). What
    ``Stepper``'s ``State.incumbent`` is after advancing to t (``Trajectory.state_at``)."""
    times = np.asarray(times, dtype=float)
    out = np.zeros((times.size, p), dtype=bool)
    inc0 = getattr(segments, 'incumbent0', None)
    if inc0 is not None:
        out[:] = np.asarray(inc0, dtype=bool)
    if not len(segments) or not times.size:
        return out
    table, row_of = segments.records()
    # the piece whose start lies before t (searchsorted 'left': at a start, the one before)
    idx = np.searchsorted(segments.starts(), times, side='left') - 1
    for k in np.unique(idx[idx >= 0]).tolist():
        sel = (idx == k).nonzero()[0]
        if row_of[k] >= 0:
            r = int(row_of[k])
            out[sel] = table.group[r] & (table.ref[r] >= 0)
            continue
        piece = segments[k]           # skipped periods: t - j T in the template period
        j = np.clip(np.ceil((times[sel] - piece.t0) / piece.T).astype(int), 1, piece.n)
        loc = times[sel] - j * piece.T
        tpl = piece.template
        # a time on a template start is the end of the segment before it (at the period's
        # start, the previous period's last one); t - j T rounds: a start within 8 floats of
        # t is taken as t (the events of skipped periods are the template's shifted, rounded)
        near = 8.0 * np.spacing(np.abs(times[sel]))
        sub = np.searchsorted([sg.t0 for sg in tpl], loc - near, side='left') - 1
        sub[sub < 0] = len(tpl) - 1
        for i, q in zip(sel.tolist(), sub.tolist()):
            out[i] = np.asarray(tpl[q].group, dtype=bool) & (tpl[q].ref >= 0)
    return out
