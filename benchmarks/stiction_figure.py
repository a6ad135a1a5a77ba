"""Stiction's figures for docs/stiction.md: the inchworm, the rule choice, zero drift vs creep.

    python -m benchmarks.stiction_figure [--out docs/stiction.png]

Prints every number the page quotes and draws its figure (three panels):

1. STICTION.md's T3 inchworm (bang-bang stroke, bristle-like friction), exact method with
   static > kinetic and with static = kinetic: displacement per period, mean speed, stick
   fractions.
2. T5's stroke reversal under Rule S (``stiction_rule='incumbent'``), ``'margin'`` and the
   kinetic model, and ``initial_stuck`` on a start at a coincident rest.
3. Drift at rest under a steady push at 95 % of the static capacity (a rigid pair on a slope,
   kinetic = 0.5 x static): the exact method over 10 s and 1e4 s, against two regularised
   friction laws with ONE coefficient (the static one, the most favourable choice for them),
   integrated here with SciPy's Radau (rtol 1e-10): a MuJoCo-style linear creep region
   F = f_s clip(v / v_c, -1, 1) and a smooth F = f_s tanh(v / v_c). Their creep speed at a
   push P is v_c P / f_s and v_c atanh(P / f_s), so their drift is set by v_c.
4. The exact method against the independent reference (test/support/stiction_reference.py) on
   the agreement test's scenes: 32 random ones and the 7 where the rules differ, both rules.
"""
from __future__ import annotations

import argparse
import math

import numpy as np
from scipy.integrate import solve_ivp

import crawler_sim as cs
from crawler_sim import gaits

G = 9.81
A3 = 2.5                      # T3's stroke acceleration [m/s^2]
PUSH = 0.95                   # push / static capacity in the drift comparison
V_CREEP = (1e-3, 1e-4, 1e-5)  # regularisation velocities v_c [m/s]


def inchworm() -> dict:
    """T3 through the exact method, with and without stiction, over three periods of 6 s."""
    gait = gaits.PiecewiseParabolic([0, 1, 2, 3, 4, 5, 6], [A3, -A3, 0, -A3, A3, 0], l0=1.0)
    out = {}
    for name, (fs, fsb) in {'stiction': (2.0, 5.0), 'kinetic': (1.0, 4.0)}.items():
        crawler = cs.Crawler([1.0, 1.0], 1.0, 4.0, static_friction=fs,
                             static_friction_backward=fsb)
        run = cs.simulate(crawler, gait, 18.0)
        out[name] = dict(run=run, per_period=run.displacement / 3.0,
                         speed=run.mean_speed(gait.period), stick=run.stick_fraction)
    return out


def rule_choice() -> dict:
    """T5 (x_0(8) - x_0(0) and X(8) - X(0) per rule) and initial_stuck at a coincident rest."""
    t5 = gaits.PiecewiseParabolic([0, 2, 4], [0.5, -0.5], l0=1.0, v0=-0.5)
    stiff = cs.Crawler([1.0, 1.0], 1.0, static_friction=[2.0, 2.5])
    kinetic = cs.Crawler([1.0, 1.0], 1.0)
    out = {}
    for name, crawler, rule in (('Rule S', stiff, 'incumbent'), ('margin', stiff, 'margin'),
                                ('kinetic', kinetic, 'incumbent')):
        run = cs.simulate(crawler, t5, 8.0, stiction_rule=rule)
        com = run.state_at([0.0, 8.0]).x @ np.array([0.5, 0.5])
        out[name] = dict(run=run, dx0=float(run.state_at(8.0).x[0] - run.state_at(0.0).x[0]),
                         dX=float(com[1] - com[0]))
    # the same stroke shifted by 1 s: t = 0 is the reversal, both bodies at rest
    shifted = gaits.PiecewiseParabolic([0, 1, 3, 4], [0.5, -0.5, 0.5], l0=1.0)
    out['initial_stuck'] = {
        str(b): float(cs.simulate(stiff, shifted, 1.0, initial_stuck=b).state_at(1.0).x[0])
        for b in (None, 0, 1)}
    return out


def _creep(law: str, v_c: float, f_s: float, push: float, M: float, t_end: float) -> float:
    """Drift [m] of a rigid body of mass M from rest under ``push`` [N] with a regularised
    friction law of static capacity f_s [N] and regularisation velocity v_c, after t_end."""
    def friction(v: float) -> float:
        if law == 'linear':     # MuJoCo-style: a linear (viscous) region |v| < v_c
            return f_s * min(1.0, max(-1.0, v / v_c))
        return f_s * math.tanh(v / v_c)

    sol = solve_ivp(lambda t, y: [y[1], (push - friction(y[1])) / M], (0.0, t_end), [0.0, 0.0],
                    method='Radau', rtol=1e-10, atol=1e-14, jac=lambda t, y: [
                        [0.0, 1.0], [0.0, -(f_s / v_c) * (
                            1.0 if law == 'linear' else 1.0 / math.cosh(y[1] / v_c) ** 2) / M]])
    return float(sol.y[0, -1])


def drift() -> dict:
    """Rigid pair (1 + 1 kg) on a slope: mu_static 0.6, mu 0.3, tan(slope) = 0.95 * 0.6."""
    mu_s, mu_k = 0.6, 0.3
    slope = math.atan(PUSH * mu_s)
    crawler = cs.Crawler([1.0, 1.0], mu=mu_k, mu_static=mu_s, slope=slope)
    rigid = gaits.Sinusoid(0.3, 0.0, 1.0)
    M = 2.0
    f_s = mu_s * M * G * math.cos(slope)
    push = M * G * math.sin(slope)                  # downhill, = 0.95 f_s
    out = {'ratio': push / f_s, 'kinetic_ratio': mu_k / mu_s, 'exact': {}, 'creep': {}}
    for t_end in (10.0, 1e4):
        run = cs.simulate(crawler, rigid, t_end)
        out['exact'][t_end] = float(np.max(np.abs(run.x - run.x[0])))
    for law in ('linear', 'tanh'):
        for v_c in V_CREEP:
            out['creep'][law, v_c] = {t: _creep(law, v_c, f_s, push, M, t) for t in (10.0, 1e4)}
    out['curve'] = {law: solve_curve(law, 1e-4, f_s, push, M) for law in ('linear', 'tanh')}
    return out


def solve_curve(law: str, v_c: float, f_s: float, push: float, M: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """(t, drift) over 10 s, for the figure."""
    t = np.linspace(0.0, 10.0, 41)
    return t, np.array([_creep(law, v_c, f_s, push, M, s) if s > 0 else 0.0 for s in t])


def agreement() -> dict:
    """Largest |x_exact - x_reference| [m] per scene set and rule, and the scenes above 1e-9."""
    from test.support.stiction_reference import (RULE_SEEDS, exact_positions, random_scene,
                                                 reference_positions)
    sets = {'random (32)': [(s, random_scene(s)) for s in range(32)],
            'rules differ (7)': [(s, random_scene(s, family='reversal')) for s in RULE_SEEDS]}
    out = {}
    for name, scenes in sets.items():
        for rule in ('incumbent', 'margin'):
            errs = [(seed, sc['family'], float(np.max(np.abs(
                exact_positions(sc, rule) - reference_positions(sc, rule))))) for seed, sc in scenes]
            out[name, rule] = (max(e for *_, e in errs),
                               [f'{fam} seed {seed}: {e:.2g} m' for seed, fam, e in errs if e > 1e-9])
    return out


def report(ins: dict, rules: dict, dr: dict, agree: dict) -> None:
    """Print the figures the page quotes."""
    print('1. T3 inchworm (exact, 3 periods of 6 s)')
    for name, r in ins.items():
        print(f'   {name:8s} displacement/period {r["per_period"]:.12g} m, mean speed '
              f'{r["speed"]:.12g} m/s, stick fraction {np.round(r["stick"], 6).tolist()}')
    print('2. T5 stroke reversal, t = 8 s')
    for name in ('Rule S', 'margin', 'kinetic'):
        r = rules[name]
        print(f'   {name:8s} x_0(8) - x_0(0) = {r["dx0"]:.12g} m, X(8) - X(0) = {r["dX"]:.12g} m')
    print('   start at the reversal (both at rest), x_0(1) - x_0(0) by initial_stuck:',
          {k: round(v, 12) for k, v in rules['initial_stuck'].items()})
    print(f'3. drift at rest, push {dr["ratio"]:.3f} x static capacity, kinetic '
          f'{dr["kinetic_ratio"]:.2f} x static')
    for t_end, d in dr['exact'].items():
        print(f'   exact, max |x(t) - x(0)| over {t_end:g} s: {d!r} m')
    for (law, v_c), d in dr['creep'].items():
        print(f'   {law:6s} v_c = {v_c:g} m/s: {d[10.0] * 1e3:.4g} mm in 10 s, '
              f'{d[1e4]:.4g} m in 1e4 s')
    print('4. exact vs the independent reference, positions at 5 times over 3 periods')
    for (name, rule), (worst, bad) in agree.items():
        print(f'   {name:16s} {rule:9s} max |dx| = {worst:.2g} m; above 1e-9 m: '
              f'{bad or "none"}')


def figure(ins: dict, rules: dict, dr: dict):
    """The page's three panels (matplotlib Figure)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=(13, 3.8))
    ax = fig.subplots(1, 3)
    t = np.linspace(0.0, 18.0, 721)
    for name, style in (('stiction', '-'), ('kinetic', '--')):
        x = ins[name]['run'].state_at(t).x
        ax[0].plot(t, x[:, 0], style, label=f'{name}: {ins[name]["per_period"]:.4g} m/period')
    ax[0].set(title='T3 inchworm: body 0', xlabel='t [s]', ylabel='x_0 [m]')
    ax[0].legend(fontsize=8)
    t = np.linspace(0.0, 8.0, 401)
    for name, style in (('Rule S', '-'), ('margin', '--'), ('kinetic', ':')):
        x = rules[name]['run'].state_at(t).x
        ax[1].plot(t, x @ np.array([0.5, 0.5]), style, label=name)
    ax[1].set(title='T5 stroke reversal: centre of mass', xlabel='t [s]', ylabel='X [m]')
    ax[1].legend(fontsize=8)
    for law, style in (('linear', '-'), ('tanh', '--')):
        tc, d = dr['curve'][law]
        ax[2].plot(tc, d * 1e3, style, label=f'regularised ({law}), v_c = 0.1 mm/s')
    ax[2].axhline(0.0, color='k', label='exact (stiction): 0')
    ax[2].set(title=f'drift at rest, push {PUSH:.0%} of static', xlabel='t [s]',
              ylabel='drift [mm] (downhill)')
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    return fig


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', default='docs/stiction.png', help='figure file (PNG)')
    args = ap.parse_args()
    ins, rules, dr = inchworm(), rule_choice(), drift()
    report(ins, rules, dr, agreement())
    from crawler_sim.bag.plot import save
    print('wrote', save(figure(ins, rules, dr), args.out))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
