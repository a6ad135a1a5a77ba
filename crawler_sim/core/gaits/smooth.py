"""Smooth periodic gaits: `Sinusoid`, `Fourier` and the `Scallop` stroke."""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import Gait, Triple, _finite, _n_links, _per_link, _positive, similar_run


class Sinusoid(Gait):
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
        self._w = 2.0 * math.pi * self.frequency

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        arg = self._w * t[:, None] + self.phase
        s, c = np.sin(arg), np.cos(arg)
        a = self.amplitude
        return self.mean + a * s, a * self._w * c, -a * self._w ** 2 * s

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return np.abs(self.amplitude) * self._w ** 3

    def snap_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return np.abs(self.amplitude) * self._w ** 4

    def at(self, t: float) -> Triple:
        if self.n_links == 1:
            l, ld, ldd = self.at1(t)
            return np.array([l]), np.array([ld]), np.array([ldd])
        arg = self._w * t + self.phase
        s, c = np.sin(arg), np.cos(arg)
        a = self.amplitude
        return self.mean + a * s, a * self._w * c, -a * self._w ** 2 * s

    def at1(self, t: float) -> tuple[float, float, float]:
        arg = self._w * t + float(self.phase[0])
        s, c = math.sin(arg), math.cos(arg)
        a = float(self.amplitude[0])
        return float(self.mean[0]) + a * s, a * self._w * c, -a * self._w ** 2 * s


class Fourier(Gait):
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
        w = 2.0 * math.pi * self.frequency
        k = np.arange(1, a.shape[-1] + 1, dtype=float)
        self._k = k
        # [cos(k th) | sin(k th)] @ matrix gives l - mean, l', l'' (th = 2 pi f t).
        a_t, b_t = self.cos.T, self.sin.T                       # (K, n)
        wk = (w * k)[:, None]
        self._m0 = np.vstack([a_t, b_t])
        self._m1 = np.vstack([wk * b_t, -wk * a_t])
        self._m2 = np.vstack([-wk ** 2 * a_t, -wk ** 2 * b_t])
        self._rows = None          # plain-float coefficients of ``at``, built on first use

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        # Reduce to the phase in cycles first so that large t keeps full accuracy.
        th = 2.0 * math.pi * np.mod(self.frequency * t, 1.0)
        arg = th[:, None] * self._k
        cs = np.hstack([np.cos(arg), np.sin(arg)])
        return self.mean + cs @ self._m0, cs @ self._m1, cs @ self._m2

    def at(self, t: float) -> Triple:
        # the series of _eval in scalar math (numpy's per-call cost dominates for a few terms)
        ft = self.frequency * t
        th = 2.0 * math.pi * (ft % 1.0)
        w = 2.0 * math.pi * self.frequency
        if self._rows is None:
            self._rows = [list(zip(a, b)) for a, b in zip(self.cos.tolist(), self.sin.tolist())]
            self._means = self.mean.tolist()
        cs = [(math.cos(k * th), math.sin(k * th)) for k in range(1, self.cos.shape[1] + 1)]
        l, ld, ldd = [], [], []
        for mean, row in zip(self._means, self._rows):
            s0 = s1 = s2 = 0.0
            for k, ((a, b), (c, s)) in enumerate(zip(row, cs), start=1):
                wk = w * k
                s0 += a * c + b * s
                s1 += wk * (b * c - a * s)
                s2 -= wk * wk * (a * c + b * s)
            l.append(mean + s0)
            ld.append(s1)
            ldd.append(s2)
        return np.array(l), np.array(ld), np.array(ldd)

    def is_constant(self, t0: float, t1: float) -> bool:
        return not (np.any(self.cos) or np.any(self.sin))

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        wk3 = (2.0 * math.pi * self.frequency * self._k) ** 3
        return (np.abs(self.cos) + np.abs(self.sin)) @ wk3

    def snap_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        wk4 = (2.0 * math.pi * self.frequency * self._k) ** 4
        return (np.abs(self.cos) + np.abs(self.sin)) @ wk4


class Scallop(Gait):
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

    def _eval(self, t: NDArray[np.float64]) -> Triple:
        c, s, w, amp = self._c, self._s, self._w, self.amplitude
        x = 2.0 * math.pi * np.mod(self.frequency * t, 1.0)[:, None] + (
            self.phase - math.pi * self.asymmetry)
        cx, sx = np.cos(x), np.sin(x)
        inv_d = 1.0 / (1.0 - c * cx)
        sin_phi, cos_phi = s * sx * inv_d, (cx - c) * inv_d
        dphi = s * inv_d
        ddphi = -s * c * sx * inv_d ** 2
        return (self.mean + amp * sin_phi, amp * w * cos_phi * dphi,
                amp * w ** 2 * (cos_phi * ddphi - sin_phi * dphi ** 2))

    def at(self, t: float) -> Triple:
        if self.n_links != 1:
            return self(t)
        l, ld, ldd = self.at1(t)
        return np.array([l]), np.array([ld]), np.array([ldd])

    def at1(self, t: float) -> tuple[float, float, float]:
        # the formulas of _eval in scalar math: about 15 times faster than the array path
        c, s, w = self._c, self._s, self._w
        amp = float(self.amplitude[0])
        x = 2.0 * math.pi * ((self.frequency * t) % 1.0) + (
            float(self.phase[0]) - math.pi * self.asymmetry)
        cx, sx = math.cos(x), math.sin(x)
        inv_d = 1.0 / (1.0 - c * cx)
        sin_phi, cos_phi = s * sx * inv_d, (cx - c) * inv_d
        dphi = s * inv_d
        ddphi = -s * c * sx * inv_d ** 2
        return (float(self.mean[0]) + amp * sin_phi, amp * w * cos_phi * dphi,
                amp * w ** 2 * (cos_phi * ddphi - sin_phi * dphi ** 2))

    def is_constant(self, t0: float, t1: float) -> bool:
        return not np.any(self.amplitude)

    def jerk_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return self._binned(3, t0, t1)

    def snap_bound(self, t0: float, t1: float) -> NDArray[np.float64]:
        return self._binned(4, t0, t1)

    def block_end(self, t0: float, t1: float) -> float:
        # whole bins from t0's bin on, at most one period ahead, whose bounds (each bin with
        # its neighbours, relative to the largest bin's, jerk and snap alike) are similar
        nb, T = self._bins, self.period
        v = self.__dict__.get('_similarity')
        if v is None:
            v = np.maximum(self._relative(3), self._relative(4))
            v = np.maximum(v, np.maximum(np.roll(v, 1), np.roll(v, -1)))
            v = self._similarity = np.maximum(v, 1e-9)
        k = math.floor(t0 / T * nb)
        n = min(math.floor((t1 - t0) / T * nb) + 2, nb)
        e = similar_run(v[(k + np.arange(n)) % nb])
        if e >= n:
            return t1
        t_b = (k + e) * T / nb
        if t_b <= t0:           # t0 on a bin edge rounded into the previous bin
            t_b = (k + e + 1) * T / nb
        return t_b if t_b < t1 else t1

    def _relative(self, n: int) -> NDArray[np.float64]:
        """Each bin's bound of |l^(n)| over the largest bin's, the largest over linkages."""
        self._binned(n, 0.0, 0.0)      # builds the table
        tab = self._bound_tables[n]
        return (tab / np.maximum(tab.max(axis=0), 1e-300)).max(axis=1)

    @property
    def _bins(self) -> int:
        """Bins per period of the bound tables: 1024, and for a stroke sharper than 3 % of the
        period a power of two times more, about 30 per sharp phase (coarser bins around a
        phase of 1e-3 of the period made each bound ~1e3 times the true one: 5 million search
        evaluations for 3 periods at asymmetry 0.001)."""
        r = min(self.asymmetry, 1.0 - self.asymmetry)
        return 1024 if r >= 0.03 else 1024 * 2 ** math.ceil(math.log2(0.03 / r))

    def _binned(self, n: int, t0: float, t1: float) -> NDArray[np.float64]:
        """``_cauchy`` bounds of ``_bins`` bins per period, computed once: the max over the bins
        that [t0, t1] touches (each bin bound holds on its closed bin, so this is a bound)."""
        tables = self.__dict__.setdefault('_bound_tables', {})
        if n not in tables:
            T, nb = self.period, self._bins
            k = np.arange(nb)
            tables[n] = self._cauchy(n, k * T / nb, (k + 1) * T / nb)     # (nb, n_links)
        tab = tables[n]
        nb = tab.shape[0]
        u0 = self.frequency * t0
        k0 = math.floor((u0 - math.floor(u0)) * nb)
        k1 = k0 + math.floor(self.frequency * (t1 - t0) * nb) + 1   # bins k0 .. k1 (wrapping)
        if k1 - k0 + 1 >= nb:
            return tab.max(axis=0)
        if k1 < nb:
            return tab[k0:k1 + 1].max(axis=0)
        return np.maximum(tab[k0:].max(axis=0), tab[:k1 - nb + 1].max(axis=0))

    def _cauchy(self, n: int, t0, t1) -> NDArray[np.float64]:
        """Rigorous bound of |d^n l / dt^n| on [t0, t1] by Cauchy's estimate, per linkage.

        l = mean + amplitude f(x), f(x) = s sin x / (1 - c cos x), x = w t + phase - pi r, is
        analytic off the poles x = 2 pi k (+ pi when c < 0) +- i rho0, cosh rho0 = 1 / |c|. On
        a disc of radius rho around a real point: |s sin z| <= s cosh rho and, with z' = z (or
        z + pi when c < 0), 1 - c cos z = 2 |c| sin((z' + i rho0) / 2) sin((z' - i rho0) / 2)
        and |sin u|^2 = sin^2 Re u + sinh^2 Im u give |1 - c cos z| >= 2 |c| (min sin^2(Re z'
        / 2) + sinh^2(max(rho0 - rho, 0) / 2)). Then |f^(n)| <= n! max|f| / rho^n; the best
        of a range of radii is kept. Local: small far from the fast phase of a sharp stroke.
        ``t0``, ``t1``: floats, or arrays of shape (B,) (then the result is (B, n_links)).
        """
        c, s, w = self._c, self._s, self._w
        amp = np.abs(self.amplitude)
        if abs(c) < 1e-12:        # r = 1/2: a plain cosine stroke
            return np.broadcast_to(amp * w ** n, np.shape(t0) + amp.shape).copy()
        rho0 = math.acosh(1.0 / abs(c))
        t0, t1 = np.asarray(t0, float)[..., None], np.asarray(t1, float)[..., None]
        x0 = w * t0 + self.phase - math.pi * self.asymmetry + (math.pi if c < 0 else 0.0)
        span = w * (t1 - t0)
        best = np.full(np.broadcast_shapes(x0.shape, span.shape), math.inf)
        radii = np.concatenate([rho0 * np.linspace(0.05, 0.95, 19), [0.25, 0.5, 1.0, 2.0, 3.0]])
        for rho in radii.tolist():
            lo = 0.5 * (x0 - rho)                  # Re(z') / 2 ranges over [lo, lo + width]
            width = 0.5 * (span + 2.0 * rho)
            contains = np.ceil(lo / math.pi) * math.pi <= lo + width
            m = np.where(contains, 0.0, np.minimum(np.sin(lo) ** 2, np.sin(lo + width) ** 2))
            den = 2.0 * abs(c) * (m + math.sinh(max(rho0 - rho, 0.0) / 2.0) ** 2)
            safe = np.where(den > 0, den, 1.0)
            bound = np.where(den > 0, math.factorial(n) * s * math.cosh(rho) / safe / rho ** n,
                             math.inf)
            best = np.minimum(best, bound)
        # 1 + 1e-12: the bound is computed in floats
        return amp * w ** n * best * (1.0 + 1e-12)
