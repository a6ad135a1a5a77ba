"""Smooth periodic gaits: `Sinusoid`, `Fourier` and the `Scallop` stroke.

Each is evaluated by its compiled kind (``solvers._gait``: FOURIER for the first two, SCALLOP
for the stroke), from Python as from the solvers.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import BuiltinGait, _finite, _n_links, _per_link, _positive


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


#: most values of one array of ``Scallop._cauchy`` (8,192 doubles: 64 KiB)
_BLOCK_VALUES = 8192
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

        Each is the smaller of two bounds that hold: Cauchy's estimate (``_cauchy``), and the
        derivative's exact values at the bin's ends (``_derivatives``, with their rounding
        error) plus the error of the chord between them, h^2 / 8 times a bound of the
        derivative two orders higher (again Cauchy's, but multiplied by h^2 / 8 its looseness
        hardly matters). Cauchy's estimate alone runs 46-184 times above the true maximum
        where the stroke is not sharp (r >= 0.05), the other 1.0-2.7 times, and the event
        search's steps shrink with the bound (5 times a Fourier gait's evaluations).
        """
        # Cauchy's estimates per group of 8 bins (a group's bound holds on each of its bins):
        # they are a bin's bound only where the chord's is worse, and the chord's error term
        # carries them times h^2 / 8; most of the tables' cost otherwise
        n = t0.size
        first = np.arange(0, n, _GROUP)
        last = np.minimum(first + _GROUP - 1, n - 1)
        c3, c4, c5, c6 = (c[np.arange(n) // _GROUP] for c in
                          self._cauchy((3, 4, 5, 6), t0[first], t1[last], n_radii=7))
        w = self._w
        amp = np.abs(self.amplitude)
        x = w * np.concatenate([t0, t1[-1:]])[:, None] + self.phase - math.pi * self.asymmetry
        f, err = self._derivatives(x, 4)
        h2 = (w * (t1 - t0))[:, None] ** 2 / 8.0            # in x: (w h)^2 / 8
        out = []
        for n, cn, cn2 in ((3, c3, c5), (4, c4, c6)):
            top = np.abs(f[n]) + err[n]                       # |f^(n)| at the bin ends
            ends = np.maximum(top[:-1], top[1:]) * amp * w ** n
            # the bound of order n + 2 carries amp w^(n + 2) and the x-width squared is
            # (w h)^2: divide by w^2
            chord = (ends + h2 * cn2 / w ** 2) * (1.0 + 1e-12)
            out.append(np.minimum(cn, chord))
        return out[0], out[1]

    def _derivatives(self, x: NDArray[np.float64], n_max: int
                     ) -> tuple[list[NDArray[np.float64]], list[NDArray[np.float64]]]:
        """f, f', ..., f^(n_max) at x, for f(x) = s sin x / D(x), D = 1 - c cos x (l = mean +
        amplitude f), and a bound of each one's rounding error: from f D = s sin x
        differentiated n times (Leibniz), f^(n) = (s sin^(n) x - sum_{k<n} C(n, k) f^(k)
        D^(n-k)) / D, with D^(m) = -c cos^(m) x for m >= 1 and sin^(n) x = sin(x + n pi / 2).
        The error of f^(n): 8 eps times the sum of the magnitudes of its terms, plus the
        errors of the f^(k) it uses, all over |D|."""
        c, s = self._c, self._s
        eps = np.finfo(float).eps
        cx, sx = np.cos(x), np.sin(x)
        sin_n = (sx, cx, -sx, -cx)          # sin^(n) x = sin(x + n pi / 2), n mod 4
        cos_n = (cx, -sx, -cx, sx)
        D = 1.0 - c * cx
        Dm = [D] + [-c * cos_n[m % 4] for m in range(1, n_max + 1)]
        f: list[NDArray[np.float64]] = []
        err: list[NDArray[np.float64]] = []
        for n in range(n_max + 1):
            acc = s * sin_n[n % 4]
            mag = np.abs(acc) + abs(s)                # sin's own rounding
            prop = np.zeros_like(x)
            for k in range(n):
                term = math.comb(n, k) * f[k] * Dm[n - k]
                acc = acc - term
                mag = mag + np.abs(term)
                prop = prop + math.comb(n, k) * err[k] * np.abs(Dm[n - k])
            f.append(acc / D)
            err.append((8.0 * eps * mag + prop) / np.abs(D))
        return f, err

    def _cauchy(self, orders: tuple[int, ...], t0, t1,
                n_radii: int = 19) -> list[NDArray[np.float64]]:
        """Rigorous bounds of |d^n l / dt^n| on [t0, t1] by Cauchy's estimate, per linkage,
        for each n of ``orders``.

        l = mean + amplitude f(x), f(x) = s sin x / (1 - c cos x), x = w t + phase - pi r, is
        analytic off the poles x = 2 pi k (+ pi when c < 0) +- i rho0, cosh rho0 = 1 / |c|. On
        a disc of radius rho around a real point: |s sin z| <= s cosh rho and, with z' = z (or
        z + pi when c < 0), 1 - c cos z = 2 |c| sin((z' + i rho0) / 2) sin((z' - i rho0) / 2)
        and |sin u|^2 = sin^2 Re u + sinh^2 Im u give |1 - c cos z| >= 2 |c| (min sin^2(Re z'
        / 2) + sinh^2(max(rho0 - rho, 0) / 2)). Then |f^(n)| <= n! max|f| / rho^n; the best
        of a range of radii is kept. Local: small far from the fast phase of a sharp stroke.
        ``t0``, ``t1``: floats, or arrays of shape (B,) (then each result is (B, n_links)).

        Many radii at once, as arrays (radius, bin, linkage), and the orders from the same lower
        bound of |1 - c cos z|: a new gait's tables are most of a sweep scene's set-up.
        """
        c, s, w = self._c, self._s, self._w
        amp = np.abs(self.amplitude)
        if abs(c) < 1e-12:        # r = 1/2: a plain cosine stroke
            return [np.broadcast_to(amp * w ** n * (1.0 + 1e-12), np.shape(t0) + amp.shape).copy()
                    for n in orders]
        rho0 = math.acosh(1.0 / abs(c))
        t0, t1 = np.asarray(t0, float)[..., None], np.asarray(t1, float)[..., None]
        x0 = w * t0 + self.phase - math.pi * self.asymmetry + (math.pi if c < 0 else 0.0)
        span = w * (t1 - t0)
        radii = np.concatenate([rho0 * np.linspace(0.05, 0.95, n_radii),
                                [0.25, 0.5, 1.0, 2.0, 3.0]])
        best = [np.full(np.broadcast_shapes(x0.shape, span.shape), math.inf) for _ in orders]
        # radii in blocks whose arrays stay well under 128 KiB: glibc maps larger ones anew each
        # time where the trim threshold is fixed (Dask's workers set MALLOC_TRIM_THRESHOLD_),
        # and the page faults then cost more than the arithmetic
        block = max(1, _BLOCK_VALUES // max(1, int(np.prod(best[0].shape))))
        for k0 in range(0, radii.size, block):
            rs = radii[k0:k0 + block]
            rho = rs.reshape((-1,) + (1,) * x0.ndim)
            lo = 0.5 * (x0 - rho)                  # Re(z') / 2 ranges over [lo, lo + width]
            width = 0.5 * (span + 2.0 * rho)
            contains = np.ceil(lo / math.pi) * math.pi <= lo + width
            m = np.where(contains, 0.0, np.minimum(np.sin(lo) ** 2, np.sin(lo + width) ** 2))
            sinh2 = np.array([math.sinh(max(rho0 - r, 0.0) / 2.0) ** 2 for r in rs.tolist()])
            den = 2.0 * abs(c) * (m + sinh2.reshape(rho.shape))
            safe = np.where(den > 0, den, 1.0)
            for b, n in zip(best, orders):
                # per radius as the formula reads (n! s cosh rho / den / rho^n), then the best
                scale = np.array([math.factorial(n) * s * math.cosh(r) for r in rs.tolist()])
                pw = np.array([r ** n for r in rs.tolist()]).reshape(rho.shape)
                bound = np.where(den > 0, scale.reshape(rho.shape) / safe / pw, math.inf)
                np.minimum(b, bound.min(axis=0), out=b)
        # 1 + 1e-12: the bound is computed in floats
        return [amp * w ** n * b * (1.0 + 1e-12) for b, n in zip(best, orders)]
