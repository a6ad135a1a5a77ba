"""The vector env of crawler_sim/Crawl-v0 (issue 41): make_vec's vector_entry_point, the seed
contract against single envs (made separately, through gymnasium.make), NEXT_STEP autoreset."""
from __future__ import annotations

import gymnasium as gym
from gymnasium.vector import AutoresetMode
import numpy as np
import pytest

import crawler_sim  # noqa: F401  (registers the id)
from crawler_sim.envs import ENV_ID, CrawlVectorEnv

N, SEED, STEPS, LIMIT = 4, 20, 12, 5


def _vector(**kw):
    return gym.make_vec(ENV_ID, num_envs=N, vectorization_mode='vector_entry_point',
                        max_episode_steps=LIMIT, **kw)


def _actions(seed: int = 5) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.0, 1.0, (STEPS, N, 1))


def test_make_vec_gives_the_batched_env_with_next_step_autoreset():
    env = _vector()
    assert isinstance(env.unwrapped, CrawlVectorEnv)
    assert env.metadata['autoreset_mode'] == AutoresetMode.NEXT_STEP
    obs, info = env.reset(seed=SEED)
    assert obs.shape == (N, 8) and env.action_space.shape == (N, 1)
    obs, r, term, trunc, info = env.step(env.action_space.sample())
    assert r.shape == (N,) and term.dtype == bool and info['x_velocity'].shape == (N,)


@pytest.mark.parametrize('randomize', [0.0, 0.3])
def test_env_i_of_a_vector_seeded_s_is_a_single_env_seeded_s_plus_i(randomize):
    """Bit for bit through the first episode, then (autoreset) the second one as a single env
    reset again without a seed (its generator goes on)."""
    acts = _actions()
    vec = _vector(randomize=randomize)
    vobs0, _ = vec.reset(seed=SEED)
    rows = [vec.step(acts[k]) for k in range(STEPS)]
    for i in range(N):
        single = gym.make(ENV_ID, max_episode_steps=LIMIT, randomize=randomize)
        obs, _ = single.reset(seed=SEED + i)
        assert obs.tobytes() == vobs0[i].tobytes()
        done = False
        for k in range(STEPS):
            vobs, vr, vterm, vtrunc, _ = rows[k]
            if done:                      # NEXT_STEP: the action is ignored, the env resets
                obs, _ = single.reset()
                r, term, trunc = 0.0, False, False
            else:
                obs, r, term, trunc, _ = single.step(acts[k, i])
            assert obs.tobytes() == vobs[i].tobytes(), (i, k)
            assert (r, term, trunc) == (vr[i], vterm[i], vtrunc[i]), (i, k)
            done = term or trunc
    # the episodes truncate after LIMIT steps, the autoreset step returns reward 0
    assert [bool(rows[k][3][0]) for k in range(STEPS)] == [k + 1 in (LIMIT, 2 * LIMIT + 1)
                                                          for k in range(STEPS)]
    assert np.all(rows[LIMIT][1] == 0.0)
    if randomize:                         # each env drew its own crawler
        masses = {tuple(p.masses.tolist()) for p in vec.unwrapped.plants}
        assert len(masses) == N


def test_the_autoreset_step_ignores_the_action_and_returns_the_rest_state():
    vec = _vector()
    first, _ = vec.reset(seed=0)
    for _ in range(LIMIT):
        obs, r, term, trunc, _ = vec.step(np.ones((N, 1)))
    assert trunc.all() and not term.any()
    obs, r, term, trunc, info = vec.step(-np.ones((N, 1)))
    assert obs.tobytes() == first.tobytes()       # at rest at the initial lengths
    assert not (term.any() or trunc.any()) and np.all(r == 0.0)
    assert np.all(info['x_velocity'] == 0.0)
    obs, *_ = vec.step(-np.ones((N, 1)))
    assert obs.tobytes() != first.tobytes()       # the next action is applied


@pytest.mark.parametrize('kwargs, field', [({'num_envs': 0}, 'num_envs'),
                                           ({'max_episode_steps': 0}, 'max_episode_steps'),
                                           ({'control_period': -1.0}, 'control_period')])
def test_bad_arguments_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field):
        CrawlVectorEnv(**{'num_envs': 2, **kwargs})


def test_a_nan_action_is_refused_naming_the_entry():
    vec = CrawlVectorEnv(3)
    vec.reset(seed=0)
    acts = np.zeros((3, 1))
    acts[2, 0] = np.nan
    with pytest.raises(ValueError, match=r'action\[2, 0\] must be finite'):
        vec.step(acts)


@pytest.mark.parametrize('crawler, limit', [
    ({'masses': [1.0, 0.8, 1.2], 'mu': 0.25, 'mu_static': [0.4, 0.3, 0.5],
      'mu_backward': 0.4}, 7),                          # p = 3, stiction
    (None, 4),
])
def test_the_batched_step_is_python_path_plants_bit_for_bit(crawler, limit):
    """The vector env's step (its N rows in one compiled loop, each engine's compiled step)
    against N single plants whose engines run the Python path (``Actuator.run``,
    ``PiecewiseCubic``, ``Stepper.advance``), seeded s + i: observations, rewards, flags and
    every engine state bit for bit across autoresets (NEXT_STEP: the env that ended is reset
    from its own generator, reward 0), with domain randomisation."""
    from gymnasium.utils import seeding
    from crawler_sim.core.plant._batch import PlantStep
    from crawler_sim.envs.plant import CrawlPlant
    from test.core.plant.test_compiled_paths import PythonEngine, _state_bytes

    class PythonPlant(CrawlPlant):
        def reset(self, rng):
            super().reset(rng)
            self.engine.__class__ = PythonEngine     # the Python path from now on

    kw = dict(control_period=0.01, randomize=0.3)
    vec = CrawlVectorEnv(N, crawler, max_episode_steps=limit, **kw)
    refs = [PythonPlant(crawler, **kw) for _ in range(N)]
    for pl in vec.plants + refs:
        pl.keep_events = True          # the events compared below (an env keeps none)
    rngs = [seeding.np_random(SEED + i)[0] for i in range(N)]
    obs, _ = vec.reset(seed=SEED)
    for pl, rng in zip(refs, rngs):
        pl.reset(rng)
    assert obs.tobytes() == np.array([pl.observation() for pl in refs]).tobytes()
    acts = np.random.default_rng(9).uniform(-1.0, 1.0, (3 * limit + 2, N, refs[0].n_links))
    ended = np.zeros(N, dtype=bool)
    resets = 0
    for a in acts:
        obs, rew, term, trunc, info = vec.step(a)
        for i, pl in enumerate(refs):
            if ended[i]:
                pl.reset(rngs[i])
                want = (0.0, 0.0, False)
                resets += 1
            else:
                want = pl.step(a[i])
            assert obs[i].tobytes() == pl.observation().tobytes()
            assert np.array([rew[i], info['x_velocity'][i]]).tobytes() == \
                np.array(want[:2]).tobytes() and term[i] == want[2]
            assert np.float64(info['x_position'][i]).tobytes() == \
                np.float64(pl.com).tobytes()
            assert _state_bytes(vec.plants[i].engine) == _state_bytes(pl.engine)
            assert repr(vec.plants[i].engine.pop_events()) == repr(pl.engine.pop_events())
        ended = term | trunc
    assert resets >= 2 * N
    assert all(isinstance(pl.engine._step, PlantStep) for pl in vec.plants)
    assert all(type(pl.engine) is PythonEngine and pl.engine._step is None for pl in refs)
