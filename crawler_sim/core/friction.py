"""The friction law of the crawler, in one home (STICTION.md, MODEL.md s. 2).

Every method, ``verify()``, the plant and the node read the law from here: the bounds of each
body (kinetic and static, forward and backward), the force a stuck cluster must get from the
ground (its two event rows), the split of a stuck cluster's force among its members, and the
names of the selection rule at a coincident rest (Rule S).

Sign convention (docs/ARCHITECTURE.md): ``friction`` is the force the ground exerts on a body
[N], x forward. Sliding forward (v > 0) it is ``-kinetic_forward[i]``; sliding backward
``+kinetic_backward[i]``; stuck it may be anywhere in
``[-static_forward[i], +static_backward[i]]``. STICTION.md writes the resisting force
F_i = -friction[i]; its f^{k,+}, f^{k,-}, f^{s,+}, f^{s,-} are ``kinetic_forward``,
``kinetic_backward``, ``static_forward`` and ``static_backward`` here.

With every static bound equal to its kinetic one (``has_stiction`` False) the law is the
convex one of MODEL.md and every method gives bit for bit what it gave before stiction.

Compiled side: ``solvers/_friction.pxd`` (the sliding ground force, the stuck split in both
arithmetic forms the methods keep, the penalty method's regularised law) and
``solvers/_inclusion.pxd`` (the kinetic inclusion that decides the mode; Rule S over it lives
in each method's mode decision: ``ExactCore.rule_s``, ``StepCore.st_decide``). The check that
nothing else spells the law out: the grep in issue 40's note.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from .model import Crawler

__all__ = ['Bounds', 'RULES', 'DEFAULT_RULE', 'bounds', 'check_rule', 'dissipation',
           'has_stiction', 'kinetic_force', 'required_constants', 'split_stuck',
           'stuck_interval']

#: Rule S at a coincident rest (STICTION.md s. 5, item 3), the ``stiction_rule`` option:
#: 'incumbent' (default): a cluster stuck just before t holds first if it can, then the largest
#: static margin; 'margin': the largest static margin alone (no incumbency). They differ in
#: STICTION.md T5 (two bodies at a stroke reversal, body 0 stuck before t = 1): 'incumbent'
#: keeps body 0 anchored (x_0(8) - x_0(0) = 0), 'margin' anchors body 1 (X(8) - X(0) = -1/4).
#: Exact ties of the margin go to the lowest body index and the instant is flagged.
RULES = ('incumbent', 'margin')
DEFAULT_RULE = 'incumbent'


def check_rule(rule: str) -> str:
    """``rule`` if it is one of ``RULES``, else ValueError naming ``stiction_rule``."""
    if rule not in RULES:
        raise ValueError(f"stiction_rule must be one of {', '.join(map(repr, RULES))}, "
                         f'got {rule!r}')
    return rule


@dataclass(frozen=True)
class Bounds:
    """The four friction bounds of each body [N], each of shape (p,), all >= 0, with
    ``static_forward >= kinetic_forward`` and ``static_backward >= kinetic_backward``."""

    kinetic_forward: NDArray[np.float64]
    kinetic_backward: NDArray[np.float64]
    static_forward: NDArray[np.float64]
    static_backward: NDArray[np.float64]

    @property
    def has_stiction(self) -> bool:
        """True when any static bound is above its kinetic one."""
        return has_stiction(self.kinetic_forward, self.kinetic_backward, self.static_forward,
                            self.static_backward)


def bounds(crawler: Crawler) -> Bounds:
    """The crawler's friction bounds (``Crawler.friction`` is the forward kinetic bound)."""
    return Bounds(crawler.friction, crawler.friction_backward, crawler.static_friction,
                  crawler.static_friction_backward)


def has_stiction(kinetic_forward: ArrayLike, kinetic_backward: ArrayLike,
                 static_forward: ArrayLike, static_backward: ArrayLike) -> bool:
    """True when any static bound is above its kinetic one (then the motion is no longer
    unique as a differential inclusion and Rule S selects it, STICTION.md s. 3-5)."""
    return bool(np.any(np.asarray(static_forward) > np.asarray(kinetic_forward))
                or np.any(np.asarray(static_backward) > np.asarray(kinetic_backward)))


def kinetic_force(b: Bounds, contact: ArrayLike) -> NDArray[np.float64]:
    """The ground force [N] on bodies sliding with ``contact`` +1 (forward: -kinetic_forward)
    or -1 (backward: +kinetic_backward); 0 where ``contact`` is 0 (stuck: not the kinetic
    law's to say). ``contact`` of shape (..., p). The compiled side: ``_friction.ground_force``."""
    c = np.asarray(contact)
    return np.where(c > 0, -b.kinetic_forward, np.where(c < 0, b.kinetic_backward, 0.0))


def dissipation(b: Bounds, v: ArrayLike) -> NDArray[np.float64]:
    """The kinetic law's dissipation potential [W] at body velocities ``v`` (..., p):
    kinetic_forward v+ + kinetic_backward v-, the support function of each body's kinetic
    interval (MODEL.md s. 2): a ground force R is the kinetic law's iff R v + this = 0."""
    v = np.asarray(v)
    return b.kinetic_forward * np.maximum(v, 0.0) + b.kinetic_backward * np.maximum(-v, 0.0)


def stuck_interval(b: Bounds, members: ArrayLike) -> tuple[float, float]:
    """The ground force a stuck cluster can get [N]: ``(-sum static_forward, +sum
    static_backward)`` over its members (``members``: a boolean mask or body indices). Only
    the total of a stuck cluster is determined; it holds while its required force is inside
    this closed interval (Rule S, persistence and arrival)."""
    idx = np.asarray(members)
    return (-float(np.sum(b.static_forward[idx])), float(np.sum(b.static_backward[idx])))


def required_constants(b: Bounds, members: ArrayLike, sliding_sign: ArrayLike,
                       external_force: float) -> float:
    """The constant part [N] of the ground force a stuck cluster C needs (STICTION.md s. 2):

        friction_C(t) = -M e_r''(t) - F_ext + sum_{j not in C} sigma_j f_j^{k, sigma_j}

    (the ground force, i.e. -F_C^req of STICTION.md), with ``sliding_sign`` sigma_j = +1/-1 the
    direction of each other body (entries of the members are ignored) and F_ext the total
    external force [N]. The cluster's two event rows are ``friction_C(t) + sum static_forward``
    and ``sum static_backward - friction_C(t)`` (both >= 0 while it holds): only these
    constants differ from the kinetic model's rows."""
    inside = np.zeros(b.static_forward.size, dtype=bool)
    inside[np.asarray(members)] = True
    sig = np.asarray(sliding_sign)
    out = ~inside
    slide = float(np.sum(np.where(sig[out] > 0, b.kinetic_forward[out],
                                  -b.kinetic_backward[out])))
    return slide - float(external_force)


def split_stuck(b: Bounds, members: ArrayLike, total: float) -> NDArray[np.float64]:
    """The documented split of a stuck cluster's ground force ``total`` [N] among its members.

    Only the total is determined (MODEL.md s. 2.5, STICTION.md s. 6). Every member gets the same
    point of its own static interval: ``friction_i = static_backward_i - theta (static_forward_i
    + static_backward_i)`` with one theta in [0, 1] for the cluster. It is always admissible
    (each force inside its own interval when the total is inside the summed one) and, with
    static == kinetic, it is the split the exact method reported before stiction (bit for
    bit). (STICTION.md s. 6 suggests the proportional split total * f_i^s / f_C^s; the two
    coincide when every member's forward and backward static bounds are proportional.)
    Entries of non-members are 0.
    """
    mask = np.zeros(b.static_forward.size, dtype=bool)
    mask[np.asarray(members)] = True
    w = np.where(mask, b.static_forward + b.static_backward, 0.0)
    bwd = np.where(mask, b.static_backward, 0.0)
    wg = float(np.sum(w))
    # clamped as the compiled evaluation does: a total a rounding outside the interval
    theta = min(max((float(np.sum(bwd)) - float(total)) / wg, 0.0), 1.0) if wg > 0 else 0.0
    return np.where(mask, bwd - theta * w, 0.0)
