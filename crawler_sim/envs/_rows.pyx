# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False
"""The environments' step, compiled: N crawlers' rows (``EnvRows``) stepped one control
period in one loop (``EnvRows.step``), each through the plant's compiled step
(``core/plant/_batch.step_engine``, sim_node's plant), then its reward, centre of mass and
observation written in its row. ``CrawlPlant`` (the single environment) is one row of its own
rows, the vector environment's plants rows of one shared ``EnvRows``: both run this code, so env
i of a vector env is bit for bit a single env (issue 41: the batched step must come from
compiled code, not a Python loop over plants).

The rules (module doc of ``plant.py``) have their one home here: the target of an action
``min_length + (a + 1) half``, half = (max_length - min_length) / 2 [m]; the centre of mass's
position sum(m_i x_i) / M [m] and its mean speed over the period [m/s]; the reward
``forward_reward_weight`` x speed - ``ctrl_cost_weight`` x sum(a^2); the observation l, l',
l'', targets, v, contact. Sums run from 0.0 in index order (below 16 terms what numpy's dot
computes, the values the Python step had).
"""
import numpy as np

from crawler_sim.core._actuator cimport servo_state
from crawler_sim.core.plant._batch cimport step_engine

__all__ = ['EnvRows']


cdef class EnvRows:
    """The per-episode numbers of ``n`` crawlers of p bodies (``n_links`` = p - 1), one row
    each, as arrays (readable attributes; ``CrawlPlant`` reads and writes its row):
    ``masses`` (n, p) [kg], ``mass`` (n,) [kg], ``com`` (n,) [m], ``targets`` (n, n_links)
    [m], ``failures`` (n,) (the engine's failures counted so far), ``x``, ``v`` (n, p)
    [m, m/s], ``contact`` (n, p) int8, ``obs`` (n, 4 n_links + 2 p); a step's ``reward``,
    ``speed`` [m/s] and ``failed`` (n,).

    ``min_length`` [m], ``half`` [m] (half the action's range), ``span_ns`` [ns] and
    ``period`` [s] (the control period), the two reward weights: the environment's settings.
    """
    cdef readonly object masses, mass, com, targets, failures, x, v, contact, obs
    cdef readonly object reward, speed, failed
    cdef readonly Py_ssize_t n, p, nl
    cdef double lo, half, period, fw, cc
    cdef long long span_ns
    cdef double[:, ::1] m_masses, m_targets, m_x, m_v, m_obs
    cdef double[::1] m_mass, m_com, m_reward, m_speed
    cdef long long[::1] m_failures
    cdef signed char[:, ::1] m_contact
    cdef unsigned char[::1] m_failed

    def __init__(self, Py_ssize_t n, Py_ssize_t p, double min_length, double half,
                 long long span_ns, double period, double forward_reward_weight,
                 double ctrl_cost_weight):
        if n < 1 or p < 2:
            raise ValueError(f'EnvRows: n >= 1 crawlers of p >= 2 bodies, got {n}, {p}')
        self.n, self.p, self.nl = n, p, p - 1
        self.lo, self.half, self.span_ns, self.period = min_length, half, span_ns, period
        self.fw, self.cc = forward_reward_weight, ctrl_cost_weight
        self.masses = np.ones((n, p))
        self.mass = np.ones(n)
        self.com = np.zeros(n)
        self.targets = np.zeros((n, p - 1))
        self.failures = np.zeros(n, dtype=np.int64)
        self.x = np.zeros((n, p))
        self.v = np.zeros((n, p))
        self.contact = np.zeros((n, p), dtype=np.int8)
        self.obs = np.zeros((n, 4 * (p - 1) + 2 * p))
        self.reward = np.zeros(n)
        self.speed = np.zeros(n)
        self.failed = np.zeros(n, dtype=bool)
        self.m_masses, self.m_targets, self.m_x, self.m_v, self.m_obs = (
            self.masses, self.targets, self.x, self.v, self.obs)
        self.m_mass, self.m_com, self.m_reward, self.m_speed = (
            self.mass, self.com, self.reward, self.speed)
        self.m_failures = self.failures
        self.m_contact = self.contact
        self.m_failed = self.failed.view(np.uint8)

    def step(self, list engines, const double[:, ::1] actions) -> None:
        """One control period of each row i whose ``engines[i]`` (an ``Engine``) is not None,
        with the checked ``actions[i]`` in [-1, 1]: its targets, the plant's step, its centre
        of mass, ``speed``, ``reward``, ``failed`` (the engine contained a solver failure)
        and observation."""
        cdef Py_ssize_t i
        if len(engines) > self.n or actions.shape[0] < len(engines) \
                or actions.shape[1] != self.nl:
            raise ValueError(f'EnvRows.step: at most {self.n} engines and actions of '
                             f'{self.nl} numbers each')
        for i in range(len(engines)):
            if engines[i] is not None:
                self._step(i, engines[i], &actions[i, 0])

    def step_row(self, Py_ssize_t i, engine,
                 const double[::1] action) -> tuple[float, float, bool]:
        """``step`` of row i alone (``action``: (n_links,)): (reward, speed [m/s], failed)."""
        if not 0 <= i < self.n or action.shape[0] != self.nl:
            raise ValueError(f'EnvRows.step_row: a row in [0, {self.n}) and '
                             f'{self.nl} numbers')
        self._step(i, engine, &action[0])
        return self.m_reward[i], self.m_speed[i], self.m_failed[i] != 0

    def observe(self, Py_ssize_t i, engine) -> None:
        """Row i's observation from ``engine`` (an ``Engine``) and the row's targets, v and
        contact (a reset writes those first)."""
        if not 0 <= i < self.n:
            raise ValueError(f'EnvRows.observe: a row in [0, {self.n})')
        self._observe(i, engine)

    def lengths_of(self, const double[::1] action) -> np.ndarray:
        """Target lengths [m] (n_links,) of one checked action."""
        out = np.empty(action.shape[0])
        cdef double[::1] o = out
        cdef Py_ssize_t j
        for j in range(action.shape[0]):
            o[j] = self.lo + (action[j] + 1.0) * self.half
        return out

    cdef int _step(self, Py_ssize_t i, object eng, const double* a) except -1:
        cdef Py_ssize_t j, nl = self.nl, p = self.p
        cdef double c = 0.0, ctrl = 0.0, speed
        cdef long long nf
        for j in range(nl):
            self.m_targets[i, j] = self.lo + (a[j] + 1.0) * self.half
        step_engine(eng, &self.m_targets[i, 0], nl, self.span_ns, &self.m_x[i, 0],
                    &self.m_v[i, 0], &self.m_contact[i, 0], p)
        for j in range(p):
            c += self.m_masses[i, j] * self.m_x[i, j]
        c = c / self.m_mass[i]
        speed = (c - self.m_com[i]) / self.period
        self.m_com[i] = c
        for j in range(nl):
            ctrl += a[j] * a[j]
        self.m_speed[i] = speed
        self.m_reward[i] = self.fw * speed - self.cc * ctrl
        nf = len(eng.failures)
        self.m_failed[i] = nf > self.m_failures[i]
        self.m_failures[i] = nf
        self._observe(i, eng)
        return 0

    cdef int _observe(self, Py_ssize_t i, object eng) except -1:
        cdef Py_ssize_t j, nl = self.nl, p = self.p
        cdef double* o = &self.m_obs[i, 0]
        servo_state(eng.actuator, o, o + nl, o + 2 * nl)
        for j in range(nl):
            o[3 * nl + j] = self.m_targets[i, j]
        for j in range(p):
            o[4 * nl + j] = self.m_v[i, j]
            o[4 * nl + p + j] = self.m_contact[i, j]
        return 0
