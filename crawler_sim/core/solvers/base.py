"""The solver contract: what every method provides, what each can do, and how a step fails.

As SciPy's ``OdeSolver`` numbers what a method implements, a solver class of this package
(``ExactSolver``, ``ImplicitSolver``, ``PenaltySolver``) provides:

1. ``__init__(crawler, gait, *, t0=, x0=, v0=, **options)``: the state at t0, body 0 at x0 [m]
   moving at v0 [m/s]; ``options`` are what its ``options`` classmethod returns.
2. ``options(**stepper_options) -> dict`` (classmethod): its own keyword arguments picked from
   ``Stepper``'s and validated (ValueError naming the argument); the others are ignored.
3. ``check_span(gait, t_end, options)`` (static): ValueError if a run to t_end cannot be done
   (too many steps, time resolution).
4. ``advance(t1, gait=None)``: integrate to t1 with ``gait`` (default: the current one) valid on
   [t, t1]. On return ``status == 'ok'``; a step that fails sets ``status`` ('failed', or
   'error' when the user's gait raised) and ``message``, then raises: ``SolverError`` for a
   failure of the method, ValueError for a gait value or state that is not finite (a bad input),
   the user's own exception when a gait of Python functions raised.
5. ``t``, ``gait``, ``events`` (a list of ``Event`` in time order), ``current()`` (the state at t
   as one output row), ``reset(t0=, x0=, v0=)``.
6. ``simulate(t_end, times, include_events, dt) -> (times, outputs, info)``: a whole run.
7. ``capabilities``: a ``Capabilities`` naming what the method can do; callers ask
   ``capabilities(method)``, never the method's name.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, TypeVar

__all__ = ['Capabilities', 'SolverError', 'register', 'capabilities', 'solver_class',
           'method_names']


@dataclass(frozen=True)
class Capabilities:
    """What a method can do (every field False unless it says otherwise).

    Attributes
    ----------
    dense_output : bool
        A whole run keeps an exact interpolant of its states (``Trajectory.state_at``).
    closed_form : bool
        Its states are closed forms between events: samples are exact, not a scheme's steps
        (``Trajectory`` computes dissipated energy and work from them exactly).
    fixed_step : bool
        It steps with a fixed ``dt`` that lands on each call's end: the plant calls it once per
        tick, and ``dt`` is its step, not the sample grid.
    streaming : bool
        It can be advanced call by call with a new gait each time (``Stepper``).
    periodic_skip : bool
        It can skip gait periods that repeat (``periodic_skip`` option).
    stiction : bool
        Static friction above the kinetic one (``Crawler.has_stiction``), with Rule S and its
        ``stiction_rule`` / ``initial_stuck`` options (``core.friction``); a crawler with
        stiction is refused by a method without it.
    batched : bool
        Steps several crawlers at once (not yet provided through ``Stepper``).
    """

    dense_output: bool = False
    closed_form: bool = False
    fixed_step: bool = False
    streaming: bool = False
    periodic_skip: bool = False
    stiction: bool = False
    batched: bool = False


class SolverError(RuntimeError):
    """A step the method could not take: ``status`` ('failed') and ``message`` as the solver
    set them (a RuntimeError, as these failures were before the contract).

    Parameters
    ----------
    message : str
        What failed, with the time and what to try.
    status : str
        The solver's ``status`` after the failure.
    method : str
        The method's name.
    """

    def __init__(self, message: str, status: str = 'failed', method: str = '') -> None:
        super().__init__(message)
        self.message = message
        self.status = status
        self.method = method


#: method name -> solver class, filled by ``register`` as the solver modules are imported
_REGISTRY: dict[str, type] = {}

_T = TypeVar('_T', bound=type)


def register(name: str) -> Callable[[_T], _T]:
    """Class decorator: the solver class of method ``name`` (it must set ``capabilities``)."""
    def deco(cls: _T) -> _T:
        if not isinstance(getattr(cls, 'capabilities', None), Capabilities):
            raise TypeError(f'{cls.__name__} must set capabilities = Capabilities(...)')
        _REGISTRY[name] = cls
        cls.method_name = name
        return cls
    return deco


def _load() -> None:
    # the solver modules register themselves on import; imported here on first use so this
    # module (read by ``trajectory``) imports none of them at module level
    from . import exact, implicit, penalty  # noqa: F401


def method_names() -> tuple[str, ...]:
    """The registered methods: the default "exact" first, then by name (not by the order the
    modules happened to be imported in)."""
    _load()
    return tuple(sorted(_REGISTRY, key=lambda name: (name != 'exact', name)))


def solver_class(method: str) -> type:
    """The solver class of ``method``; ValueError naming the methods if it has none."""
    if method not in _REGISTRY:
        _load()
    if method not in _REGISTRY:
        raise ValueError(f'method must be one of {", ".join(method_names())}; got {method!r}')
    return _REGISTRY[method]


def capabilities(method: str, *, strict: bool = True) -> Capabilities:
    """What ``method`` can do. With ``strict=False`` an unknown name (a ``Trajectory`` built by
    hand or read back with another label) has no capability instead of raising ValueError."""
    if not strict and method not in _REGISTRY:
        _load()
        return _REGISTRY[method].capabilities if method in _REGISTRY else Capabilities()
    return solver_class(method).capabilities
