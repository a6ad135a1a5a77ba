"""Method "exact": event-driven solution in closed form between stick/slip events (MODEL.md s. 2).

Between events the motion is known exactly:

* every body slides: the centre of mass X has constant acceleration a = (F_ext + sum R_i) / M, so
  X and V = X' are a quadratic and a line in t, and x_i = X + e_i(t) with e_i from the gait;
* a body r sticks (alone, or with a group Z of bodies momentarily rigidly linked to it):
  x_r is constant, x_i = x_r + s_i(t) - s_r(t), and the group's total friction is whatever
  keeps it still: R_Z = -M e_r''(t) - F_ext - sum of the sliding bodies' R_i.

Events end a segment: a sliding body's velocity reaching zero, a stuck group's required force
reaching its friction bound, the group losing rigidity, and the gait's own breakpoints (jumps of
l''), which the gait lists. At each segment start the contact mode is the solution of the
acceleration-level inclusion (``contact.solve_inclusion``); a degenerate choice (a tie at a kink
or at a bound) is decided by the same inclusion a short look-ahead later. The contact sign of a
body always comes from its actual velocity or acceleration; V is never moved to make an event.

The event search (``events``) proves each piece of a segment free of events from bounds on the
event functions' derivatives, which follow from the gait's ``jerk_bound`` / ``snap_bound``, or
splits it, and narrows the first bracketed event to ``tol`` seconds.

For the gaits the kernel evaluates, and a ``Custom`` gait without ``jerk_bound`` or breakpoints
(its functions behind a C callback, its bounds estimated: ``callback``), the segment loop itself
runs compiled (``kernel.drive``, called from ``_drive``) with the same rules, one call per
stretch of similar bounds (``Gait.block_end``); this module's ``_segment`` remains the reference
and the path for everything the compiled loop hands back (groups of bodies stuck together, a
contact sign contradicted by the velocity, other gaits).

Module size: about 800 lines, over the ~400 guide, because the mode choice, the integration
loop with its periodic skip, the event rows and the hand-over to the compiled loop all read and
write the solver state; the closed forms (``segments``, ``sampling``), the search (``events``,
``kernel``) and the inclusion (``contact``) live in their own modules.

Guarantee: for a gait whose ``jerk_bound`` (and ``snap_bound``, where it gives one) are true
bounds (every built-in gait, and a ``Custom`` gait given ``jerk_bound=``), no contact event is
missed and every event time is within ``tol`` seconds (or one float spacing of t) of the exact
one; for a ``Custom`` gait without a bound, the bound is estimated from the gait's values (a
scan of l'' refined to its time scale, ``callback``; per segment in the Python search) and the
work is redone whenever a later value contradicts the estimate (reliable, not a proof).
"""
from __future__ import annotations

import math
import weakref
from functools import partial

import numpy as np
from numpy.typing import NDArray

from ..gaits import Cubic, Custom, Fourier, Gait, PiecewiseCubic, Scallop, Sinusoid
from ..model import Crawler
from ..trajectory import Event, EventLog
from .contact import solve_inclusion
from .events import Rows, Search, check_finite_gait
from .segments import (PeriodicBlock, Records, Segment, SegmentChunk, SegmentList,
                       evaluate_records, evaluate_rows, offset_matrices)

__all__ = ['ExactSolver', 'PeriodicBlock', 'Segment', 'evaluate_rows', 'offset_matrices',
           'check_finite_gait']

_STALL_ULPS = 64          # a segment this short (in floats of t) makes no progress
_STALL_SEGMENTS = 256    # consecutive such segments before the solver reports a stall
_COMPILED = (Fourier, Sinusoid, Scallop, Cubic, PiecewiseCubic)   # gaits the kernel evaluates
# an Event from a (time, body, old, new) tuple at C speed (the namedtuple constructor is a
# Python function: ~0.4 us per event, as much as the compiled loop spends on a segment)
_new_event = partial(tuple.__new__, Event)
_AMBIGUOUS = 1e-10   # relative slack below which a mode choice is decided by look-ahead
_EPS = np.finfo(float).eps
_RETRIES = 16     # runs of the compiled loop with a Custom gait's bounds grown, then Python


def _dot(row: list, vec: list) -> float:
    acc = 0.0
    for w, y in zip(row, vec):
        acc += w * y
    return acc


def _merge_ties(kinks: NDArray, eps: float) -> NDArray:
    """Snap kinks closer than ``eps`` to one value: bodies rigidly linked have equal relative
    accelerations mathematically but not always bitwise, and must be seen as one group."""
    if kinks.size < 2:
        return kinks
    order = np.argsort(kinks, kind='stable')
    k = kinks[order]
    out = k.copy()
    for i in range(1, k.size):
        if k[i] - out[i - 1] <= eps:
            out[i] = out[i - 1]
    res = np.empty_like(kinks)
    res[order] = out
    return res


class _Constants:
    """What the solver derives from a crawler, computed once per ``Crawler`` (a simulation
    sweep or a node builds many solvers for one crawler): arrays and, for ``current`` (called
    at every publish tick of a node), plain-float copies."""

    def __init__(self, crawler: Crawler) -> None:
        self.m = crawler.masses
        self.M = float(crawler.masses.sum())                 # [kg]
        self.fp, self.fm = crawler.friction, crawler.friction_backward   # [N]
        self.fext = crawler.external_force                   # [N]
        self.C, self.W = offset_matrices(crawler.masses)
        # Frictionless bodies never stick and never change the dynamics: no events for them.
        self.free = (self.fp + self.fm) == 0.0
        self.f_total = float(self.fp.sum() + self.fm.sum())  # [N], scales of the tests
        # largest friction acceleration [m/s^2] (the periodic check's velocity tolerance)
        self.v_acc = float((self.f_total + abs(self.fext)) / self.M)
        self.fp_list, self.fm_list = self.fp.tolist(), self.fm.tolist()
        self.W_rows, self.C_rows = self.W.tolist(), self.C.tolist()
        self.m_list = self.m.tolist()
        self.g_list = crawler.gravity_forces.tolist()
        self.free_idx = np.nonzero(self.free)[0].tolist()


_CONSTANTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _constants(crawler: Crawler) -> _Constants:
    """The crawler's ``_Constants`` (a Crawler is immutable: its arrays are read-only)."""
    k = _CONSTANTS.get(crawler)
    if k is None:
        k = _CONSTANTS[crawler] = _Constants(crawler)
    return k


class ExactSolver:
    """Event-driven integrator with a streaming interface (see ``crawler_sim.core.stepper``).

    With a periodic gait the solver also checks, at every multiple of the period, whether the
    state repeats the one a period earlier (same contact state and zero set, same centre-of-mass
    velocity to the solver's accuracy, 16 (tol * max friction acceleration + eps |V|)). From
    then on the motion is the last period translated by its
    displacement, so whole periods are skipped and stored as one ``PeriodicBlock``
    (``periodic_skip=False`` turns this off).
    """

    use_kernel = True     # compiled search for the gaits in _COMPILED (``kernel``)

    def __init__(self, crawler: Crawler, gait: Gait, *, t0: float = 0.0, x0: float = 0.0,
                 v0: float = 0.0, tol: float = 1e-13, max_step: float | None = None,
                 keep_segments: bool = True, periodic_skip: bool = True) -> None:
        self.crawler = crawler
        self.gait = gait
        self.tol = float(tol)
        self.max_step = max_step
        self.keep_segments = keep_segments
        self.periodic_skip = periodic_skip
        k = _constants(crawler)
        self._m, self._M, self._fp, self._fm, self._fext = k.m, k.M, k.fp, k.fm, k.fext
        self._C, self._W, self._free = k.C, k.W, k.free
        self._f_total, self._v_acc = k.f_total, k.v_acc
        self._fp_list, self._fm_list, self._m_list = k.fp_list, k.fm_list, k.m_list
        self._g_list, self._W_rows, self._C_rows, self._free_idx = (k.g_list, k.W_rows,
                                                                    k.C_rows, k.free_idx)
        self.reset(t0=t0, x0=x0, v0=v0)
        if self._compiled(gait):
            from . import kernel    # numba: loaded here, not in the first (real-time) advance
            if not kernel.warm(self._kernel_gait(gait)[0]):
                self._drive(self.t, None)    # a call that integrates nothing: loads drive

    def _compiled(self, gait: Gait) -> bool:
        """True if the compiled loop runs this gait (``kernel``; a Custom gait through
        ``callback``)."""
        if not self.use_kernel:
            return False
        if type(gait) in _COMPILED:
            return True
        if type(gait) is not Custom:
            return False
        from .callback import bridge
        return bridge(gait) is not None

    @staticmethod
    def _kernel_gait(gait: Gait) -> tuple:
        """(kind, freq, P1, P2) of the kernel for a gait ``_compiled`` accepts."""
        from . import kernel
        coef = kernel.coefficients(gait)
        if coef is None:
            from .callback import bridge
            coef = bridge(gait).coefficients
        return coef

    # ------------------------------------------------------------------ state
    def reset(self, *, t0: float = 0.0, x0: float = 0.0, v0: float = 0.0) -> None:
        """Start at time t0 with body 0 at x0 [m] moving at v0 [m/s]."""
        l, ld, _ = self.gait.at(t0)
        e, ep = self._W @ l, self._W @ ld
        self.t = float(t0)
        self.X = float(x0 - e[0])          # centre of mass
        self.V = float(v0 - ep[0])
        v = v0 + self._C @ ld              # body velocities, exact zeros stay zero
        p = self._m.size
        self.contact = np.where(self._free, 0, np.sign(v)).astype(np.int8)
        self.zero = (v == 0.0) & ~self._free   # bodies known to be at zero velocity
        self.K = np.zeros(p)
        self.ref = -1
        self.x_ref = 0.0
        self.segments = SegmentList()
        self.events = EventLog()
        self.n_segments = 0
        self.n_skipped_periods = 0
        self.last: Segment | None = None
        self._checkpoint = None
        self._mode_cache = None
        self.n_evals = 0          # event-row evaluations (cost figure)
        n_buf = 512               # segment records per call of the compiled loop
        self._buffers = (np.empty((n_buf, 6)), np.empty(n_buf, np.int64),
                         np.empty((n_buf, p), np.int8), np.empty((n_buf, p)),
                         np.empty((n_buf, p)), np.empty(n_buf), np.empty((n_buf, 3), np.int64),
                         np.empty(12))
        self._ck = (np.empty(8), np.empty(p), np.empty(p, np.int8), np.empty(p, bool))
        self._zeros_links = np.zeros(p - 1)

    @property
    def last(self) -> Segment | None:
        """The last segment integrated (None after a skipped period)."""
        x = self._last
        if isinstance(x, tuple):          # a record of the compiled loop
            x = self._last = x[0].segment(x[1])
        return x

    @last.setter
    def last(self, seg) -> None:
        self._last = seg

    # ------------------------------------------------------------- mode choice
    def _mode(self, t: float, ep: NDArray, epp: NDArray, t_limit: float):
        """Contact mode at t for the bodies in ``self.zero``; returns (contact, a, ref, group)."""
        zero = self.zero
        contact = self.contact.copy()
        if not zero.any():
            R = np.where(contact > 0, -self._fp, self._fm)
            return contact, (self._fext + R.sum()) / self._M, -1, np.zeros_like(zero)
        choice = self._solve_mode(ep, epp, contact)
        span = max(t_limit - t, 0.0)
        loose = choice[3].sum() > 1 and not self._rigid(choice[3], t, span)
        if choice[4] or loose:
            # Degenerate tie, or bodies at rest together whose link is not rigid beyond this
            # instant: decide by the inclusion a little later (same zero set).
            # Near t the deciding quantities grow from zero, so only their sign matters: a
            # tighter ambiguity threshold there, and the furthest look-ahead if still unsure.
            # A link that is not rigid must not be merged into one kink either, however close
            # its ends' accelerations (l' and l'' of a few ulps, e.g. a tanh gait's tail):
            # a merged group would be found not rigid again one float later, for ever.
            for rel in (1e-9, 1e-7, 1e-5):
                dt = min(rel * max(span, self._timescale()), 0.5 * span) if span > 0 else 0.0
                if dt <= 0.0:
                    break
                _, ld2, ldd2 = self.gait.at(t + dt)
                choice = self._solve_mode(self._W @ ld2, self._W @ ldd2, contact, slack=1e-14,
                                          merge=not loose)
                if not choice[4]:
                    break
        return choice[:4]

    def _rigid(self, group: NDArray, t: float, span: float) -> bool:
        """True if the group's relative velocities stay zero just after t (a rigid link)."""
        if span <= 0.0:
            return True
        # two look-aheads: the nearer one can round a slowly growing rate to exactly zero
        for rel_dt in (1e-9, 1e-6):
            dt = min(rel_dt * max(span, self._timescale()), 0.5 * span)
            sd = self._C @ self.gait.at(t + dt)[1]
            rel = sd[group] - sd[group][0]
            if np.any(np.abs(rel) > 1e-13 * (np.max(np.abs(sd)) + 1e-300)):
                return False
        return True

    def _timescale(self) -> float:
        return self.gait.period if self.gait.period else (self.max_step or 1.0)

    def _solve_mode_one(self, j: int, force: float, epp: NDArray, contact: NDArray,
                        slack: float):
        """``_solve_mode`` when body j alone is at rest: the inclusion in plain floats.

        M A in force - dphi_j(A + e_j''): body j sticks (A = -e_j'') when the ground force it
        needs, M A - force with A = -e_j'', lies in [-f_plus_j, f_minus_j]; otherwise it slides
        the way that force points."""
        M = self._M
        fp, fm = float(self._fp[j]), float(self._fm[j])
        e2 = float(epp[j])
        need = -M * e2 - force                 # ground force on j if it sticks
        new = contact.copy()
        group = np.zeros(self._m.size, dtype=bool)
        acc_scale = max(max(map(abs, epp.tolist())), (self._f_total + abs(force)) / M, 1e-300)
        if need < -fp:                         # cannot hold it back: slides forward
            A = (force - fp) / M
            new[j] = 1
        elif need > fm:                        # cannot hold it forward: slides backward
            A = (force + fm) / M
            new[j] = -1
        else:
            A = -e2
            new[j] = 0
            group[j] = True
            f_scale = max(self._f_total, abs(force), M * acc_scale, 1e-300)
            ambiguous = fp + fm > 0 and min(need + fp, fm - need) <= slack * f_scale
            return new, A, j, group, bool(ambiguous)
        ambiguous = abs(A + e2) <= slack * acc_scale
        return new, A, -1, group, bool(ambiguous)

    def _solve_mode(self, ep: NDArray, epp: NDArray, contact: NDArray,
                    slack: float = _AMBIGUOUS, merge: bool = True):
        zero = self.zero
        fp, fm, M = self._fp, self._fm, self._M
        idx = zero.nonzero()[0]
        if idx.size == 1 and zero.size <= 8:
            # one body at rest (the common case): plain floats, summed in numpy's order
            j = int(idx[0])
            total = 0.0
            for i, (c, fpi, fmi) in enumerate(zip(contact.tolist(), self._fp_list,
                                                  self._fm_list)):
                if i != j:
                    total += -fpi if c > 0 else fmi
            return self._solve_mode_one(j, self._fext + total, epp, contact, slack)
        slide = ~zero
        R_slide = np.where(contact > 0, -fp, fm)[slide]
        force = self._fext + R_slide.sum()
        if idx.size == 1:
            return self._solve_mode_one(int(idx[0]), float(force), epp, contact, slack)
        acc_scale = max(float(np.max(np.abs(epp))), (fp.sum() + fm.sum() + abs(force)) / M,
                        1e-300)
        kinks = _merge_ties(-epp[zero], 1e-13 * acc_scale) if merge else -epp[zero]
        A, s = solve_inclusion(M, 0.0, force, kinks, fp[zero], fm[zero])
        rel = np.zeros_like(epp)
        rel[idx] = A - kinks                 # body accelerations (ties merged)
        new = contact.copy()
        at = kinks == A
        new[idx] = np.where(at, 0, np.sign(rel[idx])).astype(np.int8)
        ambiguous = bool(np.any(~at & (np.abs(rel[idx]) <= slack * acc_scale)))
        ref = -1
        group = np.zeros_like(zero)
        if at.any():
            group[idx[at]] = True
            ref = int(idx[at][0]) if not (self.ref >= 0 and group[self.ref]) else self.ref
            lo, hi = -fm[group].sum(), fp[group].sum()
            f_scale = max(fp.sum() + fm.sum(), abs(force), M * float(np.max(np.abs(epp))), 1e-300)
            if hi - lo > 0 and min(s - lo, hi - s) <= slack * f_scale:
                ambiguous = True
        return new, A, ref, group, ambiguous

    # ------------------------------------------------------------- integration
    def advance(self, t1: float, gait: Gait | None = None) -> None:
        """Integrate exactly to t1 with ``gait`` (default: the current one) valid on [t, t1]."""
        if gait is not None and gait is not self.gait:
            self._switch_gait(gait)
        t1 = float(t1)
        guard = 0
        T = self.gait.period if self.periodic_skip else None
        fast = self._compiled(self.gait)
        while self.t < t1:
            if fast and self._drive(t1, T):
                # the compiled loop made progress (and checks its own stalls)
                guard = 0
                continue
            t_stop = t1
            if T:
                k_next = math.floor(self.t / T * (1 + 4 * _EPS) + 4 * _EPS) + 1
                t_stop = min(t_stop, k_next * T)
            breaks = self.gait.breakpoints(self.t, t_stop)
            if breaks.size:
                t_stop = float(breaks[0])
            t_before = self.t
            self._segment(t_stop, left_limit=bool(breaks.size))
            # a degenerate mode loop: segments that advance by nothing or by a few floats
            # (events at adjacent floats that flip the mode back and forth) for longer than
            # any cascade of simultaneous events (at most a few per body) could last
            tiny = self.t - t_before <= _STALL_ULPS * _EPS * max(abs(self.t), 1.0)
            guard = guard + 1 if tiny else 0
            if guard > _STALL_SEGMENTS:
                raise RuntimeError(f'exact solver stalled at t = {self.t!r} s; '
                                   'report this scene (try method="implicit")')
            if T and self.t == t_stop and t_stop == k_next * T:
                self._period_boundary(k_next, T, t1)

    def _drive(self, t1: float, T: float | None) -> bool:
        """Run the compiled segment loop (``kernel.drive``) from t towards t1 (or the gait's next
        breakpoint); False when it made no progress: the next segment needs the Python path."""
        if type(self.gait) is Custom:
            from .callback import bridge
            b = bridge(self.gait)
            # the callback's state (bounds, stop flag) belongs to the gait, which solvers in
            # other threads may share: one call, with its checks, at a time
            with b.lock:
                return self._run_drive(t1, T, b)
        return self._run_drive(t1, T, None)

    def _run_drive(self, t1: float, T: float | None, bridge) -> bool:
        """``_drive`` with the Custom gait's ``callback.CustomBridge`` (None for the gaits the
        kernel evaluates itself)."""
        from . import kernel
        gait = self.gait
        cache = self._mode_cache
        if cache is not None and cache[3].sum() > 1:
            return False
        breaks = gait.breakpoints(self.t, t1)
        t_stop = float(breaks[0]) if breaks.size else t1
        custom = bridge is not None
        kind, freq, p1, p2 = bridge.coefficients if custom else kernel.coefficients(gait)
        mean = getattr(gait, 'mean', self._zeros_links)
        if custom:
            if bridge.retries > _RETRIES:
                return False     # bounds that keep growing: the Python search takes over
            # a stretch of similar bounds per call (``CustomBridge.prepare``)
            t_b, jerk, snap = bridge.prepare(self.t, t_stop)
            has_snap = True
        else:
            t_b = gait.block_end(self.t, t_stop)     # a stretch of similar bounds per call
            jerk = np.asarray(gait.jerk_bound(self.t, t_b), dtype=float)
            snap = gait.snap_bound(self.t, t_b)
            has_snap = snap is not None
            snap = np.asarray(snap, dtype=float) if has_snap else jerk
        left_limit = bool(breaks.size) and t_b == t_stop
        t_stop = t_b
        seg_f, seg_ref, seg_contact, seg_R, seg_K0, ev_t, ev_i, state = self._buffers
        ck_f, ck_K, ck_contact, ck_zero = self._ck
        ck = self._checkpoint
        ck_f[7] = 0.0
        if ck is None:
            ck_f[0] = -1.0
        else:
            ck_f[:5] = (ck[0], ck[2], ck[3], ck[5], ck[1][2])
            ck_K[:] = ck[4]
            ck_contact[:] = np.frombuffer(ck[1][0], dtype=np.int8)
            ck_zero[:] = np.frombuffer(ck[1][1], dtype=bool)
        # copies: the solver's arrays may be shared with kept segments
        K, contact, zero = self.K.copy(), self.contact.copy(), self.zero.copy()
        status = kernel.drive(
            self.t, t_stop, left_limit, t1, T or 0.0, self._timescale(), self.tol,
            self._cap(gait, self.t, t_stop),
            self.X, self.V, K, contact, zero, self.ref, self.x_ref, cache is not None,
            float(cache[1]) if cache is not None else 0.0,
            self._W, self._C, self._fp, self._fm, self._free, self._fext, self._M,
            self._f_total, self._v_acc, kind, freq, mean, p1, p2, jerk, snap, has_snap,
            ck_f, ck_K, ck_contact, ck_zero,
            seg_f, seg_ref, seg_contact, seg_R, seg_K0, ev_t, ev_i, state)
        n, n_ev = int(state[6]), int(state[10])
        self.n_evals += int(state[9])
        if custom:
            bridge.raise_error()
            if bridge.exceeded:
                bridge.grow()    # run the call again with the grown bounds, keeping nothing
                return True
            bridge.retries = 0
        n_kept, n_events = len(self.segments), len(self.events)
        self.K, self.contact, self.zero = K, contact, zero
        if n:
            self._store(n, n_ev)
        self.t, self.X, self.V, self.x_ref = (float(v) for v in state[:4])
        self.ref = int(state[4])
        if ck_f[7]:
            sig = (ck_contact.tobytes(), ck_zero.tobytes(), int(ck_f[4]))
            self._checkpoint = (int(ck_f[0]), sig, float(ck_f[1]), float(ck_f[2]), ck_K.copy(),
                                float(ck_f[3]),
                                n_kept + int(ck_f[5]) if self.keep_segments else 0,
                                n_events + int(ck_f[6]))
        if state[7]:
            g = np.zeros(self._m.size, dtype=bool)
            if self.ref >= 0:
                g[self.ref] = True
            self._mode_cache = (self.contact, float(state[8]), self.ref, g)
        elif n:
            self._mode_cache = None
        if status == kernel.PERIODIC:
            self._period_boundary(int(state[11]), T, t1)
        elif status == kernel.STALLED:
            raise RuntimeError(f'exact solver stalled at t = {self.t!r} s; '
                               'report this scene (try method="implicit")')
        elif status == kernel.NO_STEPS:
            raise RuntimeError(f'exact solver: the event search ran out of steps after '
                               f't = {self.t!r} s; report this scene (try method="implicit")')
        elif status == kernel.NONFINITE:
            check_finite_gait(gait._eval(np.array([self.t, t_stop])), [self.t, t_stop])
            raise ValueError('gait values must be finite')
        return status != kernel.NEED_PYTHON or n > 0

    def _store(self, n: int, n_ev: int) -> None:
        """Keep the compiled loop's first n segment records (as one ``SegmentChunk``, turned into
        ``Segment`` objects only when read) and its n_ev contact changes as events."""
        seg_f, seg_ref, seg_contact, seg_R, seg_K0, ev_t, ev_i, _ = self._buffers
        if n_ev:
            self.events.extend(map(_new_event, zip(ev_t[:n_ev].tolist(),
                                                   *ev_i[:n_ev].T.tolist())))
        chunk = SegmentChunk(self.gait, seg_f[:n].copy(), seg_ref[:n].copy(),
                             seg_contact[:n].copy(), seg_R[:n].copy(), seg_K0[:n].copy())
        self.n_segments += n
        if self.keep_segments:
            self.segments.extend_chunk(chunk)
        self.last = (chunk, n - 1)

    def _signature(self):
        return (self.contact.tobytes(), self.zero.tobytes(), self.ref)

    def _period_boundary(self, k: int, T: float, t1: float) -> None:
        """At t = k T: compare with the state one period earlier and skip repeated periods."""
        sig = self._signature()
        here = (k, sig, self.X, self.V, self.K.copy(), self.x_ref, len(self.segments),
                len(self.events))
        prev, self._checkpoint = self._checkpoint, here
        if prev is None or prev[0] != k - 1 or prev[1] != sig:
            return
        # Repeated to the solver's own accuracy: event times are known to ``tol`` seconds, so
        # velocities to about tol times the largest acceleration friction can produce.
        acc = self._v_acc
        v_tol = 16.0 * (self.tol * acc + _EPS * (abs(self.V) + abs(prev[3])))
        if self.ref < 0 and abs(self.V - prev[3]) > v_tol:
            return
        n = math.floor((t1 - self.t) / T * (1 + 4 * _EPS))
        if n < 1:
            return
        D = self.X - prev[2]
        dK = self.K - prev[4]
        new_events = self.events[prev[7]:]
        if self.keep_segments:
            template = [sg for sg in self.segments[prev[6]:] if isinstance(sg, Segment)]
            self.segments.append(PeriodicBlock(self.t, n, T, D, dK, template, (k - 1) * T))
        self.events.add_periodic(new_events, n, T)     # stored once (memory)
        self.X += n * D
        self.x_ref += n * D
        self.K = self.K + n * dK
        self.t = (k + n) * T
        self.n_skipped_periods += n
        self.last = None
        self._checkpoint = (k + n, sig, self.X, self.V, self.K.copy(), self.x_ref,
                            len(self.segments), len(self.events))

    def _switch_gait(self, gait: Gait) -> None:
        """Continue with a new gait: keep the bodies' positions, velocities and contact state."""
        self._checkpoint = None
        l0, ld0, ldd0 = self.gait.at(self.t)
        l1, ld1, ldd1 = gait.at(self.t)
        if not (l0.tolist() == l1.tolist() and ld0.tolist() == ld1.tolist()
                and ldd0.tolist() == ldd1.tolist()):
            self._mode_cache = None     # not a C2 continuation: choose the mode anew
        if self.ref < 0:
            # body 0 keeps its position and velocity
            self.X += float(self._W[0] @ (l0 - l1))
            self.V += float(self._W[0] @ (ld0 - ld1))
        self.gait = gait

    def _segment(self, t_stop: float, left_limit: bool = False) -> None:
        t0 = self.t
        l, ld, ldd = self.gait.at(t0)
        check_finite_gait((l, ld, ldd), t0)
        W = self._W
        e, ep, epp = W @ l, W @ ld, W @ ldd
        if self.ref >= 0:
            # Stuck reference body: exact velocity of the centre of mass from the gait.
            self.V = float(-ep[self.ref])
            self.X = float(self.x_ref - e[self.ref])
        # A sliding body whose velocity is zero or points against its contact sign (l' = 0
        # exactly at a breakpoint, or a jump of l' where the actuator settles to rest): the
        # contact sign comes from the actual velocity; only a body at zero velocity (to the
        # rounding of V + e_i') joins the zero set, where the inclusion chooses its mode from
        # the acceleration. (Sending a moving body to the inclusion can pick the sign opposite
        # to v: the segment then ends one float later on its velocity row, again and again;
        # taking the sign of a rounding residue, -4e-18 m/s for a body rigidly carried by a
        # stuck one, makes two such bodies trade places every float.)
        v = self.V + ep
        stale = ~self.zero & ~self._free & (self.contact * v <= 0.0)
        if stale.any():
            moving = stale & (np.abs(v) > 16.0 * _EPS * (abs(self.V) + np.abs(ep)))
            if moving.any():
                flipped = self.contact.copy()
                flipped[moving] = np.sign(v[moving])
                self._record_contact_change(t0, flipped)
            self.zero = self.zero | (stale & ~moving)
            self._mode_cache = None
        if self._mode_cache is not None:
            # the previous segment ended on a smooth boundary, not at an event: same mode
            contact, a, ref, group = self._mode_cache
        else:
            contact, a, ref, group = self._mode(t0, ep, epp, t_stop)
        self._mode_cache = None
        if ref >= 0:
            x_ref = self.x_ref if (self.ref == ref) else float(self.X + e[ref])
        else:
            x_ref = 0.0
            # bodies leaving zero velocity start exactly from zero
            leaving = self.zero & (contact != 0)
            if leaving.any():
                j = int(leaving.nonzero()[0][0])
                self.V = float(-ep[j])
        R = np.where(contact > 0, -self._fp, np.where(contact < 0, self._fm, 0.0))
        V0 = float(-ep[ref]) if ref >= 0 else self.V
        seg = Segment(t0, t_stop, self.gait, contact, R, self.K.copy(), self.X, V0, float(a),
                      ref, x_ref, group)
        self._record_contact_change(t0, contact)
        if ref >= 0 and group.all() and self.gait.is_constant(t0, t_stop):
            t_ev, hits = t_stop, []   # at rest under a constant command: nothing can happen
        else:
            t_ev, hits = self._find_event(seg, t_stop, left_limit)
            if hits and t_stop - t_ev <= 4.0 * self.tol:
                # an event within the root tolerance of a breakpoint happens at the breakpoint:
                # no sliver segment with the old piece's acceleration
                t_ev = t_stop
        seg.t1 = t_ev
        self._close(seg, t_ev, hits, left_limit)

    def provisional(self) -> Segment:
        """A zero-length segment at the current time with the mode the next segment would use."""
        t0 = self.t
        l, ld, ldd = self.gait.at(t0)
        W = self._W
        e, ep, epp = W @ l, W @ ld, W @ ldd
        X, V = self.X, self.V
        if self.ref >= 0:
            V = float(-ep[self.ref])
            X = float(self.x_ref - e[self.ref])
        contact, a, ref, group = self._mode(t0, ep, epp, t0)
        x_ref = self.x_ref if (ref >= 0 and ref == self.ref) else float(X + e[max(ref, 0)])
        if ref >= 0:
            V = float(-ep[ref])
        R = np.where(contact > 0, -self._fp, np.where(contact < 0, self._fm, 0.0))
        return Segment(t0, t0, self.gait, contact, R, self.K.copy(), X, V, float(a), ref, x_ref,
                       group)

    def current(self) -> dict:
        """The state at the current time as one output row (left limit at an event): the
        same closed form as ``Segment.evaluate``, for one time, in plain floats (a node calls
        it at every publish tick; numpy's per-call cost on arrays of p entries was 165 us)."""
        seg = self.last if (self.last is not None and self.last.t1 == self.t) else \
            self.provisional()
        t = self.t
        l, ld, ldd = (a.tolist() for a in seg.gait.at(t))
        p = len(self._m_list)
        W, C, m, M = self._W_rows, self._C_rows, self._m_list, self._M
        dot = _dot
        epp = [dot(W[i], ldd) for i in range(p)]
        d = t - seg.t0
        R = seg.R.tolist()
        K = seg.K0.tolist()
        if seg.ref < 0:
            X = seg.X0 + d * (seg.V0 + 0.5 * seg.a * d)
            V = seg.V0 + seg.a * d
            x = [X + dot(W[i], l) for i in range(p)]
            v = [V + dot(W[i], ld) for i in range(p)]
            A = seg.a
            K = [K[i] + R[i] * d for i in range(p)]
        else:
            r, g = seg.ref, seg.group.tolist()
            s = [dot(C[i], l) for i in range(p)]
            sd = [dot(C[i], ld) for i in range(p)]
            x = [seg.x_ref + (s[i] - s[r]) for i in range(p)]
            v = [sd[i] - sd[r] for i in range(p)]
            A = -epp[r]
            R = [0.0 if g[i] else R[i] for i in range(p)]
            f_slide = self._fext + sum(R)
            K = [K[i] + R[i] * d for i in range(p)]
            # the group's friction and impulse: the affine split of ``split_friction`` and
            # ``_split_impulse`` (each body at the same fraction of its own interval)
            fp = [self._fp_list[i] for i in range(p) if g[i]]
            fm = [self._fm_list[i] for i in range(p) if g[i]]
            w = sum(fp) + sum(fm)
            members = [i for i in range(p) if g[i]]
            if w > 0:
                theta = min(max((f_slide - M * A + sum(fm)) / w, 0.0), 1.0)
                imp = M * (-dot(W[r], ld) - seg.V0) - f_slide * d
                q = (-imp + sum(fm) * d) / w
                for i, fpi, fmi in zip(members, fp, fm):
                    R[i] = fmi - theta * (fpi + fmi)
                    K[i] += fmi * d - q * (fpi + fmi)
            else:
                for i in members:
                    R[i] = 0.0
        contact = seg.contact.copy()
        for i in self._free_idx:         # no friction, no stick: the sign of the velocity
            contact[i] = (v[i] > 0) - (v[i] < 0)
        lam, acc = [], 0.0
        for i in range(p - 1):
            acc += R[i] + self._g_list[i] - m[i] * (A + epp[i])
            lam.append(acc)
        return {'x': np.array(x), 'v': np.array(v), 'friction': np.array(R),
                'impulse': np.array(K), 'linkage_force': np.array(lam),
                'lengths': np.array(l), 'rates': np.array(ld), 'contact': contact,
                'indeterminate': bool(seg.ref >= 0 and sum(g) > 1)}

    def _record_contact_change(self, t: float, contact: NDArray) -> None:
        old = self.contact
        for i in (contact != old).nonzero()[0]:
            self.events.append(Event(float(t), int(i), int(old[i]), int(contact[i])))
        self.contact = contact

    def _close(self, seg: Segment, t_ev: float, hits: list[tuple[str, int]],
               left_limit: bool = False) -> None:
        """Move the state to the end of ``seg`` and mark bodies now at zero velocity."""
        d = t_ev - seg.t0
        if seg.ref < 0:
            self.X = seg.X0 + d * (seg.V0 + 0.5 * seg.a * d)
            self.V = seg.V0 + seg.a * d
            self.K = seg.K0 + seg.R * d
            zero = np.zeros(self._m.size, bool)
        else:
            l, ld, _ = self.gait.at(t_ev)
            self.V = float(-(self._W[seg.ref] @ ld))
            self.X = float(seg.x_ref - self._W[seg.ref] @ l)
            g = seg.group
            K = seg.K0 + np.where(g, 0.0, seg.R) * d
            f_slide = self._fext + float(seg.R[~g].sum())
            imp = self._M * (self.V - seg.V0) - f_slide * d
            fp, fm = self._fp[g], self._fm[g]
            w = (fp + fm).sum()
            if w > 0:     # _split_impulse for one time, without building arrays
                K[g] += fm * d - ((-imp + fm.sum() * d) / w) * (fp + fm)
            self.K = K
            zero = g.copy()
        for kind, i in hits:
            if kind == 'vel':
                zero[i] = True
                if seg.ref < 0:
                    # the body's velocity is exactly zero at the event
                    self.V = (-(float(self._W[i, 0]) * self.gait.at1(t_ev)[1])
                              if self._m.size == 2
                              else float(-(self._W[i] @ self.gait.at(t_ev)[1])))
        self.zero = zero
        self.ref = seg.ref
        self.x_ref = seg.x_ref
        if not hits and not left_limit:
            # ended on a smooth boundary: the next segment starts in the same mode unless the
            # gait switch there is not C2 (``_switch_gait`` drops this)
            self._mode_cache = (seg.contact, seg.a, seg.ref, seg.group)
        self.t = t_ev
        self.n_segments += 1
        self.last = seg
        if self.keep_segments:
            self.segments.append(seg)

    # ------------------------------------------------------------ event search
    def _rows(self, seg: Segment) -> tuple[Rows, list[tuple[str, int]]]:
        """The segment's event rows (``events.Rows``) and their labels; each row is positive
        while the mode stays valid (MODEL.md s. 2.4):

        ``vel`` i: sigma_i v_i of a sliding body (all slide: V0 + a (t - t0) + W_i l'; a body
        r sticks: (C_i - C_r) l'); ``force`` r: the stuck group's required ground force minus
        its lower bound, and its upper bound minus that force; ``rigid`` j: +-(C_j - C_r) l'
        for the other members of a group stuck together (zero while the link is rigid).
        """
        n = self._m.size
        nl = n - 1
        c0, c1, A1, A2, labels = [], [], [], [], []
        zero = np.zeros(nl)

        def add(label, a0, a1, r1, r2):
            labels.append(label)
            c0.append(a0)
            c1.append(a1)
            A1.append(r1)
            A2.append(r2)
        if seg.ref < 0:
            for i in range(n):
                if not self._free[i]:
                    sg = float(seg.contact[i])
                    add(('vel', i), sg * seg.V0, sg * seg.a, sg * self._W[i], zero)
        else:
            r, g = seg.ref, seg.group
            for i in range(n):
                if not g[i] and not self._free[i]:
                    sg = float(seg.contact[i])
                    add(('vel', i), 0.0, 0.0, sg * (self._C[i] - self._C[r]), zero)
            f_slide = self._fext + float(seg.R[~g].sum())
            lo, hi = -float(self._fp[g].sum()), float(self._fm[g].sum())
            # the ground force the group needs: total = -M W_r l'' - f_slide
            add(('force', r), -f_slide - lo, 0.0, zero, -self._M * self._W[r])
            add(('force', r), hi + f_slide, 0.0, zero, self._M * self._W[r])
            for j in g.nonzero()[0]:
                if j != r:
                    rel = self._C[j] - self._C[r]
                    add(('rigid', int(j)), 0.0, 0.0, rel, zero)
                    add(('rigid', int(j)), 0.0, 0.0, -rel, zero)
        if not labels:
            return None, labels
        return Rows(seg.t0, np.array(c0), np.array(c1), np.array(A1), np.array(A2)), labels

    def _cap(self, gait: Gait, t0: float, t_stop: float) -> float:
        """Largest grid step: the user's max_step, the gait's, period / 8, or the span / 8
        (only the cost depends on it, except for gaits without derivative bounds)."""
        cands = [self.max_step, getattr(gait, 'max_step', None),
                 gait.period / 8.0 if gait.period else None]
        cands = [c for c in cands if c is not None]
        return min(cands) if cands else max((t_stop - t0) / 8.0, 1e-300)

    def _find_event(self, seg: Segment, t_stop: float,
                    left_limit: bool = False) -> tuple[float, list[tuple[str, int]]]:
        """First event in (t0, t_stop] (see ``events``): its time and labels, or (t_stop, [])."""
        rows, labels = self._rows(seg)
        if rows is None:
            return t_stop, []
        cap = self._cap(seg.gait, seg.t0, t_stop)
        if self.use_kernel and type(seg.gait) in _COMPILED:
            from . import kernel      # imports numba: only when a trigonometric gait runs
            # trigonometric gait: the same search compiled, the gait evaluated inside
            end = float(np.nextafter(t_stop, -math.inf)) if left_limit else t_stop
            if end <= seg.t0:
                return t_stop, []
            b2, b1 = rows.bounds(seg.gait, seg.t0, t_stop)
            t_ev, hit, n_eval = kernel.search(seg.t0, end, rows, kernel.coefficients(seg.gait),
                                              b2, b1, self.tol, cap)
            self.n_evals += n_eval
            if t_ev == -2.0:
                raise RuntimeError(f'exact solver: the event search ran out of steps on '
                                   f'[{seg.t0!r}, {end!r}] s; report this scene (try '
                                   'method="implicit")')
            if t_ev < 0.0:
                check_finite_gait(seg.gait._eval(np.array([seg.t0, end])), [seg.t0, end])
                raise ValueError('gait values must be finite')
            if not math.isfinite(t_ev):
                return t_stop, []
            if t_ev >= end and end < t_stop:
                t_ev = t_stop     # the left limit at a breakpoint: the event is the breakpoint
            return t_ev, sorted({labels[k] for k in np.nonzero(hit)[0].tolist()})
        est = None
        for _ in range(16):
            search = Search(seg.gait, rows, self.tol, cap)
            h0 = None
            if not search.known:
                h0 = cap / 64.0
                if est is not None:
                    search.est = est
            t_ev, hit = search.run(t_stop, left_limit, h0)
            self.n_evals += search.n_eval
            if search.estimate_grew():
                est = search.est     # an estimated bound proved too small: redo with it
                continue
            if search.known or self._end_consistent(search, hit, t_stop, left_limit):
                break
            # estimated bounds: a row that ends below zero without being reported was
            # crossed between two samples; redo with 64 times the estimate
            est = 64.0 * np.maximum(search.est, search.used)
        else:
            raise RuntimeError(f'exact solver: no consistent event on [{seg.t0!r}, {t_stop!r}] s '
                               'with estimated gait bounds; give the Custom gait jerk_bound= '
                               'or max_step=')
        if hit is None:
            return t_stop, []
        return t_ev, sorted({labels[k] for k in hit.tolist()})

    @staticmethod
    def _end_consistent(search: Search, hit, t_stop: float, left_limit: bool) -> bool:
        """The end-of-segment check: a segment that ends without an event has every row above
        minus its noise level at its end (else an event was crossed between two samples).
        (At an event, rows crossing within ``tol`` of it may sit just below zero: not checked.)"""
        if hit is not None:
            return True
        end = float(np.nextafter(t_stop, -math.inf)) if left_limit else t_stop
        return bool((search._eval(np.array([end]))[0] >= -search._noise).all())

    # ---------------------------------------------------------------- output
    def sample(self, times: NDArray[np.float64]) -> dict:
        """Exact states at ``times`` (sorted, within the integrated span) from kept segments.

        Times inside a ``PeriodicBlock`` are mapped onto its template period and shifted; the
        segments' constants are gathered from their table (``SegmentList.records``), so no
        ``Segment`` object is built for the compiled loop's segments.
        """
        segs = self.segments
        n_t = times.size
        table, row_of = segs.records()
        idx = np.searchsorted(segs.starts(), times, side='right') - 1
        np.clip(idx, 0, len(segs) - 1, out=idx)
        owner = row_of[idx]
        local = np.array(times, dtype=float)
        blocks = (owner < 0).nonzero()[0]
        if not blocks.size:       # no skipped period among the sampled times
            return evaluate_records(self.crawler, table, owner, local, (self._C, self._W))
        shift_x = np.zeros(n_t)
        shift_k = np.zeros((n_t, self._m.size))
        parts, n_rows = [table], table.ref.size
        for k in np.unique(idx[blocks]).tolist():
            sel = (idx == k).nonzero()[0]
            piece = segs[k]
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
        out = evaluate_records(self.crawler, Records.concat(parts), owner, local,
                               (self._C, self._W))
        out['x'] += shift_x[:, None]
        out['impulse'] += shift_k
        return out
