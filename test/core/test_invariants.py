"""Invariants of the model (MODEL.md s.6) that hold for any gait, checked on the exact method.

Each test compares two runs that physics says must agree (or one run against a conserved
quantity), so no number here comes from the code under test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import gaits
from test.support.core import random_crawler as _crawler, wave as _wave

G = 9.81






# ----------------------------------------------------------------------------------------------
# Frictionless: sum of forces = F_ext = 0, so M V' = 0 and X(t) = X(0) + V(0) t exactly, with
# V(0) = v0 - e_0'(0) whatever the gait does.
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p,v0', [(2, 0.0), (3, 0.0), (10, 0.0),
                                  (2, 0.3), (3, 0.3), (10, 0.3)])
def test_without_friction_the_centre_of_mass_moves_at_constant_velocity(p, v0):
    rng = np.random.default_rng(p)
    crawler = cs.Crawler(rng.uniform(0.5, 2.0, p), 0.0)
    gait = _wave(p)
    t = np.linspace(0.0, 3.0, 301)
    tr = cs.simulate(crawler, gait, 3.0, v0=v0, t_eval=t)
    m = crawler.masses
    _, ld, _ = gait(0.0)
    s_dot = np.concatenate([[0.0], np.cumsum(ld)])
    V0 = v0 + s_dot @ m / m.sum()   # V = v_0 - e_0' and e_0' = -(sum m_k s_k')/M
    np.testing.assert_allclose(tr.com_velocity, V0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(tr.com, tr.com[0] + V0 * t, rtol=0, atol=1e-13)
    assert np.all(tr.friction == 0.0)


def test_a_frictionless_crawler_started_from_rest_under_a_constant_rate_stroke_keeps_its_momentum():
    # l' = 0.1 constant, l'' = 0, no friction: V = V(0) = v0 + m1 l'/M = 2/3 * 0.1 forever, and body
    # 0 keeps v_0 = 0 (it has no reason to move, and no force to resist moving either).
    crawler = cs.Crawler([1.0, 2.0], 0.0)
    t = np.linspace(0.0, 1.0, 11)
    tr = cs.simulate(crawler, gaits.Cubic(0.0, 0.1, 0.1, 0.0, 0.0), 1.0, t_eval=t)
    np.testing.assert_allclose(tr.com_velocity, 0.2 / 3.0, rtol=1e-14)
    np.testing.assert_allclose(tr.v[:, 0], 0.0, atol=1e-15)


# ----------------------------------------------------------------------------------------------
# Mirror symmetry. x -> -x with the body order reversed maps a solution to a solution of the
# mirrored crawler: masses and frictions reversed, f_plus <-> f_minus, slope -> -slope and
# linkage j -> p-2-j (l'_j = x'_{j+1} - x'_j = x_{p-1-j} - x_{p-2-j} = l_{p-2-j}). Initial data:
# body 0 of the mirror is body p-1 of the original: x'_0 = -(x0 + sum l(0)), v'_0 = -(v0 + sum l'(0)).
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p', [2, 3, 10])
@pytest.mark.parametrize('slope', [0.0, 0.05])
def test_the_mirror_image_of_a_run_is_the_run_of_the_mirrored_crawler(p, slope):
    c = _crawler(p, slope, seed=p)
    gait = _wave(p)
    mirror = cs.Crawler(c.masses[::-1], c.friction_backward[::-1], c.friction[::-1], slope=-slope)
    mgait = gaits.Sinusoid(gait.mean[::-1], gait.amplitude[::-1], gait.frequency,
                           gait.phase[::-1])
    x0, v0 = 0.2, 0.05
    l, ld, _ = gait(0.0)
    t = np.linspace(0.0, 3.0, 241)
    a = cs.simulate(c, gait, 3.0, x0=x0, v0=v0, t_eval=t)
    b = cs.simulate(mirror, mgait, 3.0, x0=-(x0 + l.sum()), v0=-(v0 + ld.sum()), t_eval=t)
    np.testing.assert_allclose(b.x, -a.x[:, ::-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.v, -a.v[:, ::-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.friction, -a.friction[:, ::-1], rtol=0, atol=1e-10)
    assert b.displacement == pytest.approx(-a.displacement, abs=1e-12)
    ea = sorted((round(e.time, 9), p - 1 - e.body, -e.old, -e.new) for e in a.events)
    eb = sorted((round(e.time, 9), e.body, e.old, e.new) for e in b.events)
    assert ea == eb


# Equal masses, equal (isotropic) friction, p = 2: the mirrored crawler is the crawler itself and
# the mirrored gait is the gait itself, so V -> -V maps solutions to solutions. e_0' = -l'/2,
# e_1' = l'/2: whenever |V| <= |l'|/2 the bodies slide in opposite directions and the frictions
# cancel (V' = 0), and when l' = 0 with V = 0 both stick. Hence a start with V(0) = 0 (v0 = -l'(0)/2)
# keeps V == 0: the COM never moves, for any gait, however asymmetric its stroke.
def _symmetric_gaits():
    return {
        'sinusoid': gaits.Sinusoid(0.1, 0.03, 1.0),
        'scallop': gaits.Scallop(0.1, 0.03, 1.0, 0.2),
        'fourier': gaits.Fourier(0.1, ([0.02, 0.0], [0.0, 0.008]), 1.0),
    }


@pytest.mark.parametrize('name', ['sinusoid', 'scallop', 'fourier'])
def test_equal_bodies_started_with_zero_com_velocity_never_move_their_centre_of_mass(name):
    gait = _symmetric_gaits()[name]
    crawler = cs.Crawler([1.0, 1.0], [0.8, 0.8])
    v0 = -0.5 * gait(0.0)[1][0]
    t = np.linspace(0.0, 4.0, 401)
    tr = cs.simulate(crawler, gait, 4.0, v0=v0, t_eval=t)
    np.testing.assert_allclose(tr.com_velocity, 0.0, atol=1e-14)
    np.testing.assert_allclose(tr.com, tr.com[0], rtol=0, atol=1e-14)


# From rest instead (v0 = 0, l'(0) = A w > 0, sinusoid): V(0) = l'(0)/2, body 0 at rest and body 1
# sliding forward. Body 0 sticks (needs R_0 = m l'' + f <= f since l'' <= 0 on [0, T/4]) so V = l'/2
# until l' = 0 at T/4, where V = 0; from then on V == 0 as above. So the displacement per period
# is exactly zero from the first period on, and the whole transient is A/2 (body 1 moved by A).
# The scallop starts at l' = 0 (minimum of l), so V(0) = 0 and it never moves at all.
@pytest.mark.parametrize('name', ['sinusoid', 'scallop'])
def test_equal_bodies_have_zero_steady_displacement_per_period(name):
    gait = _symmetric_gaits()[name]
    crawler = cs.Crawler([1.0, 1.0], [0.8, 0.8])
    T = gait.period
    t = np.arange(0, 9) * T / 2
    tr = cs.simulate(crawler, gait, t[-1], t_eval=t)
    steady = tr.com[2:]
    np.testing.assert_allclose(steady, steady[0], rtol=0, atol=1e-14)
    assert tr.mean_speed(T) == pytest.approx(0.0, abs=1e-14)


# For a general stroke (the Fourier one, l'(0) != 0 and l'' changing sign inside the extension) the
# transient need not end in finite time: |V| only decreases, by an amount proportional to |V|, near
# each zero of l' (MODEL: M V' = -2 f sign V while |V| > |l'|/2, 0 otherwise). So the displacement
# per period must shrink geometrically to zero, never reverse, and never grow.
def test_equal_bodies_under_a_general_stroke_have_a_displacement_per_period_decaying_to_zero():
    gait = _symmetric_gaits()['fourier']
    crawler = cs.Crawler([1.0, 1.0], [0.8, 0.8])
    t = np.arange(0, 13) * gait.period
    tr = cs.simulate(crawler, gait, t[-1], t_eval=t)
    d = np.diff(tr.com)
    assert d[0] > 1e-3
    assert np.all(np.abs(d[1:]) <= np.abs(d[:-1]) + 1e-15)
    assert abs(d[-1]) <= 1e-13


def test_equal_bodies_from_rest_move_exactly_half_the_amplitude_in_the_transient():
    A = 0.03
    tr = cs.simulate(cs.Crawler([1.0, 1.0], [0.8, 0.8]), gaits.Sinusoid(0.1, A, 1.0), 2.0,
                     t_eval=[0.0, 0.25, 2.0])
    np.testing.assert_allclose(tr.com - tr.com[0], [0.0, A / 2, A / 2], rtol=0, atol=1e-14)


# ----------------------------------------------------------------------------------------------
# A rigid link (l_j constant) between bodies j and j+1 makes them one body of mass m_j + m_{j+1}
# and friction f_j + f_{j+1} (both have the same velocity, so their forces add, in stick too).
# p = 3 with l_0 constant ('front') compares body 1 with the merged body 0 of a p = 2 crawler
# driven by l_1; with l_1 constant ('back') body 0 with body 0 and body 1 with the merged body 1.
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('rigid', ['front', 'back'])
@pytest.mark.parametrize('slope', [0.0, 0.08])
def test_a_rigid_link_behaves_as_one_merged_body(rigid, slope):
    m = np.array([0.7, 0.5, 1.1])
    fp = np.array([0.9, 0.4, 1.2])
    fm = np.array([1.4, 1.1, 0.6])
    L, A, freq = 0.12, 0.03, 1.3
    c3 = cs.Crawler(m, fp, fm, slope=slope)
    t = np.linspace(0.0, 3.0, 301)
    x0, v0 = 0.1, 0.02
    if rigid == 'front':
        g3 = gaits.Sinusoid([L, 0.1], [0.0, A], freq, [0.0, 0.4])
        c2 = cs.Crawler([m[0] + m[1], m[2]], [fp[0] + fp[1], fp[2]], [fm[0] + fm[1], fm[2]],
                        slope=slope)
        g2 = gaits.Sinusoid(0.1, A, freq, 0.4)
        a = cs.simulate(c3, g3, 3.0, t_eval=t, x0=x0, v0=v0)
        b = cs.simulate(c2, g2, 3.0, t_eval=t, x0=x0 + L, v0=v0)
        np.testing.assert_allclose(a.x[:, 1:], b.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.x[:, 0], b.x[:, 0] - L, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.v[:, 1:], b.v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.friction[:, 0] + a.friction[:, 1], b.friction[:, 0],
                                   rtol=0, atol=1e-10)
        np.testing.assert_allclose(a.friction[:, 2], b.friction[:, 1], rtol=0, atol=1e-10)
        stuck_pair = b.contact[:, 0] == 0
    else:
        g3 = gaits.Sinusoid([0.1, L], [A, 0.0], freq, [0.4, 0.0])
        c2 = cs.Crawler([m[0], m[1] + m[2]], [fp[0], fp[1] + fp[2]], [fm[0], fm[1] + fm[2]],
                        slope=slope)
        g2 = gaits.Sinusoid(0.1, A, freq, 0.4)
        a = cs.simulate(c3, g3, 3.0, t_eval=t, x0=x0, v0=v0)
        b = cs.simulate(c2, g2, 3.0, t_eval=t, x0=x0, v0=v0)
        np.testing.assert_allclose(a.x[:, :2], b.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.x[:, 2], b.x[:, 1] + L, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.v[:, :2], b.v, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.friction[:, 1] + a.friction[:, 2], b.friction[:, 1],
                                   rtol=0, atol=1e-10)
        stuck_pair = b.contact[:, 1] == 0
    # the two rigidly linked bodies stuck together: only their total is determined
    assert stuck_pair.any()
    assert np.all(a.indeterminate[stuck_pair])


# ----------------------------------------------------------------------------------------------
# Scaling all masses and friction forces by k: every force scales by k, every acceleration is
# unchanged, so positions and velocities are identical and forces scale by k.
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p', [2, 3, 10])
@pytest.mark.parametrize('k', [0.01, 3.7])
def test_scaling_all_masses_and_frictions_changes_nothing_but_the_forces(p, k):
    c = _crawler(p, slope=0.04, seed=10 + p)
    ck = cs.Crawler(k * c.masses, k * c.friction, k * c.friction_backward, slope=c.slope)
    gait = _wave(p)
    t = np.linspace(0.0, 2.5, 201)
    a = cs.simulate(c, gait, 2.5, t_eval=t, v0=0.03)
    b = cs.simulate(ck, gait, 2.5, t_eval=t, v0=0.03)
    np.testing.assert_allclose(b.x, a.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.v, a.v, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(b.contact, a.contact)
    np.testing.assert_allclose(b.friction / k, a.friction, rtol=0, atol=1e-10)
    np.testing.assert_allclose(b.linkage_force / k, a.linkage_force, rtol=0, atol=1e-10)
    assert [e.body for e in a.events] == [e.body for e in b.events]
    np.testing.assert_allclose([e.time for e in a.events], [e.time for e in b.events], atol=1e-12)


def test_scaling_masses_with_friction_coefficients_changes_nothing_on_a_slope():
    # from_coefficients: f = mu m g cos(slope) scales with m automatically.
    gait = _wave(3)
    t = np.linspace(0.0, 2.0, 101)
    a = cs.simulate(cs.Crawler.from_coefficients([1.0, 2.0, 0.5], [0.3, 0.5, 0.4], [0.6, 0.7, 0.5],
                                                 slope=0.1), gait, 2.0, t_eval=t)
    b = cs.simulate(cs.Crawler.from_coefficients([5.0, 10.0, 2.5], [0.3, 0.5, 0.4], [0.6, 0.7, 0.5],
                                                 slope=0.1), gait, 2.0, t_eval=t)
    np.testing.assert_allclose(b.x, a.x, rtol=0, atol=1e-12)


# ----------------------------------------------------------------------------------------------
# Energy balance: d/dt sum m_i v_i^2 / 2 = sum R_i v_i + sum g_i v_i + sum Lambda_j l_j'
# (the linkage forces do work Lambda_j (v_{j+1} - v_j)), so
#   actuator_work = dissipated_energy + Delta KE + Delta PE,   PE = sum m_i g sin(slope) x_i.
# Both work integrals are trapezoidal sums. The actuator power jumps at events (friction forces
# jump while l' does not vanish), so each event is sampled on both sides (t_ev -+ 1e-10 s, the
# two one-sided limits); the integrands are then smooth between samples and the mismatch is
# O(N^-2): 1e-6 of the actuator work for N = 4001 samples.
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p,slope', [(2, 0.0), (3, 0.1), (10, -0.05)])
def test_actuator_work_equals_dissipation_plus_kinetic_plus_potential_energy(p, slope):
    c = _crawler(p, slope, seed=20 + p)
    gait = _wave(p, amp=0.03)
    first = cs.simulate(c, gait, 3.0, v0=0.1)
    ev = np.array([e.time for e in first.events if 1e-9 < e.time < 3.0 - 1e-9])
    assert ev.size > 5
    t = np.union1d(np.linspace(0.0, 3.0, 4001), np.concatenate([ev - 1e-10, ev + 1e-10]))
    tr = cs.simulate(c, gait, 3.0, v0=0.1, t_eval=t)
    m = c.masses
    ke = 0.5 * (tr.v ** 2) @ m
    pe = G * math.sin(slope) * (tr.x @ m)
    balance = tr.dissipated_energy + (ke[-1] - ke[0]) + (pe[-1] - pe[0])
    assert tr.dissipated_energy > 0
    assert tr.actuator_work == pytest.approx(balance, rel=1e-6)


# ----------------------------------------------------------------------------------------------
# Skipping repeated periods is an optimisation: it must not change the answer.
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p', [2, 3])
def test_skipping_repeated_gait_periods_gives_the_same_run_as_integrating_them(p):
    c = _crawler(p, seed=30 + p)
    gait = _wave(p)
    t = np.linspace(0.0, 20.0, 777)     # no sample falls on an event (where the state is either)
    a = cs.simulate(c, gait, 20.0, t_eval=t, periodic_skip=True)
    b = cs.simulate(c, gait, 20.0, t_eval=t, periodic_skip=False)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(a.contact, b.contact)
    assert len(a.events) == len(b.events)
    np.testing.assert_allclose([e.time for e in a.events], [e.time for e in b.events], atol=1e-11)
    assert a.info['skipped_periods'] > 0 and b.info['skipped_periods'] == 0


# ----------------------------------------------------------------------------------------------
# The exact method does not depend on its numerical settings: a finer event grid (max_step) or a
# different sampling (t_eval) gives the same closed-form values.
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p', [2, 3, 10])
def test_a_finer_event_grid_does_not_change_the_exact_solution(p):
    c, gait = _crawler(p, 0.03, seed=50 + p), _wave(p)
    t = np.linspace(0.0, 2.0, 97)
    a = cs.simulate(c, gait, 2.0, t_eval=t, v0=0.05)
    b = cs.simulate(c, gait, 2.0, t_eval=t, v0=0.05, max_step=1e-3, periodic_skip=False)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.v, b.v, rtol=0, atol=1e-12)
    assert [(e.body, e.old, e.new) for e in a.events] == [(e.body, e.old, e.new) for e in b.events]


def test_values_at_requested_times_are_the_same_as_in_a_run_sampled_differently():
    c, gait = _crawler(3, 0.0, seed=55), _wave(3)
    dense = cs.simulate(c, gait, 2.0, t_eval=np.linspace(0.0, 2.0, 2001))
    sparse = cs.simulate(c, gait, 2.0, t_eval=[0.0, 0.3, 1.1, 1.7, 2.0])
    idx = [0, 300, 1100, 1700, 2000]
    np.testing.assert_allclose(sparse.x, dense.x[idx], rtol=0, atol=1e-13)
    np.testing.assert_allclose(sparse.v, dense.v[idx], rtol=0, atol=1e-13)
    np.testing.assert_allclose(sparse.friction, dense.friction[idx], rtol=0, atol=1e-12)
