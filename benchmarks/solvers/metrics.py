"""Error measures of a run against the reference (method "exact" at its tightest tolerance).

* displacement error [m]: |(X(t_end) - X(0)) - (X_ref(t_end) - X_ref(0))|, X the centre of mass;
* position error [m]: max over the common grid of |X - X_ref| (every body is X + e_i(t) with
  e_i fixed by the gait, so this is also the largest error of any body's position);
* event error [s]: for each reference stick/slip transition (body, new state), the distance to
  the nearest transition of the run of the same body to the same state; the largest of these,
  or inf when one has no counterpart;
* history mismatch [s]: the total time, summed over the bodies, during which the run's contact
  state differs from the reference's (catches spurious and missing transitions as well).
"""
from __future__ import annotations

import math
from typing import Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ['canonical_events', 'displacement_error', 'position_error', 'event_error',
           'history_mismatch']

EventLike = Sequence  # (time, body, old, new)


def displacement_error(X: NDArray, X_ref: NDArray) -> float:
    """|net displacement - reference net displacement| [m] (NaN input gives inf)."""
    d = abs((X[-1] - X[0]) - (X_ref[-1] - X_ref[0]))
    return float(d) if math.isfinite(d) else math.inf


def position_error(X: NDArray, X_ref: NDArray) -> float:
    """max |X - X_ref| over the common grid [m] (NaN input gives inf)."""
    d = float(np.max(np.abs(X - X_ref)))
    return d if math.isfinite(d) else math.inf


def canonical_events(events: Iterable[EventLike], t_end: float,
                     merge: float = 0.0) -> list[tuple[float, int, int, int]]:
    """Events in (0, t_end) as tuples, with zero-length states removed.

    Per body, consecutive events closer than ``merge`` seconds are fused (old of the first, new
    of the last) and fused events that change nothing are dropped.
    """
    per_body: dict[int, list[list]] = {}
    # stable sort on the time only: simultaneous events keep the order they happened in
    for ev in sorted(((float(e[0]), int(e[1]), int(e[2]), int(e[3])) for e in events),
                     key=lambda e: e[0]):
        t, b, old, new = ev
        lst = per_body.setdefault(b, [])
        if lst and t - lst[-1][0] <= merge:
            lst[-1][3] = new
            lst[-1][0] = t
        else:
            lst.append([t, b, old, new])
    out = [tuple(e) for lst in per_body.values() for e in lst
           if e[2] != e[3] and 0.0 < e[0] < t_end]
    return sorted(out, key=lambda e: (e[0], e[1]))


def event_error(events: Sequence[EventLike], ref_events: Sequence[EventLike]) -> tuple[float, int]:
    """(largest time error of the reference's transitions [s], number without a counterpart)."""
    index: dict[tuple[int, int], list[float]] = {}
    for t, b, _, new in events:
        index.setdefault((b, new), []).append(t)
    for v in index.values():
        v.sort()
    worst, missing = 0.0, 0
    for t, b, _, new in ref_events:
        times = index.get((b, new))
        if not times:
            missing += 1
            continue
        k = int(np.searchsorted(times, t))
        near = [abs(times[j] - t) for j in (k - 1, k) if 0 <= j < len(times)]
        worst = max(worst, min(near))
    return (worst if missing == 0 else math.inf), missing


def _steps(initial: Sequence[int], events: Sequence[EventLike], t_end: float):
    """Piecewise-constant contact states: (breakpoints (K+1,), states (K, p))."""
    state = np.array(initial, dtype=int)
    times, rows = [0.0], [state.copy()]
    for t, b, _, new in sorted(events, key=lambda e: e[0]):
        if t <= 0.0 or t >= t_end:
            continue
        if t > times[-1]:
            times.append(t)
            rows.append(state.copy())
        rows[-1][b] = new
        state[b] = new
    times.append(t_end)
    return np.array(times), np.array(rows)


def history_mismatch(initial: Sequence[int], events: Sequence[EventLike],
                     ref_initial: Sequence[int], ref_events: Sequence[EventLike],
                     t_end: float) -> float:
    """Total time [s], summed over bodies, during which the two contact histories differ."""
    ta, sa = _steps(initial, events, t_end)
    tb, sb = _steps(ref_initial, ref_events, t_end)
    cuts = np.union1d(ta, tb)
    mid = 0.5 * (cuts[1:] + cuts[:-1])
    ia = np.clip(np.searchsorted(ta, mid, side='right') - 1, 0, len(sa) - 1)
    ib = np.clip(np.searchsorted(tb, mid, side='right') - 1, 0, len(sb) - 1)
    differ = np.sum(sa[ia] != sb[ib], axis=1)
    return float(np.sum(differ * np.diff(cuts)))
