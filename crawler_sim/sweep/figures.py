"""Figures of sweeps and optimisations: a speed map over two swept parameters, and the
optimiser's history. matplotlib (Agg) is imported inside the functions; the figures are written
by `crawler_sim.bag.plot.save` (the package's one way to write a figure)."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..bag.plot import save

__all__ = ['speed_map', 'optimize_history']


def _plt():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def speed_map(df: pd.DataFrame, x: str, y: str, path: str | os.PathLike, *,
              value: str = 'mean_speed', scale: float = 1e3, unit: str = 'mm/s',
              x_label: str | None = None, y_label: str | None = None, title: str = '',
              x_transform: Any = None, ax: Any = None, zero_contour: bool = True) -> Path:
    """A colour map of ``value`` (times ``scale``) over the grid columns ``x`` and ``y`` of a
    sweep, with its zero contour, written to ``path`` (PNG). ``x_transform`` maps the x column
    (e.g. to a friction ratio). The colours are symmetric about zero (red forward, blue back).
    With ``ax`` it draws into that axes and leaves saving to the caller."""
    plt = _plt()
    xs = df[x].to_numpy(dtype=float)
    if x_transform is not None:
        xs = x_transform(xs)
    table = pd.DataFrame({'x': xs, 'y': df[y].to_numpy(dtype=float),
                          'v': df[value].to_numpy(dtype=float) * scale})
    grid = table.pivot_table(index='y', columns='x', values='v', aggfunc='first')
    X, Y = np.meshgrid(grid.columns.to_numpy(), grid.index.to_numpy())
    V = grid.to_numpy()
    lim = float(np.nanmax(np.abs(V))) or 1.0
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(6.4, 4.8))
    else:
        fig = ax.figure
    mesh = ax.pcolormesh(X, Y, V, cmap='RdBu_r', vmin=-lim, vmax=lim, shading='nearest')
    fig.colorbar(mesh, ax=ax, label=f'{value.replace("_", " ")} [{unit}]')
    if zero_contour and np.nanmin(V) < 0 < np.nanmax(V):
        ax.contour(X, Y, V, levels=[0.0], colors='k', linewidths=0.8)
    ax.set_xlabel(x_label or x)
    ax.set_ylabel(y_label or y)
    if title:
        ax.set_title(title, fontsize='medium')
    path = Path(path)
    if own:
        fig.tight_layout()
        try:
            save(fig, path, dpi=110)
        finally:
            plt.close(fig)
    return path


def optimize_history(result: Any, path: str | os.PathLike) -> Path:
    """Score of every evaluation and the best so far (global stage, then local), and the path
    of the best point through the first two parameters, written to ``path`` (PNG)."""
    plt = _plt()
    h = pd.DataFrame(result.history)
    feasible = h['feasible'].to_numpy(dtype=bool)
    key = 'mean_speed' if result.objective == 'speed' else 'cost_of_transport'
    unit_scale = 1e3 if key == 'mean_speed' else 1.0
    label = 'mean speed [mm/s]' if key == 'mean_speed' else 'cost of transport'
    vals = h[key].to_numpy(dtype=float) * unit_scale
    score = h['score'].to_numpy(dtype=float)
    best_idx = np.minimum.accumulate(score)
    best_val = np.array([vals[int(np.flatnonzero(score[:i + 1] == b)[0])]
                         for i, b in enumerate(best_idx)])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    n = np.arange(len(h))
    glob = (h['stage'] == 'global').to_numpy()
    a1.plot(n[glob & feasible], vals[glob & feasible], '.', ms=3, color='0.6',
            label='global (differential evolution)')
    a1.plot(n[~glob & feasible], vals[~glob & feasible], '.', ms=3, color='tab:orange',
            label='local (Nelder-Mead)')
    a1.plot(n, best_val, 'k-', lw=1.2, label='best so far')
    a1.set_xlabel('evaluation')
    a1.set_ylabel(label)
    a1.set_title(f'{int((~feasible).sum())} of {len(h)} evaluations outside the actuator '
                 'limits (not shown)', fontsize='small')
    a1.legend(fontsize='small')
    p0, p1 = result.family.names[:2]
    sc = a2.scatter(h.loc[feasible, p0], h.loc[feasible, p1], c=vals[feasible], s=8,
                    cmap='viridis')
    a2.scatter(h.loc[~feasible, p0], h.loc[~feasible, p1], marker='x', s=8, color='0.7',
               label='infeasible')
    a2.plot([result.params[p0]], [result.params[p1]], 'r*', ms=14, label='best')
    fig.colorbar(sc, ax=a2, label=label)
    a2.set_xlabel(p0)
    a2.set_ylabel(p1)
    a2.legend(fontsize='small')
    fig.suptitle(f'optimise {result.family.name} stroke: {result.objective}', fontsize='medium')
    fig.tight_layout()
    try:
        return save(fig, path, dpi=110)
    finally:
        plt.close(fig)
