"""Bit-identity of results across commits: every case of the differential fuzz (its families x
seeds, and the issue scenes) run and saved, once per tree, then compared array by array.

Issue 40's floor (a crawler without stiction gives the results of the commit before stiction,
bit for bit): build a clean worktree of each commit, run this module in each, compare:

    git worktree add --detach /tmp/base 4a88a12 && (cd /tmp/base && python setup.py build_ext --inplace -q)
    PYTHONPATH=/tmp/base python -m benchmarks.fuzz_bits run /tmp/base.npz 40
    PYTHONPATH=$PWD python -m benchmarks.fuzz_bits run /tmp/head.npz 40
    python -m benchmarks.fuzz_bits cmp /tmp/base.npz /tmp/head.npz

(Run the module from the tree being measured: ``PYTHONPATH`` decides which crawler_sim and which
test.support.fuzz are imported; the case draws must be the same in both trees.)
"""
from __future__ import annotations

import sys
import warnings

import numpy as np


def run(out: str, n: int) -> None:
    """Save every fuzz case's outputs (seeds 0..n-1 of each family) to ``out`` (.npz)."""
    warnings.simplefilter('ignore')
    import crawler_sim as cs
    from test.support.fuzz import FAMILIES, ISSUE_SCENES, draw_case
    res = {}
    cases = [(f'{f}/{s}', draw_case(f, s)) for f in FAMILIES for s in range(n)]
    for name, case in cases:
        try:
            if case.gait is not None:
                tr = cs.simulate(case.crawler, case.gait, case.t_end, v0=case.v0)
                arrs = [tr.t, tr.x, tr.v, tr.friction, tr.linkage_force,
                        np.array([(e.time, e.body, e.old, e.new)
                                  for e in tr.events]).reshape(-1, 4)]
            else:                                   # a streamed case: its states at each cut
                st = cs.Stepper(case.crawler, case.pieces[0][1], v0=case.v0)
                rows = []
                for t1, g in case.pieces:
                    st.advance(t1, g)
                    s = st.state
                    rows.append(np.concatenate([[s.t], s.x, s.v, s.friction]))
                arrs = [np.array(rows)]
        except Exception as exc:                    # a refusal is a result too: its message
            arrs = [np.frombuffer(repr(exc).encode(), dtype=np.uint8).astype(float)]
        for k, a in enumerate(arrs):
            res[f'{name}/{k}'] = np.asarray(a, dtype=float)
    for name, (c, g, t_end, v0) in ISSUE_SCENES.items():
        tr = cs.simulate(c, g, t_end, v0=v0)
        res[f'issue/{name}/x'] = tr.x
        res[f'issue/{name}/f'] = tr.friction
    np.savez(out, **res)
    print(len(cases) + len(ISSUE_SCENES), 'scenes')


def cmp(a: str, b: str) -> int:
    """Print how many arrays differ between two saved runs; 1 if any does, else 0."""
    A, B = np.load(a), np.load(b)
    if set(A.files) != set(B.files):
        print('different cases:', sorted(set(A.files) ^ set(B.files))[:20])
        return 1
    scenes = {k.rsplit('/', 1)[0] for k in A.files}
    worst, bad = 0.0, []
    for k in A.files:
        x, y = A[k], B[k]
        if x.shape != y.shape or not np.array_equal(x, y, equal_nan=True):
            bad.append(k)
            if x.shape == y.shape:
                worst = max(worst, float(np.nanmax(np.abs(x - y))))
    print(f'{len(scenes)} scenes, {len(A.files)} arrays, {len(bad)} differ, '
          f'max |diff| = {worst}')
    if bad:
        print(bad[:20])
    return 1 if bad else 0


if __name__ == '__main__':
    if len(sys.argv) == 4 and sys.argv[1] == 'run':
        run(sys.argv[2], int(sys.argv[3]))
    elif len(sys.argv) == 4 and sys.argv[1] == 'cmp':
        sys.exit(cmp(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
