"""Method "implicit": Moreau-Jean (catching-up) time stepping, MODEL.md section 3.

One step of size h solves exactly, in O(p log p),

    V_{k+1} = argmin_V  M/(2h) (V - V_k)^2 - F_ext V + sum_i phi_i(V + e_i'(t_{k+1})),

then X_{k+1} = X_k + h V_{k+1}. Unconditionally stable, and a stuck body has exactly zero
velocity. A step in which the contact mode changes is split where the transition happens
(located to about 1e-12 of the step from the instantaneous mode), so the method converges at
order 1 with a steady constant: the error of X is about (h / 2) (V(t) - V(0)).

With stiction (``crawler.has_stiction``: a static bound above its kinetic one) the step is no
longer a convex minimisation: the mode is continued in closed form and, where it stops holding
inside the step, the next one is selected by Rule S (``core.friction``; the incumbent cluster
with its static bounds, then the arriving clusters, then the kinetic slide pattern; the
``stiction_rule`` option decides a coincident rest; ``initial_stuck`` names the incumbent at
t0). The incumbent is the cluster stuck on the piece before an instant, carried in the contact
state across steps and calls; a body whose velocity only passes through zero at a step end is
an arrival (STICTION.md s. 9). Order 1 as without stiction. Without stiction the crawler runs
the kinetic path unchanged, bit for bit.

Every gait and every p run in the compiled loop (``_stepping``); ``TimeStepper`` is the Python
side shared with method "penalty". A run is limited to ``MAX_STEPS`` steps per ``advance`` (and
per ``simulate``): a smaller dt or a longer interval raises ValueError naming dt and the allowed
range instead of running for ever. ``ImplicitBatch`` advances B crawlers with the same p at
once (plain Moreau-Jean steps).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..friction import DEFAULT_RULE, RULES, bounds, check_rule
from ..gaits import Gait
from ..model import Crawler
from ..trajectory import Event
from . import _stepping
from .base import Capabilities, register

__all__ = ['ImplicitSolver', 'ImplicitBatch', 'TimeStepper', 'MAX_STEPS', 'MAX_ROWS',
           'check_steps', 'step_times', 'output_arrays']

#: the most steps one ``advance`` (or one ``simulate``) may take: 1e9 steps is about 2 minutes
MAX_STEPS = 10 ** 9
#: the most output rows of a default (every step) output; longer runs keep this many rows
MAX_ROWS = 2 * 10 ** 6


def check_steps(span: float, dt: float, what: str = 't_end') -> None:
    """Raise ValueError if covering ``span`` [s] with steps ``dt`` [s] needs more than
    MAX_STEPS steps."""
    n = span / dt
    if not n <= MAX_STEPS:      # also catches inf / nan
        raise ValueError(f'dt = {dt!r} s and {what} = {span!r} s need {n:.3g} steps; at most '
                         f'{MAX_STEPS:.0e} are allowed: dt must be >= {what} / {MAX_STEPS:.0e} '
                         f'(= {span / MAX_STEPS:.3g} s) or {what} <= dt * {MAX_STEPS:.0e} '
                         f'(= {dt * MAX_STEPS:.3g} s)')


def step_times(t_end: float, dt: float) -> NDArray[np.float64]:
    """The step ends of a run of steps ``dt`` from 0 to t_end (the last one shortened to land
    on t_end), with 0 first: the default output of the fixed-step methods. Beyond
    ``MAX_ROWS`` steps, ``MAX_ROWS`` evenly spaced times (the steps land on them)."""
    n = t_end / dt
    if n > MAX_ROWS:
        return np.linspace(0.0, t_end, MAX_ROWS + 1)
    # the step ends k dt < t_end, k = 0 .. m - 1 (float(k) * dt, as the steps compute them);
    # only the last few can reach t_end through rounding, so they alone are checked
    m = math.floor(n) + 1
    while m > 1 and (m - 1) * dt >= t_end:
        m -= 1
    if m > 1 and (t_end - (m - 1) * dt) / dt <= 1e-9:
        m -= 1                        # a sliver of a step: the last step lands on t_end
    times = np.arange(m + 1, dtype=np.float64)
    times[:m] *= dt
    times[m] = t_end
    return times


#: the output arrays of a run: name -> (columns, with p bodies: 'p', 'p-1' or None, dtype)
_OUTPUTS = (('x', 'p', np.float64), ('v', 'p', np.float64), ('friction', 'p', np.float64),
            ('impulse', 'p', np.float64), ('linkage_force', 'p-1', np.float64),
            ('lengths', 'p-1', np.float64), ('rates', 'p-1', np.float64),
            ('contact', 'p', np.int8), ('indeterminate', None, np.bool_))


def output_arrays(n: int, p: int) -> dict[str, NDArray]:
    """Uninitialised output arrays for ``n`` rows of ``p`` bodies, carved from ONE buffer.

    Why one buffer: a run's outputs are written once, row by row, and first-touch page faults
    of fresh memory cost as much as the steps that fill them (200,000 two-body rows: 18 MB,
    about 6 ms of faults against 14 ms of steps). One large block (rather than nine arrays of a
    few MB, each mapped and unmapped by the allocator) moves the allocator's mmap threshold
    above it once it is freed, so the next run's outputs reuse memory already touched. The
    arrays are views: keeping one keeps the block.
    """
    shapes = [((n, p if cols == 'p' else p - 1) if cols else (n,), np.dtype(dt))
              for _, cols, dt in _OUTPUTS]
    sizes = [int(np.prod(shape)) * dt.itemsize for shape, dt in shapes]
    buf = np.empty(sum(sizes), np.uint8)
    out, start = {}, 0
    for (name, _, _), (shape, dt), size in zip(_OUTPUTS, shapes, sizes):
        out[name] = buf[start:start + size].view(dt).reshape(shape)
        start += size
    return out


class TimeStepper:
    """Python side of the fixed-step methods: state, events, outputs; the steps are compiled
    (``_stepping.StepCore``)."""

    _method = _stepping.IMPLICIT

    def __init__(self, crawler: Crawler, gait: Gait, *, dt: float, t0: float = 0.0,
                 x0: float = 0.0, v0: float = 0.0, penalty: NDArray | None = None,
                 max_depth: int = _stepping.MAX_DEPTH, stiction_rule: str = DEFAULT_RULE,
                 initial_stuck: int | None = None) -> None:
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f'dt must be a finite step > 0 s, got {dt!r}')
        self.crawler = crawler
        self.gait = gait
        self._cg = gait.compiled()
        self.dt = float(dt)
        self.stiction_rule = check_rule(stiction_rule)
        self.initial_stuck = initial_stuck
        b = bounds(crawler)
        # the static bounds reach the compiled step only when they differ from the kinetic
        # ones: it then takes the Rule S path (``_stepping.st_step``), else the convex one
        self._core = _stepping.StepCore(crawler.masses, b.kinetic_forward, b.kinetic_backward,
                                        float(crawler.external_force), crawler.gravity_forces,
                                        self.dt, self._method, max_depth, penalty,
                                        b.static_forward, b.static_backward,
                                        RULES.index(self.stiction_rule))
        self.status, self.message = 'ok', ''
        self._scan_scale()
        self.reset(t0=t0, x0=x0, v0=v0, initial_stuck=initial_stuck)

    def _scan_scale(self) -> None:
        # a step holding a transition is scanned at 1/64 of the gait's period at least (a step
        # longer than the period must not step over a stick inside it)
        self._core.scan_step = self.gait.period / 64.0 if self.gait.period else math.inf

    t = property(lambda self: self._core.t)
    X = property(lambda self: self._core.X)
    V = property(lambda self: self._core.V)
    A = property(lambda self: self._core.A)
    contact = property(lambda self: self._core.contact_array)
    R = property(lambda self: self._core.R_array)
    K = property(lambda self: self._core.K_array)
    n_steps = property(lambda self: self._core.n_steps)

    def reset(self, *, t0: float = 0.0, x0: float = 0.0, v0: float = 0.0,
              initial_stuck: int | None = None) -> None:
        """Back to t0 with body 0 at x0 [m] moving at v0 [m/s] (events cleared); with
        stiction, the cluster of body ``initial_stuck`` (at rest at t0, checked by ``Stepper``)
        counts as stuck just before t0 (None: no incumbent, Rule S chooses by margin)."""
        stuck = -1 if initial_stuck is None else int(initial_stuck)
        if self._core.reset(self._cg, float(t0), float(x0), float(v0),
                            stuck) != _stepping.REACHED:
            self._nonfinite()
        self.events: list[Event] = []

    def _use(self, gait: Gait | None) -> None:
        if gait is not None and gait is not self.gait:
            self.gait = gait
            self._cg = gait.compiled()
            self._scan_scale()

    def _drain(self) -> None:
        c = self._core
        n = c.n_ev
        if n:
            self.events.extend(Event(float(t), int(b), int(o), int(w)) for t, b, o, w in zip(
                c.ev_t[:n].tolist(), c.ev_b[:n].tolist(), c.ev_o[:n].tolist(),
                c.ev_n[:n].tolist()))
        c.n_ev = 0

    def _nonfinite(self) -> None:
        t = self._core.bad_time
        self.status = 'failed'
        self.message = (f'method {self.method_name}: non-finite gait value or state at t = '
                        f'{t!r} s (check the gait and the crawler)')
        raise ValueError(self.message)

    method_name = 'implicit'

    def advance(self, t1: float, gait: Gait | None = None) -> None:
        """Step to t1 [s] with ``gait`` valid on [t, t1]; the last step lands on t1."""
        self._use(gait)
        t1 = float(t1)
        if not t1 > self.t:
            return
        check_steps(t1 - self.t, self.dt, '(t1 - t)')
        self.status, self.message = 'ok', ''
        while True:
            with self._cg.lock:
                self._cg.span_lo, self._cg.span_hi = self.t, t1
                status = self._core.advance(self._cg, t1)
            self._drain()
            if status == _stepping.NONFINITE:
                self._nonfinite()
            if status == _stepping.REACHED:
                return

    def current(self) -> dict:
        """The state at self.t as one row of output arrays, with ``incumbent`` (p,) bool: the
        bodies stuck on the last piece before t (at t0: the reset's incumbent)."""
        row = self._core.row(self._cg)
        row['incumbent'] = (self._core.incumbent0 if self._core.n_steps == 0
                            else row['contact'] == 0)
        return row

    def run(self, times: NDArray[np.float64]) -> dict:
        """Step through the sorted ``times`` (>= t) and return the output rows there."""
        out = output_arrays(times.size, self.crawler.p)
        times = np.ascontiguousarray(times, dtype=float)
        k = 0
        while True:
            with self._cg.lock:
                self._cg.span_lo = self.t
                self._cg.span_hi = float(times[-1]) if times.size else self.t
                status, k = self._core.run(
                    self._cg, times, k, out['x'], out['v'], out['friction'], out['impulse'],
                    out['linkage_force'], out['lengths'], out['rates'], out['contact'],
                    out['indeterminate'])
            self._drain()
            if status == _stepping.NONFINITE:
                self._nonfinite()
            if status == _stepping.REACHED:
                return out

    # ------------------------------------------------------------------ solver contract
    @classmethod
    def options(cls, *, dt: float | None = None, penalty: float | None = None,
                **_ignored: Any) -> dict:
        from ..gaits import _positive
        return {'dt': 1e-3 if dt is None else _positive('dt', dt, 's')}

    @staticmethod
    def check_span(gait: Gait, t_end: float, options: dict) -> None:
        check_steps(t_end, options['dt'])     # never run for ever

    def default_times(self, t_end: float) -> NDArray[np.float64]:
        return step_times(t_end, self.dt)

    def simulate(self, t_end: float, times: NDArray | None, include_events: bool,
                 dt: float | None = None) -> tuple:
        """(times, outputs, info) of a whole run on [t, t_end] (``stepper.simulate``)."""
        times = self.default_times(t_end) if times is None else times
        return times, self.run(times), self.info(times)

    def info(self, times: NDArray[np.float64]) -> dict:
        out = {'steps': self.n_steps, 'dt': self.dt}
        if self._core.stiction:
            # instants where Rule S had more than one consistent continuation to choose from
            out['stiction_rule'] = self.stiction_rule
            out['choices'] = self._core.n_choices
            out['choice_times'] = np.array(self._core.choice_t)
        return out


@register('implicit')
class ImplicitSolver(TimeStepper):
    """Moreau-Jean stepping for one crawler, transitions placed inside their step.

    ``locate_transitions=False`` gives the plain Moreau-Jean step (transitions at step ends,
    what ``ImplicitBatch`` does): first order too, but with an erratic constant.
    """

    capabilities = Capabilities(fixed_step=True, streaming=True, stiction=True)

    def __init__(self, crawler: Crawler, gait: Gait, *, dt: float, t0: float = 0.0,
                 x0: float = 0.0, v0: float = 0.0, locate_transitions: bool = True,
                 stiction_rule: str = DEFAULT_RULE, initial_stuck: int | None = None) -> None:
        super().__init__(crawler, gait, dt=dt, t0=t0, x0=x0, v0=v0,
                         max_depth=_stepping.MAX_DEPTH if locate_transitions else 0,
                         stiction_rule=stiction_rule, initial_stuck=initial_stuck)

    @classmethod
    def options(cls, *, dt: float | None = None, stiction_rule: str = DEFAULT_RULE,
                initial_stuck: int | None = None, **_ignored: Any) -> dict:
        """``dt``, and Rule S's ``stiction_rule`` and ``initial_stuck`` (``Stepper`` checks
        the body is at rest); both change nothing without stiction."""
        out = super().options(dt=dt)
        out['stiction_rule'] = check_rule(stiction_rule)
        out['initial_stuck'] = initial_stuck
        return out


class ImplicitBatch:
    """Moreau-Jean stepping of B crawlers with the same number of bodies p, vectorised.

    Parameters
    ----------
    masses, friction : array_like, shape (B, p) (or (p,), broadcast)
        Masses [kg] (> 0) and forward friction forces [N] (>= 0).
    friction_backward : array_like, shape (B, p), optional
        Backward friction [N]; default equal to ``friction``.
    slope : float or array_like (B,)
        Inclination [rad]; gravity [m/s^2].

    State: ``X`` (B,) centre of mass [m], ``V`` (B,) its velocity [m/s], ``t`` [s].
    ``step(h, rates)`` takes the linkage rates l'(t + h), shape (p-1,) shared or (B, p-1).
    Body velocities are ``V + e'``; ``body_velocities(rates)`` returns them.
    """

    def __init__(self, masses: ArrayLike, friction: ArrayLike,
                 friction_backward: ArrayLike | None = None, slope: ArrayLike = 0.0,
                 gravity: float = 9.81, *, batch: int | None = None) -> None:
        m = np.asarray(masses, dtype=float)
        f = np.asarray(friction, dtype=float)
        if m.ndim == 1:
            m = np.broadcast_to(m, (batch or 1, m.size))
        B, p = m.shape
        if p < 2:
            raise ValueError(f'masses must have p >= 2 columns, got {p}')
        if not np.all(np.isfinite(m) & (m > 0)):
            raise ValueError('masses must be finite and > 0')
        f = np.broadcast_to(f, (B, p)).astype(float)
        fb = f if friction_backward is None else np.broadcast_to(
            np.asarray(friction_backward, dtype=float), (B, p)).astype(float)
        for name, arr in (('friction', f), ('friction_backward', fb)):
            if not np.all(np.isfinite(arr) & (arr >= 0)):
                raise ValueError(f'{name} must be finite and >= 0')
        slope = np.broadcast_to(np.asarray(slope, dtype=float), (B,))
        self.masses = np.ascontiguousarray(m)
        self.M = self.masses.sum(axis=1)
        self._w = np.ascontiguousarray(self.masses / self.M[:, None])
        self.f_plus = np.ascontiguousarray(f)
        self.f_minus = np.ascontiguousarray(fb)
        self.F_ext = np.ascontiguousarray(-self.M * gravity * np.sin(slope))
        self.B, self.p = B, p
        self.X = np.zeros(B)
        self.V = np.zeros(B)
        self.t = 0.0

    def _ep(self, rates: NDArray) -> NDArray:
        rates = np.asarray(rates, dtype=float)
        s = np.zeros((self.B, self.p)) if rates.ndim == 2 else np.zeros(self.p)
        np.cumsum(rates, axis=-1, out=s[..., 1:])
        if s.ndim == 1:
            return s[None, :] - (self._w @ s)[:, None]
        return s - np.einsum('bp,bp->b', self._w, s)[:, None]

    def body_velocities(self, rates: ArrayLike) -> NDArray:
        """Velocities of the bodies (B, p) [m/s] given the linkage rates at the current time."""
        return self.V[:, None] + self._ep(rates)

    def step(self, h: float, rates: ArrayLike) -> None:
        """Advance every crawler by h [s]; ``rates`` are l'(t + h), shape (p-1,) or (B, p-1)."""
        r = np.asarray(rates, dtype=float)
        if r.shape not in ((self.p - 1,), (self.B, self.p - 1)):
            raise ValueError(f'rates must have shape ({self.p - 1},) or ({self.B}, '
                             f'{self.p - 1}), got {r.shape}')
        _stepping.batch_step(float(h), np.ascontiguousarray(r.reshape(-1, self.p - 1)),
                             self._w, self.M, self.V, self.X, self.F_ext, self.f_plus,
                             self.f_minus)
        self.t += h
