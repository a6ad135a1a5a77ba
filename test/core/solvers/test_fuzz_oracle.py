"""How the oracle's accuracy is established (test/support/oracle.py).

None of these compare with crawler_sim's solvers: closed forms derived by hand, invariances of the
model (MODEL.md section 6), self-convergence in the oracle's grid step, a fully independent
implicit-Euler prox converging at order 1 onto it, and the two values issue 14 states.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from test.support.oracle import Oracle, prox_implicit
from test.support import fuzz as tf

G = cs.gaits
W = 2 * math.pi


def _sin_kin(mean, amp, w, phase=0.0):
    mean, amp, phase = (np.atleast_1d(np.asarray(a, float)) for a in (mean, amp, phase))

    def kin(t):
        t = np.asarray(t, float)[:, None]
        s, c = np.sin(w * t + phase), np.cos(w * t + phase)
        return mean + amp * s, amp * w * c, -amp * w * w * s
    return kin


def test_the_issue_values_are_reproduced():
    # issue 14: Custom sine gait on Crawler([1, 1], [1, 1]) moves 1.13894 m in 4 s; the sharp
    # Scallop on Crawler([1, 1], [50, 10]) moves -0.19385193 m in 1 s (digits as printed there)
    o = Oracle([1, 1], [1, 1], [1, 1], 0.0, _sin_kin(1.0, 0.3, W))
    x, _ = o.solve(4.0, [0.0, 4.0], h=1e-4)
    assert abs((x[1, 0] - x[0, 0]) - 1.13894) < 5e-6
    g = G.Scallop(1.0, 0.3, 1.0, 0.05)
    o = Oracle([1, 1], [50, 10], [50, 10], 0.0, lambda t: g(np.asarray(t)))
    x, _ = o.solve(1.0, [0.0, 1.0], h=1e-5)
    assert abs((x[1, 0] - x[0, 0]) - (-0.19385193)) < 5e-9


def test_zero_friction_keeps_the_centre_of_mass_velocity():
    # no friction, no slope: M X'' = 0, so X(t) = X(0) + V(0) t exactly
    m = np.array([1.0, 3.0, 0.5])
    kin = _sin_kin([1.0, 0.7], [0.2, 0.1], 3.0, [0.0, 1.0])
    o = Oracle(m, [0, 0, 0], [0, 0, 0], 0.0, kin)
    t = np.linspace(0, 3, 31)
    x, v = o.solve(3.0, t, v0=0.4, h=1e-3)
    X, V = x @ m / m.sum(), v @ m / m.sum()
    assert np.allclose(V, V[0], rtol=0, atol=1e-13)
    assert np.allclose(X, X[0] + V[0] * t, rtol=0, atol=1e-12)


def test_a_pure_slide_is_the_hand_closed_form():
    # v0 = 20 m/s forward, T = 0.5 s: every body keeps sliding forward (its velocity stays
    # above 20 - 0.5 * a_max - |e'| > 0), so M V' = -sum f = -(1 + 2) N with M = 3 kg:
    # V(t) = V(0) - t, X(t) = X(0) + V(0) t - t^2 / 2
    m = np.array([1.0, 2.0])
    o = Oracle(m, [1.0, 2.0], [5.0, 5.0], 0.0, _sin_kin(1.0, 0.1, W))
    t = np.linspace(0, 0.5, 11)
    x, v = o.solve(0.5, t, v0=20.0, h=1e-3)
    X, V = x @ m / 3.0, v @ m / 3.0
    assert np.allclose(V, V[0] - t, rtol=0, atol=1e-13)
    assert np.allclose(X, X[0] + V[0] * t - t * t / 2, rtol=0, atol=1e-13)


def test_a_rigid_link_is_one_body_with_the_summed_mass_and_friction():
    # p = 3 with linkage 0 held at 0.5 m equals p = 2 with body 0+1 merged (mass 1 + 2,
    # friction 1 + 0.5 forward, 2 + 0.5 backward)
    kin3 = _sin_kin([0.5, 1.0], [0.0, 0.3], W, [0.0, 0.0])
    # merged body at (1 x_0 + 2 (x_0 + 0.5)) / 3 = x_0 + 1/3, so its link to body 2 is
    # 0.5 + l_1 - 1/3 = l_1 + 1/6 and it starts at x0 = 1/3
    kin2 = _sin_kin([1.0 + 1 / 6], [0.3], W)
    t = np.linspace(0, 3, 13)
    o3 = Oracle([1, 2, 3], [1, 0.5, 2], [2, 0.5, 1], -1.0, kin3)
    x3, _ = o3.solve(3.0, t, h=1e-4)
    o2 = Oracle([3, 3], [1.5, 2], [2.5, 1], -1.0, kin2)
    x2, _ = o2.solve(3.0, t, h=1e-4, x0=1 / 3)
    assert np.allclose(x3[:, 2], x2[:, 1], rtol=0, atol=1e-12)
    assert np.allclose(x3[:, 0] + 1 / 3, x2[:, 0], rtol=0, atol=1e-12)


def test_scaling_masses_and_frictions_together_changes_nothing():
    kin = _sin_kin([1.0, 0.8], [0.3, 0.2], W * 1.3, [0.0, 2.0])
    t = np.linspace(0, 2, 9)
    a = Oracle([1, 2, 0.5], [1, 3, 0.2], [2, 1, 0.4], 0.3, kin).solve(2.0, t, h=1e-4)[0]
    b = Oracle([1e3, 2e3, 5e2], [1e3, 3e3, 2e2], [2e3, 1e3, 4e2], 300.0, kin).solve(
        2.0, t, h=1e-4)[0]
    assert np.allclose(a, b, rtol=0, atol=1e-12)


def test_the_mirror_image_is_the_mirrored_motion():
    # x -> -x with the bodies in reverse order: masses reversed, forward and backward friction
    # swapped and reversed, external force negated, linkage j becomes linkage p-2-j, the
    # initial velocity of the new body 0 is minus that of the old last body.
    m, fp, fm = np.array([1.0, 2.0, 0.5]), np.array([1.0, 3.0, 0.2]), np.array([2.0, 1.0, 0.4])
    kin = _sin_kin([1.0, 0.8], [0.3, 0.2], W * 1.3, [0.0, 2.0])

    def kin_m(t):
        return tuple(a[:, ::-1] for a in kin(t))
    t = np.linspace(0, 2, 9)
    x, v = Oracle(m, fp, fm, 0.7, kin).solve(2.0, t, v0=0.3, h=1e-4)
    v_last0 = v[0, -1]
    xm, _ = Oracle(m[::-1], fm[::-1], fp[::-1], -0.7, kin_m).solve(
        2.0, t, x0=-x[0, -1], v0=-v_last0, h=1e-4)
    assert np.allclose(xm, -x[:, ::-1], rtol=0, atol=1e-12)


@pytest.mark.parametrize('family', tf.FAMILIES)
def test_a_four_times_finer_grid_changes_nothing_beyond_1e_12(family):
    for seed in (11, 12):
        case = tf.draw_case(family, seed)
        te = tf.sample_times(case)
        h = tf.oracle_h(case)
        a = Oracle.for_crawler(case.crawler, case.kin, case.breakpoints).solve(
            case.t_end, te, v0=case.v0, h=h)[0]
        b = Oracle.for_crawler(case.crawler, case.kin, case.breakpoints).solve(
            case.t_end, te, v0=case.v0, h=h / 4)[0]
        assert np.abs(a - b).max() <= 1e-12 * max(1.0, np.abs(a).max()), case


def test_an_independent_implicit_prox_converges_onto_the_oracle_at_order_one():
    # MODEL.md section 3, written separately in oracle.prox_implicit; the error must shrink
    # about 4x when dt shrinks 4x, and be small at the finest step
    c = cs.Crawler([1.0, 2.0], [0.5, 1.0])
    o = Oracle.for_crawler(c, _sin_kin(1.0, 0.3, W))
    x, _ = o.solve(1.0, [0.0, 1.0], h=1e-4)
    errs = [abs(prox_implicit(o, 1.0, dt)[1][0] - x[1, 0]) for dt in (4e-4, 1e-4)]
    assert errs[1] < 2e-4
    assert 2.5 < errs[0] / errs[1] < 6.5, errs
