"""Issue 37 ("Exact at every edge"): the exact method at the edges of float time.

Items 1-3 had one root: a step or a span below the float spacing of the time it starts from.
The search's floors (64 tol, tol / 2) and a watched row's cap (an eighth of the span) are
absolute times; past t = 512 s half of tol = 1e-13 s is below half an ulp of t, and a span of one
float has an eighth of a float as its cap, so a + h == a: the search proposed the point it
stood on, for ever ("ran out of steps"). A Custom gait's first window of a few floats near 0 had
l'' scales (|l| / h^2) and derivative factors (1 / h) beyond the float range: inf, then NaN
tolerances refused equal values, and the failed call left the gait's span behind, so the gait
object failed every later run.

Expected values come from the physics, not from the code under test: where a stream is cut
does not change the motion (a one-shot run is the reference of a streamed one), and a Custom
gait is the same motion as the built-in gait it copies (the Fourier or Sinusoid twin, evaluated
in closed form by another code path).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core.solvers.exact import ExactSolver

G = cs.gaits

# issue 37 item 1: a 3-sine Custom gait per linkage with period= and jerk_bound=, p = 4
_M = [1.5629954087545868, 2.218008644111856, 0.6761434922904597, 2.1306182039976624]
_FP = [7.389481979928198, 12.294781465888741, 5.575290751503352, 13.069789713400533]
_FM = [132.77226949455275, 0.6775298093029211, 2.923056863863834, 26.76928951178295]
_A = np.array([[0.08274333057651158, 0.010737782759968872, 0.004507352750247873],
               [0.038712761774859515, 0.002147221275624548, 0.00455914100562944],
               [0.08006592128467518, 0.015611256125972308, 0.022598188253238848]])
_PH = np.array([[-0.0, 1.4004864706210465, 0.9526582451021257],
                [-1.3675527612785898, 4.446758092084018, 4.910867901087457],
                [-2.7351055225571796, 5.8887840302700045, 1.9430912566413006]])
_F = 1.2831444710011162
_JB = [152.15259014861755, 93.79693152482456, 427.1505505286431]


def _three_sines(period: float | None) -> G.Custom:
    w = 2 * math.pi * _F
    k = np.arange(1, 4)
    return G.Custom(lambda t: 1.0 + (_A * np.sin(k * w * t + _PH)).sum(1),
                    lambda t: (_A * k * w * np.cos(k * w * t + _PH)).sum(1),
                    lambda t: -(_A * (k * w) ** 2 * np.sin(k * w * t + _PH)).sum(1),
                    period=period, jerk_bound=_JB)


def test_a_custom_gait_with_a_period_runs_past_512_s():
    # item 1: "the event search ran out of steps" at t = 505.4 s (a call's start; the search
    # stood at 512.48 s) with periodic_skip off. Reference: the same gait as a built-in Fourier
    # gait (closed-form harmonics, not Chebyshev pieces), which ran
    cr = cs.Crawler(_M, _FP, _FM)
    four = G.Fourier([1.0] * 3, (_A * np.sin(_PH), _A * np.cos(_PH)), _F)
    T = 520.0
    ref = cs.simulate(cr, four, T, t_eval=[0.0, T], periodic_skip=False).x[-1]
    for skip in (False, True):
        x = cs.simulate(cr, _three_sines(1 / _F), T, t_eval=[0.0, T], periodic_skip=skip).x[-1]
        assert np.abs(x - ref).max() <= 1e-9 * max(1.0, float(np.abs(ref).max())), skip


def test_a_search_over_one_float_of_time_ends():
    # the mechanism alone: a row at zero (watched) over the span [t0, t0 + 1 ulp], whose cap
    # (an eighth of the span) is below the float spacing: no event (the row stays at 0),
    # found in a step or two, not after ten million steps that stand still
    core = ExactSolver(cs.Crawler([1.0, 1.0], [1.0, 1.0]), G.Sinusoid(1.0, 0.1, 1.0))._core
    gait = G.Sinusoid(1.0, 0.1, 1.0).compiled()
    for t0 in (0.09430771556226782, 600.0, 1e4):
        end = math.nextafter(t0, math.inf)
        t, hit, n = core.search_rows(gait, t0, end, [0.0], [0.0], [[0.0]], [[0.0]], 1e-13,
                                     (end - t0) / 8)
        assert t == math.inf and not hit.any() and n <= 4, (t0, t, n)


_CUBIC_CRAWLER = ([0.41462391654870795, 226.302882388338],
                  [1.826232931543997, 643.6845310654703], [1.2876761737104991, 251.4747913746508])
_CUBIC = (0.0, [1.0], [0.1355729677611942], [3.331112769209654], [-101.13005926070726])


def test_a_cubic_streamed_one_float_past_each_event_follows_the_one_shot_run():
    # item 2: advance to an event time (or one float before it), then one float on, raised
    # "ran out of steps". Reference: the one-shot run sampled 10 ms later (where a stream is
    # cut does not change the motion)
    cr = cs.Crawler(*_CUBIC_CRAWLER)
    g = G.Cubic(*_CUBIC)
    one = cs.simulate(cr, g, 0.3)
    assert len(one.events) == 3
    for e in one.events:
        te = float(e.time)
        t_end = te + 0.01
        ref = cs.simulate(cr, g, t_end, t_eval=[0.0, t_end])
        for first in (te, math.nextafter(te, -1.0), math.nextafter(te, 1.0)):
            st = cs.Stepper(cr, g)
            for t1 in (first, math.nextafter(first, 1.0), math.nextafter(first, 2.0), t_end):
                if t1 > st.t:
                    st.advance(t1)
            assert np.abs(st.state.x - ref.x[-1]).max() <= 1e-12, (e, first)
            assert np.abs(st.state.v - ref.v[-1]).max() <= 1e-10, (e, first)


_W = 2 * math.pi
_SINE = (lambda t: 1.0 + 0.05 * math.sin(_W * t), lambda t: 0.05 * _W * math.cos(_W * t),
         lambda t: -0.05 * _W * _W * math.sin(_W * t))


@pytest.mark.parametrize('period', [None, 1.0])
def test_a_custom_gait_takes_a_first_step_of_a_few_floats(period):
    # item 3: a first advance to t <= 1e-200 s (one float after 0 included: an event at 0 puts
    # a stream's target there) refused the gait ("... is X, but ... gives X"); 1e-310 s made
    # NaN derivatives. Reference: the built-in Sinusoid of the same motion, in one step
    cr = cs.Crawler(masses=[1.0, 1.0], mu=0.3)
    ref = cs.Stepper(cr, G.Sinusoid(1.0, 0.05, 1.0))
    ref.advance(0.5)
    for t1 in (5e-324, 1e-310, 1e-300, 1e-200, 1e-100):
        g = G.Custom(*_SINE, period=period)
        st = cs.Stepper(cr, g)
        st.advance(t1)
        st.advance(math.nextafter(t1, 1.0))
        st.advance(0.5)
        assert np.abs(st.state.x - ref.state.x).max() <= 1e-12, t1
        # and the gait object serves a later run
        tr = cs.simulate(cr, g, 1.0, t_eval=[0.0, 1.0])
        assert np.isfinite(tr.x).all()


@pytest.mark.parametrize('period', [None, 1.0])
def test_a_failed_run_leaves_a_custom_gait_as_it_was(period):
    # item 3's second half: after a call that fails, the same gait object gave the same error
    # in every later run (the failed span was kept: a new run's first reading, inside it,
    # built the failing window again). Reference: a fresh gait of the same functions
    def acc(t):
        if t > 0.5:
            raise ZeroDivisionError('the user\'s bug past 0.5 s')
        return _SINE[2](t)

    cr = cs.Crawler(masses=[1.0, 1.0], mu=0.3)
    g = G.Custom(_SINE[0], _SINE[1], acc, period=period)
    with pytest.raises(ZeroDivisionError):
        cs.simulate(cr, g, 1.0)
    after = cs.simulate(cr, g, 0.4, t_eval=[0.0, 0.2, 0.4])
    fresh = cs.simulate(cr, G.Custom(_SINE[0], _SINE[1], acc, period=period), 0.4,
                        t_eval=[0.0, 0.2, 0.4])
    assert np.array_equal(after.x, fresh.x) and np.array_equal(after.v, fresh.v)


def test_a_periodic_custom_gait_streamed_from_three_periods_is_the_motion_from_0():
    # found by the late-start fuzz (custom_period seed 81): started at 3 periods, a time past
    # the first period was asked before that period's pieces were complete, and the table was
    # built 0.14 s longer than the period, then read modulo the period: 4.5e-4 m off. The gait
    # repeats, so the motion from 3 periods is the motion from 0 shifted (reference: the run
    # from 0, streamed to the same offsets)
    from test.support.fuzz import draw_case
    case = draw_case('custom_period', 81)
    P = case.gait.period
    offsets = [0.4669924307318728, 0.8765267915190254, 1.833736527625102, 2.1452531355034155]
    runs = []
    for t0 in (0.0, 3 * P):
        gait = draw_case('custom_period', 81).gait
        st = cs.Stepper(case.crawler, gait, t0=t0, v0=case.v0)
        xs = []
        for s in offsets:
            st.advance(t0 + s)
            xs.append(st.state.x)
        runs.append(np.array(xs))
        table = gait.compiled().table
        assert table.periodic and table.knots[-1] - table.knots[0] <= P * (1 + 1e-15)
    assert np.abs(runs[1] - runs[0]).max() <= 1e-10


@pytest.mark.parametrize('family', ['spline_periodic', 'fourier', 'scallop', 'stroke'])
def test_a_period_far_from_0_moves_the_crawler_as_the_first_ones_do(family):
    # item 4: with periodic_skip off the displacement per period drifted with t (event times
    # to ulp(t), the gait read with a phase error of ulp(t)): a p = 4 periodic Spline moved
    # 1.5e-12 m more a period at 1e3 periods, 3.6e-9 m at 1e6 (x off by ~N^2). The gait
    # repeats, so a period run from k T moves the crawler as the same period from 0 does
    # (physics: invariance under a shift by whole periods); each period now runs in its own
    # frame (local time from k T)
    from test.support.fuzz import draw_case
    seed = {'spline_periodic': 144, 'fourier': 4, 'scallop': 4, 'stroke': 5}[family]
    case = draw_case(family, seed)
    P = case.gait.period
    D, v_max = {}, 0.0
    for m in (0, 100_000, 1_000_000):
        st = cs.Stepper(case.crawler, draw_case(family, seed).gait, t0=m * P, v0=case.v0,
                        periodic_skip=False)
        xs = [float(st.state.x[0])]
        for k in range(1, 13):
            st.advance((m + k) * P)
            xs.append(float(st.state.x[0]))
            v_max = max(v_max, float(np.abs(st.state.v).max()))
        D[m] = np.diff(xs)
    scale = max(1.0, float(np.abs(D[0]).max()))
    for m in (100_000, 1_000_000):
        # the times (m + k) P are floats: a sample is known to ulp(t) of time, v_max ulp(t) of
        # position at each end (1.5e-11 s at 1e5 periods of 1.26 s); the drift was 26 times that
        tol = 1e-12 * scale + 4.0 * v_max * float(np.spacing((m + 12) * P))
        assert np.abs(D[m] - D[0]).max() <= tol, (m, np.abs(D[m] - D[0]).max(), tol)
