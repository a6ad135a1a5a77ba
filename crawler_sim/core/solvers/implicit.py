"""Method "implicit": Moreau-Jean (catching-up) time stepping, MODEL.md section 3.

One step of size h solves exactly, in O(p log p),

    V_{k+1} = argmin_V  M/(2h) (V - V_k)^2 - F_ext V + sum_i phi_i(V + e_i'(t_{k+1})),

then X_{k+1} = X_k + h V_{k+1}. Unconditionally stable, and a stuck body has exactly zero
velocity. A step in which the contact mode changes is split where the transition happens
(located to about 1e-12 of the step from the instantaneous mode, see ``implicit_kernel``), so
the method converges at order 1 with a steady constant: the error of X is about
(h / 2) (V(t) - V(0)). ``Fourier`` and ``Sinusoid`` gaits run in a compiled kernel (numba,
cached on disk; ``warm_up()`` loads or builds it outside a real-time loop); other gaits
(``Custom``, piecewise) are evaluated by numpy (or their callables) for a chunk of step ends and
stepped in the kernel. A step with a transition inside, and advances of a few steps (a node's
tick), take the Python path: the kernel's own source run by the interpreter, which imports no
numba and compiles nothing; the tests compare it with the compiled kernel.

A run is limited to ``MAX_STEPS`` steps per ``advance`` (and per ``simulate``): a smaller dt or a
longer interval raises ValueError naming dt and the allowed range instead of running for ever.
``ImplicitBatch`` advances B crawlers with the same p at once (plain Moreau-Jean steps).

(About 500 lines: the shared fixed-step loop, the single-crawler solver with its three paths,
and the batch stepper belong together; the compiled parts are in ``implicit_kernel``.)
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..gaits import Fourier, Gait, Sinusoid
from ..model import Crawler, kinematics
from ..trajectory import Event

__all__ = ['ImplicitSolver', 'ImplicitBatch', 'TimeStepper', 'MAX_STEPS', 'check_steps',
           'warm_up']

#: the most steps one ``advance`` (or one ``simulate``) may take: 1e9 steps is about 2 minutes
#: in the kernel and hours in Python
MAX_STEPS = 10 ** 9


def _interpreted_kernel():
    """``implicit_kernel`` run by the interpreter (no numba import, nothing to compile): the
    Python path's helpers, and the reference the compiled kernel is tested against."""
    path = Path(__file__).with_name('implicit_kernel.py')
    spec = importlib.util.spec_from_file_location(__package__ + '._implicit_interpreted', path)
    mod = importlib.util.module_from_spec(spec)
    mod.INTERPRETED = True
    spec.loader.exec_module(mod)
    return mod


#: the interpreted helpers (the Python path: node ticks, Custom gaits step by step)
_py = _interpreted_kernel()
#: the compiled kernel, imported on first use: importing numba takes about a second and
#: compiling (first run on a machine) tens of seconds, which only the kernel paths pay
kern = None


def _load_kernel():
    global kern
    if kern is None:
        from . import implicit_kernel
        kern = implicit_kernel
    return kern


def check_steps(span: float, dt: float, what: str = 't_end') -> None:
    """Raise ValueError if covering ``span`` [s] with steps ``dt`` [s] needs more than
    MAX_STEPS steps."""
    n = span / dt
    if not n <= MAX_STEPS:      # also catches inf / nan
        raise ValueError(f'dt = {dt!r} s and {what} = {span!r} s need {n:.3g} steps; at most '
                         f'{MAX_STEPS:.0e} are allowed: dt must be >= {what} / {MAX_STEPS:.0e} '
                         f'(= {span / MAX_STEPS:.3g} s) or {what} <= dt * {MAX_STEPS:.0e} '
                         f'(= {dt * MAX_STEPS:.3g} s)')


def _finite_gait(vals, t: float) -> None:
    # one test for the common case: a sum is finite only if every term is
    if math.isfinite(float(np.sum(vals[0]) + np.sum(vals[1]) + np.sum(vals[2]))):
        return
    for name, arr in zip(('length', 'velocity', 'acceleration'), vals):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f'gait {name} must be finite, got {np.asarray(arr).tolist()} at '
                             f't = {t!r} s')


def fourier_form(gait: Gait) -> tuple[float, NDArray, NDArray] | None:
    """(frequency [Hz], cos (n, K), sin (n, K)) of a gait the kernel evaluates, else None."""
    if type(gait) is Fourier:
        return gait.frequency, np.ascontiguousarray(gait.cos), np.ascontiguousarray(gait.sin)
    if type(gait) is Sinusoid:
        # a sin(w t + phi) = (a sin phi) cos w t + (a cos phi) sin w t
        a, ph = gait.amplitude, gait.phase
        return (gait.frequency, np.ascontiguousarray((a * np.sin(ph))[:, None]),
                np.ascontiguousarray((a * np.cos(ph))[:, None]))
    return None


def warm_up() -> None:
    """Import numba and load (or compile, the first time on a machine: tens of seconds) the
    compiled kernels: ``advance_fourier``, ``advance_table`` and ``batch_step``. A node's ticks
    (a few steps each) take the interpreted path and never need them; call this at start where
    long advances or ``simulate`` runs follow (about 1-2 s with a warm cache; then nothing
    compiles in the loop). Safe to call more than once."""
    from ..gaits import Cubic
    c = Crawler([1.0, 1.0], [0.5, 1.0])
    for g in (Fourier(1.0, ([0.0], [0.1]), 1.0), Cubic(0.0, [1.0], [0.5], [0.0], [-3.0])):
        for use_kernel in (True, False):
            ImplicitSolver(c, g, dt=0.05, use_kernel=use_kernel).advance(1.0)
    b = ImplicitBatch([1.0, 1.0], [0.5, 1.0])
    b.step(0.01, [0.1])


class TimeStepper:
    """Shared loop of the fixed-step methods: steps of ``dt`` that land exactly on t1.

    Subclasses implement ``_velocity(h, ep)`` returning (V_new, R, contact) for one step, or
    override ``_step``.
    """

    def __init__(self, crawler: Crawler, gait: Gait, *, dt: float, t0: float = 0.0,
                 x0: float = 0.0, v0: float = 0.0) -> None:
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f'dt must be a finite step > 0 s, got {dt!r}')
        self.crawler = crawler
        self.gait = gait
        self.dt = float(dt)
        self._m = crawler.masses
        self._M = float(crawler.masses.sum())
        self._w = np.ascontiguousarray(crawler.masses / self._M)
        self._fp = np.ascontiguousarray(crawler.friction, dtype=float)
        self._fm = np.ascontiguousarray(crawler.friction_backward, dtype=float)
        self._fext = float(crawler.external_force)
        p = crawler.p
        self._scratch = (np.empty(p, np.bool_), np.empty(p), np.empty(p), np.empty(p),
                         np.empty(p, np.int64), np.empty(p, np.int8))
        self.reset(t0=t0, x0=x0, v0=v0)

    def reset(self, *, t0: float = 0.0, x0: float = 0.0, v0: float = 0.0) -> None:
        l, ld, ldd = self.gait.at(float(t0))
        _finite_gait((l, ld, ldd), t0)
        e, ep, epp = kinematics(self._m, l, ld, ldd)
        self.t = float(t0)
        self.X = float(x0 - e[0])
        self.V = float(v0 - ep[0])
        # The state at t0 is the instantaneous mode: bodies at zero velocity stick or leave as
        # the acceleration inclusion says (MODEL.md 2.3).
        p = self._m.size
        zmask, kbuf, fpb, fmb, idx, _ = self._scratch
        contact = np.empty(p, np.int8)
        force = self._fext
        for i in range(p):
            v = self.V + ep[i]
            zmask[i] = v == 0.0
            if not zmask[i]:
                contact[i] = 1 if v > 0 else -1
                force += -self._fp[i] if v > 0 else self._fm[i]
        a, s = _py._accel_mode(self._M, force, zmask, np.ascontiguousarray(epp), self._fp,
                                self._fm, kbuf, fpb, fmb, idx, contact)
        R = np.where(contact > 0, -self._fp, np.where(contact < 0, self._fm, 0.0))
        stuck = contact == 0
        if stuck.any():
            tot = self._M * a - force
            wid = self._fp[stuck] + self._fm[stuck]
            th = 0.0 if wid.sum() <= 0 else min(max((tot + self._fp[stuck].sum()) / wid.sum(),
                                                    0.0), 1.0)
            R[stuck] = -self._fp[stuck] + th * wid
        self.contact = contact
        self.R = R
        self.A = float(a)
        self.K = np.zeros(p)
        self._cache = None
        self.events: list[Event] = []
        self.n_steps = 0

    def advance(self, t1: float, gait: Gait | None = None) -> None:
        """Step to t1 with ``gait`` valid on [t, t1]; the last step is shortened to land on t1."""
        if gait is not None:
            self.gait = gait
        t1 = float(t1)
        if t1 > self.t:
            check_steps(t1 - self.t, self.dt, '(t1 - t)')
        while self.t < t1:
            n_left = (t1 - self.t) / self.dt
            t_new = t1 if n_left <= 1.0 + 1e-9 else self.t + self.dt
            self._step(t_new)

    def _rates(self, t: float) -> tuple[NDArray, NDArray]:
        l, ld, ldd = self.gait.at(t)
        _finite_gait((l, ld, ldd), t)
        ep = np.empty(self._m.size)
        epp = np.empty(self._m.size)
        _py.rel_rates(self._w, np.ascontiguousarray(ld, dtype=float), ep)
        _py.rel_rates(self._w, np.ascontiguousarray(ldd, dtype=float), epp)
        return ep, epp

    def _step(self, t_new: float) -> None:
        h = t_new - self.t
        ep, _ = self._rates(t_new)
        V_new, R, contact = self._velocity(h, ep)
        self.A = (V_new - self.V) / h
        self.V = V_new
        self.X += h * V_new
        self.K = self.K + h * R
        self.R = R
        self._set_contact(contact, t_new)
        self.t = t_new
        self.n_steps += 1
        self._cache = None

    def _set_contact(self, contact: NDArray, t: float) -> None:
        old = self.contact
        for i in np.nonzero(contact != old)[0]:
            self.events.append(Event(float(t), int(i), int(old[i]), int(contact[i])))
        self.contact = np.array(contact, dtype=np.int8)

    def current(self) -> dict:
        """The state at self.t as one row of output arrays."""
        return self._row()

    def _row(self) -> dict:
        if self._cache is None or self._cache[0] != self.t:
            l, ld, ldd = self.gait.at(self.t)
            self._cache = (self.t,) + tuple(kinematics(self._m, l, ld, ldd)) + (l, ld)
        _, e, ep, epp, l, ld = self._cache
        x = self.X + e
        v = self.V + ep
        R = self.R
        body_force = R + self.crawler.gravity_forces - self._m * (self.A + epp)
        return {'t': self.t, 'x': x, 'v': v, 'friction': R.copy(), 'impulse': self.K.copy(),
                'linkage_force': np.cumsum(body_force)[:-1], 'lengths': l, 'rates': ld,
                'contact': self.contact.copy(), 'indeterminate': int(np.sum(self.contact == 0)) > 1}


class ImplicitSolver(TimeStepper):
    """Moreau-Jean stepping for one crawler, transitions placed inside their step.

    ``use_kernel`` (default True) runs ``Fourier`` and ``Sinusoid`` gaits in the compiled
    kernel; False forces the Python path (the same algorithm; the tests compare the two).
    ``locate_transitions=False`` gives the plain Moreau-Jean step (transitions at step ends,
    what ``ImplicitBatch`` does): first order too, but with an erratic constant.
    """

    def __init__(self, crawler: Crawler, gait: Gait, *, dt: float, t0: float = 0.0,
                 x0: float = 0.0, v0: float = 0.0, use_kernel: bool = True,
                 locate_transitions: bool = True) -> None:
        self.use_kernel = bool(use_kernel)
        self._max_depth = _py.MAX_DEPTH if locate_transitions else 0
        self._form: tuple = (None, None)
        super().__init__(crawler, gait, dt=dt, t0=t0, x0=x0, v0=v0)

    def reset(self, *, t0: float = 0.0, x0: float = 0.0, v0: float = 0.0) -> None:
        super().reset(t0=t0, x0=x0, v0=v0)
        self._last = None            # (t, e', e'') at the last step end, as the step used them

    # ------------------------------------------------------------------ kernel path
    def _kernel_form(self) -> tuple | None:
        if not self.use_kernel:
            return None
        if self._form[0] is not self.gait:
            self._form = (self.gait, fourier_form(self.gait))
        return self._form[1]

    def advance(self, t1: float, gait: Gait | None = None) -> None:
        """Step to t1 [s] with ``gait`` valid on [t, t1]; the last step lands on t1."""
        if gait is not None:
            self.gait = gait
        t1 = float(t1)
        if not t1 > self.t:
            return
        check_steps(t1 - self.t, self.dt, '(t1 - t)')
        form = self._kernel_form()
        if form is None:
            # a table chunk costs a vectorised gait call and a kernel dispatch: for the few
            # steps of a node's tick the Python path is as fast
            if self.use_kernel and (t1 - self.t) / self.dt > 8.0:
                self._advance_table(t1)
            else:
                super().advance(t1)
            return
        freq, ca, sb = form
        p = self._m.size
        st = np.array([self.t, self.X, self.V, self.A])
        contact = self.contact.copy()
        R = self.R.copy()
        K = self.K.copy()
        kern = _load_kernel()
        cap = 64 * p * (kern.MAX_DEPTH + 1)
        ev_t, ev_b = np.empty(cap), np.empty(cap, np.int64)
        ev_o, ev_n = np.empty(cap, np.int8), np.empty(cap, np.int8)
        ep_out, epp_out = np.empty(p), np.empty(p)
        while st[0] < t1:
            steps, n_ev = kern.advance_fourier(st, contact, R, K, self._w, self._M, self._fext,
                                               self._fp, self._fm, freq, ca, sb, t1, self.dt,
                                               1 << 62, self._max_depth, ev_t, ev_b, ev_o,
                                               ev_n, ep_out, epp_out)
            self.n_steps += int(steps)
            self.events.extend(Event(float(ev_t[k]), int(ev_b[k]), int(ev_o[k]), int(ev_n[k]))
                               for k in range(n_ev))
        if not np.isfinite(st).all():
            raise ValueError(f'method implicit: non-finite state at t = {st[0]!r} s (check the '
                             'gait and the crawler)')
        self.t, self.X, self.V, self.A = (float(v) for v in st)
        self.contact, self.R, self.K = contact, R, K
        self._last = (self.t, ep_out.copy(), epp_out.copy())
        self._cache = None

    def _step_times(self, t1: float, n: int) -> NDArray:
        """The next (at most n) step end times, as ``TimeStepper.advance`` computes them."""
        acc = np.full(n + 1, self.dt)
        acc[0] = self.t
        tt = np.add.accumulate(acc)             # sequential sums: t, t + dt, (t + dt) + dt, ...
        last = (t1 - tt[:-1]) / self.dt <= 1.0 + 1e-9
        if last.any():
            k = int(np.argmax(last))
            times = tt[1:k + 2].copy()
            times[k] = t1
            return times
        return tt[1:]

    def _advance_table(self, t1: float) -> None:
        """Any other gait: l', l'' at a chunk of step ends from one vectorised gait call, the
        steps in the kernel; a step with a transition inside goes through ``_step``."""
        kern = _load_kernel()
        p = self._m.size
        cap = 64 * p
        ev_t, ev_b = np.empty(cap), np.empty(cap, np.int64)
        ev_o, ev_n = np.empty(cap, np.int8), np.empty(cap, np.int8)
        ep_out, epp_out = np.empty(p), np.empty(p)
        while self.t < t1:
            times = self._step_times(t1, int(min(4096.0, (t1 - self.t) / self.dt + 2.0)))
            _, LD, LDD = self.gait(times)
            bad = ~(np.isfinite(LD).all(axis=-1) & np.isfinite(LDD).all(axis=-1))
            if bad.any():
                k = int(np.argmax(bad))
                _finite_gait(self.gait.at(float(times[k])), float(times[k]))
                raise ValueError(f'gait must be finite, got a non-finite rate at t = '
                                 f'{float(times[k])!r} s')
            LD, LDD = np.ascontiguousarray(LD, dtype=float), np.ascontiguousarray(LDD, dtype=float)
            k = 0
            while k < times.size:
                st = np.array([self.t, self.X, self.V, self.A])
                contact, R, K = self.contact.copy(), self.R.copy(), self.K.copy()
                k_new, n_ev = kern.advance_table(st, contact, R, K, self._w, self._M,
                                                 self._fext, self._fp, self._fm, times, LD, LDD,
                                                 k, self._max_depth, ep_out, epp_out, ev_t, ev_b,
                                                 ev_o, ev_n)
                if k_new > k:
                    self.t, self.X, self.V, self.A = (float(v) for v in st)
                    self.contact, self.R, self.K = contact, R, K
                    self.events.extend(Event(float(ev_t[i]), int(ev_b[i]), int(ev_o[i]),
                                             int(ev_n[i])) for i in range(n_ev))
                    self.n_steps += k_new - k
                    self._last = (self.t, ep_out.copy(), epp_out.copy())
                    self._cache = None
                    k = k_new
                if k < times.size and n_ev + p <= cap:      # not a full event buffer
                    if not np.isfinite(self.X + self.V):
                        raise ValueError(f'method implicit: non-finite state at t = {self.t!r} '
                                         's (check the gait and the crawler)')
                    self._step(float(times[k]))     # a transition inside: located in Python
                    k += 1

    # ------------------------------------------------------------------ Python path
    def _step(self, tb: float) -> None:
        M, fext, fp, fm = self._M, self._fext, self._fp, self._fm
        p = self._m.size
        zmask, kbuf, fpb, fmb, idx, tmp = self._scratch
        epb, eppb = self._rates(tb)
        kinks = -epb
        contact = self.contact.copy()
        R = np.empty(p)
        V, X, K, lo = self.V, self.X, self.K.copy(), self.t
        V0, t0 = V, self.t
        newc = np.empty(p, np.int8)

        def chg(c, v, ep, epp) -> bool:
            return _py.changed(c, v, ep, epp, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx, tmp)

        for depth in range(self._max_depth + 1):
            h = tb - lo
            if h <= 0.0:                    # a transition exactly at the step end
                u = V
                newc[:] = contact
                break
            u, _ = _py.prox(M / h, V, fext, kinks, fp, fm, p, idx)
            newc[:] = np.where(u == kinks, 0, np.where(u + epb > 0.0, 1, -1))
            if np.array_equal(newc, contact) and (_py.first_stuck(contact) < 0 or
                                                  not chg(contact, u, epb, eppb)):
                break
            if depth == self._max_depth or h <= _py.BISECT_REL * self.dt:
                break
            j = _py.first_stuck(contact)
            a_lo = (fext + _py.slide_sum(contact, fp, fm)) / M
            uc = -epb[j] if j >= 0 else V + a_lo * h
            if not chg(contact, uc, epb, eppb):
                u = uc                      # the prox's change was its O(h) stick test
                newc[:] = contact
                break
            a, b = lo, tb
            for _ in range(_py._BISECT):
                if b - a <= _py.BISECT_REL * self.dt:
                    break
                mid = a + 0.5 * (b - a)
                ep, epp = self._rates(mid)
                vm = -ep[j] if j >= 0 else V + a_lo * (mid - lo)
                if chg(contact, vm, ep, epp):
                    b = mid
                else:
                    a = mid
            tau = b
            ep, epp = self._rates(tau)
            vt = -ep[j] if j >= 0 else V + a_lo * (tau - lo)
            _py.new_mode(contact, vt, ep, epp, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx,
                          newc)
            hh = tau - lo
            if hh > 0.0:
                _py.interval_friction(contact, V, vt, hh, M, fext, fp, fm, R)
                X += hh * vt
                K += hh * R
            self.contact = contact
            self._set_contact(newc, tau)
            contact = self.contact.copy()
            V, lo = vt, tau
        hh = tb - lo
        if hh > 0.0:
            _py.interval_friction(newc, V, u, hh, M, fext, fp, fm, R)
        X += hh * u
        K += hh * R
        self.contact = contact
        self._set_contact(newc, tb)
        self.A = (u - V0) / (tb - t0)
        self.V, self.X, self.K, self.R, self.t = u, X, K, R, tb
        self.n_steps += 1
        self._last = (tb, epb, eppb)
        self._cache = None

    def _row(self) -> dict:
        row = super()._row()
        if self._last is not None and self._last[0] == self.t:
            # the step's own e', e'': a stuck body's velocity is then exactly zero
            _, ep, epp = self._last
            row['v'] = self.V + ep
            body_force = self.R + self.crawler.gravity_forces - self._m * (self.A + epp)
            row['linkage_force'] = np.cumsum(body_force)[:-1]
        return row

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
        _load_kernel().batch_step(float(h), np.ascontiguousarray(r.reshape(-1, self.p - 1)),
                                  self._w, self.M, self.V, self.X, self.F_ext, self.f_plus,
                                  self.f_minus)
        self.t += h
