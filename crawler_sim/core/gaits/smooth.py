"""Smooth periodic gaits: `Sinusoid`, `Fourier` and the `Scallop` stroke.

Each is evaluated by its compiled kind (``solvers._gait``: FOURIER for the first two, SCALLOP
for the stroke), from Python as from the solvers.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import BuiltinGait, _finite, _n_links, _per_link, _positive


def _first_minimum(gait: BuiltinGait, lowest: NDArray[np.float64], w: float,
                   phase: NDArray[np.float64], t0: float, t1: float
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``length_minimum`` of a stroke whose length is lowest (``lowest`` [m]) where w t +
    phase = 0 (mod 2 pi) and that rises and falls once between two of those times: the first
    such time in [t0, t1] if there is one, else the lower end (a stroke that has not reached
    its lowest point since t0 is at most once rising then falling, so its minimum on the
    interval is at an end). Closed form, O(n_links): no sampling."""
    # Python floats, not numpy: a few linkages, and simulate asks once per run (~1 us)
    tau, wt0 = 2.0 * math.pi, w * t0
    t_low = np.array([t0 + (-(wt0 + ph) % tau) / w for ph in phase.tolist()])
    if t_low.max() <= t1:
        return t_low, lowest        # a whole run of periods: no evaluation at the ends
    l0, l1 = gait.at(t0)[0], gait.at(t1)[0]
    ends_t = np.where(l1 < l0, t1, t0)
    ends_l = np.minimum(l0, l1)
    inside = t_low <= t1
    return np.where(inside, t_low, ends_t), np.where(inside, lowest, ends_l)


class Sinusoid(BuiltinGait):
    """l_j(t) = mean_j + amplitude_j sin(2 pi frequency t + phase_j).

    ``mean``, ``amplitude`` [m] and ``phase`` [rad] are per linkage (or one float for all);
    ``frequency`` [Hz] is shared so the gait is periodic. A phase lag between neighbouring
    linkages makes a travelling wave.
    """

    def __init__(self, mean: ArrayLike, amplitude: ArrayLike, frequency: float,
                 phase: ArrayLike = 0.0, *, n_links: int | None = None) -> None:
        sizes = [np.size(a) for a in (mean, amplitude, phase)]
        n = _n_links(n_links, max(sizes))
        self.n_links = n
        self.mean = _per_link('mean', mean, n)
        self.amplitude = _per_link('amplitude', amplitude, n)
        self.phase = _per_link('phase', phase, n)
        self.frequency = _positive('frequency', frequency, 'Hz')
        self.period = 1.0 / self.frequency

    def _kind(self):
        from ..solvers._gait import fourier
        # A sin(w t + phi) = A sin(phi) cos(w t) + A cos(phi) sin(w t), w t reduced mod 2 pi
        a = self.amplitude
        return fourier(self.frequency, self.mean, (a * np.sin(self.phase))[:, None],
                       (a * np.cos(self.phase))[:, None])

    def length_minimum(self, t0: float, t1: float
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        # lowest where w t + phase = -pi/2 (amplitude > 0) or +pi/2 (< 0), mod 2 pi
        a = self.amplitude
        shift = np.where(a < 0, -0.5 * math.pi, 0.5 * math.pi)
        return _first_minimum(self, self.mean - np.abs(a), 2.0 * math.pi * self.frequency,
                              self.phase + shift, float(t0), float(t1))


class Fourier(BuiltinGait):
    """A truncated Fourier series per linkage.

    l_j(t) = mean_j + sum_{k=1..K} (a_jk cos(2 pi k f t) + b_jk sin(2 pi k f t))

    Parameters
    ----------
    mean : float or array_like, shape (n_links,)
        Mean lengths [m].
    coefficients : pair (cos, sin) of array_like
        ``cos`` holds a_jk and ``sin`` holds b_jk [m], both of shape (K,) (the same series for
        every linkage) or (n_links, K). Column ``k - 1`` is harmonic k (k = 1..K); there is no
        constant term (that is ``mean``). An array of shape (2, K) or (2, n_links, K) also works.
    frequency : float
        Fundamental frequency f [Hz]; ``period = 1 / f``.
    n_links : int, optional
        Number of linkages when it cannot be read from the shapes of ``mean`` and the
        coefficients.
    """

    def __init__(self, mean: ArrayLike, coefficients: tuple[ArrayLike, ArrayLike] | ArrayLike,
                 frequency: float, *, n_links: int | None = None) -> None:
        try:
            cos, sin = coefficients
        except (TypeError, ValueError):
            raise ValueError('coefficients must be a pair (cos, sin) of arrays of shape (K,) '
                             'or (n_links, K)') from None
        a = _finite('coefficients', cos)
        b = _finite('coefficients', sin)
        if a.shape != b.shape or a.ndim not in (1, 2) or a.shape[-1] < 1:
            raise ValueError('coefficients (cos, sin) must both have shape (K,) or (n_links, K) '
                             f'with K >= 1, got {a.shape} and {b.shape}')
        rows = a.shape[0] if a.ndim == 2 else 1
        n = _n_links(n_links, max(rows, np.size(mean)))
        if a.ndim == 2 and rows != n:
            raise ValueError(f'coefficients must have {n} rows (one per linkage), got {rows}')
        self.n_links = n
        self.mean = _per_link('mean', mean, n)
        self.cos = np.broadcast_to(a, (n, a.shape[-1])).copy()
        self.sin = np.broadcast_to(b, (n, b.shape[-1])).copy()
        self.frequency = _positive('frequency', frequency, 'Hz')
        self.period = 1.0 / self.frequency

    def _kind(self):
        from ..solvers._gait import fourier
        return fourier(self.frequency, self.mean, self.cos, self.sin)


#: bins per group of ``Scallop._bounds``' Cauchy estimates
_GROUP = 8


class Scallop(BuiltinGait):

    """A smooth periodic stroke with a fast and a slow phase.

    A cosine stroke between ``mean - amplitude`` and ``mean + amplitude`` is run through an
    analytic, strictly monotone time warp so that the extension (l' > 0) lasts the fraction
    ``asymmetry`` = r of the period and the contraction the rest. With x = 2 pi f t + phase_j -
    pi r, c = cos(pi r), s = sin(pi r) and D = 1 - c cos x > 0, the warped phase phi(x) has

        sin phi = s sin x / D,   cos phi = (cos x - c) / D,
        phi' = s / D,            phi'' = -s c sin x / D^2

    (the circle map tan(phi/2) = cot(pi r / 2) tan(x/2); phi' > 0 for every r in (0, 1)), and

        l = mean + amplitude sin phi,
        l' = amplitude w cos(phi) phi',
        l'' = amplitude w^2 (cos(phi) phi'' - sin(phi) phi'^2),   w = 2 pi f,

    all in closed form, so the gait is C-infinity. r = 0.5 gives mean - amplitude cos(w t +
    phase). l is at its minimum when w t + phase = 0 (mod 2 pi), extends while w t + phase is in
    (0, 2 pi r), then contracts.

    Parameters
    ----------
    mean, amplitude : float or array_like, shape (n_links,)
        Mean length and half stroke [m]; ``amplitude >= 0``.
    frequency : float
        Stroke frequency [Hz]; ``period = 1 / frequency``.
    asymmetry : float
        Fraction r of the period spent extending, in the open interval (0, 1). r = 0.2 is a fast
        extension and a slow contraction.
    phase : float or array_like, shape (n_links,)
        Phase lead of each linkage [rad] (a lag between neighbours makes a travelling wave).
    n_links : int, optional
        Number of linkages when the per-linkage arguments are all floats.
    """

    def __init__(self, mean: ArrayLike, amplitude: ArrayLike, frequency: float,
                 asymmetry: float, phase: ArrayLike = 0.0, *, n_links: int | None = None) -> None:
        n = _n_links(n_links, max(np.size(a) for a in (mean, amplitude, phase)))
        self.n_links = n
        self.mean = _per_link('mean', mean, n)
        self.amplitude = _per_link('amplitude', amplitude, n)
        if np.any(self.amplitude < 0):
            raise ValueError(f'amplitude must be >= 0 m, got {self.amplitude.tolist()}')
        self.phase = _per_link('phase', phase, n)
        self.frequency = _positive('frequency', frequency, 'Hz')
        self.period = 1.0 / self.frequency
        try:
            r = float(asymmetry)
        except (TypeError, ValueError):
            raise ValueError(f'asymmetry must be a float in (0, 1), got {asymmetry!r}') from None
        if not 0.0 < r < 1.0:
            raise ValueError(f'asymmetry must be in the open interval (0, 1), got {asymmetry!r}')
        self.asymmetry = r
        self._c, self._s = math.cos(math.pi * r), math.sin(math.pi * r)
        self._w = 2.0 * math.pi * self.frequency

    def _kind(self):
        from ..solvers._gait import scallop
        # bound tables of ``_bins`` bins per period (each bin bound holds on its closed bin)
        T, nb = self.period, self._bins
        k = np.arange(nb)
        jerk, snap = self._bounds(k * T / nb, (k + 1) * T / nb)            # (nb, n_links)
        rows = np.column_stack([self.amplitude, self.phase - math.pi * self.asymmetry,
                                np.full(self.n_links, self._c), np.full(self.n_links, self._s)])
        return scallop(self.frequency, self.mean, rows, jerk, snap)

    def length_minimum(self, t0: float, t1: float
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        # lowest (mean - amplitude) where w t + phase = 0 (mod 2 pi), see the class docstring
        return _first_minimum(self, self.mean - self.amplitude, self._w, self.phase,
                              float(t0), float(t1))

    @property
    def _bins(self) -> int:
        """Bins per period of the bound tables: 1024, and for a stroke sharper than 3 % of the
        period a power of two times more, about 30 per sharp phase (coarser bins around a
        phase of 1e-3 of the period made each bound ~1e3 times the true one: 5 million search
        evaluations for 3 periods at asymmetry 0.001)."""
        r = min(self.asymmetry, 1.0 - self.asymmetry)
        return 1024 if r >= 0.03 else 1024 * 2 ** math.ceil(math.log2(0.03 / r))

    def _bounds(self, t0: NDArray[np.float64], t1: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Rigorous bounds of |l'''| [m/s^3] and |l''''| [m/s^4] on each bin [t0, t1] (arrays
        (B,)), per linkage: (B, n_links) each.

        Each is the smaller of two bounds that hold: Cauchy's estimate, and the derivative's
        exact values at the bin's ends (with their rounding error) plus the error of the
        chord between them, h^2 / 8 times a bound of the derivative two orders higher (again
        Cauchy's, but multiplied by h^2 / 8 its looseness hardly matters). Cauchy's estimate
        alone runs 46-184 times above the true maximum where the stroke is not sharp (r >=
        0.05), the other 1.0-2.7 times, and the event search's steps shrink with the bound (5
        times a Fourier gait's evaluations).

        Cauchy: l = mean + amplitude f(x), f(x) = s sin x / (1 - c cos x), x = w t + phase -
        pi r, is analytic off the poles x = 2 pi k (+ pi when c < 0) +- i rho0, cosh rho0 =
        1 / |c|. On a disc of radius rho around a real point, |s sin z| <= s cosh rho and,
        with z' = z (or z + pi when c < 0), 1 - c cos z = 2 |c| sin((z' + i rho0) / 2)
        sin((z' - i rho0) / 2) and |sin u|^2 = sin^2 Re u + sinh^2 Im u give |1 - c cos z| >=
        2 |c| (min sin^2(Re z' / 2) + sinh^2(max(rho0 - rho, 0) / 2)); then |f^(n)| <= n!
        max|f| / rho^n, the best of a range of radii kept.
        The values at the ends: from f D = s sin x differentiated n times (Leibniz), f^(n) =
        (s sin^(n) x - sum_{k<n} C(n, k) f^(k) D^(n-k)) / D, with D^(m) = -c cos^(m) x for m
        >= 1; the error of f^(n): 8 eps times the sum of the magnitudes of its terms, plus
        the errors of the f^(k) it uses, all over |D|. Both in ``_gait.scallop_bins``.
        """
        # Cauchy's estimates per group of 8 bins (a group's bound holds on each of its bins):
        # they are a bin's bound only where the chord's is worse, and the chord's error term
        # carries them times h^2 / 8; the best of 7 radii inside the poles' distance and 5
        # beyond it (compiled: ``_gait.scallop_bins``)
        from ..solvers._gait import scallop_bins
        return scallop_bins(self._c, self._s, self._w, self.amplitude, self.phase,
                            math.pi * self.asymmetry, np.asarray(t0, dtype=float),
                            np.asarray(t1, dtype=float), _GROUP, 7)
