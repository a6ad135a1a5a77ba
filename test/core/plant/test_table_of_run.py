"""``_gait.table_of_run`` (the engine's table of a run of pieces, one compiled pass, issue 41)
builds the struct ``table`` builds with ``cubic.table_jumps``' breakpoints, bit for bit."""
import math

import numpy as np
import pytest

from crawler_sim.core.gaits.cubic import cubic_values, table_jumps
from crawler_sim.core.solvers._gait import table, table_of_run, table_struct


def _tables(seed: int, count: int):
    """Random tables that are not periodic: free pieces (l'' jumps at most joins), C2 joins
    as the actuator makes them (a few ulps at the join: no jump), some with jerk 0, rest
    pieces, integer jerks (l''' continues across joins), a first piece from -inf; 1 to 199
    pieces (beyond 2^6: every level of the aligned extremes), 1 to 3 linkages."""
    rng = np.random.default_rng(seed)
    for trial in range(count):
        n = int(rng.integers(1, 200)) if trial % 3 else int(rng.integers(1, 12))
        nl = int(rng.integers(1, 4))
        starts = np.cumsum(rng.uniform(1e-4, 1e-2, n)) + rng.uniform(0, 100)
        coef = rng.normal(size=(n, nl, 4))
        mode = trial % 5
        if mode in (1, 2):
            for k in range(1, n):
                coef[k, :, :3] = np.array(cubic_values(*coef[k - 1].T,
                                                       starts[k] - starts[k - 1])).T
            if mode == 2:
                coef[rng.integers(0, n, 3), :, 3] = 0.0
        elif mode == 3:
            coef[rng.random(n) < 0.5, :, 1:] = 0.0
        elif mode == 4:
            coef[:, :, 3] = np.round(coef[:, :, 3])
        anchors = starts.copy()
        if trial % 7 == 0:
            starts[0] = -math.inf
        yield starts, anchors, np.ascontiguousarray(coef)


@pytest.mark.parametrize('seed', [1, 2])
def test_table_of_run_is_tables_struct_bit_for_bit(seed):
    kinds = {'jumps': 0, 'no jumps': 0, 'rest': 0}
    for starts, anchors, coef in _tables(seed, 600):
        want = table_struct(table(coef, starts=starts, anchors=anchors,
                                  jumps=table_jumps(starts, anchors, coef)))
        got = table_struct(table_of_run(starts, anchors, coef))
        assert want.keys() == got.keys()
        for key, a in want.items():
            b = got[key]
            if isinstance(a, np.ndarray):
                assert a.shape == b.shape and a.astype(float).tobytes() == \
                    b.astype(float).tobytes(), key
            else:
                assert a == b, key
        kinds['jumps' if want['jump'].any() else 'no jumps'] += 1
        kinds['rest'] += bool(want['rest'].any())
    assert min(kinds.values()) > 50        # every case reached
