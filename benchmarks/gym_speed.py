"""Speed of crawler_sim/Crawl-v0 (issue 41) against MuJoCo's Swimmer-v5, side by side in one
process, CPU time (``time.process_time``), median of ``--repeats`` runs, the two alternated.

* single env, p = 2, ``control_period=0.04`` (Swimmer's step: frame_skip 4 x 0.01 s), both
  through ``gymnasium.make`` (wrappers included), uniform random actions drawn beforehand, a
  reset at each truncation: steps per CPU second and the ratio crawler / Swimmer (floor 2);
* vector env, p = 2, ``control_period=0.01``, ``--envs`` 256 envs through
  ``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``: env-steps per CPU
  second (floor 1e5, goal 1e6).

Without mujoco (``pip install ".[bench]"``) the Swimmer line gives the issue's measured
9,400 steps/s, labelled as cited. Reproduce::

    .venv/bin/python setup.py build_ext --inplace -q
    .venv/bin/python -m benchmarks.gym_speed [--repeats 5] [--steps 4000] [--envs 256]
    .venv/bin/python -m benchmarks.gym_speed --profile      # cProfile of the vector step
    .venv/bin/python -m benchmarks.gym_speed --breakdown    # where one env-step's time goes
    .venv/bin/python -m benchmarks.gym_speed --compare      # compiled step vs Python path

``--breakdown``: one env-step (control_period 0.01, 10 ticks) through the Python path the
plant's compiled step stands for, taken apart (the command, the actuator run, the exact
solver's table of the 10 constant-jerk pieces, the exact integration, the read of x, v and
contact the env observes), each timed in CPU time, against the compiled step
(``CrawlPlant.step``) alternated with it, the states checked bit for bit.

``--compare``: the single and vector figures with the engines' compiled step
(``core/plant/_batch``) and with it turned off (every engine through ``Actuator.run``,
``PiecewiseCubic``, ``Stepper.advance``), alternated in one process.
"""
from __future__ import annotations

import argparse
import cProfile
import pstats
import statistics
import time

import gymnasium as gym
import numpy as np

import crawler_sim  # noqa: F401  (registers crawler_sim/Crawl-v0)

SWIMMER_CITED = 9400.0        # steps/s, issue 41 (Swimmer-v5 through gymnasium.make)


def _single_rate(env, steps: int, seed: int = 0) -> float:
    """Steps per CPU second of ``steps`` random steps (resets included, as a learner sees)."""
    acts = np.random.default_rng(seed).uniform(-1, 1, (steps,) + env.action_space.shape)
    env.reset(seed=seed)
    t0 = time.process_time()
    for a in acts:
        _, _, term, trunc, _ = env.step(a)
        if term or trunc:
            env.reset()
    return steps / (time.process_time() - t0)


def _vector_rate(env, steps: int, seed: int = 0) -> float:
    acts = np.random.default_rng(seed).uniform(-1, 1, (steps,) + env.action_space.shape)
    env.reset(seed=seed)
    t0 = time.process_time()
    for a in acts:
        env.step(a)
    return steps * env.num_envs / (time.process_time() - t0)


def _python_path(on: bool) -> None:
    """Turn the engines' compiled step (``core/plant/_batch``) off (``on``) or back on: every
    ``Engine`` then runs the Python path it stands for (``Actuator.run``, ``PiecewiseCubic``,
    ``Stepper.advance``; the same states, bit for bit), for a comparison in one process."""
    from crawler_sim.core.plant.engine import Engine
    own = _OWN_FAST.setdefault('fast', Engine._fast)
    Engine._fast = (lambda self: False) if on else own


#: ``Engine._fast`` as the class defines it (``_python_path`` puts it back)
_OWN_FAST: dict = {}


def _forget_steps(env) -> None:
    """Forget the engines' cached compiled steps (``Engine._step``) after ``_python_path``."""
    for pl in getattr(env.unwrapped, 'plants', None) or [env.unwrapped.plant]:
        pl.engine._step = None


def breakdown(steps: int = 3000) -> None:
    """Print the CPU time of one env-step (module doc): the compiled step of a plant's row
    (``EnvRows.step_row``: targets, command, the actuator's run into the table, the exact
    integration, the state read, reward and observation) against the Python path's parts on
    an engine stepped beside it (checked bit for bit), alternated step by step."""
    from crawler_sim.core.gaits import PiecewiseCubic
    from crawler_sim.envs.plant import CrawlPlant

    pl, ref = CrawlPlant(control_period=0.01), CrawlPlant(control_period=0.01)
    pl.reset(None)
    ref.reset(None)
    e = ref.engine
    acts = np.random.default_rng(0).uniform(-1, 1, (steps, 1))
    parts = dict.fromkeys(('Engine.command', 'Actuator.run (10 ticks)',
                           'table of the pieces (PiecewiseCubic.compiled)',
                           'exact integration (Stepper.advance)',
                           'state read (Stepper.read_state: x, v, contact)'),
                          0.0)
    names = list(parts)
    compiled = 0.0
    clock = time.process_time
    x, v, contact = pl.x.copy(), pl.v.copy(), pl.contact.copy()
    for k in range(steps):
        t0 = clock()
        pl.step(acts[k])
        compiled += clock() - t0
        marks = [clock()]
        e.command(ref.lengths_of(acts[k]).tolist())
        marks.append(clock())
        pieces = e.actuator.run(e.t_ns, e.cfg.dt_ns, ref.ticks)
        marks.append(clock())
        e.t_ns += ref.ticks * e.cfg.dt_ns
        gait = PiecewiseCubic.from_arrays(pieces.starts, pieces.anchors, pieces.coef)
        gait.compiled()
        marks.append(clock())
        e.stepper.advance(e.t, gait)
        marks.append(clock())
        e.stepper.read_state(x, v, contact)
        marks.append(clock())
        for name, a, b in zip(names, marks, marks[1:]):
            parts[name] += b - a
        assert x.tobytes() == pl.x.tobytes(), 'the Python path no longer makes the plant\'s step'
    total = sum(parts.values())
    print(f'one env-step of the plant, control_period 0.01 (10 ticks), {steps} steps, CPU us')
    print('the Python path, part by part:')
    for name, v in parts.items():
        print(f'  {name:48s} {1e6 * v / steps:6.1f} ({100 * v / total:4.1f} %)')
    print(f'  {"sum":48s} {1e6 * total / steps:6.1f}')
    print(f'the compiled step (CrawlPlant.step: EnvRows.step_row, reward and observation '
          f'included): {1e6 * compiled / steps:.1f} ({total / compiled:.1f} x faster)')


def compare(args) -> None:
    """The compiled step against the engines' Python path (``_python_path``), alternated in
    one process, ``--repeats`` rounds: single env and vector env, medians and ratios."""
    crawl = gym.make('crawler_sim/Crawl-v0', control_period=0.04)
    vec = gym.make_vec('crawler_sim/Crawl-v0', num_envs=args.envs,
                       vectorization_mode='vector_entry_point', control_period=0.01)
    _single_rate(crawl, 200)
    rates = {(kind, path): [] for kind in ('single', 'vector') for path in ('python', 'compiled')}
    for r in range(args.repeats):
        for path in ('python', 'compiled'):
            _python_path(path == 'python')
            _forget_steps(crawl)
            _forget_steps(vec)
            rates['single', path].append(_single_rate(crawl, args.steps, r))
            rates['vector', path].append(_vector_rate(vec, args.vector_steps, r))
            if path == 'python':
                _python_path(False)
    print(f'median of {args.repeats} runs each, CPU time, one process, alternated')
    for kind, unit, what in (('single', 'steps/s', 'p=2 control_period=0.04'),
                             ('vector', 'env-steps/s',
                              f'p=2 control_period=0.01 {args.envs} envs')):
        py, co = (statistics.median(rates[kind, p]) for p in ('python', 'compiled'))
        print(f'  {kind} {what}: Python path {py:11,.0f}, compiled step {co:11,.0f} {unit} '
              f'({co / py:.2f} x; runs {", ".join(f"{x:,.0f}" for x in rates[kind, "python"])}'
              f' / {", ".join(f"{x:,.0f}" for x in rates[kind, "compiled"])})')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--steps', type=int, default=4000, help='single-env steps per run')
    ap.add_argument('--envs', type=int, default=256)
    ap.add_argument('--vector-steps', type=int, default=40, help='vector steps per run')
    ap.add_argument('--profile', action='store_true')
    ap.add_argument('--breakdown', action='store_true')
    ap.add_argument('--compare', action='store_true',
                    help='the compiled step against the engines\' Python path, alternated')
    args = ap.parse_args()
    if args.breakdown:
        breakdown()
        return
    if args.compare:
        compare(args)
        return

    crawl = gym.make('crawler_sim/Crawl-v0', control_period=0.04)
    try:
        swimmer = gym.make('Swimmer-v5')
    except Exception as exc:          # mujoco missing: the cited figure
        print(f'Swimmer-v5 unavailable ({type(exc).__name__}: {exc}); its figure is cited')
        swimmer = None
    vec = gym.make_vec('crawler_sim/Crawl-v0', num_envs=args.envs,
                       vectorization_mode='vector_entry_point', control_period=0.01)
    if args.profile:
        cProfile.runctx('_vector_rate(vec, args.vector_steps)', globals(), locals(),
                        '/tmp/gym_speed.prof')
        pstats.Stats('/tmp/gym_speed.prof').sort_stats('tottime').print_stats(20)
        return
    c_rates, s_rates, v_rates = [], [], []
    _single_rate(crawl, 200)                      # warm-up (first builds, caches)
    for r in range(args.repeats):
        c_rates.append(_single_rate(crawl, args.steps, r))
        if swimmer is not None:
            s_rates.append(_single_rate(swimmer, args.steps, r))
        v_rates.append(_vector_rate(vec, args.vector_steps, r))
    c = statistics.median(c_rates)
    s = statistics.median(s_rates) if s_rates else SWIMMER_CITED
    v = statistics.median(v_rates)
    print(f'median of {args.repeats} runs, CPU time, one process')
    print(f'  crawler_sim/Crawl-v0 p=2 control_period=0.04: {c:9,.0f} steps/s '
          f'(runs: {", ".join(f"{x:,.0f}" for x in c_rates)})')
    print(f'  Swimmer-v5{"" if s_rates else " (cited, issue 41)"}:                  '
          f'{s:9,.0f} steps/s' + (f' (runs: {", ".join(f"{x:,.0f}" for x in s_rates)})'
                                  if s_rates else ''))
    print(f'  ratio crawler / Swimmer: {c / s:.2f} (floor 2)')
    print(f'  vector env p=2 control_period=0.01 {args.envs} envs: {v:11,.0f} env-steps/s '
          f'(floor 1e5; runs: {", ".join(f"{x:,.0f}" for x in v_rates)})')


if __name__ == '__main__':
    main()
