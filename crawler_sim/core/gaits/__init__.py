"""Gaits: the imposed linkage lengths l_j(t) and their first two time derivatives.

Every gait returns ``(l, l', l'')`` in metres, m/s and m/s^2. For a float time each array has
shape ``(n_links,)``; the built-in gaits also take an array of times of shape ``(N,)`` and then
return arrays of shape ``(N, n_links)``. ``l_j = x_{j+1} - x_j`` (see docs/ARCHITECTURE.md).

One module per family:

- ``base``: the `Gait` contract and the argument checks the gaits share.
- ``smooth``: `Sinusoid` (one harmonic per linkage), `Fourier` (a truncated series) and the
  analytic `Scallop` stroke with a fast and a slow phase.
- ``piecewise``: `PiecewiseParabolic` (bang-bang strokes, exact piecewise quadratics) and
  `Spline` (a C2 cubic spline through sampled lengths).
- ``cubic``: `Cubic` (one constant-jerk piece, the node's actuator model) and `PiecewiseCubic`.
- ``custom``: `Custom`, user callables of one float time (not vectorised).
"""
from .base import CLOSURE_RTOL, Gait, Triple, _positive  # noqa: F401 (shared with the solvers)
from .cubic import Cubic, PiecewiseCubic, cubic_values
from .custom import Custom
from .piecewise import PiecewiseParabolic, Spline
from .smooth import Fourier, Scallop, Sinusoid

__all__ = ['Gait', 'Custom', 'Sinusoid', 'Fourier', 'Scallop', 'PiecewiseParabolic', 'Spline',
           'Cubic', 'PiecewiseCubic', 'cubic_values']
