"""verify() audits the friction law with stiction (issue 40): a stuck cluster's force inside its
static bounds (not the kinetic ones), a sliding body's at its kinetic value, breakaways at the
static bound, and the selection rule (Rule S, or 'margin') at every event and at the start: a
run made with kinetic answers for a crawler with stiction is flagged, the Rule S run passes.

The trajectories are built by hand from closed forms (STICTION.md T2), or are runs whose
expected flags are hand margins (T3, T5: the force a candidate needs against its static bound).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import friction as law
from crawler_sim.core.gaits import PiecewiseParabolic
from crawler_sim.core.trajectory import Trajectory

G = 9.81
SIN, COS = 1 / math.sqrt(5.0), 2 / math.sqrt(5.0)      # tan a = 1/2


def _t2_crawler(mu_static=(0.7, 0.55)):
    # STICTION.md T2: m = (1, 2), mu_k = (0.5, 0.35), a rigid pair l = 0.3 on tan a = 1/2
    return cs.Crawler([1.0, 2.0], slope=math.atan(0.5), mu=[0.5, 0.35], mu_static=mu_static)


GAIT2 = PiecewiseParabolic([0.0, 1.0], [0.0], 0.3, 0.0)


def _rigid_pair(crawler, t, x0, v, friction, contact, events=()):
    """A T2 trajectory built by hand: both bodies move together (l = 0.3, l' = 0) at v(t),
    from positions x0 + ..."""
    n = t.size
    x = np.stack([x0, x0 + 0.3], axis=1)
    vv = np.stack([v, v], axis=1)
    impulse = np.cumsum(np.vstack([np.zeros(2), 0.5 * (friction[1:] + friction[:-1])
                                   * np.diff(t)[:, None]]), axis=0)
    return Trajectory(t=t, x=x, v=vv, friction=friction, contact=contact.astype(np.int8),
                      linkage_force=np.zeros((n, 1)), impulse=impulse,
                      lengths=np.full((n, 1), 0.3), rates=np.zeros((n, 1)),
                      events=list(events), indeterminate=np.zeros(n, bool), crawler=crawler,
                      method='hand', info={})


def _held(crawler):
    # held on the slope: the ground must give M g sin a = 3 g / sqrt5 = 13.16 N uphill in all,
    # split as the law documents it (the total is all that is determined)
    t = np.linspace(0.0, 2.0, 21)
    total = 3.0 * G * SIN
    split = law.split_stuck(law.bounds(crawler), [0, 1], total)
    return _rigid_pair(crawler, t, np.zeros_like(t), np.zeros_like(t),
                       np.tile(split, (t.size, 1)), np.zeros((t.size, 2)))


def _kinetic_slide(crawler):
    # the kinetic answer from rest: a_dn = -g (3 sin a - 1.2 cos a) / 3 = -0.2 g / sqrt5, each
    # body feeling its kinetic backward bound mu_k m g cos a (ground force +, uphill)
    t = np.linspace(0.0, 2.0, 21)
    a = -0.2 * G * SIN
    fk = np.array([0.5 * 1.0, 0.35 * 2.0]) * G * COS
    return _rigid_pair(crawler, t, 0.5 * a * t ** 2, a * t, np.tile(fk, (t.size, 1)),
                       np.full((t.size, 2), -1))


def _others_ok(r, skip: str) -> None:
    for name in ('momentum', 'friction_bound', 'complementarity', 'stuck_velocity',
                 'slide_sign', 'required_force', 'shooting', 'shooting_position', 'rule_s'):
        if name != skip:
            assert getattr(r, name + '_rel') <= 1e-9, (name, r)
    assert r.contact == 0


def test_a_held_cluster_may_use_its_static_bounds_beyond_the_kinetic_ones():
    # 13.16 N is above the kinetic capacity 2.4 g / sqrt5 = 10.53 N and within the static
    # 3.6 g / sqrt5 = 15.79 N: admissible with stiction (the kinetic bounds would flag it)
    c = _t2_crawler()
    r = cs.verify(_held(c), GAIT2)
    assert r.ok(), r


def test_a_held_cluster_beyond_its_static_bounds_is_flagged():
    # mu_s = (0.55, 0.45): capacity 1.45 * 2 g / sqrt5 = 12.72 N < 13.16 N: it cannot hold
    c = _t2_crawler(mu_static=(0.55, 0.45))
    tr = _held(_t2_crawler())
    r = cs.verify(dataclasses.replace(tr, crawler=c), GAIT2)
    need = 3.0 * G * SIN - 1.45 * 2 * G * SIN          # 0.1 g / sqrt5 = 0.4387 N by hand
    assert r.required_force == pytest.approx(need, rel=1e-12)
    assert r.friction_bound > 0 and not r.ok()


def test_the_kinetic_slide_from_rest_of_t2b_is_flagged_by_its_static_margin():
    # a valid solution of the inclusion (every other check passes), but Rule S holds the pair:
    # it could hold with margin 3.6 g / sqrt5 - 3 g / sqrt5 = 0.6 g / sqrt5 = 2.632 N
    c = _t2_crawler()
    r = cs.verify(_kinetic_slide(c), GAIT2)
    assert r.rule_s == pytest.approx(0.6 * G * SIN, rel=1e-12)
    assert not r.ok()
    _others_ok(r, 'rule_s')
    # the same trajectory for the crawler without stiction is the right answer
    kin = cs.Crawler([1.0, 2.0], slope=math.atan(0.5), mu=[0.5, 0.35])
    assert cs.verify(_kinetic_slide(kin), GAIT2).ok()


@pytest.mark.parametrize('v0', [0.0, 1.0])
def test_t2_runs_with_rule_s_pass_and_their_kinetic_twins_are_flagged(v0):
    # v0 = 1 (T2a): launched uphill, arrives at rest at t_s and can hold (margin 2.632 N):
    # the kinetic run slides back down from there
    c = _t2_crawler()
    kin = cs.Crawler([1.0, 2.0], slope=math.atan(0.5), mu=[0.5, 0.35])
    assert cs.verify(cs.simulate(c, GAIT2, 2.0, v0=v0), GAIT2).ok()
    imp = cs.verify(cs.simulate(c, GAIT2, 2.0, 'implicit', dt=1e-3, v0=v0), GAIT2)
    assert imp.rule_s_rel < 1e-4                  # the scheme's O(dt) only
    for method in ('exact', 'implicit'):
        tr = cs.simulate(kin, GAIT2, 2.0, method, v0=v0)
        r = cs.verify(dataclasses.replace(tr, crawler=c, info={}), GAIT2)
        assert r.rule_s == pytest.approx(0.6 * G * SIN, rel=1e-9)


def _t3():
    # STICTION.md T3: bristles f_k = (1 fwd, 4 bwd), f_s = (2, 5), m = (1, 1); bang-bang A = 2.5
    c = cs.Crawler([1.0, 1.0], [1.0, 1.0], [4.0, 4.0], static_friction=[2.0, 2.0],
                   static_friction_backward=[5.0, 5.0])
    g = PiecewiseParabolic([0, 1, 2, 3, 4, 5, 6], [2.5, -2.5, 0, -2.5, 2.5, 0], 1.0, 0.0)
    return c, g, cs.Crawler([1.0, 1.0], [1.0, 1.0], [4.0, 4.0])


def test_a_breakaway_before_the_static_bound_is_flagged_and_one_at_it_passes():
    # kinetic answers: body 0 breaks at t = 1 where it needs 1.5 N (l'' turns to -A: -f_k + A),
    # inside its static bound 2 N: flagged by the margin 0.5 N. The Rule S run holds it there
    # (and releases nothing before a bound): it passes to rounding.
    c, g, kin = _t3()
    assert cs.verify(cs.simulate(c, g, 12.0), g).ok()
    tr = cs.simulate(kin, g, 12.0)
    assert any(ev.time == 1.0 and ev.old == 0 for ev in tr.events)
    r = cs.verify(dataclasses.replace(tr, crawler=c, info={}), g)
    assert r.rule_s == pytest.approx(0.5, rel=1e-9)
    assert not r.ok()


def test_a_breakaway_at_the_static_bound_passes_and_one_at_the_kinetic_bound_is_flagged():
    # STICTION.md T1b's ramp with a Sinusoid: body 1 frictionless, l = 1 + A sin(w t), so body
    # 0 held needs F_0 = -m_1 l'' = A w^2 sin(w t) [N] (m_1 = 1), rising through its static
    # bound 2 N at t_b = asin(2 / (A w^2)) / w (Rule S) and through its kinetic 1 N at
    # asin(1 / (A w^2)) / w (the kinetic answer, flagged by the margin 2 - 1 = 1 N)
    A, w = 0.1, 2 * math.pi
    c = cs.Crawler([1.0, 1.0], [1.0, 0.0], static_friction=[2.0, 0.0])
    kin = cs.Crawler([1.0, 1.0], [1.0, 0.0])
    g = cs.gaits.Sinusoid(1.0, A, 1.0)
    tr = cs.simulate(c, g, 0.5)
    first = next(ev for ev in tr.events if ev.body == 0 and ev.old == 0)
    assert first.time == pytest.approx(math.asin(2 / (A * w * w)) / w, abs=1e-12)
    assert cs.verify(tr, g).ok()
    imp = cs.verify(cs.simulate(c, g, 0.5, 'implicit', dt=1e-3), g)
    assert imp.rule_s_rel < 1e-4
    trk = cs.simulate(kin, g, 0.5)
    first = next(ev for ev in trk.events if ev.body == 0 and ev.old == 0)
    assert first.time == pytest.approx(math.asin(1 / (A * w * w)) / w, abs=1e-12)
    r = cs.verify(dataclasses.replace(trk, crawler=c, info={}), g)
    assert r.rule_s == pytest.approx(1.0, rel=1e-9)


def test_the_rule_of_a_run_is_audited_t5():
    # STICTION.md T5: at t = 1 body 0 (incumbent) and body 1 (arriving) can both hold, body 0
    # with margin 0.5 N, body 1 with 1.0 N. A 'margin' run anchors body 1: audited against
    # Rule S it is flagged by the incumbent's margin 0.5 N; against 'margin' it passes; the
    # implicit run carries its rule in info (the default of verify)
    c = cs.Crawler([1.0, 1.0], [1.0, 1.0], static_friction=[2.0, 2.5])
    g = PiecewiseParabolic([0, 2, 4], [0.5, -0.5], 1.0, -0.5)
    rule_s = cs.simulate(c, g, 8.0)
    margin = cs.simulate(c, g, 8.0, stiction_rule='margin')
    assert cs.verify(rule_s, g).ok()
    assert cs.verify(margin, g, stiction_rule='margin').ok()
    r = cs.verify(margin, g, stiction_rule='incumbent')
    assert r.rule_s == pytest.approx(0.5, rel=1e-9)
    imp = cs.simulate(c, g, 8.0, 'implicit', dt=1e-3, stiction_rule='margin')
    assert imp.info['stiction_rule'] == 'margin'
    assert cs.verify(imp, g).rule_s_rel < 1e-4
    assert cs.verify(imp, g, stiction_rule='incumbent').rule_s == pytest.approx(0.5, rel=1e-6)
    with pytest.raises(ValueError, match='stiction_rule'):
        cs.verify(imp, g, stiction_rule='largest')


def test_a_crawler_without_stiction_is_not_audited_for_a_rule():
    c, g, kin = _t3()
    r = cs.verify(cs.simulate(kin, g, 12.0), g)
    assert r.ok() and r.rule_s == 0.0


@pytest.mark.parametrize('seed', [0, 1, 5, 10])
def test_random_scenes_rule_s_runs_pass_and_their_kinetic_twins_are_flagged(seed):
    # test_stiction_implicit's random scenes (2-3 bodies, static up to 2x kinetic): the exact
    # method's Rule S runs pass to rounding; the kinetic answers (the same crawler without
    # stiction, relabelled) let bodies slide where a candidate could hold (these seeds are
    # scenes where stiction changes the motion), flagged by a margin of over 5 % of the
    # force scale; the implicit run's audit shows its O(dt) at most
    from test.core.solvers.test_stiction_implicit import _random_scene
    c, g, _ = _random_scene(seed)
    assert cs.verify(cs.simulate(c, g, 4.0), g).ok()
    assert cs.verify(cs.simulate(c, g, 4.0, 'implicit', dt=1e-3), g).rule_s_rel < 1e-4
    kin = cs.Crawler(c.masses, c.friction, c.friction_backward)
    r = cs.verify(dataclasses.replace(cs.simulate(kin, g, 4.0), crawler=c, info={}), g)
    assert r.rule_s_rel > 0.05
