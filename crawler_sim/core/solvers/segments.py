"""Closed-form pieces of the exact method's solution and their evaluation (MODEL.md s. 2).

``Segment``: one piece between events (every body sliding: X quadratic in t; a body stuck:
its position fixed and the group's friction what holds it). ``PeriodicBlock``: n repetitions
of one period of segments, shifted. ``evaluate_records`` samples many segments at once, with
the compiled closed forms of the crawler (``crawler_constants``).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from bisect import bisect_right
import weakref

import numpy as np
from numpy.typing import NDArray

from ..friction import bounds
from ..gaits import Gait
from ..model import Crawler

__all__ = ['CrawlerConstants', 'PeriodicBlock', 'Records', 'Segment', 'SegmentChunk',
           'SegmentList', 'crawler_constants', 'evaluate_records', 'offset_matrices']


def offset_matrices(masses: NDArray) -> tuple[NDArray, NDArray]:
    """Matrices C (p, p-1) and W (p, p-1) with s = C l (offsets from body 0) and e = W l
    (offsets from the centre of mass), so that derivatives follow by the same product."""
    p = masses.size
    C = np.tril(np.ones((p, p - 1)), -1)
    W = C - (masses / masses.sum()) @ C
    return C, W


class CrawlerConstants:
    """What the exact method derives from a crawler, once per ``Crawler`` (a sweep or a node
    builds many solvers for one crawler): its compiled closed forms (``_exact.ClosedForm``,
    which hold masses, friction bounds, external and gravity forces and the offset matrices;
    the segment loop copies them from it), and in Python the masses [kg] and W."""

    def __init__(self, crawler: Crawler) -> None:
        from ._exact import ClosedForm
        self.m = crawler.masses
        C, self.W = offset_matrices(crawler.masses)
        b = bounds(crawler)
        self.closed = ClosedForm(self.m, b.kinetic_forward, b.kinetic_backward,
                                 float(crawler.external_force), crawler.gravity_forces, self.W,
                                 C, b.static_forward, b.static_backward)


_CONSTANTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def crawler_constants(crawler: Crawler) -> CrawlerConstants:
    """The crawler's ``CrawlerConstants`` (built on first use)."""
    k = _CONSTANTS.get(crawler)
    if k is None:
        k = _CONSTANTS[crawler] = CrawlerConstants(crawler)
    return k


@dataclass(slots=True)
class PeriodicBlock:
    """``n`` repetitions of one period of segments (``template``), each shifted forward by
    ``D`` [m] in position and ``dK`` [N s] in impulse: the steady crawl, stored once."""

    t0: float
    n: int
    T: float
    D: float
    dK: NDArray[np.float64]
    template: list
    template_t0: float

    @property
    def t1(self) -> float:
        return self.t0 + self.n * self.T


@dataclass(slots=True)
class Segment:
    """One closed-form piece of the solution on [t0, t1]."""

    t0: float
    t1: float
    gait: Gait
    contact: NDArray[np.int8]     # (p,)
    R: NDArray[np.float64]        # (p,) ground force of the sliding bodies (group entries unused)
    K0: NDArray[np.float64]       # (p,) impulse at t0
    X0: float                     # slide: centre of mass at t0
    V0: float                     # slide: its velocity at t0
    a: float                      # slide: its acceleration
    ref: int                      # stick: reference stuck body (-1 when all slide)
    x_ref: float                  # stick: its fixed position
    group: NDArray[np.bool_]      # stick: bodies stuck with ref

    def evaluate(self, crawler: Crawler, tau: NDArray[np.float64]) -> dict:
        """Exact state at the times ``tau`` [s] (shape (N,), inside [t0, t1])."""
        return evaluate_records(crawler, Records.from_segments([self]),
                                np.zeros(np.size(tau), dtype=np.int64),
                                np.asarray(tau, dtype=float).reshape(-1))


@dataclass(slots=True)
class SegmentChunk:
    """Consecutive segments of one call of the compiled loop (``_exact.ExactCore.drive``) as
    flat records, one row each: ``f`` = (t0, t1, X0, V0, a, x_ref), ``ref``, ``contact``,
    ``R``, ``K0`` and ``group`` (the bodies stuck with ``ref``)."""

    gait: Gait
    f: NDArray[np.float64]
    ref: NDArray[np.int64]
    contact: NDArray[np.int8]
    group: NDArray[np.bool_]
    R: NDArray[np.float64]
    K0: NDArray[np.float64]

    def segment(self, k: int) -> Segment:
        t0, t1, X0, V0, a, x_ref = self.f[k].tolist()
        return Segment(t0, t1, self.gait, self.contact[k].copy(), self.R[k].copy(),
                       self.K0[k].copy(), X0, V0, a, int(self.ref[k]), x_ref,
                       self.group[k].copy())


@dataclass(slots=True)
class Records:
    """Segment constants as arrays, one row per segment (what ``evaluate_records`` gathers):
    ``f`` = (t0, t1, X0, V0, a, x_ref) (the layout of ``SegmentChunk.f``), ``ref``,
    ``group``, ``contact``, ``R``, ``K0``; the gait of row k is ``gaits[gait_id[k]]``."""

    f: NDArray[np.float64]
    ref: NDArray[np.int64]
    group: NDArray[np.bool_]
    contact: NDArray[np.int8]
    R: NDArray[np.float64]
    K0: NDArray[np.float64]
    gait_id: NDArray[np.int64]
    gaits: list

    @classmethod
    def from_segments(cls, segs: list) -> Records:
        gaits = list({id(sg.gait): sg.gait for sg in segs}.values())
        ids = {id(g): k for k, g in enumerate(gaits)}
        return cls(np.array([(sg.t0, sg.t1, sg.X0, sg.V0, sg.a, sg.x_ref) for sg in segs],
                            dtype=float).reshape(-1, 6),
                   np.array([sg.ref for sg in segs], dtype=np.int64),
                   np.array([sg.group for sg in segs], dtype=bool),
                   np.array([sg.contact for sg in segs], dtype=np.int8),
                   np.array([sg.R for sg in segs], dtype=float),
                   np.array([sg.K0 for sg in segs], dtype=float),
                   np.array([ids[id(sg.gait)] for sg in segs], dtype=np.int64), gaits)

    @classmethod
    def from_chunk(cls, chunk: SegmentChunk) -> Records:
        n = chunk.ref.size
        return cls(chunk.f, chunk.ref, chunk.group, chunk.contact, chunk.R,
                   chunk.K0, np.zeros(n, dtype=np.int64), [chunk.gait])

    @classmethod
    def concat(cls, parts: list) -> Records:
        if len(parts) == 1:
            return parts[0]
        gaits: list = []
        ids: dict = {}
        gait_id = []
        for part in parts:
            remap = []
            for g in part.gaits:
                if id(g) not in ids:
                    ids[id(g)] = len(gaits)
                    gaits.append(g)
                remap.append(ids[id(g)])
            gait_id.append(np.array(remap, dtype=np.int64)[part.gait_id])
        return cls(*(np.concatenate([getattr(q, k) for q in parts])
                     for k in ('f', 'ref', 'group', 'contact', 'R', 'K0')),
                   np.concatenate(gait_id), gaits)


class SegmentList(Sequence):
    """The exact solver's kept pieces in time order: the compiled loop's records
    (``SegmentChunk``, one per call, turned into ``Segment`` objects only when read: most of a
    run is never read one segment at a time), ``PeriodicBlock`` objects and ``Segment``
    objects."""

    def __init__(self) -> None:
        self._parts: list = []       # SegmentChunk | PeriodicBlock | Segment
        self._ends: list[int] = []   # cumulative item counts
        self._built: dict = {}       # item index -> Segment built from a chunk row
        self._table: Records | None = None
        self._rows: NDArray | None = None
        self._starts: NDArray | None = None

    def __len__(self) -> int:
        return self._ends[-1] if self._ends else 0

    def _get(self, k: int):
        i = bisect_right(self._ends, k)
        part = self._parts[i]
        if not isinstance(part, SegmentChunk):
            return part
        seg = self._built.get(k)
        if seg is None:
            seg = self._built[k] = part.segment(k - (self._ends[i - 1] if i else 0))
        return seg

    def __getitem__(self, k):
        n = len(self)
        if isinstance(k, slice):
            return [self._get(i) for i in range(*k.indices(n))]
        if k < 0:
            k += n
        if not 0 <= k < n:
            raise IndexError('segment index out of range')
        return self._get(k)

    def _add(self, part, n: int) -> None:
        self._parts.append(part)
        self._ends.append(len(self) + n)
        self._table = self._rows = self._starts = None

    def append(self, item: Segment | PeriodicBlock) -> None:
        """One ``Segment`` or ``PeriodicBlock``."""
        self._add(item, 1)

    def extend_chunk(self, chunk: SegmentChunk) -> None:
        self._add(chunk, chunk.f.shape[0])

    def only_chunk(self) -> SegmentChunk | None:
        """The one ``SegmentChunk`` when that is all the list holds (a run integrated in one
        call of the compiled loop, no period skipped), else None."""
        if len(self._parts) == 1 and isinstance(self._parts[0], SegmentChunk):
            return self._parts[0]
        return None

    def records(self) -> tuple[Records, NDArray[np.int64]]:
        """Every segment's constants as one ``Records`` table, and each item's row in it (-1
        for a ``PeriodicBlock``), without building ``Segment`` objects."""
        if self._table is None:
            tables, rows, n_rows = [], [], 0
            for part in self._parts:
                if isinstance(part, SegmentChunk):
                    n = part.f.shape[0]
                    tables.append(Records.from_chunk(part))
                    rows.append(np.arange(n_rows, n_rows + n))
                    n_rows += n
                elif isinstance(part, PeriodicBlock):
                    rows.append(np.array([-1]))
                else:
                    tables.append(Records.from_segments([part]))
                    rows.append(np.array([n_rows]))
                    n_rows += 1
            self._table = Records.concat(tables) if tables else Records.from_segments([])
            self._rows = (np.concatenate(rows) if rows else np.empty(0)).astype(np.int64)
        return self._table, self._rows

    def starts(self) -> NDArray[np.float64]:
        """Start times of the pieces, without building them."""
        if self._starts is None:
            parts = [part.f[:, 0] if isinstance(part, SegmentChunk) else np.array([part.t0])
                     for part in self._parts]
            self._starts = np.concatenate(parts) if parts else np.empty(0)
        return self._starts


def evaluate_records(crawler: Crawler, rec: Records, owner: NDArray[np.int64],
                     tau: NDArray[np.float64]) -> dict:
    """Exact states of many segments at once: row i is segment ``owner[i]`` of ``rec`` at time
    ``tau[i]`` [s] (sorted or not).

    The closed forms of ``Segment.evaluate`` (slide: X quadratic in t; stick: the reference
    body fixed, the group's friction the affine split of what holds it), compiled
    (``_exact.ClosedForm``): sampling a run costs one compiled gait evaluation per gait and
    one loop over the rows.
    """
    l, ld, ldd = _gait_values(rec, owner, tau)
    c = np.ascontiguousarray
    x, v, R, K, lam, state, ind = crawler_constants(crawler).closed.evaluate(
        l, ld, ldd, c(rec.f, dtype=float), c(rec.ref, dtype=np.int64), c(rec.group),
        c(rec.contact, dtype=np.int8), c(rec.R, dtype=float), c(rec.K0, dtype=float),
        c(owner, dtype=np.int64), c(tau, dtype=float))
    return {'x': x, 'v': v, 'friction': R, 'impulse': K, 'linkage_force': lam,
            'lengths': l, 'rates': ld, 'contact': state, 'indeterminate': ind}


def _gait_values(rec: Records, owner: NDArray[np.int64], tau: NDArray[np.float64]):
    """(l, l', l'') at ``tau[i]`` from the gait of row ``owner[i]`` (one call per gait)."""
    if len(rec.gaits) == 1:
        cg = rec.gaits[0].compiled()
        with cg.lock:
            return cg.values(tau)
    which = rec.gait_id[owner]
    out = None
    for key, gait in enumerate(rec.gaits):
        sel = np.nonzero(which == key)[0]
        if not sel.size:
            continue
        cg = gait.compiled()
        with cg.lock:
            vals = cg.values(tau[sel])
        if out is None:
            out = tuple(np.empty((tau.size,) + v.shape[1:]) for v in vals)
        for o, v in zip(out, vals):
            o[sel] = v
    return out
