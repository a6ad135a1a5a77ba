"""The crawler: p bodies on a line with Coulomb dry friction, and the kinematics of its linkages.

Sign conventions (docs/ARCHITECTURE.md): x points forward (uphill on a slope); ``friction`` [N]
resists forward sliding, ``friction_backward`` [N] resists backward sliding; the ground exerts
``-friction[i]`` on a body sliding forward and ``+friction_backward[i]`` on one sliding backward.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ['Crawler', 'DERIVED_LIMIT', 'kinematics']


def _check_scalar(name: str, value: float, *, lo: float | None = None,
                  lo_open: bool = False, allowed: str = '') -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a number ({allowed}), got {value!r}') from None
    if not math.isfinite(x) or (lo is not None and (x <= lo if lo_open else x < lo)):
        raise ValueError(f'{name} must be finite and {allowed}, got {value!r}')
    return x


def _check_vector(name: str, value: ArrayLike, p: int | None, *, positive: bool) -> NDArray:
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    rule = '> 0' if positive else '>= 0'
    if arr.ndim != 1:
        raise ValueError(f'{name} must be a float or a list, got shape {arr.shape}')
    if p is not None:
        if arr.size == 1:
            arr = np.full(p, arr[0])
        elif arr.size != p:
            raise ValueError(f'{name} must have 1 or {p} entries (one per body), got {arr.size}')
    bad = ~np.isfinite(arr) | ((arr <= 0) if positive else (arr < 0))
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ValueError(f'{name}[{i}] must be finite and {rule}, got {arr[i]!r}')
    arr.setflags(write=False)
    return arr


# Largest derived force [N], mass [kg] or acceleration [m/s^2] a crawler may have. Solvers
# multiply two such quantities (force x time x velocity, mass x velocity^2, ...), so 1e100 keeps
# every product they form far from overflow (1.8e308) and no output can turn into inf or NaN.
DERIVED_LIMIT = 1e100


def _check_derived(masses: NDArray, fp: NDArray, fm: NDArray, slope: float,
                   gravity: float) -> None:
    """Sums and products of valid single values can still overflow: check them by name."""
    lim = DERIVED_LIMIT
    with np.errstate(over='ignore', invalid='ignore'):
        M = float(np.sum(masses))
        weight = M * gravity
        f_total = float(np.sum(fp) + np.sum(fm))
        push = weight * abs(math.sin(slope))
        acc = (f_total + push) / M if M > 0 else math.inf
    if not M <= lim:
        raise ValueError(f'masses: their sum must be <= {lim:g} kg, got {M!r} '
                         f'(each mass must be finite and > 0, and so must their total)')
    if not f_total <= lim:
        raise ValueError(f'friction: sum(friction) + sum(friction_backward) must be <= {lim:g} N, '
                         f'got {f_total!r}')
    if not weight <= lim:
        raise ValueError(f'gravity: gravity * sum(masses) (the total weight) must be <= '
                         f'{lim:g} N, got {weight!r} (gravity {gravity!r} m/s^2, sum(masses) '
                         f'{M!r} kg)')
    if not acc <= lim:
        raise ValueError(f'friction: (total friction + weight * |sin(slope)|) / sum(masses), the '
                         f'largest acceleration the forces can give, must be <= {lim:g} m/s^2, '
                         f'got {acc!r}; reduce friction or raise masses')


def _forces(m: NDArray[np.float64], coefficients: dict[str, NDArray[np.float64]],
            slope: float, gravity: float) -> tuple[NDArray[np.float64], ...]:
    """Friction forces [N] f_i = mu_i m_i g cos(slope) of each checked coefficient array (in
    the order given); ValueError naming the coefficient when a force would exceed
    ``DERIVED_LIMIT``."""
    slope = _check_scalar('slope', slope, allowed='in (-pi/2, pi/2) rad')
    gravity = _check_scalar('gravity', gravity, lo=0.0, allowed='>= 0 m/s^2')
    with np.errstate(over='ignore', invalid='ignore'):
        normal = m * gravity * math.cos(slope)
    out = []
    for name, mu_arr in coefficients.items():
        with np.errstate(over='ignore', invalid='ignore'):
            f = mu_arr * normal
        bad = ~(f <= DERIVED_LIMIT)
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ValueError(f'{name}[{i}]: the friction force {name}[{i}] * masses[{i}] * '
                             f'gravity * cos(slope) must be <= {DERIVED_LIMIT:g} N, got '
                             f'{float(f[i])!r} (mu {float(mu_arr[i])!r}, mass {float(m[i])!r}'
                             ' kg)')
        out.append(f)
    return tuple(out)


# the keyword arguments of each kind: forces [N] or coefficients (mixing them is refused)
_FORCE_KIND = ('friction_backward', 'static_friction', 'static_friction_backward')
_COEFF_KIND = ('mu_backward', 'mu_static', 'mu_static_backward')


def _check_kinds(forces: bool, given: dict) -> None:
    """Refuse a coefficient keyword with ``friction`` or a force keyword with ``mu``, naming
    both."""
    base, wrong, other = (('friction', _COEFF_KIND, 'mu') if forces
                          else ('mu', _FORCE_KIND, 'friction'))
    for name in wrong:
        if given[name] is not None:
            mate = dict(zip(_COEFF_KIND + _FORCE_KIND, _FORCE_KIND + _COEFF_KIND))[name]
            raise ValueError(f'{name} goes with {other}, not with {base}: with {base} give '
                             f'{mate} (forces [N] and coefficients cannot be mixed)')


def _static_defaults(fwd: NDArray, bwd: NDArray, isotropic: bool, static: ArrayLike | None,
                     static_backward: ArrayLike | None, name: str, p: int
                     ) -> tuple[NDArray, NDArray]:
    """The static bounds (or coefficients) ``name`` and ``name + '_backward'``, checked to be
    at least their kinetic ones ``fwd`` / ``bwd``. Defaults: forward = the kinetic forward;
    backward = the static forward when no backward kinetic value was given (``isotropic``: an
    isotropic crawler stays isotropic), else the kinetic backward."""
    s = fwd if static is None else _check_vector(name, static, p, positive=False)
    name_b = name + '_backward'
    if static_backward is not None:
        sb = _check_vector(name_b, static_backward, p, positive=False)
    else:
        sb = s if isotropic else bwd
    kinetic = 'mu' if name.startswith('mu') else 'friction'
    for field, stat, kin, kname in ((name, s, fwd, kinetic),
                                    (name_b, sb, bwd, kinetic + '_backward')):
        low = stat < kin
        if np.any(low):
            i = int(np.argmax(low))
            raise ValueError(f'{field}[{i}] must be >= {kname}[{i}] = {float(kin[i])!r} (static '
                             f'friction is at least the kinetic one), got {float(stat[i])!r}')
    return s, sb


def _check_derived_static(fs: NDArray, fsb: NDArray) -> None:
    """The static bounds' total, as ``_check_derived`` checks the kinetic one: a stuck
    cluster's event rows add them."""
    with np.errstate(over='ignore', invalid='ignore'):
        total = float(np.sum(fs) + np.sum(fsb))
    if not total <= DERIVED_LIMIT:
        raise ValueError(f'static_friction: sum(static_friction) + sum(static_friction_backward)'
                         f' must be <= {DERIVED_LIMIT:g} N, got {total!r}')


@dataclass(frozen=True, init=False, eq=False)
class Crawler:
    """A chain of p >= 2 bodies on a line.

    Parameters
    ----------
    masses : array_like, shape (p,)
        Body masses [kg], finite and > 0.
    friction : float or array_like, shape (p,)
        Friction force magnitude resisting forward (+x) sliding [N], finite and >= 0 (or give
        ``mu`` instead).
    friction_backward : float or array_like, shape (p,), optional
        The same for backward sliding [N]; defaults to ``friction``.
    slope : float
        Inclination [rad], uphill is +x, in (-pi/2, pi/2); adds ``-m_i g sin(slope)`` to body i.
    gravity : float
        Gravitational acceleration [m/s^2], finite and >= 0.
    mu, mu_backward : float or array_like, shape (p,), keyword only
        Friction coefficients instead of forces: f_i = mu_i m_i g cos(slope)
        (``Crawler([0.5, 1.0], mu=0.3)``; the same as :meth:`from_coefficients`).
    static_friction, static_friction_backward : float or array_like, shape (p,), keyword only
        Static friction bounds [N] (with ``friction``): a stuck body holds while the force it
        needs is within ``[-static_friction[i], static_friction_backward[i]]`` (STICTION.md).
        Defaults: ``static_friction`` = ``friction``; ``static_friction_backward`` =
        ``static_friction`` when ``friction_backward`` is not given (an isotropic crawler stays
        isotropic), else ``friction_backward``. Each must be >= its kinetic bound.
    mu_static, mu_static_backward : float or array_like, shape (p,), keyword only
        The same as coefficients (with ``mu``), with the same defaults from ``mu`` and
        ``mu_backward``. Forces and coefficients cannot be mixed.

    Derived quantities are checked too (ValueError naming the field): sum(masses) [kg], the
    total friction sum(friction) + sum(friction_backward) [N], the weight gravity * sum(masses)
    [N] and the largest acceleration (total friction + weight |sin slope|) / sum(masses)
    [m/s^2] must each be at most ``DERIVED_LIMIT`` = 1e100, so no product a solver forms can
    overflow into inf or NaN.
    """

    masses: NDArray[np.float64]
    friction: NDArray[np.float64]
    friction_backward: NDArray[np.float64]
    static_friction: NDArray[np.float64]
    static_friction_backward: NDArray[np.float64]
    slope: float
    gravity: float

    def __init__(self, masses: ArrayLike, friction: ArrayLike | None = None,
                 friction_backward: ArrayLike | None = None, slope: float = 0.0,
                 gravity: float = 9.81, *, mu: ArrayLike | None = None,
                 mu_backward: ArrayLike | None = None,
                 static_friction: ArrayLike | None = None,
                 static_friction_backward: ArrayLike | None = None,
                 mu_static: ArrayLike | None = None,
                 mu_static_backward: ArrayLike | None = None) -> None:
        m = _check_vector('masses', masses, None, positive=True)
        if m.size < 2:
            raise ValueError(f'masses must list p >= 2 bodies, got p = {m.size}')
        p = m.size
        if (friction is None) == (mu is None):
            raise ValueError('give friction forces [N] or coefficients mu, exactly one of them')
        _check_kinds(friction is not None, {
            'friction_backward': friction_backward, 'static_friction': static_friction,
            'static_friction_backward': static_friction_backward, 'mu_backward': mu_backward,
            'mu_static': mu_static, 'mu_static_backward': mu_static_backward})
        if mu is not None:
            mu_f = _check_vector('mu', mu, p, positive=False)
            mu_b = mu_f if mu_backward is None else _check_vector(
                'mu_backward', mu_backward, p, positive=False)
            mu_s, mu_sb = _static_defaults(mu_f, mu_b, mu_backward is None, mu_static,
                                           mu_static_backward, 'mu_static', p)
            friction, friction_backward, static_friction, static_friction_backward = _forces(
                m, {'mu': mu_f, 'mu_backward': mu_b, 'mu_static': mu_s,
                    'mu_static_backward': mu_sb}, slope, gravity)
        f = _check_vector('friction', friction, p, positive=False)
        fb = f if friction_backward is None else _check_vector(
            'friction_backward', friction_backward, p, positive=False)
        fs, fsb = _static_defaults(f, fb, friction_backward is None, static_friction,
                                   static_friction_backward, 'static_friction', p)
        slope = _check_scalar('slope', slope, allowed='in (-pi/2, pi/2) rad')
        if not abs(slope) < math.pi / 2:
            raise ValueError(f'slope must be in (-pi/2, pi/2) rad, got {slope!r}')
        gravity = _check_scalar('gravity', gravity, lo=0.0, allowed='>= 0 m/s^2')
        _check_derived(m, f, fb, slope, gravity)
        _check_derived_static(fs, fsb)
        object.__setattr__(self, 'masses', m)
        object.__setattr__(self, 'friction', f)
        object.__setattr__(self, 'friction_backward', fb)
        object.__setattr__(self, 'static_friction', fs)
        object.__setattr__(self, 'static_friction_backward', fsb)
        object.__setattr__(self, 'slope', slope)
        object.__setattr__(self, 'gravity', gravity)

    @classmethod
    def from_coefficients(cls, masses: ArrayLike, mu: ArrayLike,
                          mu_backward: ArrayLike | None = None, slope: float = 0.0,
                          gravity: float = 9.81, *, mu_static: ArrayLike | None = None,
                          mu_static_backward: ArrayLike | None = None) -> Crawler:
        """Build from friction coefficients: f_i = mu_i m_i g cos(slope) (the same as
        ``Crawler(masses, mu=mu, ...)``)."""
        return cls(masses, slope=slope, gravity=gravity, mu=mu, mu_backward=mu_backward,
                   mu_static=mu_static, mu_static_backward=mu_static_backward)

    @property
    def has_stiction(self) -> bool:
        """True when any static bound is above its kinetic one (``core.friction``)."""
        from .friction import has_stiction
        return has_stiction(self.friction, self.friction_backward, self.static_friction,
                            self.static_friction_backward)

    @property
    def p(self) -> int:
        """Number of bodies."""
        return int(self.masses.size)

    @property
    def total_mass(self) -> float:
        """M = sum of the masses [kg]."""
        return float(self.masses.sum())

    @property
    def gravity_forces(self) -> NDArray[np.float64]:
        """External force on each body along the line, -m_i g sin(slope) [N]."""
        return -self.masses * self.gravity * math.sin(self.slope)

    @property
    def external_force(self) -> float:
        """Total external force F_ext = -M g sin(slope) [N]."""
        return -self.total_mass * self.gravity * math.sin(self.slope)

    def to_dict(self) -> dict:
        """Plain-data description (for scenes and bags): ``Crawler(**d)`` rebuilds it. The
        static bounds are included only when they differ from the kinetic ones
        (``has_stiction``), so the description of a crawler without stiction is what it was
        before stiction existed."""
        d = {'masses': self.masses.tolist(), 'friction': self.friction.tolist(),
             'friction_backward': self.friction_backward.tolist(),
             'slope': self.slope, 'gravity': self.gravity}
        if self.has_stiction:
            d['static_friction'] = self.static_friction.tolist()
            d['static_friction_backward'] = self.static_friction_backward.tolist()
        return d

    def __repr__(self) -> str:
        static = (f', static_friction={self.static_friction.tolist()}, '
                  f'static_friction_backward={self.static_friction_backward.tolist()}'
                  if self.has_stiction else '')
        return (f'Crawler(masses={self.masses.tolist()}, friction={self.friction.tolist()}, '
                f'friction_backward={self.friction_backward.tolist()}, slope={self.slope}, '
                f'gravity={self.gravity}{static})')


def offsets(lengths: NDArray[np.float64]) -> NDArray[np.float64]:
    """s_i = l_0 + ... + l_{i-1} (s_0 = 0): position of body i relative to body 0.

    ``lengths`` has shape (..., p-1); the result has shape (..., p).
    """
    out = np.zeros(lengths.shape[:-1] + (lengths.shape[-1] + 1,))
    np.cumsum(lengths, axis=-1, out=out[..., 1:])
    return out


def kinematics(masses: NDArray[np.float64], l: NDArray, ld: NDArray, ldd: NDArray
               ) -> tuple[NDArray, NDArray, NDArray]:
    """Offsets of the bodies from the centre of mass and their first two derivatives.

    Returns ``(e, e', e'')``, each of shape (..., p): x_i = X + e_i with X the centre of mass.
    """
    m_over_M = masses / masses.sum()
    out = []
    for arr in (l, ld, ldd):
        s = offsets(arr)
        out.append(s - (s @ m_over_M)[..., None])
    return tuple(out)
