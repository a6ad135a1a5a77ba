# cython: language_level=3
"""The actuator's tick from C (``_actuator.pyx``): what the plant's compiled step
(``core/plant/_batch.pyx``) calls on an ``actuator.Actuator`` without a Python call, so a
control period of a crawler is one compiled pass (issue 41). ``servo`` is a ``Servo``
(checked). Units: s, m, m/s, m/s^2, m/s^3; times in integer nanoseconds."""

cdef Py_ssize_t servo_run(object servo, long long t0_ns, long long dt_ns, Py_ssize_t n,
                          double* st, double* an, double* cf) except -1
cdef int servo_target(object servo, const double* new) except -1
cdef int servo_state(object servo, double* l, double* v, double* a) except -1
cdef bint servo_following(object servo) except -1
