"""Draw docs/speed_map.png: Wagner & Lauga's two asymmetry conditions on one speed map.

    PYTHONPATH=. .venv/bin/python docs/speed_map.py [--out docs/speed_map.png] [--workers N]

Runs config/sweeps/wagner_lauga.yaml (two equal masses, isotropic Coulomb friction, body 0 at
mu = 0.3 and body 1 swept; a Scallop stroke whose extension takes the fraction r of the period)
and maps the steady mean speed over the friction ratio mu_1 / mu_0 and r. It also prints the
largest |speed| on the two zero lines, which the model's symmetries predict exactly:
equal frictions (the bodies swap under x -> -x) and r = 0.5 (the stroke is antisymmetric over a
half period, so V(t + T/2) = -V(t) in the steady state).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import sys

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from crawler_sim.sweep import load_spec, sweep  # noqa: E402
from crawler_sim.sweep.figures import speed_map  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', default=str(REPO / 'docs' / 'speed_map.png'))
    ap.add_argument('--workers', type=int, default=None)
    args = ap.parse_args()
    spec = load_spec(REPO / 'config' / 'sweeps' / 'wagner_lauga.yaml')
    df = sweep(spec, workers=args.workers, progress=True)
    mu0 = spec.base['crawler']['mu'][0]
    ratio = df['crawler.mu[1]'].to_numpy(dtype=float) / mu0
    r = df['gait.asymmetry'].to_numpy(dtype=float)
    v = df['mean_speed'].to_numpy(dtype=float)
    on_equal, on_half = np.abs(v[ratio == 1.0]).max(), np.abs(v[r == 0.5]).max()
    off = (ratio != 1.0) & (r != 0.5)
    print(f'{len(df)} scenes, {int((df["error"] != "").sum())} errors, '
          f'{int((~df["steady"].astype(bool)).sum())} not steady')
    print(f'max |mean speed| with equal frictions: {on_equal:.3g} m/s')
    print(f'max |mean speed| with r = 0.5:         {on_half:.3g} m/s')
    print(f'max |mean speed| with both asymmetries: {np.abs(v[off]).max():.3g} m/s')

    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.2, 5.0))
    speed_map(df, 'crawler.mu[1]', 'gait.asymmetry', args.out, ax=ax,
              x_transform=lambda x: x / mu0, x_label='friction ratio mu_1 / mu_0',
              y_label='stroke asymmetry r (fraction of the period spent extending)',
              title='Steady mean speed of two equal masses (Wagner & Lauga\'s conditions)',
              zero_contour=False)
    ax.set_xscale('log')
    ticks = [1 / 3, 0.5, 1.0, 2.0, 3.0]
    ax.set_xticks(ticks, ['1/3', '1/2', '1', '2', '3'])
    ax.minorticks_off()
    ax.axvline(1.0, color='k', ls='--', lw=0.8)
    ax.axhline(0.5, color='k', ls='--', lw=0.8)
    ax.text(1.02, 0.13, 'equal frictions: 0', fontsize='small', rotation=90)
    ax.text(0.36, 0.51, 'r = 0.5 (antisymmetric stroke): 0', fontsize='small')
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    plt.close(fig)
    print(args.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
