"""The one figure of a run (recorded or offline): positions, velocities, friction forces,
linkage lengths and stick bands."""
from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .errors import BagError
from .files import OutputRefused, check_output, write_atomically

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from crawler_sim.core.trajectory import Trajectory
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


#: the panels of :func:`figure`, top to bottom (their y labels)
PANELS = ('position x [m]', 'velocity v [m/s]', 'friction [N]', 'linkage length [m]',
          'stuck (contact = 0)')


def figure(run: Run | Trajectory, title: str | None = None) -> Figure:
    """A matplotlib Figure (Agg canvas, no pyplot state) of a run: a recorded one (a loaded
    bag, :class:`Run`) or an offline one (:class:`crawler_sim.Trajectory`): they name their
    arrays alike. Panels (:data:`PANELS`): positions, velocities and friction forces per body,
    linkage lengths, and the stick bands of each body (shaded where contact == 0). ``title``
    defaults to the bag's name, p, the number of states and the duration."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    t = np.asarray(run.t)
    p = run.x.shape[1]
    fig = Figure(figsize=(10, 11), layout='constrained')
    FigureCanvasAgg(fig)
    axes = fig.subplots(5, 1, sharex=True, height_ratios=[3, 3, 3, 2, 1.2 + 0.2 * p])
    colours = [f'C{i % 10}' for i in range(p)]
    bodies = tuple(getattr(run, 'bodies', ()))
    names = bodies if len(bodies) == p else tuple(f'body_{i}' for i in range(p))
    for ax, values, label in zip(axes, (run.x, run.v, run.friction), PANELS):
        for i in range(p):
            ax.plot(t, values[:, i], color=colours[i], lw=1.0, label=names[i])
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc='best', fontsize='small', ncols=min(p, 6))
    ax = axes[3]
    lengths = np.asarray(run.lengths)
    for j in range(lengths.shape[1] if lengths.ndim == 2 else 0):
        ax.plot(t, lengths[:, j], lw=1.0, label=f'linkage_{j}')
    if lengths.ndim == 2 and lengths.shape[1]:
        ax.legend(loc='best', fontsize='small', ncols=min(lengths.shape[1], 6))
    ax.set_ylabel(PANELS[3])
    ax.grid(True, alpha=0.3)
    ax = axes[4]
    if run.contact.shape[1] == p:
        for i in range(p):
            bars = stick_intervals(t, run.contact[:, i] == 0)
            ax.broken_barh(bars, (i - 0.4, 0.8), facecolors=colours[i], alpha=0.6)
    else:
        ax.text(0.5, 0.5, 'no contact states recorded', transform=ax.transAxes, ha='center')
    ax.set_yticks(range(p), names)
    ax.set_ylim(-0.6, p - 0.4)
    ax.invert_yaxis()
    ax.set_ylabel(PANELS[4])
    ax.set_xlabel('sim time t [s]')
    ax.grid(True, axis='x', alpha=0.3)
    if title is None:
        duration = float(t[-1] - t[0]) if len(t) else 0.0
        title = f'{Path(getattr(run, "path", "run")).name}: p = {p}, {len(t)} states, ' \
                f'{duration:.3f} s'
        if getattr(run, 'truncated', False):
            title += ' (incomplete recording)'
    fig.suptitle(title)
    return fig


def figure_output(out: os.PathLike | str) -> tuple[Path, str]:
    """``(Path(out), format)`` of a figure file: the format its suffix names (PNG without one),
    checked before any drawing. :class:`crawler_sim.bag.files.OutputRefused` naming ``out``
    for a format matplotlib cannot write or an output that may not be written
    (:func:`crawler_sim.bag.files.check_output`: an input, a directory...)."""
    from matplotlib.backend_bases import FigureCanvasBase

    out = check_output(out)
    fmt = out.suffix[1:].lower() or 'png'
    formats = FigureCanvasBase.get_supported_filetypes()
    if fmt not in formats:
        raise OutputRefused(f'{out}: cannot draw a figure as {fmt!r}; use a file name ending '
                            f'in one of {", ".join("." + f for f in sorted(formats))}')
    return out, fmt


def save(fig: Figure, out: os.PathLike | str, dpi: int = 120) -> Path:
    """Write ``fig`` to the file ``out`` (every figure of the package is saved here) and return
    its path: exactly the file named (matplotlib would append ``.png`` to a name without a
    suffix), in the format of :func:`figure_output`, through
    :func:`crawler_sim.bag.files.write_atomically` (never through a link, the old file whole
    until the new one is). :class:`crawler_sim.bag.files.OutputRefused` as
    :func:`figure_output`; :class:`BagError` naming the file if it cannot be written."""
    out, fmt = figure_output(out)
    try:
        return write_atomically(out, lambda fh: fig.savefig(fh, format=fmt, dpi=dpi))
    except OSError as exc:
        raise BagError(f'{out}: {exc.strerror or exc}') from None


def plot(path: os.PathLike | str, out_png: os.PathLike | str, *,
         namespace: str | None = None, dpi: int = 120) -> Path:
    """Plot the run in bag ``path`` to ``out_png`` and return that path.

    The panels of :func:`figure`. The output is checked (:func:`figure_output`, with ``path``
    as the input: not the bag, nor inside its folder) before the bag is read.
    Raises :class:`BagError` for unreadable bags or a bag without states.
    """
    from .files import reading

    with reading(path):
        figure_output(out_png)
        run = load(path, namespace=namespace)
        if len(run) == 0:
            raise BagError(f'{path}: no states to plot')
        return save(figure(run), out_png, dpi)
