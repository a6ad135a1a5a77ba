# cython: language_level=3
"""The friction law's compiled side (its one home is ``crawler_sim/core/friction.py``, which
documents it): what the compiled loops need per body, inlined.

Sign convention: the ground force on body i [N]; -fp sliding forward (contact +1), +fm
sliding backward (contact -1); a stuck body anywhere in [-sfp, +sfm] (static bounds, equal to
fp, fm without stiction).
"""


cdef inline double ground_force(signed char contact, double fp, double fm) noexcept nogil:
    """The ground force [N] on a body sliding with ``contact`` +1 / -1 (0: stuck or
    frictionless, no kinetic force: 0)."""
    return -fp if contact > 0 else (fm if contact < 0 else 0.0)


cdef inline double split_theta(double total, double sum_sfm, double width) noexcept nogil:
    """The stuck cluster's split (``friction.split_stuck``): theta in [0, 1] such that each
    member's force sfm_i - theta (sfp_i + sfm_i) sums to ``total`` [N]; ``sum_sfm`` and
    ``width`` = sum (sfp_i + sfm_i) over the members (> 0). Clamped: a total a rounding
    outside the summed interval."""
    return min(max((-total + sum_sfm) / width, 0.0), 1.0)


cdef inline double split_force(double theta, double sfp, double sfm) noexcept nogil:
    """A member's share [N] of its stuck cluster's ground force (``split_theta``)."""
    return sfm - theta * (sfp + sfm)


cdef inline double split_theta_fwd(double total, double sum_sfp, double width) noexcept nogil:
    """The same split measured from the forward end (the implicit method's arithmetic, kept
    for its bits): theta_f = 1 - theta in [0, 1] such that each member's force
    -sfp_i + theta_f (sfp_i + sfm_i) sums to ``total`` [N]; ``sum_sfp`` over the members."""
    return min(max((total + sum_sfp) / width, 0.0), 1.0)


cdef inline double split_force_fwd(double theta_f, double sfp, double sfm) noexcept nogil:
    """A member's share [N] of its stuck cluster's ground force (``split_theta_fwd``)."""
    return -sfp + theta_f * (sfp + sfm)


cdef inline double penalty_force(double nv, double fp, double fm) noexcept nogil:
    """The penalty method's regularised law (the seed paper's): the resisting force [N]
    F = clip(n v, -fm, fp) of a body at velocity v with penalty n (``nv`` = n v); the ground
    force is -F. Kinetic bounds only: the method refuses stiction."""
    return min(max(nv, -fm), fp)
