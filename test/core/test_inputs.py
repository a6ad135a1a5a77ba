"""Bad input raises ValueError naming the parameter (issue 3: "Bad input gets a ValueError that
names the parameter and its allowed range")."""
from __future__ import annotations

import math

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core import gaits

NAN, INF = float('nan'), float('inf')


def _ok_crawler():
    return cs.Crawler([1.0, 2.0], [1.0, 1.0])


def _ok_gait():
    return gaits.Sinusoid(0.1, 0.02, 1.0)


# ---------------------------------------------------------------------------- Crawler
@pytest.mark.parametrize('masses', [[1.0], [], 1.0])
def test_fewer_than_two_bodies_is_rejected_naming_masses(masses):
    with pytest.raises(ValueError, match=r'masses.*p >= 2|p >= 2.*masses|masses'):
        cs.Crawler(masses, 1.0)


@pytest.mark.parametrize('bad', [0.0, -1.0, NAN, INF, -INF])
def test_a_mass_that_is_not_finite_and_positive_is_rejected_naming_masses_and_the_range(bad):
    with pytest.raises(ValueError, match=r'masses.*> 0'):
        cs.Crawler([1.0, bad, 2.0], 1.0)


@pytest.mark.parametrize('bad', [-1e-9, -1.0, NAN, INF])
def test_a_negative_or_non_finite_friction_is_rejected_naming_friction(bad):
    with pytest.raises(ValueError, match=r'^friction.*>= 0'):
        cs.Crawler([1.0, 2.0], [1.0, bad])


@pytest.mark.parametrize('bad', [-0.5, NAN, INF])
def test_a_bad_backward_friction_is_rejected_naming_friction_backward(bad):
    with pytest.raises(ValueError, match=r'friction_backward.*>= 0'):
        cs.Crawler([1.0, 2.0], 1.0, [bad, 1.0])


@pytest.mark.parametrize('name,kw', [('friction', dict(friction=[1.0, 1.0, 1.0])),
                                     ('friction', dict(friction=[])),
                                     ('friction_backward',
                                      dict(friction=1.0, friction_backward=[1.0, 1.0, 1.0]))])
def test_a_friction_list_of_the_wrong_length_is_rejected_naming_it(name, kw):
    with pytest.raises(ValueError, match=rf'^{name}\b'):
        cs.Crawler([1.0, 2.0], **kw)


@pytest.mark.parametrize('slope', [math.pi / 2, -math.pi / 2, 2.0, NAN, INF])
def test_a_slope_outside_the_open_right_angle_is_rejected_naming_slope(slope):
    with pytest.raises(ValueError, match=r'slope'):
        cs.Crawler([1.0, 2.0], 1.0, slope=slope)


@pytest.mark.parametrize('gravity', [-9.81, NAN, INF])
def test_a_bad_gravity_is_rejected_naming_gravity(gravity):
    with pytest.raises(ValueError, match=r'gravity'):
        cs.Crawler([1.0, 2.0], 1.0, gravity=gravity)


@pytest.mark.parametrize('kw,name', [(dict(mu=[-0.1, 0.2]), 'mu'), (dict(mu=[0.1, NAN]), 'mu'),
                                     (dict(mu=0.2, mu_backward=[0.1, -1.0]), 'mu_backward'),
                                     (dict(mu=[0.1, 0.2, 0.3]), 'mu')])
def test_bad_friction_coefficients_are_rejected_naming_them(kw, name):
    with pytest.raises(ValueError, match=rf'^{name}\b'):
        cs.Crawler.from_coefficients([1.0, 2.0], **kw)


def test_from_coefficients_gives_mu_m_g_cos_slope():
    # f_i = mu_i m_i g cos(slope): (0.5 * 1 * 9.81 cos 0.1, 0.25 * 2 * 9.81 cos 0.1)
    c = cs.Crawler.from_coefficients([1.0, 2.0], [0.5, 0.25], [1.0, 0.1], slope=0.1)
    np.testing.assert_allclose(c.friction, 0.5 * 9.81 * math.cos(0.1), rtol=1e-15)
    np.testing.assert_allclose(c.friction_backward, [9.81 * math.cos(0.1), 0.2 * 9.81 *
                                                     math.cos(0.1)], rtol=1e-15)
    assert c.external_force == pytest.approx(-3.0 * 9.81 * math.sin(0.1), rel=1e-15)


# ---------------------------------------------------------------------------- gaits
def test_a_gait_whose_shape_does_not_match_p_is_rejected_naming_the_gait():
    three_links = gaits.Sinusoid([0.1, 0.1, 0.1], 0.02, 1.0)
    with pytest.raises(ValueError, match=r'gait'):
        cs.simulate(_ok_crawler(), three_links, 1.0)
    with pytest.raises(ValueError, match=r'gait'):
        cs.Stepper(cs.Crawler([1.0, 1.0, 1.0], 1.0), _ok_gait())


@pytest.mark.parametrize('which', ['length', 'velocity', 'acceleration'])
@pytest.mark.parametrize('bad', [NAN, INF])
def test_a_gait_returning_non_finite_values_is_rejected_naming_the_gait(which, bad):
    fns = {'length': lambda t: 0.1, 'velocity': lambda t: 0.0, 'acceleration': lambda t: 0.0}
    fns[which] = lambda t: bad
    g = gaits.Custom(fns['length'], fns['velocity'], fns['acceleration'])
    for method in ('exact', 'implicit'):
        with pytest.raises(ValueError, match=r'gait'):
            cs.simulate(_ok_crawler(), g, 1.0, method)


@pytest.mark.filterwarnings('ignore:invalid value encountered')
@pytest.mark.parametrize('method', ['exact', 'implicit', 'penalty'])
def test_a_gait_that_turns_non_finite_during_the_run_is_rejected_not_propagated(method):
    # Finite at t = 0, NaN from t = 0.5 on: the run must not return NaN positions silently.
    def vel(t):
        return 0.01 if t < 0.5 else NAN
    g = gaits.Custom(lambda t: 0.1 + 0.01 * t, vel, lambda t: 0.0)
    with pytest.raises(ValueError, match=r'gait|finite'):
        cs.simulate(_ok_crawler(), g, 1.0, method, penalty=1e3)


def test_a_non_gait_object_is_rejected_naming_the_gait():
    with pytest.raises(ValueError, match=r'gait'):
        cs.simulate(_ok_crawler(), lambda t: (0.1, 0.0, 0.0), 1.0)


def test_a_crawler_that_is_not_a_crawler_is_rejected():
    with pytest.raises(ValueError, match=r'crawler'):
        cs.simulate({'masses': [1, 2]}, _ok_gait(), 1.0)


# ---------------------------------------------------------------------------- simulate
@pytest.mark.parametrize('t_end', [0.0, -1.0, NAN, INF, 'soon'])
def test_a_non_positive_or_non_finite_t_end_is_rejected_naming_t_end(t_end):
    with pytest.raises(ValueError, match=r't_end.*> 0'):
        cs.simulate(_ok_crawler(), _ok_gait(), t_end)


@pytest.mark.parametrize('method', ['implicit', 'penalty', 'exact'])
@pytest.mark.parametrize('dt', [0.0, -1e-3, NAN, INF])
def test_a_non_positive_or_non_finite_dt_is_rejected_naming_dt(method, dt):
    with pytest.raises(ValueError, match=r'dt.*> 0'):
        cs.simulate(_ok_crawler(), _ok_gait(), 1.0, method, dt=dt, penalty=1e3)


@pytest.mark.parametrize('method', ['Exact', 'euler', '', None])
def test_an_unknown_method_is_rejected_listing_the_methods(method):
    with pytest.raises(ValueError, match=r'method.*exact.*implicit.*penalty'):
        cs.simulate(_ok_crawler(), _ok_gait(), 1.0, method)
    with pytest.raises(ValueError, match=r'method'):
        cs.Stepper(_ok_crawler(), _ok_gait(), method)


def test_penalty_is_required_for_the_penalty_method():
    with pytest.raises(ValueError, match=r'penalty'):
        cs.simulate(_ok_crawler(), _ok_gait(), 1.0, 'penalty')


@pytest.mark.parametrize('penalty', [0.0, -10.0, NAN, INF, [10.0, 10.0, 10.0], [[10.0, 10.0]],
                                     [10.0, -1.0]])
def test_an_invalid_penalty_is_rejected_naming_penalty(penalty):
    with pytest.raises(ValueError, match=r'penalty'):
        cs.simulate(_ok_crawler(), _ok_gait(), 1.0, 'penalty', penalty=penalty)
    with pytest.raises(ValueError, match=r'penalty'):
        cs.penalty_bound(_ok_crawler(), penalty, 1.0)


@pytest.mark.parametrize('name,kw', [('v0', dict(v0=NAN)), ('x0', dict(x0=INF))])
def test_non_finite_initial_conditions_are_rejected_naming_them(name, kw):
    with pytest.raises(ValueError, match=name):
        cs.simulate(_ok_crawler(), _ok_gait(), 1.0, **kw)


@pytest.mark.parametrize('t_eval', [[], [0.0, 2.0], [0.5, 0.2], [-0.1, 0.5], [0.0, NAN],
                                    [0.0, NAN, 0.5], [NAN], [0.0, INF], [0.0, 0.6, 0.5, 0.7]])
def test_t_eval_outside_the_run_or_unsorted_is_rejected_naming_t_eval(t_eval):
    with pytest.raises(ValueError, match=r't_eval'):
        cs.simulate(_ok_crawler(), _ok_gait(), 1.0, t_eval=t_eval)


@pytest.mark.parametrize('kw,name', [(dict(tol=0.0), 'tol'), (dict(max_step=-1.0), 'max_step')])
def test_bad_exact_method_settings_are_rejected_naming_them(kw, name):
    with pytest.raises(ValueError, match=name):
        cs.simulate(_ok_crawler(), _ok_gait(), 1.0, **kw)


# ---------------------------------------------------------------------------- Stepper
def test_advancing_a_stepper_backwards_in_time_is_rejected_naming_t1():
    st = cs.Stepper(_ok_crawler(), _ok_gait())
    st.advance(0.5)
    with pytest.raises(ValueError, match=r't1'):
        st.advance(0.25)
    with pytest.raises(ValueError, match=r't1'):
        st.advance(NAN)


def test_switching_to_a_gait_of_the_wrong_shape_between_calls_is_rejected():
    st = cs.Stepper(_ok_crawler(), _ok_gait())
    st.advance(0.2)
    with pytest.raises(ValueError, match=r'gait'):
        st.advance(0.4, gait=gaits.Sinusoid([0.1, 0.1], 0.02, 1.0))


# ---------------------------------------------------------------------------- ImplicitBatch
@pytest.mark.parametrize('kw,name', [(dict(masses=[[1.0]], friction=[[1.0]]), 'masses'),
                                     (dict(masses=[[1.0, 0.0]], friction=[[1.0, 1.0]]), 'masses'),
                                     (dict(masses=[[1.0, NAN]], friction=[[1.0, 1.0]]), 'masses'),
                                     (dict(masses=[[1.0, 1.0]], friction=[[1.0, -1.0]]),
                                      'friction'),
                                     (dict(masses=[[1.0, 1.0]], friction=[[1.0, 1.0]],
                                           friction_backward=[[INF, 1.0]]), 'friction_backward')])
def test_the_batch_stepper_rejects_bad_parameters_naming_them(kw, name):
    with pytest.raises(ValueError, match=name):
        cs.ImplicitBatch(**kw)


@pytest.mark.parametrize('which', [1, 2])
def test_a_smooth_periodic_gait_turning_non_finite_mid_run_is_named_in_the_error(which):
    # A periodic gait's event grid comes from a per-period table (exact solver); the values the
    # gait gives at segment ends are still checked, and the error names the bad quantity.
    class Broken(gaits.Sinusoid):
        def at(self, t):
            vals = list(super().at(t))
            if t > 0.3:
                vals[which] = vals[which] * NAN
            return tuple(vals)

    name = ('length', 'velocity', 'acceleration')[which]
    with pytest.raises(ValueError, match=f'gait {name} must be finite'):
        cs.simulate(cs.Crawler([1.0, 1.0], [1.0, 1.0]), Broken(0.1, 0.02, 1.0), 1.0)


# ---------------------------------------------------------------------------- derived quantities
# Issue 11 point 2: each value finite and in range, but a sum or product overflows. Before the
# fix these were accepted and every output of simulate was NaN.
@pytest.mark.parametrize('kw,message', [
    (dict(masses=[1e308] * 3, friction=1.0), r'^masses: their sum must be <= 1e\+100 kg'),
    (dict(masses=[1e101, 1.0], friction=1.0), r'^masses: their sum must be <= 1e\+100 kg'),
    (dict(masses=[1.0, 1.0], friction=[1e308, 1e308]),
     r'^friction: sum\(friction\) \+ sum\(friction_backward\) must be <= 1e\+100 N'),
    (dict(masses=[1.0, 1.0], friction=1.0, friction_backward=[1e308, 1e308]),
     r'^friction: sum\(friction\) \+ sum\(friction_backward\)'),
    (dict(masses=[1e99, 1e99], friction=1.0), r'^gravity: gravity \* sum\(masses\)'),
    (dict(masses=[1.0, 1.0], friction=1.0, gravity=1e300), r'^gravity: gravity \* sum\(masses\)'),
    (dict(masses=[1e-300, 1e-300], friction=[1.0, 1.0]),
     r'^friction: \(total friction \+ weight \* \|sin\(slope\)\|\) / sum\(masses\)'),
])
def test_a_derived_quantity_that_overflows_is_rejected_naming_the_field_and_range(kw, message):
    with pytest.raises(ValueError, match=message):
        cs.Crawler(**kw)


def test_friction_from_coefficients_that_overflows_is_rejected_naming_mu():
    with pytest.raises(ValueError, match=r'^mu\[0\]: the friction force .* must be <= 1e\+100 N'):
        cs.Crawler.from_coefficients([1e200, 1.0], [1e200, 0.1], gravity=1e-150)
    with pytest.raises(ValueError, match=r'^mu_backward\[1\]'):
        cs.Crawler.from_coefficients([1.0, 1e50], 0.1, [0.1, 1e60])


@pytest.mark.parametrize('method', ['exact', 'implicit', 'penalty'])
def test_a_crawler_at_the_derived_limits_gives_finite_outputs(method):
    # the largest accepted weight and friction: every output stays finite (the limit leaves
    # room for the products the solvers form)
    c = cs.Crawler([1e99 / 3] * 3, [1e99 / 7] * 3, gravity=1.0, slope=0.5)
    tr = cs.simulate(c, gaits.Sinusoid([1.0, 1.0], 0.3, 1.0), 1.0, method=method,
                     penalty=1e6 if method == 'penalty' else None)
    for name in ('x', 'v', 'friction', 'impulse', 'linkage_force'):
        assert np.all(np.isfinite(getattr(tr, name))), name


def test_a_crawler_takes_coefficients_by_keyword_as_from_coefficients_does():
    """Issue 27: ``Crawler(masses, mu=...)`` was a TypeError. f_i = mu_i m_i g cos(slope):
    0.3 * 0.5 * 9.81 = 1.4715 N by hand."""
    from crawler_sim import Crawler
    c = Crawler([0.5, 1.0], mu=0.3, mu_backward=[0.5, 0.2], slope=0.1)
    ref = Crawler.from_coefficients([0.5, 1.0], 0.3, [0.5, 0.2], slope=0.1)
    assert c.friction.tolist() == ref.friction.tolist()
    assert c.friction_backward.tolist() == ref.friction_backward.tolist()
    assert Crawler([0.5, 1.0], mu=0.3).friction[0] == pytest.approx(1.4715, rel=1e-15)
    for kw, msg in ((dict(), 'exactly one'), (dict(friction=1.0, mu=0.3), 'exactly one'),
                    (dict(mu=0.3, friction_backward=1.0), 'with mu give mu_backward'),
                    (dict(friction=1.0, mu_backward=0.3), 'with friction give')):
        with pytest.raises(ValueError, match=msg):
            Crawler([1.0, 1.0], **kw)
