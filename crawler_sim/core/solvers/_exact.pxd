# cython: language_level=3
"""The exact solver's core from C (``_exact.pyx``): what the plant's compiled step
(``core/plant/_batch.pyx``) calls on an ``ExactCore`` (``core``, checked) in place of
``ExactSolver.advance``'s Python loop, for a gait that is not periodic (issue 41). Times in
seconds; statuses as ``_exact.REACHED`` etc."""
from crawler_sim.core.solvers._gait cimport CompiledGait

cdef int core_switch(object core, CompiledGait old, CompiledGait new) except -1
cdef int core_drive(object core, CompiledGait gait, double t1, long ev_base,
                    long* counts) except -1
cdef double core_time(object core) except? -1.0
cdef int core_settle(object core, bint skip, double tscale, double cap) except -1
cdef int core_forget(object core) except -1
cdef int core_read(object core, double* x, double* v, signed char* contact) except -1

ctypedef struct EventRecord:
    double t                # [s]
    long body, old, new     # the body, its contact state before and after (+1, 0, -1)

cdef object core_event_records(object core, long n)
