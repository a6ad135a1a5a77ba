"""Stepper (streaming use) and the Trajectory figures.

Stepper: the same physics whether advanced in one call or many, bit-for-bit deterministic,
gait changes between calls, events delivered once, reset. Figures: stick fraction, mean speed,
cost of transport, dissipated energy and linkage forces checked against hand values and Newton.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import gaits
from test.support.core import random_crawler as _crawler, wave as _wave

G = 9.81






def _state_arrays(s):
    return [s.x, s.v, s.friction, s.contact, s.linkage_force, s.lengths, s.rates]


# ----------------------------------------------------------------------------------------------
# Many small advances == one advance (exact: closed form, so to rounding; implicit: same steps).
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p', [2, 3, 10])
def test_advancing_the_exact_stepper_in_many_small_calls_equals_one_call(p):
    crawler, gait, T = _crawler(p, 0.02, seed=80 + p), _wave(p), 3.0
    one = cs.Stepper(crawler, gait, v0=0.05)
    one.advance(T)
    ev_one = one.pop_events()
    many = cs.Stepper(crawler, gait, v0=0.05)
    rng = np.random.default_rng(p)
    cuts = np.sort(rng.uniform(0.0, T, 150))
    ev_many = []
    for tc in np.append(cuts, T):
        many.advance(tc)
        ev_many += many.pop_events()
    a, b = one.state, many.state
    assert a.t == b.t == T
    for x, y in zip(_state_arrays(a), _state_arrays(b)):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-11)
    assert [(e.body, e.old, e.new) for e in ev_one] == [(e.body, e.old, e.new) for e in ev_many]
    np.testing.assert_allclose([e.time for e in ev_one], [e.time for e in ev_many], atol=1e-11)
    assert len(ev_one) > 3


def test_advancing_the_implicit_stepper_in_step_multiples_equals_one_call():
    crawler, gait, h = _crawler(3, 0.0, seed=83), _wave(3), 1e-3
    one = cs.Stepper(crawler, gait, 'implicit', dt=h)
    one.advance(1.0)
    many = cs.Stepper(crawler, gait, 'implicit', dt=h)
    for k in range(1, 41):
        many.advance(k * 0.025)
    assert one.solver.n_steps == many.solver.n_steps == 1000
    for x, y in zip(_state_arrays(one.state), _state_arrays(many.state)):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)


@pytest.mark.parametrize('method', ['exact', 'implicit', 'penalty'])
def test_two_identical_stepper_runs_are_bit_identical(method):
    crawler, gait = _crawler(3, 0.03, seed=84), _wave(3)
    runs = []
    for _ in range(2):
        st = cs.Stepper(crawler, gait, method, dt=2e-3, penalty=500.0, v0=0.02)
        out = []
        for tc in np.linspace(0.0, 2.0, 37)[1:]:
            st.advance(tc)
            out.append((_state_arrays(st.state), st.pop_events()))
        runs.append(out)
    for (sa, ea), (sb, eb) in zip(*runs):
        for x, y in zip(sa, sb):
            assert np.array_equal(x, y)
        assert ea == eb


# ----------------------------------------------------------------------------------------------
# Gait switch between calls: a chain of constant-jerk pieces (the node's actuator model) handed
# to the stepper one per call is the same piecewise-cubic, C2 stroke as a Custom gait holding all
# pieces; l'' is continuous at the knots so no event can hide there.
# ----------------------------------------------------------------------------------------------
def _piecewise_cubic(n_links, seed, n_pieces=12, dt=0.1):
    rng = np.random.default_rng(seed)
    jerks = rng.normal(0.0, 15.0, (n_pieces, n_links))
    l, v, a = np.full(n_links, 0.1), np.zeros(n_links), np.zeros(n_links)
    knots = []
    for k in range(n_pieces):
        knots.append((k * dt, l.copy(), v.copy(), a.copy(), jerks[k]))
        j = jerks[k]
        l = l + v * dt + a * dt ** 2 / 2 + j * dt ** 3 / 6
        v = v + a * dt + j * dt ** 2 / 2
        a = a + j * dt

    def piece(t):
        k = min(max(int(math.floor(t / dt)), 0), n_pieces - 1)
        t0, l0, v0, a0, j = knots[k]
        d = t - t0
        return (l0 + v0 * d + a0 * d ** 2 / 2 + j * d ** 3 / 6, v0 + a0 * d + j * d ** 2 / 2,
                a0 + j * d)

    custom = gaits.Custom(lambda t: piece(t)[0], lambda t: piece(t)[1], lambda t: piece(t)[2])
    cubics = [gaits.Cubic(t0, l0, v0, a0, j) for t0, l0, v0, a0, j in knots]
    return custom, cubics, n_pieces * dt


@pytest.mark.parametrize('p,seed,f', [(2, 97, (0.3, 0.6)), (3, 91, (1.0, 0.2))])
def test_switching_cubic_gait_pieces_between_calls_equals_the_whole_stroke_in_one_gait(p, seed, f):
    crawler = cs.Crawler(np.linspace(1.0, 0.5, p), np.linspace(*f, p))
    custom, cubics, T = _piecewise_cubic(p - 1, seed=seed)
    ref = cs.simulate(crawler, custom, T, t_eval=[0.0, T], max_step=0.01)
    st = cs.Stepper(crawler, cubics[0], max_step=0.01)
    events = []
    for k, g in enumerate(cubics):
        st.advance((k + 1) * 0.1 if k + 1 < len(cubics) else T, gait=g)
        events += st.pop_events()
    s = st.state
    np.testing.assert_allclose(s.x, ref.x[-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.v, ref.v[-1], rtol=0, atol=1e-12)
    assert [(e.body, e.old, e.new) for e in events] == [(e.body, e.old, e.new) for e in ref.events]
    np.testing.assert_allclose([e.time for e in events], [e.time for e in ref.events], atol=1e-12)
    assert len(events) >= 5


# ----------------------------------------------------------------------------------------------
# pop_events and reset.
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('method', ['exact', 'implicit'])
def test_pop_events_returns_each_event_exactly_once_in_time_order(method):
    crawler, gait = _crawler(3, 0.0, seed=85), _wave(3)
    whole = cs.simulate(crawler, gait, 3.0, method, dt=1e-3)
    st = cs.Stepper(crawler, gait, method, dt=1e-3)
    got = []
    for tc in np.linspace(0.0, 3.0, 61)[1:]:
        st.advance(tc)
        batch = st.pop_events()
        assert all(tc - 0.05 - 1e-12 <= e.time <= tc for e in batch)
        got += batch
        assert st.pop_events() == []
    assert len(got) == len(whole.events) > 5
    assert [(e.body, e.old, e.new) for e in got] == [(e.body, e.old, e.new) for e in whole.events]
    np.testing.assert_allclose([e.time for e in got], [e.time for e in whole.events], atol=1e-11)
    assert all(a.time <= b.time for a, b in zip(got, got[1:]))
    assert len(set(got)) == len(got)


@pytest.mark.parametrize('method', ['exact', 'implicit'])
def test_reset_returns_the_stepper_to_the_initial_state_and_replays_identically(method):
    crawler, gait = _crawler(2, 0.0, seed=86), _wave(2)
    fresh = cs.Stepper(crawler, gait, method, dt=1e-3, x0=0.3, v0=0.04)
    first_state = fresh.state
    st = cs.Stepper(crawler, gait, method, dt=1e-3, x0=0.3, v0=0.04)
    st.advance(1.7)
    first_run = (_state_arrays(st.state), st.pop_events())
    st.advance(2.2)
    st.reset(x0=0.3, v0=0.04)
    assert st.t == 0.0
    assert st.pop_events() == []
    for x, y in zip(_state_arrays(st.state), _state_arrays(first_state)):
        assert np.array_equal(x, y)
    assert st.state.x[0] == pytest.approx(0.3, rel=1e-15)
    assert st.state.v[0] == pytest.approx(0.04, rel=1e-15)
    st.advance(1.7)
    for x, y in zip(_state_arrays(st.state), first_run[0]):
        assert np.array_equal(x, y)
    assert st.pop_events() == first_run[1]


def test_reset_to_another_time_and_state_matches_a_new_stepper_started_there():
    crawler, gait = _crawler(2, 0.0, seed=87), _wave(2)
    st = cs.Stepper(crawler, gait)
    st.advance(1.0)
    st.reset(t0=0.4, x0=-0.2, v0=0.1)
    new = cs.Stepper(crawler, gait, t0=0.4, x0=-0.2, v0=0.1)
    st.advance(1.3)
    new.advance(1.3)
    for x, y in zip(_state_arrays(st.state), _state_arrays(new.state)):
        assert np.array_equal(x, y)


# ----------------------------------------------------------------------------------------------
# Trajectory figures on a crawl solvable by hand (see test_closed_form): m = (0.1, 0.1),
# f_plus = 0.2, f_minus = 0.5, l = 0.1 + A sin(2 pi t), A = 0.01, flat. Body 0 sticks exactly
# while l' > 0 (extension: [0, T/4] and [3T/4, T]), body 1 exactly while l' < 0, so each is stuck
# half the time; both advance 2A per period, so the mean speed is 2A / T. The sliding body works
# against f_plus over 2A per half stroke: dissipation per period = 2 * f_plus * 2A; the linkage
# force on the sliding body is m l'' + f_plus > 0.2 - 0.1 * 0.01 * (2 pi)^2 > 0 with l' of the
# same sign, so the actuator power is never negative and the positive work per period is also
# 2 * f_plus * 2A (kinetic energy returns to zero at the stroke ends). Hence
# CoT = 2 f_plus 2A / (M g 2A) = 2 f_plus / (M g) = 0.4 / (0.2 g).
# ----------------------------------------------------------------------------------------------
A_BR, F_PLUS = 0.01, 0.2


def _bristle_run(t_end, t_eval=None):
    crawler = cs.Crawler([0.1, 0.1], F_PLUS, 0.5)
    return cs.simulate(crawler, gaits.Sinusoid(0.1, A_BR, 1.0), t_end, t_eval=t_eval)


def test_stick_fraction_of_the_hand_solved_crawl_is_one_half_for_each_body():
    tr = _bristle_run(3.0)
    np.testing.assert_allclose(tr.stick_fraction, [0.5, 0.5], rtol=0, atol=1e-12)


def test_stick_fraction_matches_the_fraction_of_fine_samples_in_the_stuck_state():
    crawler, gait = _crawler(3, 0.0, seed=88), _wave(3)
    coarse = cs.simulate(crawler, gait, 3.0)
    N = 30001
    fine = cs.simulate(crawler, gait, 3.0, t_eval=np.linspace(0.0, 3.0, N))
    frac = np.mean(fine.contact == 0, axis=0)
    n_ev = np.bincount([e.body for e in coarse.events], minlength=3)
    # each state change can misplace at most one sample
    np.testing.assert_array_less(np.abs(frac - coarse.stick_fraction), (n_ev + 2) / (N - 1))
    assert np.any((coarse.stick_fraction > 0.05) & (coarse.stick_fraction < 0.95))


def test_mean_speed_over_the_last_period_is_two_amplitudes_per_period():
    # t_end - T = 1.5 is a sample: exact. Any window of one period advances 2A here.
    tr = _bristle_run(2.5, t_eval=[0.0, 1.5, 2.5])
    assert tr.mean_speed(1.0) == pytest.approx(2 * A_BR, rel=1e-12)
    # Default samples: t_end - T is interpolated linearly between samples h = 2.5e-3 apart; the
    # error is at most h^2 / 8 max|X''|, and X'' = -e_r'' = l''/2 with |l''| <= A w^2.
    tr = _bristle_run(2.5)
    h = 2.5 / 1000
    assert tr.mean_speed(1.0) == pytest.approx(2 * A_BR, abs=h ** 2 / 8 * A_BR * (2 * math.pi)
                                               ** 2 / 2 + 1e-15)


def test_mean_speed_equals_the_exact_displacement_over_the_last_period_for_a_generic_crawl():
    crawler, gait = _crawler(3, 0.02, seed=89), _wave(3)
    T, t_end = 1.0, 3.0
    ends = cs.simulate(crawler, gait, t_end, t_eval=[t_end - T, t_end])
    exact = (ends.com[1] - ends.com[0]) / T
    # t_end - T among the samples: no interpolation
    tr = cs.simulate(crawler, gait, t_end, t_eval=np.linspace(0.0, t_end, 301))
    assert tr.mean_speed(T) == pytest.approx(exact, rel=1e-12)
    # default samples (h = 3e-3, t_end - T not a sample): linear interpolation of X, error at most
    # h^2 / 8 max|X''| / T with |M X''| = |F_ext + sum R_i| <= |F_ext| + sum max(f_plus, f_minus)
    tr = cs.simulate(crawler, gait, t_end)
    x_dd = (abs(crawler.external_force) + np.maximum(crawler.friction, crawler.friction_backward)
            .sum()) / crawler.total_mass
    assert tr.mean_speed(T) == pytest.approx(exact, abs=(t_end / 1000) ** 2 / 8 * x_dd / T)
    assert tr.mean_speed() == pytest.approx(tr.displacement / t_end, rel=1e-15)
    with pytest.raises(ValueError, match='period'):
        tr.mean_speed(4.0)


def test_dissipation_actuator_work_and_cost_of_transport_of_the_hand_solved_crawl():
    n = 2
    t = np.linspace(0.0, n, 8001)
    tr = _bristle_run(float(n), t_eval=t)
    M = 0.2
    assert tr.displacement == pytest.approx(2 * A_BR * n, rel=1e-12)
    assert tr.dissipated_energy == pytest.approx(2 * F_PLUS * 2 * A_BR * n, rel=1e-6)
    assert tr.positive_actuator_work == pytest.approx(2 * F_PLUS * 2 * A_BR * n, rel=1e-6)
    assert tr.actuator_work == pytest.approx(tr.positive_actuator_work, rel=1e-12)
    assert tr.cost_of_transport == pytest.approx(2 * F_PLUS / (M * G), rel=1e-6)


def test_cost_of_transport_is_positive_for_a_crawl_and_infinite_without_displacement():
    crawler, gait = _crawler(3, 0.0, seed=89), _wave(3)
    tr = cs.simulate(crawler, gait, 3.0)
    assert tr.displacement != 0.0
    assert 0.0 < tr.cost_of_transport < math.inf
    # equal bodies started with V = 0 never move their COM (test_invariants)
    g = gaits.Sinusoid(0.1, 0.03, 1.0)
    still = cs.simulate(cs.Crawler([1.0, 1.0], 0.8), g, 2.0, v0=-0.5 * g(0.0)[1][0])
    assert still.displacement == pytest.approx(0.0, abs=1e-14)
    assert still.positive_actuator_work > 0
    assert still.cost_of_transport > 1e6


# ----------------------------------------------------------------------------------------------
# Linkage forces satisfy Newton's second law for every body (Lambda_j acts +on body j+1 and
# -on body j): m_i a_i = R_i + g_i + Lambda_{i-1} - Lambda_i, with a_i from central differences
# of the exact velocities (h = 1e-6: truncation h^2 |v'''| ~ 1e-11, rounding 1e-16 / h ~ 1e-10).
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('p,slope', [(2, 0.0), (3, 0.1), (10, -0.05)])
def test_linkage_forces_satisfy_newtons_law_for_every_body(p, slope):
    crawler, gait = _crawler(p, slope, seed=95 + p), _wave(p, amp=0.03)
    probe = cs.simulate(crawler, gait, 2.0, v0=0.05)
    ev = np.array([e.time for e in probe.events])
    rng = np.random.default_rng(p)
    t = np.sort(rng.uniform(0.01, 1.99, 200))
    t = t[np.min(np.abs(t[:, None] - ev[None, :]), axis=1) > 1e-4] if ev.size else t
    h = 1e-6
    tt = np.sort(np.concatenate([t - h, t, t + h]))
    tr = cs.simulate(crawler, gait, 2.0, v0=0.05, t_eval=tt)
    v = tr.v.reshape(-1, 3, p)
    acc = (v[:, 2] - v[:, 0]) / (2 * h)
    mid = slice(1, None, 3)
    lam = np.concatenate([np.zeros((t.size, 1)), tr.linkage_force[mid],
                          np.zeros((t.size, 1))], axis=1)
    rhs = tr.friction[mid] + crawler.gravity_forces + lam[:, :-1] - lam[:, 1:]
    np.testing.assert_allclose(crawler.masses * acc, rhs, rtol=0, atol=1e-6)
    # the brief's statement for body 0
    np.testing.assert_allclose(crawler.masses[0] * acc[:, 0], tr.friction[mid, 0] +
                               crawler.gravity_forces[0] - tr.linkage_force[mid, 0], atol=1e-6)


def test_the_stepper_state_reports_the_same_forces_as_the_trajectory():
    crawler, gait = _crawler(3, 0.05, seed=97), _wave(3)
    tr = cs.simulate(crawler, gait, 1.234, t_eval=[0.0, 1.234])
    st = cs.Stepper(crawler, gait)
    st.advance(1.234)
    s = st.state
    np.testing.assert_allclose(s.x, tr.x[-1], atol=1e-12)
    np.testing.assert_allclose(s.friction, tr.friction[-1], atol=1e-10)
    np.testing.assert_allclose(s.linkage_force, tr.linkage_force[-1], atol=1e-10)
    np.testing.assert_array_equal(s.contact, tr.contact[-1])


# ----------------------------------------------------------------------------------------------
# Sampling: the batched evaluation of many segments (ExactSolver.sample) against each segment's
# own closed form (Segment.evaluate), one time at a time: the two are separate code paths.
@pytest.mark.parametrize('scene', ['wave4', 'slope_rest', 'free_body', 'periodic_skip'])
def test_batched_sampling_equals_each_segments_own_closed_form(scene):
    from crawler_sim.core.solvers.exact import ExactSolver, PeriodicBlock, Segment
    if scene == 'wave4':
        crawler, gait, t_end = _crawler(4, seed=3), _wave(4), 2.0
    elif scene == 'slope_rest':       # stroke, then a rest on a slope: stuck groups of 2 and 3
        crawler = cs.Crawler([1.0, 0.9, 1.2], [2.0, 2.5, 3.0], slope=0.05)
        gait = gaits.PiecewiseParabolic([0.0, 0.2, 0.4], [[1.0, 0.5], [-1.0, -0.5]],
                                        [0.1, 0.1], periodic=False)
        t_end = 1.0
    elif scene == 'free_body':        # body 1 without friction
        crawler, gait, t_end = cs.Crawler([1.0, 0.5, 1.0], [1.0, 0.0, 2.0]), _wave(3), 2.0
    else:
        crawler, gait, t_end = _crawler(2, seed=1), _wave(2, freq=2.0), 5.0
    solver = ExactSolver(crawler, gait)
    solver.advance(t_end)
    times = np.linspace(0.0, t_end, 301)
    got = solver.sample(times)
    segs = [sg for sg in solver.segments if isinstance(sg, Segment)]
    if scene == 'periodic_skip':
        assert any(isinstance(sg, PeriodicBlock) for sg in solver.segments)
        times = times[times <= segs[-1].t1]     # before the skipped periods
    assert any(sg.ref >= 0 for sg in segs) and any(sg.ref < 0 for sg in segs)
    starts = np.array([sg.t0 for sg in segs])
    for i, t in enumerate(times):
        sg = segs[max(int(np.searchsorted(starts, t, side='right')) - 1, 0)]
        one = sg.evaluate(crawler, np.array([t]))
        for name in ('x', 'v', 'friction', 'impulse', 'linkage_force', 'lengths', 'rates'):
            scale = 1.0 + np.max(np.abs(one[name]))
            assert np.allclose(got[name][i], one[name][0], rtol=0, atol=1e-12 * scale), (name, t)
        assert np.array_equal(got['contact'][i], one['contact'][0]), t
        assert got['indeterminate'][i] == (sg.group.sum() > 1)


# ----------------------------------------------------------------------------------------------
# Two routes of the exact solver's event search: rigorous interval bounds from the built-in
# gait's compiled kind, and, for a gait that hides its bounds, the Chebyshev pieces its own
# values are sampled into (crawler_sim.core.solvers.proxy). Both must find the same events and
# states: each is the other's independent reference.
def _no_jerk_bound(gait):
    class Hidden(type(gait)):
        def jerk_bound(self, t0, t1):
            return None

        def snap_bound(self, t0, t1):
            return None
    hidden = object.__new__(Hidden)
    hidden.__dict__.update(gait.__dict__)
    return hidden


def _actuator_windows(seed, n_windows=300, per=10, dt=1e-3):
    """PiecewiseCubic windows as the node hands them to the solver: an actuator chasing
    random step targets, ``per`` ticks per window."""
    from crawler_sim.core.actuator import Actuator, ActuatorLimits
    rng = np.random.default_rng(seed)
    act = Actuator([0.1, 0.1], dt, ActuatorLimits(bandwidth=8.0, max_speed=0.4,
                                                   max_acceleration=6.0))
    windows = []
    for w in range(n_windows):
        if w % 7 == 0:
            act.set_target(list(rng.uniform(0.07, 0.13, 2)))
        starts = [(w * per + k) * dt for k in range(per)]
        pieces = [act.step(t, t + dt) for t in starts]
        windows.append((starts, pieces))
    return windows


@pytest.mark.parametrize('scene', ['actuator_p3', 'sinusoid_p4', 'parabolic_p2', 'scallop_p2'])
def test_bounded_and_sampled_event_searches_find_the_same_events(scene):
    def run(hide: bool):
        wrap = _no_jerk_bound if hide else (lambda g: g)
        if scene == 'actuator_p3':
            crawler = cs.Crawler([1.0, 0.8, 1.2], [2.9, 2.4, 3.5])
            windows = _actuator_windows(seed=4)
            st = cs.Stepper(crawler, wrap(gaits.PiecewiseCubic(*windows[0])))
            for k, (starts, pieces) in enumerate(windows):
                end = windows[k + 1][0][0] if k + 1 < len(windows) else starts[-1] + 1e-3
                st.advance(end, wrap(gaits.PiecewiseCubic(starts, pieces)))
        else:
            if scene == 'sinusoid_p4':
                crawler, gait, t_end = _crawler(4, seed=5), _wave(4, amp=0.03, freq=1.5), 3.0
            elif scene == 'scallop_p2':
                crawler, gait, t_end = cs.Crawler([1, 1], [50, 10]), \
                    gaits.Scallop(1.0, 0.3, 1.0, 0.05), 2.0
            else:
                crawler = cs.Crawler([0.5, 1.0], [1.5, 3.0])
                gait, t_end = gaits.PiecewiseParabolic.stroke(0.1, 0.02, 2.0, 0.3), 2.0
            st = cs.Stepper(crawler, wrap(gait), periodic_skip=False)
            st.advance(t_end)
        return st.pop_events(), st.state

    ev_a, state_a = run(hide=False)
    ev_b, state_b = run(hide=True)
    assert len(ev_a) == len(ev_b) > 5
    for a, b in zip(ev_a, ev_b):
        assert (a.body, a.old, a.new) == (b.body, b.old, b.new)
        assert abs(a.time - b.time) <= 1e-12
    assert np.allclose(state_a.x, state_b.x, rtol=0, atol=1e-12)
    assert np.array_equal(state_a.contact, state_b.contact)


# --- lengths <= 0 refused (issue 43: the offline API ran a Scallop down to -0.1 m) -----------

SEED = cs.Crawler(masses=[0.5, 1.0], mu=0.3)


def test_simulate_refuses_a_scallop_whose_length_goes_below_zero_before_any_work():
    gait = gaits.Scallop(mean=0.1, amplitude=0.2, frequency=2.0, asymmetry=0.2, phase=1.0)
    with pytest.raises(ValueError, match=r'linkage 0 reaches -0\.1 m at t = 0\.4204') as info:
        cs.simulate(SEED, gait, 20.0)
    err = info.value
    assert (err.linkage, err.value) == (0, pytest.approx(-0.1))
    assert err.time == pytest.approx((2 * math.pi - 1.0) / (4 * math.pi))   # w t + phase = 2 pi
    # a run shorter than the time of the lowest point: its lowest is at an end
    gait = gaits.Sinusoid([0.1, 0.1], [0.02, 0.2], 1.0, [0.0, math.pi])
    with pytest.raises(ValueError, match=r'linkage 1 reaches .* m at t = 0\.1 s') as info:
        cs.simulate(cs.Crawler(masses=[1.0, 1.0, 1.0], mu=0.3), gait, 0.1)
    assert info.value.value == pytest.approx(0.1 + 0.2 * math.sin(0.2 * math.pi + math.pi))


def test_simulate_warns_of_a_custom_gait_from_the_run_samples_or_refuses_when_asked():
    gait = gaits.Custom(lambda t: 0.05 + 0.1 * math.sin(t), lambda t: 0.1 * math.cos(t),
                        lambda t: -0.1 * math.sin(t))
    said = r'linkage 0 reaches -0\.00127693 m at t = 3\.68 s'
    with pytest.warns(UserWarning, match=said):
        run = cs.simulate(SEED, gait, 20.0)
    assert run.t[-1] == 20.0                  # found after the work: the run is kept
    with pytest.raises(ValueError, match=said):
        cs.simulate(SEED, gait, 20.0, lengths_check='raise')
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        cs.simulate(SEED, gait, 3.5)          # before its length reaches 0: silent


def test_stepper_advance_refuses_a_length_below_zero_on_the_span_it_integrates():
    gait = gaits.Sinusoid(0.1, 0.15, 1.0)           # 0.1 + 0.15 sin(2 pi t): < 0 from t = 0.616
    st = cs.Stepper(SEED, gait)
    st.advance(0.5)                                  # still > 0 on [0, 0.5]
    with pytest.raises(ValueError, match=r'linkage 0 reaches -0\.05 m at t = 0\.75 s'):
        st.advance(1.0)
    assert st.t == 0.5                               # refused before any work


def test_valid_runs_are_unchanged_by_the_length_check():
    gait = gaits.Scallop(mean=0.1, amplitude=0.02, frequency=2.0, asymmetry=0.2)
    run = cs.simulate(SEED, gait, 20.0)
    assert run.displacement == 0.2914990946299904    # the seed crawl before the check, bit for bit


# --- closed-form minimum length (issue 43: lengths <= 0 refused before any work) -------------

@pytest.mark.parametrize('gait', [
    gaits.Sinusoid([0.1, 0.2], [0.03, -0.05], 1.3, [0.4, -2.0]),
    gaits.Scallop([0.1, 0.2], [0.03, 0.05], 1.3, 0.15, [0.4, -2.0]),
    gaits.Scallop(0.1, 0.02, 2.0, 0.2),
])
@pytest.mark.parametrize('span', [(0.0, 5.0), (0.31, 0.52), (1.07, 1.2), (3.0, 3.0001)])
def test_length_minimum_is_the_smallest_sampled_length_and_where_it_is_first(gait, span):
    t0, t1 = span
    times, lowest = gait.length_minimum(t0, t1)
    grid = np.linspace(t0, t1, 200001)
    sampled = gait.length(grid)                                 # (N, n_links)
    assert np.all(lowest <= sampled.min(axis=0) + 1e-15)       # a bound of every sample ...
    np.testing.assert_allclose(lowest, sampled.min(axis=0), atol=1e-9)    # ... reached on the grid
    assert np.all((times >= t0) & (times <= t1))
    np.testing.assert_allclose(gait.length(times).diagonal(), lowest, atol=1e-14)   # reached at times
    for j in range(gait.n_links):          # the first time: every earlier sample is higher
        before = sampled[grid < times[j] - 1e-3, j]
        assert before.size == 0 or before.min() > lowest[j]


def test_gaits_without_a_closed_form_minimum_say_none():
    custom = gaits.Custom(lambda t: 0.1, lambda t: 0.0, lambda t: 0.0)
    assert custom.length_minimum(0.0, 1.0) is None
    assert gaits.Fourier(0.1, ([0.01], [0.0]), 1.0).length_minimum(0.0, 1.0) is None
