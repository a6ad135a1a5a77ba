"""Differential fuzz of the exact method against the independent oracle (issue 14 part 4).

Each case is drawn from a numpy generator seeded by hypothesis (``draw_case(family, rng)``), so
the quick profile here and the long profile of ``python -m benchmarks.solvers stress`` (``run_fuzz``) share one
generator. Scenes: p = 2..8, masses and frictions over four decades, zero and
direction-dependent friction, slopes, v0 != 0. Gait families: Custom lambdas of ``math``
functions without a period, with a jerk bound, with breakpoints (a bang-bang stroke), Custom
lambda copies of Scallops down to asymmetry 0.01 (with and without period=) and of Fourier gaits
of 3-6 harmonics, every built-in gait (Sinusoid, Fourier, Scallop down to asymmetry 0.02,
PiecewiseParabolic strokes and random non-periodic bang-bang strokes, Spline clamped and
periodic, PiecewiseCubic of a few and of hundreds of pieces), and gait switches mid-run through
``Stepper.advance(t1, gait)`` as the node does (C2 Cubic pieces streamed one by one, the same
pieces as one PiecewiseCubic, and a Sinusoid continued by Cubic pieces).

Pass: at every sample, positions within 1e-10 m (1e-10 relative beyond 1 m) and velocities within
1e-10 (relative to 1 + the largest velocity) of the oracle, no exception and no stall, and, for
``simulate`` runs, ``verify(tr, gait).ok()``.

Issue 37's edges of float time: each one-gait case streamed (``check_stream``) after first
steps of one float and of 1e-200 s onto every event time of its one-shot run and the floats
either side, and each periodic case started past 600 s (``check_late_start``, where tol / 2 is
below half a float spacing of t) against the oracle's run from 0, with what ulp(t) of time does
to the gait's values; ``N_EXAMPLES // 5`` cases a family here, every case in the long profile.

The quick profile (``make test``) runs ``CRAWLER_SIM_FUZZ_EXAMPLES`` (default 10) derandomised
examples per family without the example database, so CI is deterministic; shrinking is off
(the failing case's parameters are printed instead, to rerun with ``check_case``).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings, strategies as st

import crawler_sim as cs
from test.support.fuzz import (FAMILIES, ISSUE_SCENES, N_EXAMPLES, TOL, Case,  # noqa: F401
                               check_case, check_late_start, check_stream, draw_case, oracle_h,
                               sample_times, stream_targets)

G = cs.gaits
_QUICK = settings(max_examples=N_EXAMPLES, derandomize=True, database=None, deadline=None,
                  phases=[Phase.explicit, Phase.generate],
                  suppress_health_check=list(HealthCheck))


@pytest.mark.parametrize('family', FAMILIES)
@_QUICK
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_exact_agrees_with_the_oracle(family, seed):
    check_case(draw_case(family, seed))


# issue 37: the edges of float time, fewer examples (the long profile runs more, ``run_fuzz``)
_EDGES = settings(_QUICK, max_examples=max(1, N_EXAMPLES // 5))
_ONE_GAIT = [f for f in FAMILIES if not f.startswith('switch_')]
_PERIODIC = ('custom_period', 'sinusoid', 'fourier', 'scallop', 'stroke', 'spline_periodic')


@pytest.mark.parametrize('family', _ONE_GAIT)
@_EDGES
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_streams_onto_event_times_agree_with_the_oracle(family, seed):
    # a first step of one float and of 1e-200 s, then every event time and the floats either
    # side of it (items 2 and 3)
    check_stream(draw_case(family, seed))


@pytest.mark.parametrize('family', _PERIODIC)
@_EDGES
@given(seed=st.integers(0, 2 ** 32 - 1))
def test_periodic_gaits_started_past_512_s_agree_with_the_oracle(family, seed):
    # where tol / 2 is below half a float spacing of t (item 1), against the motion from 0
    check_late_start(draw_case(family, seed))


def test_stream_targets_sit_on_and_around_each_event():
    te = 0.09430771556226782
    ts = stream_targets([0.0, te], 1.0)
    assert ts[0] == 5e-324 and 1e-200 in ts and ts == sorted(set(ts))
    assert {math.nextafter(te, 0.0), te, math.nextafter(te, 1.0)} <= set(ts)
    assert all(0.0 < t < 1.0 for t in ts)


@pytest.mark.parametrize('name', list(ISSUE_SCENES))
def test_the_issue_scenes_agree_with_the_oracle(name):
    c, g, T, v0 = ISSUE_SCENES[name]
    kin_g = G.Sinusoid(1.0, 0.3, 1.0) if isinstance(g, G.Custom) else g
    case = Case(family='issue', seed=0, crawler=c, t_end=T, v0=v0,
                kin=lambda t: kin_g(np.asarray(t, float)), breakpoints=np.empty(0),
                timescale=0.05 if name == 'sharp_scallop' else 0.5, gait=g, desc=name)
    check_case(case)


def test_the_generator_covers_the_ranges_the_issue_asks_for():
    # p = 2..8, masses and frictions over decades, zero and direction-dependent friction,
    # slopes and v0 != 0 all occur among the first 200 seeds of each family
    cases = [draw_case(f, s) for f in FAMILIES for s in range(25)]
    ps = {c.crawler.p for c in cases}
    assert ps == set(range(2, 9))
    m = np.concatenate([c.crawler.masses for c in cases])
    assert m.min() < 0.05 and m.max() > 20
    assert any(np.any(c.crawler.friction == 0) for c in cases)
    assert any(np.any(c.crawler.friction != c.crawler.friction_backward) for c in cases)
    assert any(c.crawler.slope != 0 for c in cases)
    assert any(c.v0 != 0 for c in cases)
    assert any(c.gait is not None and c.gait.period is None for c in cases if
               c.family == 'custom')


