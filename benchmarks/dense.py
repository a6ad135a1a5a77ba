"""Exact dense output (issue 39): the floors' figures, and what ``Trajectory.state_at`` costs.

Floors, each printed with PASS/FAIL:

* ``mean_speed(period)`` of the README's example (``Crawler(masses=[0.5, 1.0], mu=0.3)``,
  ``Scallop(mean=0.1, amplitude=0.02, frequency=f, asymmetry=0.2)``, t_end = 20 s) equal to
  the exact window, a run whose ``t_eval`` holds t_end - period exactly, to 1e-12 relative;
  also printed: against a run integrated without the periodic skip, the figure the
  interpolation gave before, and the derivative in f by central differences;
* every sweep figure (``scene_figures``, score "ideal") and optimiser figure (``Objective``,
  score "node": the actuator's output, a grid that misses the period boundaries by rounding)
  of an exact run: its speed equal to the window [k0 T, N T] sampled exactly, to 1e-12;
* ``Trajectory.positive_work`` (the cost of transport's numerator) equal to an independent
  quadrature (roots by brentq, Gauss-Legendre between events and roots) to 1e-12 relative;
* the exact positive work's cost: a sweep scene and an optimiser evaluation (scores node and
  ideal) at most 1.1x their CPU with the trapezoid it replaced (interleaved, this process);
* ``Trajectory.state_at(t)`` equal to a run sampled at t to 1e-13 m (Scallop with skipped
  periods, three-body Fourier, PiecewiseCubic, Custom), and within 1e-11 m of runs without the
  periodic skip (every period integrated, not shifted).

Costs (CPU time, median of --repeats rounds, in this process): ``state_at`` of one time and of
1000 times, against ``simulate(..., t_eval=[t])`` of the same run (what an exact value cost
before).

    .venv/bin/python -m benchmarks.dense
    .venv/bin/python -m benchmarks.dense --quick
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

import crawler_sim as cs
from crawler_sim.core.actuator import ActuatorLimits
from crawler_sim.core.plant.streams import simulate_as_node
from crawler_sim.core.scene import scene_from_dict, scene_to_dict
from crawler_sim.sweep.metrics import scene_figures
from crawler_sim.sweep.optimize import STREAM, Objective, family, plant_for
from test.support.quadrature import positive_work_reference

G = cs.gaits
README = cs.Crawler(masses=[0.5, 1.0], mu=0.3)
T_END = 20.0


def _com(crawler: cs.Crawler, x: np.ndarray) -> np.ndarray:
    m = crawler.masses
    return x @ (m / m.sum())


def _scallop(f: float) -> G.Scallop:
    return G.Scallop(mean=0.1, amplitude=0.02, frequency=f, asymmetry=0.2)


def _verdict(value: float, floor: float) -> str:
    return 'PASS' if value <= floor else 'FAIL'


def mean_speed_rows(freqs: list[float]) -> float:
    """The README example's mean_speed(period) against the exact window; returns the worst."""
    print('mean_speed(period), README example, t_end = 20 s')
    print(f'{"f [Hz]":>7} {"mean_speed [m/s]":>22} {"rel. to window":>15} '
          f'{"rel. to no-skip":>16} {"interpolated, rel.":>19}')
    worst = 0.0
    for f in freqs:
        g, T = _scallop(f), 1.0 / f
        tr = cs.simulate(README, g, T_END)
        fig = tr.mean_speed(T)
        win = cs.simulate(README, g, T_END, t_eval=[T_END - T, T_END])
        exact = float(np.diff(win.com)[0] / T)
        full = cs.simulate(README, g, T_END, t_eval=[T_END - T, T_END], periodic_skip=False)
        noskip = float(np.diff(full.com)[0] / T)
        old = (tr.com[-1] - np.interp(T_END - T, tr.t, tr.com)) / T
        scale = abs(exact) or 1.0           # absolute where it does not move
        rel = abs(fig - exact) / scale
        worst = max(worst, rel)
        print(f'{f:7.3f} {fig:22.17g} {rel:15.2e} {abs(fig - noskip) / scale:16.2e} '
              f'{abs(old - exact) / scale:19.2e}')
    print(f'floor: mean_speed(period) = exact window to 1e-12 relative: worst {worst:.2e} '
          f'{_verdict(worst, 1e-12)}')
    return worst


def derivative_rows(f: float = 1.37) -> None:
    """d mean_speed / d f by central differences: the figure's and the window's (no skip)."""
    def fig(x):
        return cs.simulate(README, _scallop(x), T_END).mean_speed(1.0 / x)

    def window(x):
        T = 1.0 / x
        r = cs.simulate(README, _scallop(x), T_END, t_eval=[T_END - T, T_END],
                        periodic_skip=False)
        return float(np.diff(r.com)[0] / T)

    def interpolated(x):
        tr = cs.simulate(README, _scallop(x), T_END)
        T = 1.0 / x
        return (tr.com[-1] - np.interp(T_END - T, tr.t, tr.com)) / T

    print(f'\nd mean_speed / d f at {f} Hz by central differences [m/s/Hz]')
    print(f'{"h [Hz]":>8} {"mean_speed":>12} {"window, no skip":>16} {"interpolated":>13}')
    for h in (1e-2, 1e-3, 1e-4, 1e-5):
        row = [(fn(f + h) - fn(f - h)) / (2 * h) for fn in (fig, window, interpolated)]
        print(f'{h:8.0e} {row[0]:12.5e} {row[1]:16.5e} {row[2]:13.5e}')


def _rel(fig_speed: float, window: float, dx: float) -> float:
    """|fig_speed * window - dx| relative to |dx| (absolute when the crawler does not move)."""
    return abs(fig_speed * window - dx) / (abs(dx) if dx else 1.0)


def _sampled_speed(tr: cs.Trajectory, k0: int, T: float, t_end: float) -> float:
    """The speed from the samples nearest k0 T and t_end (what run_figures read before)."""
    i0, i1 = np.abs(tr.t - k0 * T).argmin(), tr.t.size - 1
    return float((tr.com[i1] - tr.com[i0]) / (tr.t[i1] - tr.t[i0]))


def sweep_rows() -> float:
    """Sweep (score "ideal") and optimiser (score "node") speeds against the exact window."""
    from dataclasses import replace

    base = scene_from_dict({'crawler': {'masses': [0.5, 1.0], 'mu': 0.3},
                            'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02,
                                     'frequency': 1.0, 'asymmetry': 0.3}})
    limits = ActuatorLimits()
    fam = family('scallop', base, limits)
    plant = plant_for(base, fam, limits)
    periods, spp = 10, 40
    print('\nsweep ("ideal") and optimiser ("node") speeds, 10 periods, 40 samples a period, '
          'relative to the window [k0 T, N T] sampled exactly (before: from the samples)')
    print(f'{"z (amplitude, f, r)":>22} {"sweep":>9} {"before":>9} {"node":>9} {"before":>9}')
    worst = 0.0
    for z in ([0.035, 1.5, 0.42], [0.02, 1.37, 0.2], [0.04, 0.9, 0.3], [0.025, 2.2, 0.25]):
        g = fam.gait(np.array(z))
        T = g.period
        t_end = periods * T
        row = []
        sc = replace(base, gait=g)
        f = scene_figures(sc, periods, spp)
        k0 = f['transient_periods']
        dx = float(np.diff(cs.simulate(sc.crawler, g, t_end, t_eval=[k0 * T, t_end]).com)[0])
        tr = cs.simulate(sc.crawler, g, t_end, dt=t_end / (periods * spp))
        row += [_rel(f['mean_speed'], t_end - k0 * T, dx),
                _rel(_sampled_speed(tr, k0, T, t_end), t_end - k0 * T, dx)]
        obj = Objective(scene_to_dict(base), fam, limits, 'speed', periods, spp, 'node',
                        plant=plant.values, stream=STREAM)
        f = obj.figures(g)
        k0 = f['transient_periods']
        stream = replace(STREAM, duration=min(STREAM.duration, t_end + 2.0 / STREAM.rate))
        dx = float(np.diff(simulate_as_node(plant, g, stream, t_end,
                                            t_eval=[k0 * T, t_end]).com)[0])
        tr = simulate_as_node(plant, g, stream, t_end, dt=t_end / (periods * spp))
        row += [_rel(f['mean_speed'], t_end - k0 * T, dx),
                _rel(_sampled_speed(tr, k0, T, t_end), t_end - k0 * T, dx)]
        worst = max(worst, row[0], row[2])
        print(f'{str(z):>22} ' + ' '.join(f'{r:9.2e}' for r in row))
    print(f'floor: sweep/optimiser speed = exact window to 1e-12 relative: worst {worst:.2e} '
          f'{_verdict(worst, 1e-12)}')
    return worst


def _cases() -> list:
    w = 2 * math.pi
    custom = G.Custom(lambda t: np.array([0.1 + 0.02 * math.sin(w * t)]),
                      lambda t: np.array([0.02 * w * math.cos(w * t)]),
                      lambda t: np.array([-0.02 * w * w * math.sin(w * t)]), period=1.0)
    three = cs.Crawler(masses=[1.0, 0.4, 0.7], mu=[0.3, 0.5, 0.2])
    fourier = G.Fourier([0.1, 0.12], ([[0.02, 0.004], [0.015, 0.0]],
                                      [[0.0, 0.003], [0.01, 0.002]]), 2.3)
    rng = np.random.default_rng(3)
    starts = np.arange(0.0, 10.0, 0.05)
    pieces = [G.Cubic(float(s), [0.1], [0.0], [0.0], [float(rng.uniform(-2, 2))])
              for s in starts]
    cubic = G.PiecewiseCubic(starts, pieces)
    return [('Scallop 1.37 Hz (skipped periods)', README, _scallop(1.37), 20.0),
            ('Fourier, 3 bodies', three, fourier, 30.0),
            ('PiecewiseCubic, 200 pieces', README, cubic, 10.0),
            ('Custom (sampled pieces)', README, custom, 10.0)]


def state_at_rows(n: int) -> float:
    print(f'\nstate_at(t) at {n} random times against runs sampled there [m]')
    print(f'{"gait":>36} {"vs sampled run":>15} {"vs no-skip run":>15}')
    worst = 0.0
    rng = np.random.default_rng(11)
    for name, crawler, g, t_end in _cases():
        tr = cs.simulate(crawler, g, t_end)
        times = np.sort(rng.uniform(0.0, t_end, n))
        got = tr.state_at(times).x
        ref = cs.simulate(crawler, g, t_end, t_eval=times).x
        full = cs.simulate(crawler, g, t_end, t_eval=times, periodic_skip=False).x
        err = float(np.abs(got - ref).max())
        worst = max(worst, err)
        print(f'{name:>36} {err:15.2e} {float(np.abs(got - full).max()):15.2e}')
    print(f'floor: state_at(t) = run sampled at t to 1e-13 m: worst {worst:.2e} '
          f'{_verdict(worst, 1e-13)}')
    return worst




def positive_work_rows() -> float:
    """Trajectory.positive_work (the cost of transport's numerator) against the independent
    quadrature, and what the trapezoid over the default samples gave."""
    print('\npositive actuator work over [1.3, 17.77] s, README example, t_end = 20 s, '
          'relative to an independent quadrature (brentq roots, Gauss between events)')
    print(f'{"case":>22} {"positive_work [J]":>20} {"rel.":>9} {"trapezoid rel.":>15}')
    worst = 0.0
    for name, crawler in (('level', README),
                          ('slope 0.1 rad', cs.Crawler(masses=[0.5, 1.0], mu=0.3, slope=0.1))):
        g = _scallop(1.37)
        tr = cs.simulate(crawler, g, T_END)
        ref = positive_work_reference(crawler, g, T_END, 1.3, 17.77)
        got = tr.positive_work(1.3, 17.77)
        sel = (tr.t >= 1.3) & (tr.t <= 17.77)
        pw = np.maximum(np.sum(tr.linkage_force[sel] * tr.rates[sel], axis=1), 0.0)
        trap = float(np.sum(0.5 * (pw[1:] + pw[:-1]) * np.diff(tr.t[sel])))
        rel = abs(got - ref) / ref
        worst = max(worst, rel)
        print(f'{name:>22} {got:20.15f} {rel:9.1e} {abs(trap - ref) / ref:15.1e}')
    print(f'floor: positive work = independent quadrature to 1e-12 relative: worst {worst:.1e} '
          f'{_verdict(worst, 1e-12)}')
    return worst


def _cpu(fn, repeats: int, inner: int) -> float:
    """Median CPU time of one call [s] over ``repeats`` rounds of ``inner`` calls."""
    out = []
    for _ in range(repeats):
        t0 = time.process_time()
        for _ in range(inner):
            fn()
        out.append((time.process_time() - t0) / inner)
    return statistics.median(out)


def cost_rows(repeats: int) -> None:
    g = _scallop(1.37)
    tr = cs.simulate(README, g, T_END)
    many = np.linspace(0.0, T_END, 1000)
    one = _cpu(lambda: tr.state_at(13.3), repeats, 50)
    vec = _cpu(lambda: tr.state_at(many), repeats, 5)
    rerun = _cpu(lambda: cs.simulate(README, g, T_END, t_eval=[13.3]), repeats, 20)
    work = _cpu(lambda: tr.positive_work(), repeats, 5)
    run = _cpu(lambda: cs.simulate(README, g, T_END), repeats, 5)
    print(f'\ncost (CPU, median of {repeats} rounds; README example at 1.37 Hz)')
    print(f'state_at(one time)               {one * 1e6:9.1f} us')
    print(f'state_at(1000 times)             {vec * 1e6:9.1f} us ({vec / 1000 * 1e6:.2f} us '
          'a time)')
    print(f'simulate(..., t_eval=[t])        {rerun * 1e6:9.1f} us (state_at of one time: '
          f'{one / rerun:.2f}x)')
    print(f'positive_work() of the run       {work * 1e6:9.1f} us (the run itself: '
          f'{run * 1e6:.1f} us)')


def _trapezoid_work(tr: cs.Trajectory, start: float | None = None,
                    end: float | None = None) -> float:
    """What ``Trajectory.positive_work`` was before it was exact: the trapezoid of
    max(power, 0) over the run's samples in [start, end] (the cost compared against)."""
    t = tr.t
    a = float(t[0]) if start is None else float(start)
    b = float(t[-1]) if end is None else float(end)
    i0, i1 = int(np.searchsorted(t, a, 'left')), int(np.searchsorted(t, b, 'right'))
    power = np.maximum(np.sum(tr.linkage_force[i0:i1] * tr.rates[i0:i1], axis=1), 0.0)
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t[i0:i1])))


def work_cost_rows(repeats: int, scenes: int) -> float:
    """CPU of a sweep scene (benchmarks.sweep's spec, 20 periods) and of an optimiser
    evaluation (objective cot, 8 periods; scores node and ideal) with the exact positive work
    against the same with the trapezoid, interleaved in this process; returns the worst
    ratio (floor 1.1)."""
    from benchmarks.sweep import bench_spec

    spec = bench_spec(scenes)
    sweep_scenes = [spec.scene(spec.param_set(k)) for k in range(scenes)]
    base = scene_from_dict({'crawler': {'masses': [0.5, 1.0], 'mu': 0.3},
                            'gait': {'type': 'scallop', 'mean': 0.1, 'amplitude': 0.02,
                                     'frequency': 1.0, 'asymmetry': 0.3}})
    limits = ActuatorLimits()
    fam = family('scallop', base, limits)
    plant = plant_for(base, fam, limits)
    zs = [np.array(z) for z in ([0.035, 1.5, 0.42], [0.02, 1.37, 0.2], [0.04, 0.9, 0.3],
                                [0.025, 2.2, 0.25])]
    objs = {score: Objective(scene_to_dict(base), fam, limits, 'cot', 8, 40, score,
                             plant=plant.values if score == 'node' else None, stream=STREAM)
            for score in ('node', 'ideal')}
    jobs = {f'sweep scene ({scenes} of random_2body, 20 periods)':
            (lambda: [scene_figures(sc, 20, 50) for sc in sweep_scenes], scenes),
            'optimiser evaluation, score node (8 periods)':
            (lambda: [objs['node'].evaluate(z) for z in zs], len(zs)),
            'optimiser evaluation, score ideal (8 periods)':
            (lambda: [objs['ideal'].evaluate(z) for z in zs], len(zs))}
    exact = cs.Trajectory.positive_work
    print(f'\ncost of the exact positive work (CPU per item, median of {repeats} interleaved '
          'rounds; trapezoid = the figure before it was exact)')
    print(f'{"":>48} {"trapezoid":>10} {"exact":>10} {"ratio":>6}')
    worst = 0.0
    try:
        for name, (fn, n) in jobs.items():
            fn()                                         # warm: compiled gaits, imports
            times = {'trapezoid': [], 'exact': []}
            for _ in range(repeats):
                for mode in times:
                    cs.Trajectory.positive_work = exact if mode == 'exact' else _trapezoid_work
                    t0 = time.process_time()
                    fn()
                    times[mode].append((time.process_time() - t0) / n)
            old, new = (statistics.median(times[k]) for k in ('trapezoid', 'exact'))
            worst = max(worst, new / old)
            print(f'{name:>48} {old * 1e3:8.3f} ms {new * 1e3:7.3f} ms {new / old:6.2f}')
    finally:
        cs.Trajectory.positive_work = exact
    print(f'floor: exact positive work at most 1.1x the trapezoid\'s cost: worst {worst:.2f}x '
          f'{_verdict(worst, 1.1)}')
    return worst


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--quick', action='store_true', help='fewer frequencies, times, rounds')
    ap.add_argument('--repeats', type=int, default=7)
    args = ap.parse_args()
    freqs = [1.37, 2.0] if args.quick else [0.7, 1.0, 1.37, 2.0, 3.1]
    worst = [mean_speed_rows(freqs)]
    derivative_rows()
    worst.append(sweep_rows())
    worst.append(state_at_rows(20 if args.quick else 200))
    worst.append(positive_work_rows())
    cost_rows(3 if args.quick else args.repeats)
    cost = work_cost_rows(3 if args.quick else args.repeats, 20 if args.quick else 60)
    ok = (worst[0] <= 1e-12 and worst[1] <= 1e-12 and worst[2] <= 1e-13 and worst[3] <= 1e-12
          and cost <= 1.1)
    print(f'\nall floors: {"PASS" if ok else "FAIL"}')


if __name__ == '__main__':
    main()
