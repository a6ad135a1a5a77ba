"""The policy learned by ``benchmarks.learn_crawl`` played live into a real sim_node over DDS.

A sim_node (``SimNode``, in this process, its own ROS context and domain, discovery off) is
started with the plant parameters of the learning env; the policy's target lengths go out on
``linkage_cmd`` at the start of each control period, the node ticks (1 kHz) and publishes
``body_states``; the same actions go through a ``CrawlEnv`` beside it. Prints the node's steady
speed and the largest difference between its published positions and the env's (0: what the
policy learned is what sim_node does). Reproduce::

    .venv/bin/python -m benchmarks.learn_crawl --json /tmp/learn.json
    .venv/bin/python -m benchmarks.play_crawl /tmp/learn.json [--seconds 20]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from benchmarks.learn_crawl import CONTROL_PERIOD, actions, env_kwargs
from crawler_sim.ros.messages import ns_from_stamp
from test.support.ros import Harness, cmd, ticks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('policy', type=Path, help='the JSON written by learn_crawl --json')
    ap.add_argument('--seconds', type=float, default=20.0)
    args = ap.parse_args()
    theta = np.array(json.loads(args.policy.read_text())['theta'])
    env = gym.make('crawler_sim/Crawl-v0', max_episode_steps=None, **env_kwargs())
    _, info = env.reset(seed=0)
    plant = env.unwrapped.plant
    h = Harness()
    try:
        node = h.sim(seed=True, publish_clock=False, **plant.plant_config.values)
        states = h.listen(JointState, 'body_states')
        pub = h.publisher(Float64MultiArray, 'linkage_cmd')
        n = round(args.seconds / CONTROL_PERIOD)
        dx, com = 0.0, []
        masses = plant.masses
        for k in range(n):
            a = actions(theta[None], k)[0]
            h.send(pub, cmd(*plant.lengths_of(a)), node, 'commands_accepted')
            ticks(node, plant.ticks)
            _, _, _, _, info = env.step(a)
            t_ns = round(info['t'] * 1e9)
            h.until(lambda: any(ns_from_stamp(m.header.stamp) == t_ns for m in states[-3:]),
                    f'body_states at {t_ns} ns')
            x = np.array(next(m for m in states[-3:]
                              if ns_from_stamp(m.header.stamp) == t_ns).position)
            dx = max(dx, float(np.max(np.abs(x - info['x']))))
            com.append(float(masses @ x) / float(masses.sum()))
        half = n // 2
        speed = (com[-1] - com[half - 1]) / ((n - half) * CONTROL_PERIOD)
        print(f'sim_node, {args.seconds:g} s of the learned policy over DDS: steady speed '
              f'{1e3 * speed:.3f} mm/s (second half); max |x_node - x_env| = {dx:g} m')
    finally:
        h.close()


if __name__ == '__main__':
    main()
