"""The Crawler's static friction contract (issue 40): defaults, kinds, checks, round trip."""
import math

import numpy as np
import pytest

from crawler_sim.core import friction as law
from crawler_sim.core.model import Crawler


def test_static_bounds_default_to_the_kinetic_ones_and_the_crawler_has_no_stiction():
    c = Crawler([1.0, 2.0], [0.5, 1.0])
    assert c.static_friction.tolist() == [0.5, 1.0]
    assert c.static_friction_backward.tolist() == [0.5, 1.0]
    assert not c.has_stiction
    with pytest.raises(ValueError):
        c.static_friction[0] = 2.0          # read-only, as the other arrays


def test_an_isotropic_crawler_stays_isotropic_and_an_anisotropic_one_keeps_its_backward_bound():
    iso = Crawler([1.0, 1.0], 1.0, static_friction=2.0)
    assert iso.static_friction_backward.tolist() == [2.0, 2.0]
    aniso = Crawler([1.0, 1.0], 1.0, 4.0, static_friction=2.0)
    # no backward static given: the backward kinetic bound (4), not the forward static one
    assert aniso.static_friction_backward.tolist() == [4.0, 4.0]
    assert aniso.has_stiction


def test_coefficients_give_forces_mu_m_g_cos_slope_with_the_same_defaults():
    # by hand: f = mu m g cos(a) with m = (1, 2), g = 9.81, a = atan(1/2), cos a = 2/sqrt(5)
    a = math.atan(0.5)
    c = Crawler([1.0, 2.0], slope=a, mu=[0.5, 0.35], mu_static=[0.7, 0.55])
    cos_a = 2 / math.sqrt(5)
    np.testing.assert_allclose(c.static_friction, [0.7 * 9.81 * cos_a, 0.55 * 2 * 9.81 * cos_a],
                               rtol=1e-15)
    np.testing.assert_allclose(c.static_friction_backward, c.static_friction, rtol=0)
    d = Crawler([1.0, 2.0], mu=0.3, mu_backward=0.6, mu_static=0.4)
    np.testing.assert_allclose(d.static_friction_backward, d.friction_backward, rtol=0)


@pytest.mark.parametrize('kwargs, names', [
    ({'friction': 1.0, 'mu_static': 0.5}, ('mu_static', 'friction')),
    ({'mu': 0.5, 'static_friction': 2.0}, ('static_friction', 'mu')),
    ({'mu': 0.5, 'friction_backward': 2.0}, ('friction_backward', 'mu')),
    ({'friction': 1.0, 'mu_static_backward': 0.5}, ('mu_static_backward', 'friction')),
])
def test_mixing_forces_and_coefficients_is_refused_naming_both(kwargs, names):
    with pytest.raises(ValueError) as err:
        Crawler([1.0, 1.0], **kwargs)
    msg = str(err.value)
    assert all(n in msg for n in names) and '\n' not in msg


@pytest.mark.parametrize('kwargs, field', [
    ({'friction': 1.0, 'static_friction': 0.5}, 'static_friction[0]'),
    ({'friction': 1.0, 'friction_backward': 3.0, 'static_friction_backward': [3.0, 2.0]},
     'static_friction_backward[1]'),
    ({'mu': 0.5, 'mu_static': [0.6, 0.4]}, 'mu_static[1]'),
    ({'friction': 1.0, 'static_friction': -1.0}, 'static_friction[0]'),
])
def test_a_static_bound_below_its_kinetic_one_is_refused_naming_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field.replace('[', r'\[').replace(']', r'\]')):
        Crawler([1.0, 1.0], **kwargs)


def test_to_dict_and_repr_name_static_bounds_only_with_stiction_and_round_trip():
    plain = Crawler([1.0, 2.0], [0.5, 1.0], 0.7)
    assert set(plain.to_dict()) == {'masses', 'friction', 'friction_backward', 'slope',
                                    'gravity'}
    assert 'static' not in repr(plain)
    sticky = Crawler([1.0, 2.0], [0.5, 1.0], 0.7, static_friction=[0.6, 1.0])
    d = sticky.to_dict()
    assert d['static_friction'] == [0.6, 1.0] and d['static_friction_backward'] == [0.7, 0.7]
    back = Crawler(**d)
    assert back.to_dict() == d and 'static_friction=[0.6, 1.0]' in repr(sticky)


def test_the_law_split_keeps_each_member_inside_its_static_interval_and_sums_to_the_total():
    c = Crawler([1.0, 1.0, 1.0], [1.0, 2.0, 0.5], [3.0, 1.0, 0.5],
                static_friction=[2.0, 2.5, 1.0], static_friction_backward=[4.0, 1.5, 0.5])
    b = law.bounds(c)
    members = np.array([True, True, False])
    lo, hi = law.stuck_interval(b, members)
    assert (lo, hi) == (-4.5, 5.5)          # -(2 + 2.5), 4 + 1.5
    for total in (-4.5, -1.0, 0.0, 3.0, 5.5):
        f = law.split_stuck(b, members, total)
        assert math.isclose(f.sum(), total, abs_tol=1e-14) and f[2] == 0.0
        assert np.all(f[:2] >= -b.static_forward[:2] - 1e-15)
        assert np.all(f[:2] <= b.static_backward[:2] + 1e-15)


def test_the_required_force_constant_adds_the_sliding_bodies_kinetic_forces():
    # ground force on a stuck body 0 with body 1 sliding forward (-f1+ = -1) and body 2
    # backward (+f2- = 0.5), on a slope with F_ext = -2: -M e_r'' - F_ext + sum sigma f, constant
    # part 2 + 1 - 0.5 (M V' = F_ext + sum of ground forces, V' = -e_r'')
    c = Crawler([1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [0.5, 0.5, 0.5])
    b = law.bounds(c)
    assert law.required_constants(b, [0], [0, 1, -1], -2.0) == 2.0 + 1.0 - 0.5


def test_the_rule_option_names_its_values():
    assert law.check_rule('margin') == 'margin' and law.DEFAULT_RULE == 'incumbent'
    with pytest.raises(ValueError, match='stiction_rule'):
        law.check_rule('largest')
