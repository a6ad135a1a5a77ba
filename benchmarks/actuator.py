"""The node's actuator model, compiled (``crawler_sim/core/_actuator.pyx``) against the pure-Python
model it replaced (test/core/actuator_oracle.py), in the same process.

Figures (median of ``--repeats`` runs, 5 by default), sim_node's default plant (one linkage,
1 kHz ticks, default limits):

* step commands: a new random target every 20 ticks (a 50 Hz ``linkage_cmd`` stream), us per
  tick of ``Actuator.step`` (the node's per-tick call) and of ``Actuator.run`` (20 ticks per
  call, the runs between inputs);
* following a trajectory: a quintic reference of a 1 Hz sinusoid sampled at 50 Hz, us per tick
  of ``step`` and of ``run`` (one call);
* ``streams.actuator_output`` for 240,000 ticks (240 s of sim time) of that sinusoid, played as
  one preloaded trajectory (what ``crawler-sim optimize`` writes) and as 50 Hz commands: s per
  call; the oracle runs through the engine as it was (one ``tick()``, one ``step`` per tick).

Each line gives the compiled figure, the oracle's and their ratio, and checks that both
produced the same pieces bit for bit.

``--engine`` (issues 41/42): the node's ``Engine`` (default sim_node plant, exact method) in CPU
time (``time.process_time``), with the cubic tables built as now (the joins handed to
``table``, ``gaits.cubic.table_jumps``) and as before (``table`` searching them itself),
alternated in this process, the states compared bit for bit: flat out for 10 simulated seconds
(a 2 Hz sine command at 50 Hz, ``tick_to_grid`` to each 100 Hz publish tick), ms of CPU per
simulated second; and driven step by step (``command`` + ``run_to`` one 1 kHz tick, then the
state), steps per CPU second. Reproduce with::

    .venv/bin/python setup.py build_ext --inplace
    .venv/bin/python -m benchmarks.actuator [--repeats 5] [--links 1] [--engine]
"""
from __future__ import annotations

import argparse
import contextlib
import math
import statistics
import time

import numpy as np

from test.support import actuator_oracle as oracle

from crawler_sim.core import actuator, gaits  # noqa: E402
from crawler_sim.core.plant import PlantConfig, streams  # noqa: E402

DT = 1e-3


def _median(fn, repeats: int) -> tuple[float, object]:
    """Median wall time [s] of ``fn()`` over ``repeats`` calls, and its last result."""
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def _rows(pieces) -> list:
    """(t0, rows) of every piece as Python floats (bit-for-bit comparison, signed zeros by
    repr)."""
    return [(repr(pc.t0), repr(pc._rows)) for pc in pieces]


def commands(mod, n_links: int, n_ticks: int, bulk: bool) -> list:
    """A 50 Hz stream of random targets through ``mod``'s Actuator (step per tick, or, for
    the compiled one with ``bulk``, one ``run`` per 20 ticks)."""
    rng = np.random.default_rng(1)
    targets = rng.uniform(0.05, 0.3, (n_ticks // 20 + 1, n_links)).tolist()
    act = mod.Actuator([0.1] * n_links, DT, mod.ActuatorLimits())
    dt_ns = round(DT * 1e9)
    out = []
    if bulk:
        for k in range(0, n_ticks, 20):
            act.set_target(targets[k // 20])
            out.append(act.run(k * dt_ns, dt_ns, 20))
        return out
    step = act.step
    for k in range(n_ticks):
        if k % 20 == 0:
            act.set_target(targets[k // 20])
        out.append(step(k * dt_ns / 1e9, (k + 1) * dt_ns / 1e9))
    return out


def following(mod, n_links: int, n_ticks: int, bulk: bool) -> list:
    """A quintic trajectory (a 1 Hz sinusoid sampled at 50 Hz) followed for ``n_ticks``."""
    gait = gaits.Sinusoid(0.1, 0.02, 1.0, np.linspace(0, 1, n_links), n_links=n_links)
    times = np.arange(1, int(n_ticks * DT * 50) + 2) * 0.02
    l, ld, ldd = gait(times)
    act = mod.Actuator([0.1] * n_links, DT, mod.ActuatorLimits())
    act.set_trajectory(mod.TrajectoryReference.from_arrays(0.0, act.state(), times, l, ld, ldd))
    dt_ns = round(DT * 1e9)
    if bulk:
        return [act.run(0, dt_ns, n_ticks)]
    step = act.step
    return [step(k * dt_ns / 1e9, (k + 1) * dt_ns / 1e9) for k in range(n_ticks)]


def _same_pieces(compiled: list, orc: list) -> bool:
    pieces = [p.piece(k) for p in compiled for k in range(len(p.starts))] \
        if compiled and isinstance(compiled[0], actuator.Pieces) else compiled
    return _rows(pieces) == _rows(orc)


def output(stream: streams.Stream, use_oracle: bool, t_end: float):
    """``streams.actuator_output`` of the default plant for the sinusoid (the oracle: the
    engine as it was, ``actuator_oracle.OracleEngine``)."""
    plant = PlantConfig.defaults()
    gait = gaits.Sinusoid(0.1, 0.02, 1.0, n_links=plant.n_links)
    engine = streams.Engine
    streams.Engine = oracle.OracleEngine if use_oracle else engine
    try:
        return streams.actuator_output(plant, gait, stream, t_end)
    finally:
        streams.Engine = engine


def _same_output(a, b) -> bool:
    return (a.starts.tolist() == b.starts.tolist()
            and _rows(a.pieces) == _rows(b.pieces))


def _engine():
    """An Engine of sim_node's default plant (two bodies, 1 kHz ticks, publish at 100 Hz)."""
    from crawler_sim.core.plant import Engine
    from crawler_sim.ros.sim.params import PARAMETERS, SimConfig
    return Engine(SimConfig.from_values({k: v[0] for k, v in PARAMETERS.items()}).engine_config())


def _sine(t: float) -> list[float]:
    return [0.1 + 0.02 * math.sin(2.0 * math.pi * 2.0 * t)]


def engine_flat(seconds: float = 10.0) -> tuple[float, list]:
    """CPU [s] of ``seconds`` of sim time flat out, and the state at every publish tick."""
    engine, out, k = _engine(), [], 0
    end = round(seconds * 1e9)
    t0 = time.process_time()
    while engine.t_ns < end:
        if k % 2 == 0:                  # 50 Hz commands, publish ticks at 100 Hz
            engine.command(_sine(engine.t))
        engine.tick_to_grid()
        st = engine.stepper.state
        out.append((st.x.tolist(), st.v.tolist()))
        k += 1
    return time.process_time() - t0, out


def engine_steps(n: int = 3000) -> tuple[float, list]:
    """CPU [s] of ``n`` steps of command + run_to one 1 kHz tick + state, and the states."""
    engine, out = _engine(), []
    t0 = time.process_time()
    for _ in range(n):
        engine.command(_sine(engine.t))
        engine.run_to(engine.t_ns + engine.cfg.dt_ns)
        st = engine.state
        out.append((st.x.tolist(), st.v.tolist()))
    return time.process_time() - t0, out


@contextlib.contextmanager
def _tables_search_their_joins():
    """The cubic gaits' ``_kind`` as before issues 41/42: ``table`` classifies every join."""
    from crawler_sim.core.solvers._gait import table

    def one(self):
        return table(np.array([self._rows], dtype=float), starts=np.array([-math.inf]),
                     anchors=np.array([self.t0]))

    def many(self):
        if self._arrays is not None:
            starts, anchors, coef = self._arrays
            return table(coef, starts=starts, anchors=anchors)
        return table(np.array([pc._rows for pc in self.pieces], dtype=float),
                     starts=np.array(self._starts), anchors=np.array([pc.t0 for pc in self.pieces]))

    saved = gaits.Cubic._kind, gaits.PiecewiseCubic._kind
    gaits.Cubic._kind, gaits.PiecewiseCubic._kind = one, many
    try:
        yield
    finally:
        gaits.Cubic._kind, gaits.PiecewiseCubic._kind = saved


def engine_figures(repeats: int) -> None:
    """Print the engine's figures (``--engine``): now and before, alternated, medians."""
    print(f'Engine, sim_node default plant, exact; median of {repeats}, CPU time; now, before '
          '(table searching its joins), speed-up, states')
    for name, fn, figure, higher in (
            ('flat out 10 s, 50 Hz sine commands [ms CPU per sim s]', engine_flat,
             lambda cpu: cpu / 10.0 * 1e3, False),
            ('command + run_to per 1 kHz tick [steps per CPU s]', engine_steps,
             lambda cpu: 3000 / cpu, True)):
        now, before, same = [], [], True
        for _ in range(repeats):
            cpu, a = fn()
            now.append(figure(cpu))
            with _tables_search_their_joins():
                cpu, b = fn()
            before.append(figure(cpu))
            same = same and a == b
        m_now, m_before = statistics.median(now), statistics.median(before)
        gain = m_now / m_before if higher else m_before / m_now
        print(f'{name:56s} {m_now:9.1f} {m_before:9.1f} {gain:6.2f}x  '
              f'{"same" if same else "DIFFERENT"}')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--links', type=int, default=1, help='linkages of the per-tick figures')
    ap.add_argument('--ticks', type=int, default=240_000, help='ticks of actuator_output')
    ap.add_argument('--engine', action='store_true',
                    help="only the engine's per-sync figures (issues 41/42)")
    args = ap.parse_args()
    if args.engine:
        engine_figures(args.repeats)
        return
    r, nl = args.repeats, args.links
    n = 20_000
    print(f'median of {r}; {nl} linkage(s), dt = 1 ms; us per tick unless said otherwise')
    print(f'{"":44s} {"compiled":>10s} {"oracle":>10s} {"ratio":>7s}  bits')
    for name, fn in (('step commands (50 Hz)', commands), ('following a trajectory', following)):
        t_or, orc = _median(lambda: fn(oracle, nl, n, False), r)
        for how, bulk in (('step()', False), ('run()', True)):
            t_c, got = _median(lambda: fn(actuator, nl, n, bulk), r)
            same = _same_pieces(got, orc)
            print(f'{name + ", " + how:44s} {t_c / n * 1e6:10.3f} {t_or / n * 1e6:10.3f} '
                  f'{t_or / t_c:6.1f}x  {"same" if same else "DIFFERENT"}')
    t_end = args.ticks * DT
    for name, stream in (('preloaded trajectory', streams.Stream('trajectory', 50.0, 4.0, True,
                                                                  t_end)),
                         ('50 Hz commands', streams.Stream('command', 50.0, preload=False))):
        t_c, got = _median(lambda: output(stream, False, t_end), r)
        t_or, orc = _median(lambda: output(stream, True, t_end), r)
        same = _same_output(got, orc)
        print(f'{"actuator_output, " + name + " [s]":44s} {t_c:10.3f} {t_or:10.3f} '
              f'{t_or / t_c:6.1f}x  {"same" if same else "DIFFERENT"}')


if __name__ == '__main__':
    main()
