"""Speed of the exact method against scipy LSODA on the seed's penalised ODE (issue 14 floors).

Three scenes, 10 periods of l = 1 + 0.3 (sin wt + 0.3 sin 2wt): m = (1, 1), f = (0.5, 1) and
m = (1, 2), f = (1, 1) at 1 Hz; m = (1, 1), f = (5, 10) at 5 Hz. For each: median of 5 wall
times of ``simulate`` (built-in Fourier gait, and the same gait as a Custom of math lambdas
without hints), and of LSODA (rtol = atol = 1e-10, n = 1e8, analytic Jacobian) on

    M y' + clip(n y, -f0, f0) + clip(n (y + l'), -f1, f1) = -m1 l'',   x0' = y

(MODEL.md s. 4), all in this process; ratios LSODA / exact. Errors of x0(T): LSODA and the
Custom run against the built-in exact run; the built-in run against itself without the
periodic skip. The cold start is the first ``simulate`` in a fresh interpreter (subprocess).

    nice .venv/bin/python -m benchmarks.exact_speed
"""
from __future__ import annotations

import math
import statistics
import subprocess
import sys
import time

from scipy.integrate import solve_ivp

import crawler_sim as cs

SCENES = [((1.0, 1.0), (0.5, 1.0), 1.0), ((1.0, 2.0), (1.0, 1.0), 1.0),
          ((1.0, 1.0), (5.0, 10.0), 5.0)]
N_PEN = 1e8


def fourier(freq: float):
    return cs.gaits.Fourier(1.0, ([0.0, 0.0], [0.3, 0.09]), freq)


def custom(freq: float):
    w = 2 * math.pi * freq
    return cs.gaits.Custom(
        lambda t: 1 + 0.3 * (math.sin(w * t) + 0.3 * math.sin(2 * w * t)),
        lambda t: 0.3 * w * (math.cos(w * t) + 0.6 * math.cos(2 * w * t)),
        lambda t: -0.3 * w * w * (math.sin(w * t) + 1.2 * math.sin(2 * w * t)))


def lsoda(m, f, freq, T):
    m0, m1 = m
    f0, f1 = f
    M = m0 + m1
    w = 2 * math.pi * freq
    n = N_PEN

    def ld(t):
        return 0.3 * w * (math.cos(w * t) + 0.6 * math.cos(2 * w * t))

    def ldd(t):
        return -0.3 * w * w * (math.sin(w * t) + 1.2 * math.sin(2 * w * t))

    def rhs(t, s):
        y = s[1]
        r0 = min(max(n * y, -f0), f0)
        r1 = min(max(n * (y + ld(t)), -f1), f1)
        return [y, (-m1 * ldd(t) - r0 - r1) / M]

    def jac(t, s):
        y = s[1]
        d = (n if abs(n * y) < f0 else 0.0) + (n if abs(n * (y + ld(t))) < f1 else 0.0)
        return [[0.0, 1.0], [0.0, -d / M]]

    sol = solve_ivp(rhs, (0.0, T), [0.0, 0.0], method='LSODA', jac=jac, rtol=1e-10,
                    atol=1e-10)
    return float(sol.y[0, -1])


def timed(fn, reps=5):
    """Median wall time and median CPU time of the process (the CPU figure is the fair one on
    a shared machine: another process's load stretches wall time, not this one's CPU time)."""
    out, wall, cpu = None, [], []
    for _ in range(reps):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu), out


def cold_start() -> float:
    code = ('import time; t0 = time.perf_counter(); import crawler_sim as cs; '
            't1 = time.perf_counter(); '
            'cs.simulate(cs.Crawler([1, 1], [0.5, 1]), cs.gaits.Fourier(1.0, ([0, 0], '
            '[0.3, 0.09]), 1.0), 10.0, t_eval=[0, 10]); '
            'print(t1 - t0, time.perf_counter() - t1)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout.split()
    return float(out[0]), float(out[1])


def main() -> None:
    imp, first = cold_start()
    print(f'cold start: import crawler_sim {imp * 1e3:.0f} ms, first simulate {first * 1e3:.1f} ms')
    print('wall ms (CPU ms) medians of 5; ratio = LSODA / exact on CPU time')
    print(f'{"scene":>30} {"lsoda":>15} {"exact":>15} {"ratio":>6} {"custom":>17} '
          f'{"ratio":>6} {"err lsoda":>9} {"err custom":>10} {"err skip":>9}')
    for m, f, freq in SCENES:
        T = 10.0 / freq
        crawler = cs.Crawler(list(m), list(f))
        g, gc = fourier(freq), custom(freq)

        def run(gait, skip=True):
            return float(cs.simulate(crawler, gait, T, t_eval=[0.0, T],
                                     periodic_skip=skip).x[-1, 0])
        t_ls, c_ls, x_ls = timed(lambda: lsoda(m, f, freq, T))
        t_ex, c_ex, x_ex = timed(lambda: run(g))
        t_cu, c_cu, x_cu = timed(lambda: run(gc))
        x_ns = run(g, skip=False)
        name = f'm={m} f={f} {freq:g}Hz'
        print(f'{name:>30} {t_ls * 1e3:7.1f} ({c_ls * 1e3:5.1f}) {t_ex * 1e3:7.2f} '
              f'({c_ex * 1e3:5.2f}) {c_ls / c_ex:6.1f} {t_cu * 1e3:8.1f} ({c_cu * 1e3:6.1f}) '
              f'{c_ls / c_cu:6.1f} {abs(x_ls - x_ex):9.1e} {abs(x_cu - x_ex):10.1e} '
              f'{abs(x_ns - x_ex):9.1e}')


if __name__ == '__main__':
    main()
