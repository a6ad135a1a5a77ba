"""``plot``: positions, velocities, friction forces and stick bands of a recorded run."""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .errors import BagError

if TYPE_CHECKING:
    from matplotlib.figure import Figure
from .reader import Run, load


def stick_intervals(t: NDArray[np.float64], stuck: NDArray[np.bool_]) -> list[tuple[float, float]]:
    """``(start, width)`` [s] of each run of ``stuck`` samples.

    A run lasts until the next sample (piecewise constant to the right).
    """
    if len(t) == 0:
        return []
    edges = np.diff(np.concatenate(([0], stuck.astype(np.int8), [0])))
    begins = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    t_end = np.append(t, t[-1])          # the last run ends at the last sample
    return [(float(t[b]), float(t_end[e] - t[b])) for b, e in zip(begins, ends)]


def figure(run: Run) -> Figure:
    """A matplotlib Figure (Agg canvas, no pyplot state) of ``run``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 9), layout='constrained')
    FigureCanvasAgg(fig)
    axes = fig.subplots(4, 1, sharex=True, height_ratios=[3, 3, 3, 1.2 + 0.2 * run.p])
    colours = [f'C{i % 10}' for i in range(run.p)]
    names = run.bodies if len(run.bodies) == run.p else tuple(f'body_{i}' for i in range(run.p))
    for ax, values, label in ((axes[0], run.x, 'position x [m]'),
                              (axes[1], run.v, 'velocity v [m/s]'),
                              (axes[2], run.friction, 'friction [N]')):
        for i in range(run.p):
            ax.plot(run.t, values[:, i], color=colours[i], lw=1.0, label=names[i])
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc='best', fontsize='small', ncols=min(run.p, 6))
    ax = axes[3]
    if run.contact.shape[1] == run.p:
        for i in range(run.p):
            bars = stick_intervals(run.t, run.contact[:, i] == 0)
            ax.broken_barh(bars, (i - 0.4, 0.8), facecolors=colours[i], alpha=0.6)
    else:
        ax.text(0.5, 0.5, 'no contact states recorded', transform=ax.transAxes, ha='center')
    ax.set_yticks(range(run.p), names)
    ax.set_ylim(-0.6, run.p - 0.4)
    ax.invert_yaxis()
    ax.set_ylabel('stuck (contact = 0)')
    ax.set_xlabel('sim time t [s]')
    ax.grid(True, axis='x', alpha=0.3)
    title = f'{Path(run.path).name}: p = {run.p}, {len(run)} states, {run.duration:.3f} s'
    if run.truncated:
        title += ' (incomplete recording)'
    fig.suptitle(title)
    return fig


def plot(path: os.PathLike | str, out_png: os.PathLike | str, *,
         namespace: str | None = None, dpi: int = 120) -> Path:
    """Plot the run in bag ``path`` to ``out_png`` and return that path.

    Panels: x, v and friction per body, and stick bands (shaded where contact == 0).
    Raises :class:`BagError` for unreadable bags or a bag without states.
    """
    run = load(path, namespace=namespace)
    if len(run) == 0:
        raise BagError(f'{path}: no states to plot')
    out = Path(out_png)
    try:
        figure(run).savefig(out, dpi=dpi)
    except OSError as exc:
        raise BagError(f'cannot write {out}: {exc.strerror or exc}') from None
    return out
