"""The differential fuzz cases: every gait family drawn at random, run by the exact method and by the
independent oracle (test/support/oracle.py). The tests (test/core/solvers/test_fuzz.py) and the long
stress profile (benchmarks/stress) run them.

What the cases cover and what passes: the docstring of test/core/solvers/test_fuzz.py.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

import crawler_sim as cs
from test.support.oracle import Oracle

G = cs.gaits
FAMILIES = ('custom', 'custom_sharp', 'custom_bound', 'custom_period', 'custom_breaks',
            'sinusoid', 'fourier', 'scallop', 'stroke', 'bang_bang', 'spline', 'spline_periodic',
            'piecewise_cubic', 'long_piecewise_cubic', 'switch_cubic', 'switch_sinusoid')
TOL = 1e-10
N_EXAMPLES = int(os.environ.get('CRAWLER_SIM_FUZZ_EXAMPLES', '10'))


@dataclass
class Case:
    """One differential case: a crawler, how the solver is driven, and the oracle's kinematics."""

    family: str
    seed: int
    crawler: cs.Crawler
    t_end: float
    v0: float
    kin: Callable                       # vectorised (l, l', l'') for the oracle
    breakpoints: np.ndarray             # where l'' may jump, for the oracle's grid
    timescale: float                    # fastest time scale of the gait [s]
    gait: object = None                 # simulate(...) with this gait, or
    pieces: list = field(default_factory=list)   # [(t1, gait)] Stepper.advance calls
    desc: str = ''
    twin: object = None                 # the built-in gait a Custom case copies, if any

    def __repr__(self) -> str:
        return (f'Case({self.family!r}, seed={self.seed}, {self.crawler!r}, t_end={self.t_end}, '
                f'v0={self.v0}, {self.desc})')


def _crawler(rng: np.random.Generator, p: int) -> tuple[cs.Crawler, str]:
    m = 10.0 ** rng.uniform(-2, 2, p)
    f = 10.0 ** rng.uniform(-2, 2, p)
    f[rng.random(p) < 0.15] = 0.0
    fb = None
    if rng.random() < 0.35:
        fb = 10.0 ** rng.uniform(-2, 2, p)
        fb[rng.random(p) < 0.15] = 0.0
    if rng.random() < 0.08:
        f[:] = 0.0
        fb = None
    slope = float(rng.uniform(-0.5, 0.5)) if rng.random() < 0.3 else 0.0
    return cs.Crawler(m, f, fb, slope=slope), ''


def _vec(fn):
    """A vectorised kinematics function from a gait (the gait is the input, not the solver)."""
    return lambda t: fn(np.asarray(t, float))


def draw_case(family: str, seed: int) -> Case:
    """The case of ``family`` drawn from ``numpy.random.default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    p = int(rng.integers(2, 9))
    n = p - 1
    crawler, _ = _crawler(rng, p)
    v0 = float(rng.uniform(-1.0, 1.0)) if rng.random() < 0.4 else 0.0
    t_end = float(rng.uniform(1.0, 2.5))
    mean = rng.uniform(0.5, 1.5, n)
    amp = rng.uniform(0.02, 0.3, n)
    freq = float(rng.uniform(0.5, 2.5))
    phase = rng.uniform(0, 2 * math.pi, n)
    kw = dict(family=family, seed=seed, crawler=crawler, t_end=t_end, v0=v0)
    if family == 'custom':
        w1 = 2 * math.pi * rng.uniform(0.3, 2.5, n)
        w2 = 2 * math.pi * rng.uniform(0.3, 4.0, n)
        a2 = amp * rng.uniform(0, 0.5, n)
        ms, a1s, a2s, w1s, w2s, phs = (x.tolist() for x in (mean, amp, a2, w1, w2, phase))

        def length(t):
            return [ms[j] + a1s[j] * math.sin(w1s[j] * t + phs[j]) + a2s[j] * math.sin(w2s[j] * t)
                    for j in range(n)]

        def velocity(t):
            return [a1s[j] * w1s[j] * math.cos(w1s[j] * t + phs[j])
                    + a2s[j] * w2s[j] * math.cos(w2s[j] * t) for j in range(n)]

        def accel(t):
            return [-a1s[j] * w1s[j] ** 2 * math.sin(w1s[j] * t + phs[j])
                    - a2s[j] * w2s[j] ** 2 * math.sin(w2s[j] * t) for j in range(n)]

        def kin(t):
            t = np.asarray(t, float)[:, None]
            s1, c1 = np.sin(w1 * t + phase), np.cos(w1 * t + phase)
            s2, c2 = np.sin(w2 * t), np.cos(w2 * t)
            return (mean + amp * s1 + a2 * s2, amp * w1 * c1 + a2 * w2 * c2,
                    -amp * w1 ** 2 * s1 - a2 * w2 ** 2 * s2)
        g = G.Custom(length, velocity, accel)
        return Case(kin=kin, gait=g, breakpoints=np.empty(0), timescale=float(2 * math.pi / max(w1.max(), w2.max())),
                    desc=f'custom w1={w1.tolist()} w2={w2.tolist()}', **kw)
    if family in ('custom_bound', 'custom_period'):
        # the 'custom' lambdas with a true jerk bound (the sum of a w^3), or a periodic copy of
        # a sharp Scallop given period= (sampled over one period, then repeated)
        if family == 'custom_period':
            r = float(10 ** rng.uniform(math.log10(0.005), math.log10(0.1)))
            src = G.Scallop(mean, amp, freq, r, phase)
            fns = ((lambda t: src.at1(t)[0], lambda t: src.at1(t)[1], lambda t: src.at1(t)[2])
                   if n == 1 else (lambda t: src.at(t)[0], lambda t: src.at(t)[1],
                                   lambda t: src.at(t)[2]))
            return Case(kin=_vec(src), gait=G.Custom(*fns, period=src.period), twin=src,
                        breakpoints=np.empty(0), timescale=r / freq,
                        desc=f'periodic Custom copy of Scallop {freq=} asymmetry={r}', **kw)
        w = 2 * math.pi * rng.uniform(0.3, 2.5, n)
        ms, as_, ws, phs = (x.tolist() for x in (mean, amp, w, phase))
        fns = (lambda t: [ms[j] + as_[j] * math.sin(ws[j] * t + phs[j]) for j in range(n)],
               lambda t: [as_[j] * ws[j] * math.cos(ws[j] * t + phs[j]) for j in range(n)],
               lambda t: [-as_[j] * ws[j] ** 2 * math.sin(ws[j] * t + phs[j])
                          for j in range(n)])

        def kin(t):
            t = np.asarray(t, float)[:, None]
            return (mean + amp * np.sin(w * t + phase), amp * w * np.cos(w * t + phase),
                    -amp * w ** 2 * np.sin(w * t + phase))
        return Case(kin=kin, gait=G.Custom(*fns, jerk_bound=amp * w ** 3),
                    breakpoints=np.empty(0), timescale=float(2 * math.pi / w.max()),
                    desc=f'custom with jerk_bound w={w.tolist()}', **kw)
    if family == 'custom_breaks':
        # a random non-periodic bang-bang stroke as Custom lambdas given its breakpoints
        k = int(rng.integers(3, 10))
        times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 0.4, k))])
        acc = rng.choice([-1.0, 0.0, 1.0], (k, n)) * rng.uniform(0.5, 5.0, (k, n))
        src = G.PiecewiseParabolic(times, acc, mean, rng.uniform(-0.3, 0.3, n), periodic=False)
        br = src.breakpoints(-1.0, t_end + 1.0)
        fns = (lambda t: src.at(t)[0], lambda t: src.at(t)[1], lambda t: src.at(t)[2])
        return Case(kin=_vec(src), gait=G.Custom(*fns, breakpoints=br),
                    breakpoints=src.breakpoints(0.0, t_end),
                    timescale=float(np.diff(times).min()), desc=f'Custom bang-bang {times=}',
                    **kw)
    if family == 'spline_periodic':
        k = int(rng.integers(4, 12))
        times = np.linspace(0.0, 1.0 / freq, k)
        y = mean + amp * rng.normal(0, 1, (k, n))
        y[-1] = y[0]
        g = G.Spline(times, y, periodic=True)
        return Case(kin=_vec(g), gait=g, breakpoints=np.empty(0),
                    timescale=float(times[1] - times[0]), desc=f'periodic {times=}', **kw)
    if family == 'long_piecewise_cubic':
        # the node's pieces at its tick (1-5 ms), hundreds of them, as one gait
        from crawler_sim.core.gaits.cubic import cubic_values
        l, ld, ldd = mean, rng.uniform(-0.3, 0.3, n), rng.uniform(-2, 2, n)
        starts, cubics, t = [], [], 0.0
        while t < t_end:
            dt = float(rng.uniform(1e-3, 5e-3))
            jerk = rng.uniform(-300, 300, n) - 400 * (l - mean) - 40 * ld
            starts.append(t)
            cubics.append(G.Cubic(t, l, ld, ldd, jerk))
            l, ld, ldd = cubic_values(l, ld, ldd, jerk, dt)
            t += dt
        pw = G.PiecewiseCubic(starts, cubics)
        return Case(kin=_vec(pw), gait=pw, breakpoints=pw.breakpoints(0.0, t_end),
                    timescale=1e-3, desc=f'{len(cubics)} cubic pieces', **kw)
    if family == 'sinusoid':
        g = G.Sinusoid(mean, amp, freq, phase)
        return Case(kin=_vec(g), gait=g, breakpoints=np.empty(0), timescale=1 / freq, desc=f'{freq=}', **kw)
    if family == 'fourier':
        K = int(rng.integers(1, 4))
        a = rng.normal(0, 1, (n, K)) * amp[:, None] / np.arange(1, K + 1)
        b = rng.normal(0, 1, (n, K)) * amp[:, None] / np.arange(1, K + 1)
        g = G.Fourier(mean, (a, b), freq)
        return Case(kin=_vec(g), gait=g, breakpoints=np.empty(0), timescale=1 / (freq * K), desc=f'{freq=} {K=}', **kw)
    if family == 'custom_sharp':
        # the user's copy of a sharp Scallop or a many-harmonic Fourier gait as plain lambdas
        # (no period, no bound): the Chebyshev pieces (``solvers.proxy``) against the
        # oracle fed the built-in gait
        if rng.random() < 0.6:
            r = float(10 ** rng.uniform(math.log10(0.01), math.log10(0.1)))
            src = G.Scallop(mean, amp, freq, r if rng.random() < 0.5 else 1 - r, phase)
            scale, what = r / freq, f'Scallop {freq=} asymmetry={r}'
        else:
            K = int(rng.integers(3, 7))
            a = rng.normal(0, 1, (n, K)) * amp[:, None] / np.arange(1, K + 1)
            b = rng.normal(0, 1, (n, K)) * amp[:, None] / np.arange(1, K + 1)
            src = G.Fourier(mean, (a, b), freq)
            scale, what = 1 / (freq * K), f'Fourier {freq=} {K=}'
        if n == 1:
            g = G.Custom(lambda t: src.at1(t)[0], lambda t: src.at1(t)[1],
                         lambda t: src.at1(t)[2])
        else:
            g = G.Custom(lambda t: src.at(t)[0], lambda t: src.at(t)[1], lambda t: src.at(t)[2])
        return Case(kin=_vec(src), gait=g, breakpoints=np.empty(0), timescale=scale,
                    desc=f'Custom copy of {what}', **kw)
    if family == 'scallop':
        r = float(10 ** rng.uniform(math.log10(0.02), math.log10(0.5)))
        r = r if rng.random() < 0.5 else 1 - r
        g = G.Scallop(mean, amp, freq, r, phase)
        return Case(kin=_vec(g), gait=g, breakpoints=np.empty(0), timescale=min(r, 1 - r) / freq,
                    desc=f'{freq=} asymmetry={r}', **kw)
    if family == 'stroke':
        r = float(rng.uniform(0.1, 0.9))
        g = G.PiecewiseParabolic.stroke(mean, amp, freq, r, n_links=n)
        return Case(kin=_vec(g), gait=g, breakpoints=g.breakpoints(0.0, t_end),
                    timescale=min(r, 1 - r) / freq, desc=f'{freq=} asymmetry={r}', **kw)
    if family == 'bang_bang':
        k = int(rng.integers(3, 12))
        times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 0.4, k))])
        acc = rng.choice([-1.0, 0.0, 1.0], (k, n)) * rng.uniform(0.5, 5.0, (k, n))
        g = G.PiecewiseParabolic(times, acc, mean, rng.uniform(-0.3, 0.3, n), periodic=False)
        return Case(kin=_vec(g), gait=g, breakpoints=g.breakpoints(0.0, t_end),
                    timescale=float(np.diff(times).min()), desc=f'{times=} {acc=}', **kw)
    if family == 'spline':
        k = int(rng.integers(4, 10))
        times = np.linspace(0.0, t_end * rng.uniform(0.6, 1.2), k)
        y = mean + amp * rng.normal(0, 1, (k, n))
        g = G.Spline(times, y)
        return Case(kin=_vec(g), gait=g, breakpoints=g.breakpoints(0.0, t_end),
                    timescale=float(times[1] - times[0]), desc=f'{times=}', **kw)
    if family in ('switch_cubic', 'switch_sinusoid', 'piecewise_cubic'):
        # the node's way: Cubic pieces, C2 at the joins, one Stepper.advance per piece
        if family == 'switch_sinusoid':
            head = G.Sinusoid(mean, amp, freq, phase)
            t_s = float(rng.uniform(0.2, 0.6) * t_end)
            l, ld, ldd = head(t_s)
        else:
            head, t_s = None, 0.0
            l, ld, ldd = mean, rng.uniform(-0.3, 0.3, n), rng.uniform(-2, 2, n)
        starts, cubics = [], []
        t = t_s
        while t < t_end:
            dt = float(rng.uniform(0.02, 0.3))
            jerk = rng.uniform(-30, 30, n)
            c = G.Cubic(t, l, ld, ldd, jerk)
            starts.append(t)
            cubics.append(c)
            l, ld, ldd = c(t + dt)
            t += dt
        ends = starts[1:] + [t_end]
        pieces = ([(t_s, head)] if head is not None else []) + list(zip(ends, cubics))
        pw = G.PiecewiseCubic(starts, cubics)

        def kin(tt, head=head, t_s=t_s, pw=pw):
            tt = np.asarray(tt, float)
            out = [np.array(a, float) for a in pw(np.maximum(tt, t_s))]
            if head is not None:
                before = tt < t_s
                if np.any(before):
                    hv = head(tt[before])
                    for o, h in zip(out, hv):
                        o[before] = h
            return tuple(out)
        bps = np.array(starts[1:] + ([t_s] if head is not None else []))
        if family == 'piecewise_cubic':     # the same pieces as one gait (the node's sync)
            return Case(kin=kin, gait=pw, breakpoints=bps, timescale=0.02,
                        desc=f'{len(cubics)} cubic pieces', **kw)
        return Case(kin=kin, pieces=pieces, breakpoints=bps,
                    timescale=min(0.02, 1 / freq), desc=f'{len(cubics)} cubic pieces from '
                    f't = {t_s}', **kw)
    raise ValueError(f'unknown family {family!r}')


def sample_times(case: Case) -> np.ndarray:
    rng = np.random.default_rng(case.seed + 1)
    return np.union1d(np.sort(rng.uniform(0.0, case.t_end, 5)), [0.0, case.t_end])


def oracle_h(case: Case) -> float:
    """Oracle grid step: well below the gait's fastest time scale (see oracle.py)."""
    return float(max(min(2e-4, case.timescale / 400), case.t_end / 4e5))


def check_case(case: Case) -> dict:
    """Run the case; return figures (errors vs the oracle). Raises AssertionError on failure."""
    te = sample_times(case)
    o = Oracle.for_crawler(case.crawler, case.kin, case.breakpoints)
    xo, vo = o.solve(case.t_end, te, v0=case.v0, h=oracle_h(case))
    if case.gait is not None:
        tr = cs.simulate(case.crawler, case.gait, case.t_end, t_eval=te, v0=case.v0)
        x, v = tr.x, tr.v
        rep = cs.verify(tr, case.gait)
    else:
        st = cs.Stepper(case.crawler, case.pieces[0][1], v0=case.v0)
        xs, vs = [], []
        times = iter(te)
        tn = next(times)
        for t1, g in case.pieces:
            while tn is not None and tn <= t1:
                st.advance(tn, g)
                s = st.state
                xs.append(s.x)
                vs.append(s.v)
                tn = next(times, None)
            st.advance(t1, g)
        x, v = np.array(xs), np.array(vs)
        rep = None
    ex = float(np.abs(x - xo).max())
    ev = float(np.abs(v - vo).max())
    x_tol = TOL * max(1.0, float(np.abs(xo).max()))
    v_tol = TOL * (1.0 + float(np.abs(vo).max()))
    out = {'err_x': ex, 'err_v': ev, 'verify': None if rep is None else rep.worst,
           'oracle_events': o.n_events}
    assert ex <= x_tol and ev <= v_tol, f'{case!r}: |dx| = {ex:.3g} m, |dv| = {ev:.3g} m/s ' \
        f'(tolerances {x_tol:.1g}, {v_tol:.1g})'
    assert rep is None or rep.ok(), f'{case!r}: verify {rep}'
    return out


#: a stream's first targets: one float after 0 (where an event at 0 puts the next target) and
#: 1e-200 s (issue 37 item 3: a Custom gait's first window of a few floats)
TINY_FIRST = (5e-324, 1e-200)


def stream_targets(event_times, t_end: float, t_first=TINY_FIRST) -> list[float]:
    """Where ``check_stream`` advances: ``t_first``, then every event time and the floats
    either side of it (issue 37 item 2: a Cubic streamed to an event, then one float on), all
    in (0, t_end), sorted and distinct."""
    out = set(float(t) for t in t_first)
    for t in event_times:
        t = float(t)
        out |= {math.nextafter(t, -math.inf), t, math.nextafter(t, math.inf),
                math.nextafter(math.nextafter(t, math.inf), math.inf)}
    return sorted(t for t in out if 0.0 < t < t_end)


def check_stream(case: Case) -> dict:
    """A case with one gait streamed through ``Stepper.advance`` the hard way: a first step of
    a few floats (``TINY_FIRST``), then to every event time of the one-shot run and one float
    either side of it, then to each sample time: positions and velocities at the samples
    against the oracle, as ``check_case``. The stream runs on a fresh copy of the case's gait
    (drawn again from its seed: a Custom gait's table is built by the stream itself). Raises
    AssertionError on failure."""
    assert case.gait is not None, 'check_stream takes a case with one gait'
    te = sample_times(case)
    o = Oracle.for_crawler(case.crawler, case.kin, case.breakpoints)
    xo, vo = o.solve(case.t_end, te, v0=case.v0, h=oracle_h(case))
    one = cs.simulate(case.crawler, case.gait, case.t_end, t_eval=te, v0=case.v0)
    targets = stream_targets([e.time for e in one.events], case.t_end)
    gait = draw_case(case.family, case.seed).gait
    st = cs.Stepper(case.crawler, gait, v0=case.v0)
    xs, vs = [], []
    for t in sorted(set(targets) | set(te.tolist())):
        if t > st.t:
            st.advance(t)
        if t in te:
            s = st.state
            xs.append(s.x)
            vs.append(s.v)
    x, v = np.array(xs), np.array(vs)
    ex = float(np.abs(x - xo).max())
    ev = float(np.abs(v - vo).max())
    x_tol = TOL * max(1.0, float(np.abs(xo).max()))
    v_tol = TOL * (1.0 + float(np.abs(vo).max()))
    assert ex <= x_tol and ev <= v_tol, f'{case!r} streamed to {len(targets)} targets on its ' \
        f'event times: |dx| = {ex:.3g} m, |dv| = {ev:.3g} m/s (tolerances {x_tol:.1g}, {v_tol:.1g})'
    return {'err_x': ex, 'err_v': ev, 'targets': len(targets)}


#: past 512 s, tol / 2 = 5e-14 s is below half a float spacing of t (issue 37 item 1)
LATE = 600.0


def check_late_start(case: Case, t_late: float = LATE) -> dict:
    """A case of a periodic gait started at the first multiple of its period past ``t_late``
    instead of at 0 (a fresh copy of the gait, ``Stepper(t0=...)``): the gait repeats, so the
    motion is the case's own shifted in time, against the oracle's from 0 at the sample times
    (as ``check_case``). Raises AssertionError on failure."""
    P = case.gait.period
    t0 = math.ceil(t_late / P) * P
    te = sample_times(case)
    o = Oracle.for_crawler(case.crawler, case.kin, case.breakpoints)
    xo, vo = o.solve(case.t_end, te, v0=case.v0, h=oracle_h(case))
    st = cs.Stepper(case.crawler, draw_case(case.family, case.seed).gait, t0=t0, v0=case.v0)
    xs, vs = [], []
    for t in te.tolist():
        if t0 + t > st.t:
            st.advance(t0 + t)
        s = st.state
        xs.append(s.x)
        vs.append(s.v)
    ex = float(np.abs(np.array(xs) - xo).max())
    ev = float(np.abs(np.array(vs) - vo).max())
    # the shift k P is a float and a time near t0 is known to ulp(t0) (1.1e-13 s at 600 s):
    # the gait's own values move by that much time (16 ulp of l' and l'' at their largest,
    # over the run for positions) beyond the oracle's tolerance
    _, ld, ldd = case.kin(np.linspace(0.0, P, 2001))
    dt = 16.0 * float(np.spacing(t0 + case.t_end))
    v_tol = TOL * (1.0 + float(np.abs(vo).max())) + dt * float(np.abs(ldd).max())
    x_tol = (TOL * max(1.0, float(np.abs(xo).max())) + dt * float(np.abs(ld).max())
             + v_tol * case.t_end)
    assert ex <= x_tol and ev <= v_tol, f'{case!r} started at t0 = {t0!r} s: |dx| = {ex:.3g} ' \
        f'm, |dv| = {ev:.3g} m/s (tolerances {x_tol:.1g}, {v_tol:.1g})'
    return {'err_x': ex, 'err_v': ev, 't0': t0}


_W = 2 * math.pi
ISSUE_SCENES = {   # issue 14's reproducers: (crawler, gait, t_end, v0)
    'custom_sine_4s': (cs.Crawler([1, 1], [1, 1]), G.Custom(
        lambda t: 1 + .3 * math.sin(_W * t), lambda t: .3 * _W * math.cos(_W * t),
        lambda t: -.3 * _W * _W * math.sin(_W * t)), 4.0, 0.0),
    'custom_sine_4.25s': (cs.Crawler([1, 1], [1, 1]), G.Custom(
        lambda t: 1 + .3 * math.sin(_W * t), lambda t: .3 * _W * math.cos(_W * t),
        lambda t: -.3 * _W * _W * math.sin(_W * t)), 4.25, 0.0),
    'sharp_scallop': (cs.Crawler([1, 1], [50, 10]), G.Scallop(1.0, 0.3, 1.0, 0.05), 1.0, 0.0),
    'scallop_period_boundary': (cs.Crawler([2, 1], [2, 1]),
                                G.Scallop(1.0, .15, 0.6227466888177834, .4),
                                6 / 0.6227466888177834, 6.0),
}
def run_fuzz(n_per_family: int, seed: int = 0, families=FAMILIES,
             progress: Callable | None = None, streams: bool = False) -> dict:
    """The long profile (``python -m benchmarks.solvers stress``): ``n_per_family`` cases per family from seeds
    seed, seed + 1, ...; returns counts, worst errors and the failing cases. ``streams``: each
    case with one gait is also streamed onto its event times (``check_stream``)."""
    say = progress or (lambda *a: None)
    out = {'cases': 0, 'failed': 0, 'errors': 0, 'worst_x': 0.0, 'failures': [],
           'by_family': {}}
    for fam in families:
        bad_before = out['failed'] + out['errors']
        for k in range(n_per_family):
            case = draw_case(fam, seed + k)
            out['cases'] += 1
            try:
                r = check_case(case)
                out['worst_x'] = max(out['worst_x'], r['err_x'])
                if streams and case.gait is not None:
                    r = check_stream(case)
                    out['worst_x'] = max(out['worst_x'], r['err_x'])
            except AssertionError as exc:
                out['failed'] += 1
                out['failures'].append(str(exc)[:400])
            except Exception as exc:   # a stall or crash of the solver is a failure too
                out['errors'] += 1
                out['failures'].append(f'{case!r}: {type(exc).__name__}: {exc}'[:400])
        out['by_family'][fam] = f'{out["failed"] + out["errors"] - bad_before}/{n_per_family} failed'
        say(f'fuzz {fam}: {out["by_family"][fam]}')
    return out
