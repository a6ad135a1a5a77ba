"""Method "implicit" with stiction (issue 40): observed orders and the cost of the Rule S path.

Orders: the error at h, h/2, h/4, h/8 (h = 4 ms) and the slope of log error against log h, on
STICTION.md T2a (X(2) against the hand value sqrt5 / (3.6 g)), T3 (the sup error of the
positions over [0, 18] s against the hand closed form; at whole periods the error is second
order), T5 ('margin': X(8) - X(0) against -1/4; Rule S: x_0(8) - x_0(0) against 0), and the
random scenes of test/core/solvers/test_stiction_implicit.py against the exact method with
stiction (sup error of the positions at 41 samples over 4 s).

Cost: CPU time per step of the Rule S path (static up to 2x kinetic) against the convex path
(the same scene with static = kinetic), medians of rounds run in turn in this process, p = 2,
3 and 8 (a Scallop stroke of 2 Hz, 20 s at dt = 1 ms).

    .venv/bin/python -m benchmarks.stiction_implicit [--repeats 7]
"""
from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

import crawler_sim as cs
from crawler_sim.core.gaits import PiecewiseParabolic

G = 9.81
DTS = np.array([4e-3, 2e-3, 1e-3, 5e-4])


def slope(errs: list[float]) -> float:
    """Observed order: the slope of log |error| against log h."""
    return float(np.polyfit(np.log(DTS), np.log(np.abs(errs)), 1)[0])


def t2a() -> list[float]:
    c = cs.Crawler([1.0, 2.0], slope=math.atan(0.5), mu=[0.5, 0.35], mu_static=[0.7, 0.55])
    g = PiecewiseParabolic([0.0, 1.0], [0.0], 0.3, 0.0)
    hand = math.sqrt(5.0) / (3.6 * G)
    return [float(np.diff(cs.simulate(c, g, 2.0, 'implicit', dt=float(h), v0=1.0,
                                      t_eval=[0.0, 2.0]).com)[0] - hand) for h in DTS]


def t3() -> list[float]:
    from test.core.solvers.test_stiction_implicit import _t3, _t3_hand
    c, g = _t3()
    grid = np.linspace(0.0, 18.0, 181)
    hand = _t3_hand(grid)
    return [float(np.abs(cs.simulate(c, g, 18.0, 'implicit', dt=float(h), t_eval=grid).x
                         - hand).max()) for h in DTS]


def t5(rule: str) -> list[float]:
    c = cs.Crawler([1.0, 1.0], [1.0, 1.0], static_friction=[2.0, 2.5])
    g = PiecewiseParabolic([0, 2, 4], [0.5, -0.5], 1.0, -0.5)
    out = []
    for h in DTS:
        tr = cs.simulate(c, g, 8.0, 'implicit', dt=float(h), t_eval=[0.0, 8.0],
                         stiction_rule=rule)
        out.append(float(tr.com[-1] - tr.com[0] + 0.25) if rule == 'margin'
                   else float(tr.x[-1, 0] - tr.x[0, 0]))
    return out


def random_scene(seed: int) -> list[float]:
    from test.core.solvers.test_stiction_implicit import _random_scene
    c, g, _ = _random_scene(seed)
    grid = np.linspace(0.0, 4.0, 41)
    ex = cs.simulate(c, g, 4.0, t_eval=grid)
    return [float(np.abs(cs.simulate(c, g, 4.0, 'implicit', dt=float(h), t_eval=grid).x
                         - ex.x).max()) for h in DTS]


def cost(p: int, repeats: int) -> tuple[float, float]:
    """Median CPU seconds per step (Rule S path, convex path) of a 20 s run at dt = 1 ms."""
    m = np.linspace(0.5, 1.0, p)
    fk = 0.3 * G * m
    sticky = cs.Crawler(m, fk, static_friction=fk * np.linspace(2.0, 1.2, p))
    convex = cs.Crawler(m, fk)
    gait = cs.gaits.Scallop(mean=0.1, amplitude=0.02, frequency=2.0, asymmetry=0.2,
                            phase=np.linspace(0.0, -2.0, p - 1))
    times: dict[str, list[float]] = {'rule_s': [], 'convex': []}
    for _ in range(repeats + 1):
        for name, c in (('rule_s', sticky), ('convex', convex)):
            t0 = time.process_time()
            cs.simulate(c, gait, 20.0, 'implicit', dt=1e-3, t_eval=[0.0, 20.0])
            times[name].append((time.process_time() - t0) / 20000)
    return statistics.median(times['rule_s'][1:]), statistics.median(times['convex'][1:])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=7)
    args = ap.parse_args()
    print('orders (errors at h = 4, 2, 1, 0.5 ms)')
    cases = [('T2a X(2)', t2a()), ('T3 sup |x|', t3()), ("T5 'margin' X(8)", t5('margin'))]
    cases += [(f'random scene {s} vs exact', random_scene(s)) for s in (3, 4, 5, 6, 7)]
    for name, errs in cases:
        print(f'  {name:26s} ' + ' '.join(f'{e:10.3e}' for e in errs)
              + f'   slope {slope(errs):.3f}')
    print(f"  T5 Rule S x_0(8) - x_0(0): {max(abs(e) for e in t5('incumbent')):.1e} "
          '(all h; hand value 0)')
    print('cost per step, CPU time (medians)')
    for p in (2, 3, 8):
        a, b = cost(p, args.repeats)
        print(f'  p = {p}: Rule S {a * 1e9:7.1f} ns, convex {b * 1e9:7.1f} ns, '
              f'ratio {a / b:.2f}', flush=True)


if __name__ == '__main__':
    main()
