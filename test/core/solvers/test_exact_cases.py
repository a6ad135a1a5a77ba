"""The exact solver on the cases of issue 14 and on scenes no test was tuned to.

References, independent of the solver under test:
- ``oracle``: the independent event-driven reference (test/support/oracle.py: its own grid search
  and mode choice, written apart from the solvers), accurate to ~1e-12 m on these scenes
  (test_fuzz_oracle checks it), compared here at 1e-9 m;
- two routes of the exact solver that share no event-search arithmetic: a built-in gait, whose
  bounds make the search rigorous, and the same function as a ``Custom`` gait of math lambdas,
  whose bounds the solver must estimate from the values (compared at 1e-11 m);
- closed forms where the motion has one (a stick/slip pattern derived by hand).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim import gaits

from test.support.oracle import Oracle

W = 2 * math.pi


def _sine_custom(mean=1.0, amp=0.3, freq=1.0, **kw):
    w = 2 * math.pi * freq
    return gaits.Custom(lambda t: mean + amp * math.sin(w * t),
                        lambda t: amp * w * math.cos(w * t),
                        lambda t: -amp * w * w * math.sin(w * t), **kw)


def _x0(crawler, gait, t_end, **kw):
    tr = cs.simulate(crawler, gait, t_end, t_eval=[0.0, t_end], **kw)
    return float(tr.x[-1, 0] - tr.x[0, 0])


def body0_displacement(crawler, gait, t_end: float, h: float, v0: float = 0.0) -> float:
    """x_0(t_end) - x_0(0) by the independent oracle on a grid of step h."""
    ref, _ = Oracle.for_crawler(crawler, lambda t: gait(np.asarray(t, float))).solve(
        t_end, [0.0, t_end], v0=v0, h=h)
    return float(ref[1, 0] - ref[0, 0]), None


def test_the_oracle_reproduces_a_closed_form_slide():
    # frictionless front body: X is linear (momentum), x_0 = X + e_0 exactly; the oracle must
    # agree to its own accuracy, which sets the tolerance used below.
    c = cs.Crawler([1.0, 1.0], [1.0, 0.0])
    g = gaits.Sinusoid(1.0, 0.3, 1.0)
    ref, _ = body0_displacement(c, g, 1.0, 1e-4)
    got = _x0(c, g, 1.0)
    assert abs(ref - got) <= 1e-9


def test_a_custom_sine_without_a_period_gives_the_true_displacement():
    # issue 14: the plain Custom gait returned dx 0.150 (true 1.13894) and stalled at 4.25 s
    c = cs.Crawler([1, 1], [1, 1])
    got = _x0(c, _sine_custom(), 4.0)
    builtin = _x0(c, gaits.Sinusoid(1.0, 0.3, 1.0), 4.0)
    ref, _ = body0_displacement(c, gaits.Sinusoid(1.0, 0.3, 1.0), 4.0, 1e-4)
    assert abs(got - builtin) <= 1e-11
    assert abs(got - ref) <= 1e-9
    assert abs(got - 1.13894) <= 1e-5           # the 6 digits
    tr = cs.simulate(c, _sine_custom(), 4.25)  # used to raise "stalled at t = 0.0"
    assert np.all(np.isfinite(tr.x))
    assert abs(float(tr.x[-1, 0] - _x0(c, gaits.Sinusoid(1.0, 0.3, 1.0), 4.25))) <= 1e-11


def test_the_sharp_scallop_does_not_miss_the_short_slip_inside_a_stick():
    # issue 14: dx -0.19387035 (true -0.19385193)
    c = cs.Crawler([1, 1], [50, 10])
    g = gaits.Scallop(1.0, 0.3, 1.0, 0.05)
    got = _x0(c, g, 1.0)
    ref, _ = body0_displacement(c, g, 1.0, 2e-5)
    assert abs(got - ref) <= 1e-9
    assert abs(got - (-0.19385193)) <= 1e-8


def test_a_repeated_grid_point_at_a_period_boundary_does_not_crash():
    # issue 14: "min() arg is an empty sequence"
    c = cs.Crawler([2, 1], [2, 1])
    g = gaits.Scallop(1.0, .15, 0.6227466888177834, .4)
    T = 6 * g.period
    tr = cs.simulate(c, g, T, v0=6.0)
    assert np.all(np.isfinite(tr.x))
    ref, _ = body0_displacement(c, g, T, 1e-4, v0=6.0)
    assert abs(float(tr.x[-1, 0] - tr.x[0, 0]) - ref) <= 1e-9
    assert cs.simulate(c, g, T, v0=6.0, periodic_skip=False).x[-1, 0] == pytest.approx(
        tr.x[-1, 0], abs=1e-11)


def _random_custom(rng, n_links):
    """A sum of two sines per linkage, as plain math lambdas (no period, no bounds)."""
    A = rng.uniform(0.02, 0.2, (n_links, 2)) * rng.choice([-1, 1], (n_links, 2))
    w = 2 * math.pi * rng.uniform(0.3, 3.0, 2)
    ph = rng.uniform(0, 2 * math.pi, (n_links, 2))

    def comp(k, t):
        return np.array([sum(A[j, i] * (w[i] ** k) * math.sin(w[i] * t + ph[j, i] + k * math.pi / 2)
                             for i in range(2)) for j in range(n_links)])
    custom = gaits.Custom(lambda t: 1.0 + comp(0, t), lambda t: comp(1, t),
                          lambda t: comp(2, t))

    class Vec(gaits.Gait):          # the same function, vectorised, for the oracle
        n_links = custom.n_links

        def _eval(self, t):
            out = []
            for k in range(3):
                arg = t[:, None, None] * w[None, None, :] + ph[None] + k * math.pi / 2
                out.append((k == 0) + np.sum(A * w ** k * np.sin(arg), axis=2))
            return tuple(out)
    return custom, Vec()


@pytest.mark.parametrize('seed', range(4))
def test_random_custom_gait_scenes_agree_with_the_implicit_oracle(seed):
    rng = np.random.default_rng(100 + seed)
    p = 2 + seed % 3
    m = rng.uniform(0.3, 3.0, p)
    f = rng.uniform(0.2, 3.0, p) * m
    c = cs.Crawler(m, f, rng.uniform(0.5, 1.5, p) * f)
    custom, vec = _random_custom(rng, p - 1)
    t_end = 3.0
    got = _x0(c, custom, t_end)
    ref, _ = body0_displacement(c, vec, t_end, 1e-5)
    assert abs(got - ref) <= 2e-5 * max(1.0, abs(ref)), (got, ref)


def test_gait_switches_mid_run_give_the_one_run_result():
    # the node's pattern: Stepper.advance(t1, gait) with a new gait object every window. The
    # same function as a new object each time (Custom and Sinusoid alternating) must give the
    # single run; switching to another function must agree with the oracle run on the joined
    # function.
    c = cs.Crawler([1.0, 1.5, 0.7], [1.2, 2.0, 0.9])
    sin = gaits.Sinusoid([1.0, 1.0], [0.2, 0.1], 1.0, [0.0, 1.0])

    def as_custom():
        return gaits.Custom(lambda t: sin(t)[0], lambda t: sin(t)[1], lambda t: sin(t)[2])
    st = cs.Stepper(c, sin)
    for k in range(1, 31):
        st.advance(0.1 * k, as_custom() if k % 2 else sin)
    one = cs.Stepper(c, sin)
    one.advance(3.0)
    assert np.allclose(st.state.x, one.state.x, rtol=0, atol=1e-11)
    assert np.array_equal(st.state.contact, one.state.contact)


def test_stick_then_slip_of_a_cubic_onset_matches_the_closed_form():
    # m = (1, 1), f = (4, 1), l = 0.1 + 1e-3 t + t^3 (jerk 6): body 1 slides forward (l' > 0),
    # friction -f_1 on it; body 0 stuck means X'' = m_1 l'' / M, so the ground must push body 0
    # with R_0 = M X'' + f_1 = 6 t + 1, admissible while <= f_0 = 4: the slip (backward) starts
    # at t = 0.5 exactly, the event of a force row at a simple root.
    c = cs.Crawler([1.0, 1.0], [4.0, 1.0])
    g = gaits.Cubic(0.0, 0.1, 1e-3, 0.0, 6.0)
    tr = cs.simulate(c, g, 0.8)
    ev = [e for e in tr.events if e.body == 0 and e.time > 0]
    assert ev and ev[0].old == 0 and ev[0].new == -1
    assert abs(ev[0].time - 0.5) <= 1e-15 * 4


@pytest.mark.parametrize('seed', range(5))
def test_the_exact_solver_matches_the_independent_oracle_on_smooth_random_scenes(seed):
    # Fourier and Scallop gaits (p = 2..4, slopes): the compiled segment loop against the
    # independent event-driven oracle (test/support/oracle.py: its own grid search and mode
    # choice), positions and velocities at 41 times.
    rng = np.random.default_rng(seed)
    p = 2 + seed % 3
    m = rng.uniform(0.5, 2.0, p)
    c = cs.Crawler(m, rng.uniform(0.3, 2.0, p) * m, slope=0.05 * (seed % 3))
    if seed < 3:
        g = gaits.Fourier(np.full(p - 1, 1.0), (rng.uniform(-0.1, 0.1, (p - 1, 2)),
                                                rng.uniform(-0.2, 0.2, (p - 1, 2))), 1.3)
    else:      # sharp and mild Scallops, phases lagging along the body
        g = gaits.Scallop(1.0, rng.uniform(0.1, 0.3, p - 1), 1.1, (0.07, 0.35)[seed - 3],
                          -0.8 * np.arange(p - 1))
    t = np.linspace(0.0, 4.0, 41)
    tr = cs.simulate(c, g, 4.0, t_eval=t, periodic_skip=False)
    assert len(tr.events) > 5
    ref_x, ref_v = Oracle.for_crawler(c, lambda s: g(np.asarray(s, float))).solve(4.0, t,
                                                                                  h=2e-4)
    np.testing.assert_allclose(tr.x, ref_x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(tr.v, ref_v, rtol=0, atol=1e-8)


def _random_strokes(rng, n_links: int, n_pieces: int, dt: float):
    """Constant-jerk pieces as the node's actuator makes them: l and l' continuous at every
    join, l'' continuous at most joins and jumping at some (breakpoints). Returns the gait, an
    independent evaluation of it (the pieces' polynomials in numpy) and its jump times."""
    from crawler_sim.core.gaits.cubic import cubic_values
    l, v, a = np.full(n_links, 1.0), np.zeros(n_links), np.zeros(n_links)
    starts, pieces, coef, jumps = [], [], [], []
    for k in range(n_pieces):
        t0 = k * dt
        if rng.random() < 0.3:
            a = rng.uniform(-2.0, 2.0, n_links)          # a jump of l'': a breakpoint
            if k:
                jumps.append(t0)
        jerk = rng.choice([0.0, 1.0, -1.0], n_links) * rng.uniform(0.0, 60.0, n_links)
        starts.append(t0)
        pieces.append(gaits.Cubic(t0, l, v, a, jerk))
        coef.append((t0, l.copy(), v.copy(), a.copy(), jerk.copy()))
        l, v, a = cubic_values(l, v, a, jerk, dt)

    def kin(t):
        t = np.atleast_1d(np.asarray(t, float))
        k = np.clip(np.searchsorted(starts, t, side='right') - 1, 0, len(starts) - 1)
        out = [np.empty((t.size, n_links)) for _ in range(3)]
        for i, (t0, l0, v0, a0, j0) in enumerate(coef):
            sel = k == i
            d = (t[sel] - t0)[:, None]
            out[0][sel] = l0 + v0 * d + a0 * d ** 2 / 2 + j0 * d ** 3 / 6
            out[1][sel] = v0 + a0 * d + j0 * d ** 2 / 2
            out[2][sel] = a0 + j0 * d
        return tuple(out)
    return gaits.PiecewiseCubic(starts, pieces), kin, jumps


@pytest.mark.parametrize('seed', range(6))
def test_actuator_pieces_match_the_independent_oracle(seed):
    # The node's gaits (constant-jerk pieces with breakpoints, l''' jumping at every join) as
    # one PiecewiseCubic, against the oracle fed the pieces' polynomials and jump times
    # computed here, not by the gait.
    rng = np.random.default_rng(100 + seed)
    p = 2 + seed % 3
    m = rng.uniform(0.5, 2.0, p)
    c = cs.Crawler(m, rng.uniform(0.3, 2.0, p) * m, slope=0.05 * (seed % 2))
    g, kin, jumps = _random_strokes(rng, p - 1, 40, 0.05)
    # every jump of l'' is a breakpoint (and joins whose l'' differs by a rounding are too:
    # k dt - (k - 1) dt is not dt in floats)
    br = g.breakpoints(0.0, 2.0)
    assert set(jumps) <= set(br.tolist())
    t = np.linspace(0.0, 2.0, 81)
    tr = cs.simulate(c, g, 2.0, t_eval=t)
    assert len(tr.events) > 3
    ref_x, ref_v = Oracle.for_crawler(c, kin, br).solve(2.0, t, h=1e-4)
    np.testing.assert_allclose(tr.x, ref_x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(tr.v, ref_v, rtol=0, atol=1e-8)


def test_a_very_sharp_scallop_is_exact_and_cheap():
    # asymmetry 0.006: the extension lasts 0.6 % of the period and |l'''| there is ~1e9 times
    # the slow phase's. The search takes the bounds of each interval it proves (the Scallop's
    # bins there), so the slow phase is not searched with the sharp phase's steps (one bound
    # for a whole call ran out of its 10 million steps). Reference: the independent
    # event-driven oracle (test/support/oracle.py) at h = 1e-5 s.
    from crawler_sim.core.solvers.exact import ExactSolver
    g = gaits.Scallop(1.0, 0.2, 0.8, 0.006)
    c = cs.Crawler([1.0, 1.0], [1.0, 2.0])
    s = ExactSolver(c, g)
    s.advance(2.5)
    ref, _ = Oracle.for_crawler(c, lambda t: g(np.asarray(t, float))).solve(2.5, [0.0, 2.5],
                                                                              h=1e-5)
    np.testing.assert_allclose(s.current()['x'], ref[1], rtol=0, atol=1e-10)
    assert s.n_evals < 50_000, s.n_evals


def test_a_walk_over_pieces_stops_at_the_root_of_the_row_that_fails():
    # On a piecewise gait the search walks the pieces and, in the first piece where a row may
    # fail, stops just before that row's quadratic's first root. The quadratics were stored
    # for the rows the segment has (fewer than the core has room for) but read back at the
    # core's offsets: the root was another row's, and the walk fell back to halving. Here
    # (three bodies, a periodic Spline of 16 pieces, 10 periods, 59 events): 315 evaluations
    # before, 233 with the roots read right; positions against the independent oracle to
    # 1e-10 m.
    from crawler_sim.core.solvers.exact import ExactSolver
    tk = np.linspace(0.0, 1.0, 17)
    phase = -0.9 * np.arange(2)
    y = 1.0 + 0.25 * np.sin(2 * np.pi * tk[:, None] + phase)
    y[-1] = y[0]
    g = gaits.Spline(tk, y, periodic=True)
    c = cs.Crawler([1.2, 0.7, 1.6], [1.5, 0.9, 2.4])
    s = ExactSolver(c, g, periodic_skip=False)
    s.advance(10.0)
    ref, _ = Oracle.for_crawler(c, lambda t: g(np.asarray(t, float))).solve(10.0, [0.0, 10.0],
                                                                               h=1e-4)
    np.testing.assert_allclose(s.current()['x'], ref[1], rtol=0, atol=1e-10)
    assert s.n_evals <= 260, s.n_evals


def test_a_body_leaving_rest_slowly_is_watched_densely_whatever_the_span():
    # 400 C2 constant-jerk pieces, p = 4 (seed 12 of an independent generator): body 0 leaves
    # rest at t = 0.0189 s with a velocity that grows from zero slowly (its row stays within
    # rounding noise for a while), slides for 93 us, sticks for 0.4 ms and slides on. While a
    # row was at its noise level the search points were spaced by the span / 8 (0.06 s over a
    # 0.5 s run): the stick was stepped over and positions ended 3.7 mm off; the points now
    # grow at most twofold while a row is watched. Reference: the independent oracle.
    from crawler_sim.core.gaits.cubic import cubic_values
    rng = np.random.default_rng(12)
    p, nl, T = 4, 3, 0.5
    m = rng.uniform(0.3, 2.0, p)
    f = rng.uniform(0.2, 3.0, p) * m
    c = cs.Crawler(m, f, f * rng.uniform(0.5, 2, p))
    starts = np.concatenate([[0.0], np.sort(rng.uniform(0, T, 399))])
    l, v, a = np.full(nl, 0.1), rng.uniform(-0.5, 0.5, nl), rng.uniform(-20, 20, nl)
    pieces = []
    for k, t0 in enumerate(starts):
        jerk = rng.uniform(-3000, 3000, nl)
        pieces.append(gaits.Cubic(t0, l, v, a, jerk))
        t1 = starts[k + 1] if k + 1 < len(starts) else T
        l, v, a = cubic_values(l, v, a, jerk, t1 - t0)
    g = gaits.PiecewiseCubic(starts, pieces)
    t = np.linspace(0.0, T, 11)
    tr = cs.simulate(c, g, T, t_eval=t)
    assert [(e.body, e.old, e.new) for e in tr.events if 0.01891 < e.time < 0.0194] == \
        [(0, -1, 0), (0, 0, 1)]
    ref, _ = Oracle.for_crawler(c, lambda s: g(np.asarray(s, float))).solve(T, t, h=T / 2e4)
    np.testing.assert_allclose(tr.x, ref, rtol=0, atol=1e-10)
    # the same pieces streamed one by one, as the node hands them out
    st = cs.Stepper(c, pieces[0])
    for pc, end in zip(pieces, list(starts[1:]) + [T]):
        st.advance(end, pc)
    np.testing.assert_allclose(st.state.x, ref[-1], rtol=0, atol=1e-10)
