"""The solver contract as code (issue 39): capabilities, one failure type, periodic_skip auto."""
from pathlib import Path

import numpy as np
import pytest

import crawler_sim as cs
from crawler_sim.core.solvers import _exact
from crawler_sim.core.solvers.base import Capabilities, SolverError, capabilities, method_names
from crawler_sim.core.solvers.exact import SKIP_MIN_SEGMENTS, ExactSolver
from crawler_sim.core.stepper import METHODS

G = cs.gaits
ROOT = Path(__file__).resolve().parents[3] / 'crawler_sim'


def test_every_method_declares_its_capabilities_in_one_registry():
    assert set(method_names()) == set(METHODS)
    for name, cls in METHODS.items():
        assert capabilities(name) is cls.capabilities
        assert isinstance(cls.capabilities, Capabilities)
        assert not cls.capabilities.batched
    # stiction (issue 40): exact and implicit; the penalty method has no analogue
    assert sorted(n for n in METHODS if capabilities(n).stiction) == ['exact', 'implicit']
    exact, implicit = capabilities('exact'), capabilities('implicit')
    assert exact.dense_output and exact.closed_form and exact.periodic_skip
    assert not exact.fixed_step and implicit.fixed_step and not implicit.dense_output
    assert capabilities('penalty').fixed_step and not capabilities('penalty').dense_output
    with pytest.raises(ValueError, match='method must be one of exact, implicit, penalty'):
        capabilities('rk45')
    assert capabilities('hand-made', strict=False) == Capabilities()


def test_callers_ask_capabilities_not_the_method_name():
    # every module of the package (engine, sweeps, optimiser, CLI, trajectory, stepper, the
    # nodes): no test of the method's name left outside the solvers' own registry
    for path in sorted(ROOT.rglob('*.py')):
        if path.parent.name == 'solvers':
            continue
        text = path.read_text()
        for pattern in ("== 'exact'", "!= 'exact'", "== 'implicit'", "!= 'implicit'"):
            assert pattern not in text, (str(path.relative_to(ROOT)), pattern)


def test_a_failed_exact_step_is_a_solver_error_with_status_and_message():
    c = cs.Crawler.from_coefficients([0.5, 1.0], 0.3)
    s = ExactSolver(c, G.Sinusoid(mean=0.1, amplitude=0.02, frequency=2.0))
    for status in (_exact.STALLED, _exact.NO_STEPS):
        with pytest.raises(SolverError, match='report this scene') as err:
            s._fail(status, 1.0)
        assert isinstance(err.value, RuntimeError)      # as these failures were before
        assert (err.value.status, err.value.message, err.value.method) == (
            'failed', s.message, 'exact')
        assert s.status == 'failed'


def _scallop(p):
    c = cs.Crawler.from_coefficients(np.linspace(0.5, 1.0, p), 0.3)
    return c, G.Scallop(mean=0.1, amplitude=0.02, frequency=2.0, asymmetry=0.2)


@pytest.mark.parametrize('periods, skips', [(10, False), (200, True)])
def test_periodic_skip_defaults_to_a_choice_from_the_scene(periods, skips):
    # 2 bodies, 5 segments a period: 10 periods (50 segments) are cheaper without the skip,
    # 200 (1000 segments) with it; the default used to skip both
    c, g = _scallop(2)
    t_end = periods * g.period
    auto = cs.simulate(c, g, t_end)
    off = cs.simulate(c, g, t_end, periodic_skip=False)
    on = cs.simulate(c, g, t_end, periodic_skip=True)
    assert on.info['skipped_periods'] > 0
    assert (auto.info['skipped_periods'] > 0) == skips
    assert auto.info['segments'] * (1 if skips else 1) > 0
    np.testing.assert_allclose(auto.x, off.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(auto.v, off.v, rtol=0, atol=1e-12)
    assert [e.time for e in auto.events] == pytest.approx([e.time for e in off.events],
                                                          abs=1e-12)
    assert auto.state_at(0.37 * t_end).x == pytest.approx(off.state_at(0.37 * t_end).x,
                                                          abs=1e-12)
    if not skips:       # the probe's period and the rest are one chunk (one compiled sample)
        assert auto.info['segments'] < SKIP_MIN_SEGMENTS


def test_explicit_periodic_skip_and_streaming_keep_their_behaviour():
    c, g = _scallop(2)
    assert cs.simulate(c, g, 10 * g.period, periodic_skip=True).info['skipped_periods'] > 0
    st = cs.Stepper(c, g)           # streaming: auto is on (no run length to weigh)
    st.advance(10 * g.period)
    assert st.solver.n_skipped_periods > 0


def test_the_plant_falls_back_on_a_solver_error_of_the_exact_method(monkeypatch):
    from crawler_sim.core.plant import engine as engine_mod
    from test.core.plant.test_engine import config
    eng = engine_mod.Engine(config(2, 10))
    eng.command([0.13])
    calls = []

    def failing(self, t1, gait=None):
        calls.append(t1)
        self.status, self.message = 'failed', 'exact solver stalled'
        raise SolverError(self.message)
    monkeypatch.setattr(ExactSolver, 'advance', failing)
    eng.tick_to_grid()                          # does not raise: redone with "implicit"
    assert calls and eng.stepper.method == 'implicit'
    assert any('exact solver stalled' in f for f in eng.failures)
