"""What the exact method takes for a velocity at zero: a row's rounding at the start of a search,
not over its span, and a body's zero at an event only where its velocity is zero to rounding
(V is continuous). Expected values are derived by hand in each test."""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim.core as cs
from crawler_sim.core import gaits as G


def test_a_slip_from_rest_at_the_start_of_a_long_period_is_placed_at_its_time() -> None:
    # Body 0 (friction 1e-3 N) at rest, body 1 (1e3 N) carried at l'(0) = 2 pi f A: both slide
    # (body 1 cannot hold body 0 back), V' = -(1e3 - 1e-3) / M, and body 1's velocity
    # V + l'/2 = l'(0) - (1e3 - 1e-3) t / 2 (l'' = 0 at t = 0; its change is ~1e-35 m/s here)
    # reaches zero at t* = 2 l'(0) / (1e3 - 1e-3) = 1.2566e-14 s. The search took the velocity
    # for zero while it was within 1e-13 of its size over the 1e3 s period (5e-8 m/s): 1e-10 s.
    c = cs.Crawler([1.0, 1.0], [1e-3, 1e3])
    f, A = 1e-3, 1e-9
    g = G.Sinusoid(1.0, A, f)
    t_star = 2.0 * (2.0 * math.pi * f * A) / (1e3 - 1e-3)
    tr = cs.simulate(c, g, 3000.0)
    first = tr.events[1]
    assert (first.body, first.old, first.new) == (1, 1, 0)
    assert abs(first.time - t_star) <= 1e-13 * t_star + np.spacing(t_star)
    st = cs.Stepper(c, g)
    st.advance(5e-11)
    assert st.pop_events()[1].time == first.time


@pytest.mark.parametrize('r', [0.3, 0.5, 0.7])
def test_a_1khz_stroke_keeps_the_momentum_the_friction_gives(r: float) -> None:
    # A 1 kHz stroke of 0.1 m, masses 1e-3 / 1e3 / 1e3 kg, friction 1 / 2 / 2 N, both linkages
    # in phase: e = (-1.5, -0.5, 0.5) l to 5e-7, every body slides at ~1e3 m/s and turns only
    # where l' = 0 (within ~1e-11 s: V / |e''|). Extending (r T), bodies 0 and 1 slide back
    # (+1 N, +2 N), body 2 forward (-2 N): M V' = +1 N; contracting, -1 N. So at whole periods
    # V(k T) = k (2 r - 1) T / M, and V(r T) = r T / M (each to ~1e-13 m/s). The bodies' zeros
    # near l' = 0 are 1e-13 s apart with |e''| ~ 1e6 m/s^2: V was put onto the zero of a body
    # taken with another's event or moved onto the breakpoint r T, 3.5e-7 m/s away (a
    # momentum jump of M 3.5e-7 m/s), and the periodic skip then repeated the wrong period.
    m = np.array([1e-3, 1e3, 1e3])
    c = cs.Crawler(m, [1.0, 2.0, 2.0])
    f = 1000.0
    T = 1.0 / f
    M = float(m.sum())
    g = G.PiecewiseParabolic.stroke(1.0, 0.1, f, r, n_links=2)
    te = np.linspace(0.0, 40 * T, 9)
    k = np.round(te / T)
    expected = k * (2 * r - 1) * T / M
    for skip in (True, False):
        tr = cs.simulate(c, g, 40 * T, t_eval=te, periodic_skip=skip)
        V = tr.v @ m / M
        assert np.abs(V - expected).max() <= 1e-10, (skip, V - expected)
        assert cs.verify(tr, g).ok()
    st = cs.Stepper(c, g)
    st.advance(r * T)
    assert abs(st.state.v @ m / M - r * T / M) <= 1e-12
    st.advance(1.25 * T)
    assert abs(st.state.v @ m / M - ((2 * r - 1) * T + 0.25 * T) / M) <= 1e-12
