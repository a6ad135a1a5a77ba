"""The exact method at 256 bodies and more (the scene limit is 1000).

``ExactCore.drive`` starts a segment only with room for its worst case of contact changes left
in the call's event records (2 p + 2). Those records were 2 N_BUF = 512 for every p, so from
p = 256 on no segment ever started: each call returned 'full' with nothing done and
``ExactSolver.advance`` called again, for ever (255 bodies ran, 256 hung). The runs here go in
a subprocess with a timeout, so a hang fails the test instead of stopping the suite.

Expected values from physics: a chain of identical bodies whose linkages are all constant but
one is two rigid blocks (each block's bodies move together, so its friction is the sum of
theirs), i.e. the two-body crawler with the blocks' masses and friction bounds, whose exact run
(p = 2) gives the blocks' motion; the friction impulses sum to the change of total momentum
(level ground); and the implicit method converges to it at first order as dt -> 0.
"""
import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(
    __file__)))))

SCRIPT = r'''
import json, sys
import numpy as np
import crawler_sim
from crawler_sim import gaits

def chain(p):
    """p bodies of 1 kg, mu = 0.3; only linkage k - 1 (between the head block 0..k-1 and the
    tail block k..p-1) moves: a scallop stroke 0.1 +/- 0.02 m at 2 Hz; the others stay 0.01 m."""
    k = p // 3
    amp = np.zeros(p - 1); amp[k - 1] = 0.02
    mean = np.full(p - 1, 0.01); mean[k - 1] = 0.1
    return k, crawler_sim.Crawler([1.0] * p, mu=0.3), gaits.Scallop(mean, amp, 2.0, 0.2)

out = {}
te = np.linspace(0.0, 2.0, 17)
for p in json.loads(sys.argv[1]):
    k, c, g = chain(p)
    tr = crawler_sim.simulate(c, g, 2.0, method='exact', t_eval=te)
    two = crawler_sim.simulate(crawler_sim.Crawler([float(k), float(p - k)], mu=0.3),
                               gaits.Scallop(0.1, 0.02, 2.0, 0.2), 2.0, method='exact', t_eval=te)
    d = tr.x - tr.x[0]                 # displacements (the blocks' offsets differ)
    d2 = two.x - two.x[0]
    r = {'x_err': max(float(np.abs(d[:, k - 1] - d2[:, 0]).max()),
                      float(np.abs(d[:, k] - d2[:, 1]).max())),
         # every body of a block moves with it
         'block_err': max(float(np.abs(tr.v[:, :k] - two.v[:, :1]).max()),
                          float(np.abs(tr.v[:, k:] - two.v[:, 1:]).max())),
         'moved': float(two.x[-1, 0] - two.x[0, 0]),
         'dP': float(tr.v[-1].sum() - tr.v[0].sum()),
         'impulse': float(tr.impulse[-1].sum() - tr.impulse[0].sum()),
         'n_events': len(tr.events)}
    if p == 300:
        r['implicit_err'] = [
            float(np.abs(crawler_sim.simulate(c, g, 2.0, method='implicit', dt=dt, t_eval=te).x
                         - tr.x).max()) for dt in (2e-3, 5e-4)]
    out[p] = r
print(json.dumps(out))
'''


def _run(ps, timeout):
    env = dict(os.environ, PYTHONPATH=ROOT, MPLBACKEND='Agg')
    try:
        res = subprocess.run([sys.executable, '-c', SCRIPT, json.dumps(ps)], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f'the exact solver did not finish p = {ps} within {timeout} s (hang)')
    assert res.returncode == 0, res.stderr[-3000:]
    return {int(p): r for p, r in json.loads(res.stdout.strip().splitlines()[-1]).items()}


def test_chains_of_256_to_1000_bodies_run_and_move_as_their_two_rigid_blocks():
    # 0.2-1.6 s each here; before the fix p = 256 never returned
    runs = _run([255, 256, 300, 1000], timeout=240)
    for p, r in runs.items():
        # the blocks move as the two-body crawler (to the rounding of sums over p bodies)
        assert r['x_err'] <= 1e-12, (p, r)
        assert r['block_err'] <= 1e-12, (p, r)
        assert r['moved'] > 0.02, (p, r)          # it crawls forward: not a trivial rest
        # friction impulses = change of total momentum (1 kg bodies, level ground)
        assert abs(r['dP'] - r['impulse']) <= 1e-9 * max(abs(r['dP']), 1e-3), (p, r)
        assert r['n_events'] > 2 * p, (p, r)
    # the implicit method converges to the exact run at first order (dt / 4: error / ~4)
    e1, e2 = runs[300]['implicit_err']
    assert e2 < e1 / 2.5, runs[300]
