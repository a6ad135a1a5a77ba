"""The plant's compiled shortcuts (issue 41) against the paths they replace, bit for bit:
``_gait.table_of_run`` (the engine's table of a run of pieces in one pass) against ``table``
with ``cubic.table_jumps``' breakpoints; ``ExactCore.switch_gait`` (a gait switch at each
sync) against the Python arithmetic of ``ExactSolver._switch_gait`` written out here;
``Servo._command`` (a step command's settle rule) against the list rule it replaced."""
import math

import numpy as np
import pytest

from crawler_sim.core.actuator import Actuator, ActuatorLimits
from crawler_sim.core.gaits.cubic import PiecewiseCubic, cubic_values, table_jumps
from crawler_sim.core.model import Crawler
from crawler_sim.core.stepper import Stepper
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


def _python_switch(solver, gait):
    """``ExactSolver._switch_gait`` as Python arithmetic (numpy's dot of W_0 and the jump)."""
    core, k = solver._core, solver._k
    cg = gait.compiled()
    t = core.t
    core.tl, core.origin, core.origin_k = t, 0.0, 0
    l0, ld0, ldd0 = solver._cg.at(t)
    l1, ld1, ldd1 = cg.at(t)
    core.ck_valid = False
    if not (l0.tolist() == l1.tolist() and ld0.tolist() == ld1.tolist()
            and ldd0.tolist() == ldd1.tolist()):
        core.forget_mode()
    if core.ref < 0:
        core.X += float(k.W[0] @ (l0 - l1))
        core.V += float(k.W[0] @ (ld0 - ld1))
    solver.gait = gait
    solver._cg = cg


@pytest.mark.parametrize('p', [2, 3, 5])
@pytest.mark.parametrize('static', [None, 0.45])
def test_a_compiled_gait_switch_is_the_python_arithmetic_bit_for_bit(p, static):
    """Gaits of random pieces switched every 20 ms, continuing C2 or jumping in l, l' and
    l'' (so W_0 . jump is not 0 and the mode is chosen anew), sliding (no reference body)
    and stuck: the compiled switch and the Python one give the same X, V and states."""
    rng = np.random.default_rng(p)
    crawler = Crawler(rng.uniform(0.5, 1.5, p), mu=0.3, mu_backward=0.5,
                      **({} if static is None else {'mu_static': static}))
    nl = p - 1

    def gait(t0, prev):
        starts = t0 + np.arange(4) * 0.005
        coef = rng.normal(0.0, [0.01, 0.05, 2.0, 200.0], (4, nl, 4))
        if prev is not None and rng.random() < 0.5:         # continues C2
            coef[0, :, :3] = np.array(prev.at(t0)).T
        for k in range(1, 4):
            coef[k, :, :3] = np.array(cubic_values(*coef[k - 1].T, 0.005)).T
        coef[:, :, 0] += 0.1
        return PiecewiseCubic.from_arrays(starts, starts.copy(), np.ascontiguousarray(coef))

    g = gait(0.0, None)
    a, b = (Stepper(crawler, g, 'exact') for _ in range(2))
    refs = set()
    for k in range(60):
        t0 = 0.02 * k
        g = gait(t0, g)
        a._solver._switch_gait(g)
        _python_switch(b._solver, g)
        ca, cb = a._solver._core, b._solver._core
        assert (ca.X, ca.V, ca.cache_ok, ca.tl) == (cb.X, cb.V, cb.cache_ok, cb.tl)
        refs.add(ca.ref >= 0)
        a.advance(t0 + 0.02, g)
        b.advance(t0 + 0.02, g)
        sa, sb = a.state, b.state
        assert sa.x.tobytes() == sb.x.tobytes() and sa.v.tobytes() == sb.v.tobytes()
    assert refs == {True, False}          # switched while sliding and while stuck


def test_a_command_unsettles_exactly_the_linkages_whose_target_changes():
    """set_target (its rule compiled, Servo._command) against the rule it replaced, on Python
    lists: a linkage is unsettled where the new target differs from the old (NaN differs from
    everything, -0.0 equals 0.0), settled flags kept elsewhere, the targets the new ones bit for
    bit; commands between runs of ticks, repeated, equal, partly equal."""
    rng = np.random.default_rng(5)
    limits = ActuatorLimits(5.0, 0.5, 5.0, -1.0, 1.0)
    unsettled_some = False
    for trial in range(300):
        n = int(rng.integers(1, 5))
        act = Actuator([0.0] * n, 1e-3, limits)
        for k in range(6):
            old_target, old_settled = act.target, act._settled
            new = [float(x) for x in rng.choice([0.0, -0.0, 0.1, -0.2], n)]
            if k % 2:
                new = [o if rng.random() < 0.5 else x for o, x in zip(old_target, new)]
            want = [ok and x == o for ok, x, o in zip(old_settled, new, old_target)]
            act.set_target(new)
            assert act._settled == want
            assert np.array(act.target).tobytes() == np.array(new).tobytes()
            unsettled_some |= not all(want) and any(want)
            act.run(k * 10_000_000, 1_000_000, int(rng.integers(1, 400)))
    assert unsettled_some
    act = Actuator([0.1, 0.1], 1e-3, limits)
    act.set_target([0.1, 0.1])
    assert act._settled == [True, True]
    act._command([math.nan, 0.1])           # NaN differs from everything
    assert act._settled == [False, True]


def test_native_kind_found_per_class():
    """``BuiltinGait._compile`` keeps per class whether its gaits run as their compiled kind:
    a subclass that overrides an evaluation runs sampled even after its parent compiled (the
    parent's answer is not inherited), one that does not runs native, and so does a subclass
    of it compiled after the overriding one."""
    from crawler_sim.core.gaits import Cubic

    class Plain(Cubic):
        pass

    class Overrides(Cubic):
        def at(self, t):
            return super().at(t)

    class Below(Plain):
        pass

    def native(cls):
        g = cls(0.0, [0.1], [0.2], [0.0], [1.0])
        return g.compiled() is g.__dict__.get('_native_kind')

    assert [native(c) for c in (Cubic, Plain, Overrides, Below, Overrides, Plain)] == \
        [True, True, False, True, False, True]


# ---------------------------------------------------------------------- the plant's compiled step
from crawler_sim.core.plant._batch import PlantStep, step_plants  # noqa: E402
from crawler_sim.core.plant.engine import Engine  # noqa: E402


class PythonEngine(Engine):
    """sim_node's plant without its compiled step: ``Actuator.run``, ``sync`` and
    ``Stepper.advance`` as Python calls (the path the compiled step must repeat)."""

    def _fast(self):
        return False


def _state_bytes(engine: Engine) -> list[bytes]:
    st = engine.state
    inc = b'' if st.incumbent is None else np.asarray(st.incumbent).tobytes()
    return [np.float64(st.t).tobytes(), st.x.tobytes(), st.v.tobytes(),
            st.contact.astype(np.int8).tobytes(), st.friction.tobytes(),
            st.linkage_force.tobytes(), st.lengths.tobytes(), st.rates.tobytes(), inc,
            np.array(engine.actuator_state()).tobytes()]


@pytest.mark.parametrize('crawler, period', [
    ({'masses': [0.5, 1.0], 'mu': 0.3, 'mu_backward': 0.6}, 0.01),
    ({'masses': [1.0, 0.8, 1.2], 'mu': 0.25, 'mu_static': [0.4, 0.3, 0.5],
      'mu_backward': 0.4}, 0.01),                                   # p = 3, stiction
    ({'masses': [1.0, 0.7, 1.3], 'mu': [0.3, 0.2, 0.4], 'slope': 0.1}, 0.04),
    ({'masses': [0.5, 1.0], 'mu': 0.3, 'mu_static': 0.45}, 0.001),  # one tick a period
])
def test_n_plants_stepped_together_are_n_python_engines_bit_for_bit(crawler, period):
    """``_batch.step_plants`` (N engines, each command + run + state read in one compiled loop,
    the vector env's step) against N engines stepped through the Python path
    (``Actuator.run``, ``PiecewiseCubic``, ``Stepper.advance``): every state (x, v, contact,
    friction, forces, lengths, incumbent), the actuator, the events, the journal and the
    failures, bit for bit, over 150 periods of random commands, with commands repeated until
    the actuator settles (a run at rest: the Python rule's Cubic), a command that is not
    finite (the gait refused, the solver failure contained: the plant restarts at rest) and an
    integration cut off the publish grid between two periods (the next span starts off it)."""
    from crawler_sim.envs.plant import CrawlPlant
    cfg = CrawlPlant(crawler, control_period=period).engine_config
    n, p = 4, cfg.crawler.p
    logs = [[] for _ in range(2 * n)]

    def journal(k):
        return lambda kind, t_ns, payload: logs[k].append(repr((kind, t_ns, payload)))
    fast = [Engine(cfg, 0, journal(i)) for i in range(n)]
    slow = [PythonEngine(cfg, 0, journal(n + i)) for i in range(n)]
    span = round(period * 1e9)
    rng = np.random.default_rng(p + round(1e3 * period))
    x, v, c = np.zeros((n, p)), np.zeros((n, p)), np.zeros((n, p), dtype=np.int8)
    xr, vr, cr = x[0].copy(), v[0].copy(), c[0].copy()
    targets = rng.uniform(0.05, 0.15, (n, p - 1))
    events = 0
    for k in range(150):
        fresh = rng.uniform(0.05, 0.15, (n, p - 1))
        if k % 30 >= 12:
            fresh[1] = targets[1]               # engine 1 holds its command: it settles
        targets = fresh
        if k == 60:
            targets[2] = math.nan               # refused, contained
        if k % 40 == 17:
            for e in (fast[3], slow[3]):        # a cut off the grid: the next span starts off it
                e.run_to(e.t_ns + 3 * cfg.dt_ns)
                e.sync()
        step_plants(fast, targets, span, x, v, c)
        for i, e in enumerate(slow):
            e.command(targets[i].tolist())
            e.run_to(e.t_ns + span)
            e.read_state(xr, vr, cr)
            assert (x[i].tobytes(), v[i].tobytes(), c[i].tobytes()) == \
                (xr.tobytes(), vr.tobytes(), cr.tobytes())
            assert _state_bytes(fast[i]) == _state_bytes(e)
            got, want = fast[i].pop_events(), e.pop_events()
            assert repr(got) == repr(want)
            events += len(got)
            assert fast[i].failures == e.failures and fast[i].t_ns == e.t_ns
    assert logs[:n] == logs[n:]
    assert events > 0                  # the events path (``ExactSolver._store``) ran
    # the exact solver's failure, then the implicit fallback's: contained
    assert len(fast[2].failures) == 2 and 'starts again at rest' in fast[2].failures[1]
    assert all(isinstance(e._step, PlantStep) for e in fast)      # the compiled step ran
    assert all(e._step is None for e in slow)
