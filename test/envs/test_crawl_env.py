"""crawler_sim/Crawl-v0 (issue 41): Gymnasium's checks, seeding, the plant it drives, bad input.

Expected values come from the physics or from an independent path: the stuck body's exact
position (its friction exceeds any force the actuator can ask of it), the journal of the
env's plant replayed through ``core.plant.replay`` (sim_node's replay path, its own Engine),
and the registry seen from a fresh interpreter.
"""
from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
from gymnasium.utils.env_checker import check_env
import numpy as np
import pytest

import crawler_sim  # noqa: F401  (registers the id)
from crawler_sim.core.plant.replay import Input, replay
from crawler_sim.envs import ENV_ID, CrawlEnv
from crawler_sim.envs.render import COLOURS


def _actions(n: int, n_links: int = 1, seed: int = 7) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.2, 1.2, (n, n_links))   # some clipped


@pytest.mark.parametrize('kwargs', [{}, {'randomize': 0.3},
                                    {'crawler': {'masses': [1.0, 2.0, 1.5], 'mu': [0.3, 0.2, 0.4],
                                                 'mu_backward': 0.6}, 'control_period': 0.01}])
def test_gymnasium_check_env_passes(kwargs):
    env = gym.make(ENV_ID, **kwargs)
    check_env(env.unwrapped, skip_render_check=True)
    assert env.spec.max_episode_steps == 1000
    assert env.unwrapped.control_period == kwargs.get('control_period', 0.04)


def test_registration_waits_for_gymnasium_and_keeps_it_out_of_import_crawler_sim():
    code = ('import sys, crawler_sim; assert "gymnasium" not in sys.modules; '
            'import gymnasium; print(gymnasium.spec("crawler_sim/Crawl-v0").vector_entry_point)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'crawler_sim.envs.vector:CrawlVectorEnv'
    code = 'import gymnasium, crawler_sim; gymnasium.make("crawler_sim/Crawl-v0").reset(seed=0)'
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr


def test_same_seed_same_episode_bit_for_bit_and_the_seed_draws_the_crawler():
    def episode(seed):
        env = gym.make(ENV_ID, randomize=0.3)
        obs, info = env.reset(seed=seed)
        rows = [obs]
        for a in _actions(30):
            obs, r, term, trunc, info = env.step(a)
            rows.append(np.append(obs, [r, info['x_position']]))
        return env.unwrapped.plant.masses.copy(), np.concatenate(rows)
    m1, a = episode(3)
    m2, b = episode(3)
    m3, c = episode(4)
    assert a.tobytes() == b.tobytes() and m1.tolist() == m2.tolist()
    assert m1.tolist() != m3.tolist() and a.tobytes() != c.tobytes()
    # the draw stays within the spread around the seed's masses [0.5, 1.0]
    assert np.all(np.abs(m3 / np.array([0.5, 1.0]) - 1.0) <= 0.3)


def test_a_stuck_body_does_not_creep_and_the_observation_is_its_state():
    # mu = 100: body 1 (1 kg) holds up to 981 N, body 0 (0.5 kg) 490.5 N; the actuator's
    # l'' <= 5 m/s^2 asks at most m0 * 5 = 2.5 N of the linkage, so the lighter-friction body 0
    # does all the sliding and body 1 stays at its start, 0.1 m, exactly
    env = CrawlEnv({'masses': [0.5, 1.0], 'mu': 100.0}, render_mode='rgb_array')
    env.reset(seed=0)
    for a in _actions(40):
        obs, r, term, trunc, info = env.step(a)
        assert info['x'][1] == 0.1
        # obs = [l, l', l'', target, v0, v1, contact0, contact1]
        assert obs[7] == 0 and obs[5] == 0.0                 # body 1 stuck, at rest
        assert obs[4] == pytest.approx(-obs[1], abs=1e-12)   # x0 = x1 - l: v0 = -l'
        assert info['x'][1] - info['x'][0] == pytest.approx(obs[0], abs=1e-15)  # x1 - x0 = l
        img = env.render()
        assert img.shape == (120, 480, 3) and img.dtype == np.uint8
        colours = {tuple(c) for c in img.reshape(-1, 3).tolist()}
        assert COLOURS[0] in colours                          # the stuck body 1
        assert COLOURS[int(obs[6])] in colours                # body 0, by its contact state


def test_the_reward_is_the_centre_of_mass_speed_minus_the_control_cost():
    env = gym.make(ENV_ID, ctrl_cost_weight=0.5, forward_reward_weight=2.0)
    _, info = env.reset(seed=0)
    x0 = info['x_position']
    for a in _actions(20):
        _, r, _, _, info = env.step(a)
        a = np.clip(a, -1, 1)
        speed = (info['x_position'] - x0) / 0.04
        assert r == pytest.approx(2.0 * speed - 0.5 * float(a @ a), rel=1e-12, abs=1e-15)
        x0 = info['x_position']
    # the centre of mass from the body positions and masses (0.5, 1.0)
    assert info['x_position'] == pytest.approx((0.5 * info['x'][0] + info['x'][1]) / 1.5,
                                               abs=1e-15)


def test_an_episode_replayed_through_the_plant_journal_gives_the_same_states():
    inputs: list[Input] = []
    env = CrawlEnv(randomize=0.0, control_period=0.02,
                   journal=lambda kind, t_ns, payload: inputs.append(Input(t_ns, kind, payload)))
    env.reset(seed=1)
    xs, ts = [], []
    for a in _actions(150, seed=11):
        _, _, _, _, info = env.step(a)
        xs.append(info['x'])
        ts.append(round(info['t'] * 1e9))
    assert [i.kind for i in inputs] == ['command'] * 150
    # sim_node's replay of the same journal: its own Engine from the recorded parameters
    values = env.plant.plant_config.values
    snaps = replay(values, inputs, ts[-1])
    x, _ = snaps.at(ts, 2)
    assert np.max(np.abs(x - np.array(xs))) == 0.0
    assert np.ptp(np.array(xs)[:, 0]) > 0.01         # it moved


@pytest.mark.parametrize('kwargs, field', [
    ({'control_period': 0.0}, 'control_period'), ({'control_period': -0.04}, 'control_period'),
    ({'control_period': float('nan')}, 'control_period'),
    ({'control_period': 0.0015}, 'control_period'), ({'control_period': 11.0}, 'control_period'),
    ({'min_length': 0.2, 'max_length': 0.1}, 'min_length'), ({'randomize': 1.5}, 'randomize'),
    ({'crawler': {'masses': [1.0, -1.0], 'mu': 0.3}}, 'crawler.masses'),
    ({'initial_lengths': [0.1, 0.1]}, 'initial_lengths'),
    ({'ctrl_cost_weight': -1.0}, 'ctrl_cost_weight')])
def test_bad_arguments_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field) as err:
        CrawlEnv(**kwargs)
    assert '\n' not in str(err.value)


@pytest.mark.parametrize('action, text', [([float('nan')], r'action\[0\] must be finite'),
                                          ([np.inf], r'action\[0\] must be finite'),
                                          ([0.1, 0.2], 'action must have shape'),
                                          (['x'], 'action must be numbers')])
def test_bad_actions_are_refused_naming_the_field(action, text):
    env = CrawlEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=text):
        env.step(action)


def test_randomisation_keeps_each_bodys_friction_ratios_and_stiction_reaches_the_plant():
    # one factor for all of a body's friction entries: backward / forward stays 0.4 / 0.3 and
    # static / sliding 0.5 / 0.3 (a static bound below the sliding one would be refused)
    env = CrawlEnv({'masses': [0.5, 1.0], 'mu': 0.3, 'mu_backward': 0.4, 'mu_static': 0.5},
                   randomize=0.5)
    seen = set()
    for seed in range(4):
        env.reset(seed=seed)
        c = env.plant.engine.cfg.crawler
        assert np.allclose(c.friction_backward / c.friction, 4 / 3, rtol=1e-14)
        assert np.allclose(c.static_friction / c.friction, 5 / 3, rtol=1e-14)
        assert np.all(np.abs(c.masses / np.array([0.5, 1.0]) - 1) <= 0.5)
        seen.add(tuple(c.masses.tolist()))
    assert len(seen) == 4


def test_a_crawler_with_stiction_replays_through_the_journal_bit_for_bit():
    inputs: list[Input] = []
    env = CrawlEnv({'masses': [0.5, 1.0], 'mu': 0.3, 'mu_static': 0.45}, control_period=0.02,
                   journal=lambda kind, t_ns, payload: inputs.append(Input(t_ns, kind, payload)))
    env.reset(seed=0)
    xs, ts = [], []
    for a in _actions(100, seed=2):
        _, _, _, _, info = env.step(a)
        xs.append(info['x'])
        ts.append(round(info['t'] * 1e9))
    values = env.plant.plant_config.values
    assert values['static_friction'] == pytest.approx([0.45 * 0.5 * 9.81, 0.45 * 9.81])
    x, _ = replay(values, inputs, ts[-1]).at(ts, 2)
    assert np.max(np.abs(x - np.array(xs))) == 0.0


@pytest.mark.parametrize('crawler', [None, {'masses': [1.0, 0.8, 1.2], 'mu': 0.25,
                                            'mu_static': [0.4, 0.3, 0.5], 'mu_backward': 0.4}])
def test_the_steps_state_read_is_the_engines_state_bit_for_bit(crawler):
    """The env's step reads x, v and contact through ``Engine.read_state`` (the exact core's
    closed form written into the plant's arrays, issue 41); ``Engine.state`` (the State of
    sim_node and replay) gives the same bytes at every step, stiction included, and so does a
    read off the publish grid, where the engine cut the integration itself (``sync``)."""
    from crawler_sim.envs.plant import CrawlPlant
    pl = CrawlPlant(crawler, control_period=0.01)
    pl.reset(None)
    acts = _actions(200, pl.n_links)
    x, v, c = pl.x.copy(), pl.v.copy(), pl.contact.copy()
    seen = set()
    for k, a in enumerate(acts):
        pl.step(np.clip(a, -1.0, 1.0))
        st = pl.engine.state
        seen.update(pl.contact.tolist())
        assert (pl.x.tobytes(), pl.v.tobytes(), pl.contact.tobytes()) == \
            (st.x.tobytes(), st.v.tobytes(), st.contact.astype(np.int8).tobytes())
        if k % 7 == 0:
            pl.engine.run_to(pl.engine.t_ns + 3 * pl.engine.cfg.dt_ns)
            pl.engine.read_state(x, v, c)
            st = pl.engine.state
            assert (x.tobytes(), v.tobytes(), c.tobytes()) == \
                (st.x.tobytes(), st.v.tobytes(), st.contact.astype(np.int8).tobytes())
    assert seen == {-1, 0, 1}          # sliding both ways and stuck bodies were read


def test_a_small_action_is_clipped_as_numpy_clips_it():
    """A single env's action is checked and clipped in Python floats (cheaper than numpy on a
    few numbers): the same bytes as np.clip, -0.0, the bounds and values beyond them
    included; the plant's targets as numpy's expression of them."""
    from crawler_sim.envs.plant import CrawlPlant, check_action
    rng = np.random.default_rng(3)
    pl = CrawlPlant()
    for k in range(3000):
        a = rng.uniform(-1.5, 1.5, int(rng.integers(1, 5)))
        a[rng.integers(0, a.size)] = (-0.0, 1.0, -1.0, 0.0, 2.0)[k % 5]
        got = check_action(a.tolist(), a.shape)
        want = np.clip(a, -1.0, 1.0)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert got.tobytes() == want.tobytes()
        lengths = pl.min_length + (want + 1.0) * (0.5 * (pl.max_length - pl.min_length))
        assert pl.lengths_of(got).tobytes() == lengths.tobytes()


@pytest.mark.parametrize('masses', [[0.5, 1.0], [1.0, 0.7, 1.3], [0.9, 1e-3, 2.0, 1e3, 0.4]])
def test_the_steps_sums_are_numpys_bit_for_bit(masses):
    """The compiled step's sums (``_rows``: masses . x for the centre of mass, action . action
    for the control cost, from 0.0 in order) give numpy's float(a @ b) to the bit below 16
    terms, so the centre of mass, the speed and the reward are numpy's expressions of the
    state read; masses spanning six decades, actions with -0.0 and the bounds."""
    from crawler_sim.envs.plant import CrawlPlant
    pl = CrawlPlant({'masses': masses, 'mu': 0.3}, control_period=0.01,
                    ctrl_cost_weight=0.37, forward_reward_weight=1.3)
    pl.reset(None)
    rng = np.random.default_rng(len(masses))
    com = float(pl.masses @ pl.x) / pl.mass
    for k in range(300):
        a = rng.uniform(-1.0, 1.0, pl.n_links)
        a[k % pl.n_links] = (-0.0, 1.0, -1.0, 0.0, 0.3)[k % 5]
        reward, speed, _ = pl.step(a)
        want_com = float(pl.masses @ pl.x) / pl.mass
        want_speed = (want_com - com) / pl.control_period
        want_reward = 1.3 * want_speed - 0.37 * float(a @ a)
        assert np.float64(pl.com).tobytes() == np.float64(want_com).tobytes()
        assert np.float64(speed).tobytes() == np.float64(want_speed).tobytes()
        assert np.float64(reward).tobytes() == np.float64(want_reward).tobytes()
        com = want_com


def test_an_episode_keeps_no_contact_events_and_its_states_do_not_depend_on_them():
    """The env never pops the engine's contact events, so it keeps none (an episode without end
    would hold every event of it: memory growing with the run; before, 200 steps of the seed's
    crawler kept 100s of them). A plant told to keep them (``keep_events``) steps to the same
    states bit for bit and does see contact changes: the switch drops only the record."""
    from crawler_sim.envs.plant import CrawlPlant
    kept, dropped = CrawlPlant(control_period=0.01), CrawlPlant(control_period=0.01)
    kept.keep_events = True
    for pl in (kept, dropped):
        pl.reset(None)
    acts = np.random.default_rng(3).uniform(-1.0, 1.0, (200, kept.n_links))
    for a in acts:
        assert kept.step(a) == dropped.step(a)
        assert kept.observation().tobytes() == dropped.observation().tobytes()
    assert kept.x.tobytes() == dropped.x.tobytes()
    assert len(kept.engine.pop_events()) > 20        # the crawler stuck and slid many times
    assert dropped.engine.pop_events() == []
    env = gym.make(ENV_ID, max_episode_steps=None)
    env.reset(seed=0)
    for a in acts[:50]:
        env.step(a)
    assert env.unwrapped.plant.engine.pop_events() == []
