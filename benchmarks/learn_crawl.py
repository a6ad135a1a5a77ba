"""Learning to crawl from scratch on crawler_sim/Crawl-v0 (issue 41): augmented random search
(ARS V1-t, Mania, Guy and Recht 2018), numpy only, over an open-loop periodic policy, on the
crawler of config/scenes/scallop_2body.yaml; then the learned gait played through the plant
beside the best stroke of ``crawler-sim optimize config/scenes/scallop_2body.yaml --family
stroke`` (seed 0, scored through sim_node's plant, as the command does).

Policy (8 numbers theta, all 0 at the start: the crawler holds its length; nothing comes from
an optimised stroke): frequency f = 0.5 + 4.5 sigmoid(theta_0) Hz, its period rounded to m
whole control periods (0.02 s each), and at control period k the phase ph = 2 pi (k mod m) / m
and the action a = clip(theta_1 + sum_j theta_{2j} cos(j ph) + theta_{2j+1} sin(j ph), -1, 1),
j = 1..3: a target length, sent as sim_node's linkage_cmd.
A clipped series can be a square wave: bang-bang targets the servo follows at its limits.

Each ARS iteration evaluates theta +- nu delta_i for ``--directions`` Gaussian directions and
theta itself in ONE vector env (``gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")``, 2 N + 1 crawlers stepped together), keeps the best ``--top`` directions
and steps theta along their return differences divided by the returns' standard deviation. The
return of an episode is its mean reward after a warm-up (``--warmup``): the mean forward
speed of the centre of mass [m/s] (minus a negligible control cost) once the gait repeats.

Steady speed of a gait "through the plant": a single CrawlEnv run for ``--play`` s, the centre
of mass's displacement over its last half divided by that time. Floor (issue 41): >= 80 % of
the optimiser's best steady speed.

Reproduce (about two minutes of CPU on one core)::

    .venv/bin/python -m benchmarks.learn_crawl [--iterations 80] [--seed 0] \
        [--figure docs/gym_learning.png]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
import time

import gymnasium as gym
import numpy as np

import crawler_sim  # noqa: F401  (registers crawler_sim/Crawl-v0)
from crawler_sim.core.scene import load_scene

SCENE = Path(__file__).resolve().parents[1] / 'config' / 'scenes' / 'scallop_2body.yaml'
HARMONICS = 3
CONTROL_PERIOD = 0.02


def env_kwargs(scene_path: Path = SCENE) -> dict:
    """The environment of the scene's crawler: the action range the optimiser's stroke family
    spans (mean 0.1 m +- 0.9 x 0.1 m), the node's actuator defaults."""
    scene = load_scene(scene_path)
    mean = float(np.atleast_1d(scene.gait_spec['mean'])[0])
    return {'crawler': _mapping(scene_path),
            'control_period': CONTROL_PERIOD, 'min_length': 0.1 * mean,
            'max_length': 1.9 * mean, 'initial_lengths': mean}


def _mapping(scene_path: Path) -> dict:
    """The scene file's crawler mapping, as written (scene.crawler_from_mapping reads it)."""
    import yaml
    return yaml.safe_load(scene_path.read_text())['scene']['crawler']


def frequency(theta: np.ndarray) -> np.ndarray:
    """Stroke frequency [Hz] of parameters theta (..., 8)."""
    return 0.5 + 4.5 / (1.0 + np.exp(-theta[..., 0]))


def steps_per_period(theta: np.ndarray) -> np.ndarray:
    """The stroke period in control periods: 1 / (f CONTROL_PERIOD) rounded, so that the
    commands repeat exactly (a period that is not a whole number of control periods makes the
    sampled stroke beat: its speed drifts over seconds and an episode's return with it)."""
    return np.maximum(2, np.round(1.0 / (frequency(theta) * CONTROL_PERIOD)))


def actions(theta: np.ndarray, k: int) -> np.ndarray:
    """Actions (n, 1) of n policies theta (n, 8) at control period k of the episode."""
    m = steps_per_period(theta)
    ph = 2.0 * np.pi * (k % m) / m
    k = np.arange(1, HARMONICS + 1)
    a = theta[:, 1] + np.sum(theta[:, 2::2] * np.cos(k * ph[:, None])
                             + theta[:, 3::2] * np.sin(k * ph[:, None]), axis=1)
    return np.clip(a, -1.0, 1.0)[:, None]


def returns(vec, thetas: np.ndarray, steps: int, warmup: int, seed: int) -> np.ndarray:
    """Mean reward of each policy over one episode of ``steps`` control periods from rest,
    the first ``warmup`` left out: what a gait does once it repeats. (With them, a policy is
    paid for the one-off motion of the centre of mass while the crawler first contracts from
    its initial length, which a steady gait never repeats.)"""
    vec.reset(seed=seed)
    total = np.zeros(len(thetas))
    for k in range(steps):
        _, r, _, _, _ = vec.step(actions(thetas, k))
        if k >= warmup:
            total += r
    return total / (steps - warmup)


def ars(iterations: int, directions: int, top: int, step: float, noise: float,
        episode: float, warmup: float, seed: int, log=print) -> tuple[np.ndarray, list[dict]]:
    """ARS V1-t from theta = 0, the step size decaying as 1 / (1 + iteration / 40); returns the
    best theta evaluated (the environment is deterministic: its return is exact, not an
    estimate) and the history of (iteration, return of theta, CPU s)."""
    rng = np.random.default_rng(seed)
    steps = round(episode / CONTROL_PERIOD)
    vec = gym.make_vec('crawler_sim/Crawl-v0', num_envs=2 * directions + 1,
                       vectorization_mode='vector_entry_point', max_episode_steps=steps + 1,
                       **env_kwargs())
    theta = np.zeros(2 + 2 * HARMONICS)
    best_theta, best_return = theta, -np.inf
    history = []
    t0 = time.process_time()
    for it in range(iterations):
        delta = rng.standard_normal((directions, theta.size))
        thetas = np.vstack([theta + noise * delta, theta - noise * delta, theta[None]])
        r = returns(vec, thetas, steps, round(warmup / CONTROL_PERIOD), seed)
        plus, minus, here = r[:directions], r[directions:2 * directions], r[-1]
        if here > best_return:
            best_theta, best_return = theta, here
        history.append({'iteration': it, 'speed': here, 'cpu_s': time.process_time() - t0,
                        'frequency': float(frequency(theta))})
        log(f'iteration {it:3d}: mean speed of theta {1e3 * here:7.3f} mm/s, '
            f'{steps_per_period(theta):.0f} steps a period, CPU {history[-1]["cpu_s"]:.0f} s')
        best = np.argsort(np.maximum(plus, minus))[::-1][:top]
        sigma = np.std(np.concatenate([plus[best], minus[best]])) or 1.0
        alpha = step / (1.0 + it / 40.0)
        theta = theta + alpha / (top * sigma) * ((plus[best] - minus[best]) @ delta[best])
    return best_theta, history


def steady_speed(policy, play: float) -> tuple[float, np.ndarray, np.ndarray]:
    """Steady speed [m/s] of ``policy(k) -> action`` (k: control period) played through one CrawlEnv for ``play``
    seconds (displacement of the centre of mass over the second half / its duration), and the
    lengths [m] at each step with their times."""
    env = gym.make('crawler_sim/Crawl-v0', max_episode_steps=None, **env_kwargs())
    _, info = env.reset(seed=0)
    n = round(play / CONTROL_PERIOD)
    xs, ls = [info['x_position']], []
    for k in range(n):
        obs, _, term, trunc, info = env.step(policy(k))
        xs.append(info['x_position'])
        ls.append(obs[0])
        assert not term
    half = n // 2
    return ((xs[-1] - xs[half]) / ((n - half) * CONTROL_PERIOD),
            np.arange(1, n + 1) * CONTROL_PERIOD, np.array(ls))


def optimiser_best() -> dict:
    """``crawler-sim optimize config/scenes/scallop_2body.yaml --family stroke`` (its defaults,
    seed 0): the best stroke's parameters and steady speed as sim_node plays it (the
    optimiser's own score, through the plant), and l(t) of that run (``simulate_as_node``)."""
    from crawler_sim.core.plant.streams import simulate_as_node
    from crawler_sim.sweep.optimize import optimize

    res = optimize(load_scene(SCENE), family_name='stroke', seed=0)
    T = res.gait.period
    tr = simulate_as_node(res.plant, res.gait, res.stream, 4 * T, dt=T / 200)
    return {'params': res.params, 'mean_speed': float(res.best['mean_speed']),
            't': tr.t, 'l': tr.lengths[:, 0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--iterations', type=int, default=80)
    ap.add_argument('--directions', type=int, default=16)
    ap.add_argument('--top', type=int, default=8)
    ap.add_argument('--step', type=float, default=0.15)
    ap.add_argument('--noise', type=float, default=0.3)
    ap.add_argument('--episode', type=float, default=8.0, help='s of sim time per episode')
    ap.add_argument('--warmup', type=float, default=3.0,
                    help='s at the start of an episode left out of its return')
    ap.add_argument('--play', type=float, default=30.0, help='s played to score a gait')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--figure', type=Path, default=None)
    ap.add_argument('--json', type=Path, default=None)
    args = ap.parse_args()

    theta, history = ars(args.iterations, args.directions, args.top, args.step, args.noise,
                         args.episode, args.warmup, args.seed)
    learned, t_l, l_l = steady_speed(lambda k: actions(theta[None], k)[0], args.play)
    opt = optimiser_best()
    ratio = learned / opt['mean_speed']
    print(f'learned policy: f = {1 / (steps_per_period(theta) * CONTROL_PERIOD):.3f} Hz, theta = '
          f'{np.round(theta, 3).tolist()}')
    print(f'steady speed through the plant: learned {1e3 * learned:.3f} mm/s; optimiser '
          f'(--family stroke, seed 0) {1e3 * opt["mean_speed"]:.3f} mm/s {opt["params"]}; '
          f'ratio {ratio:.3f} (floor 0.8); ARS CPU {history[-1]["cpu_s"]:.0f} s')
    if args.json:
        args.json.write_text(json.dumps({'theta': theta.tolist(), 'history': history,
                                         'learned_speed': learned, 'optimiser': {
                                             k: opt[k] for k in ('params', 'mean_speed')},
                                         'ratio': ratio}, indent=1))
    if args.figure:
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.6))
        a1.plot([h['iteration'] for h in history], [1e3 * h['speed'] for h in history], 'k.-')
        a1.axhline(1e3 * opt['mean_speed'], color='tab:red', ls='--',
                   label='optimiser best stroke (through the plant)')
        a1.axhline(0.8e3 * opt['mean_speed'], color='tab:red', ls=':', label='80 %')
        a1.set_xlabel(f'ARS iteration ({2 * args.directions + 1} episodes of {args.episode:g} s each)')
        a1.set_ylabel('mean speed of the policy [mm/s]')
        a1.legend(loc='lower right', fontsize=8)
        a1.set_title('learning from scratch (episode return)')
        T = 2.0 * float(steps_per_period(theta)) * CONTROL_PERIOD
        sel = t_l >= args.play - T
        a2.plot(t_l[sel] - t_l[sel][0], 1e3 * l_l[sel], 'k', label='learned policy (l, sampled each control period)')
        To = 1.0 / opt['params']['frequency']
        so = opt['t'] >= opt['t'][-1] - 2 * To
        a2.plot(opt['t'][so] - opt['t'][so][0], 1e3 * opt['l'][so], color='tab:red',
                label='optimiser best stroke (l as sim_node plays it)')
        a2.set_xlabel('t [s] (two periods, steady)')
        a2.set_ylabel('linkage length l [mm]')
        a2.set_ylim(top=1.45 * a2.get_ylim()[1])          # room for the legend above
        a2.legend(fontsize=8, loc='upper center')
        a2.set_title('the gaits as the servo makes them')
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
        print(f'figure: {args.figure}')


if __name__ == '__main__':
    main()
