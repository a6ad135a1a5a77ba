"""Dense output of an exact run: its state at any time of the run, from the closed forms.

``simulate`` (method "exact") keeps the solver's closed-form pieces with the ``Trajectory``
it returns (``Trajectory.dense``), and ``Trajectory.state_at`` evaluates them: the same
pieces and the same evaluation (``ExactSolver.sample``) as a run sampled at those times, so
``state_at(t)`` equals ``simulate(..., t_eval=[..., t, ...])`` at t bit for bit. Inside a
block of periodically skipped periods a time is mapped onto the block's template period and
shifted by whole periods' displacements, as the samples of the run are; nothing is
interpolated and nothing is integrated again.

What it needs: the crawler, the gait the run used (kept alive by the ``Trajectory``) and the
pieces (one record per segment between events, about 100 bytes; a skipped block is stored
once). A built-in gait is immutable. A gait of Python functions (``gaits.Custom``, a user's
``Gait`` subclass) is read through the Chebyshev pieces it was sampled into during the run
(``solvers/proxy.py``), which the gait keeps: its functions are not called again, so a later
change of what they return does not change ``state_at``.
"""
from __future__ import annotations

import pickle

import numpy as np
from numpy.typing import NDArray

from .gaits import Gait
from .model import Crawler
from .solvers.exact import ExactSolver
from .solvers.segments import SegmentList

__all__ = ['DenseOutput']


class DenseOutput:
    """The closed-form pieces of an exact run on ``span`` = (t0, t_end) [s].

    Parameters
    ----------
    crawler, gait : what the run simulated.
    segments : the run's ``SegmentList`` (``ExactSolver.segments`` with ``keep_history``).
    span : (t0, t_end) [s], the integrated interval; ``sample`` accepts times inside it.
    tol, max_step : the run's options (a solver is built with them to evaluate the pieces).

    Pickling: the pieces travel with the gait when the gait pickles; otherwise (a ``Custom``
    gait of lambdas) the copy holds only the reason, and its ``sample`` raises RuntimeError.
    """

    __slots__ = ('crawler', 'gait', 'segments', 'span', 'tol', 'max_step')

    def __init__(self, crawler: Crawler, gait: Gait, segments: SegmentList,
                 span: tuple[float, float], *, tol: float = 1e-13,
                 max_step: float | None = None) -> None:
        self.crawler = crawler
        self.gait = gait
        self.segments = segments
        self.span = (float(span[0]), float(span[1]))
        self.tol = float(tol)
        self.max_step = max_step

    def sample(self, times: NDArray[np.float64]) -> dict:
        """The exact states at ``times`` [s] (sorted, shape (N,), inside ``span``): the
        dict of ``ExactSolver.sample`` (x, v, friction, impulse, linkage_force, lengths,
        rates, contact, indeterminate; a leading axis of N)."""
        # a solver of the run's crawler and gait holding the run's pieces: its ``sample`` is
        # the one evaluation of the closed forms (a solver costs ~2 us; keeping one would keep
        # its compiled buffers alive with every Trajectory)
        solver = ExactSolver(self.crawler, self.gait, t0=self.span[0], tol=self.tol,
                             max_step=self.max_step, keep_segments=True)
        solver.segments = self.segments
        return solver.sample(np.ascontiguousarray(times, dtype=float))

    def __reduce__(self):
        try:
            blob = pickle.dumps((self.gait, self.segments), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:    # a gait of lambdas or closures: not picklable
            reason = (f'its gait ({type(self.gait).__name__}) could not be pickled: '
                      f'{type(exc).__name__}: {exc}')
            return (_Unavailable, (reason,))
        return (_restore, (self.crawler, blob, self.span, self.tol, self.max_step))


def _restore(crawler: Crawler, blob: bytes, span: tuple[float, float], tol: float,
             max_step: float | None) -> DenseOutput:
    gait, segments = pickle.loads(blob)
    return DenseOutput(crawler, gait, segments, span, tol=tol, max_step=max_step)


class _Unavailable:
    """A pickled ``DenseOutput`` whose gait could not travel: ``sample`` says why."""

    __slots__ = ('reason',)

    def __init__(self, reason: str) -> None:
        self.reason = reason

    @property
    def span(self) -> tuple[float, float]:
        return self.sample(np.empty(0))

    def sample(self, times: NDArray[np.float64]) -> dict:
        raise RuntimeError(f'this Trajectory was unpickled without its dense output: '
                           f'{self.reason}; state_at needs the gait the run used (simulate '
                           'again, or sample the run with simulate(..., t_eval=...))')

    def __reduce__(self):
        return (_Unavailable, (self.reason,))
