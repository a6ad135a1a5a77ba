# cython: language_level=3
"""The plant's compiled step from C (``_batch.pyx``): one ``Engine`` commanded, run for a
span and read, as ``step_plants`` does for each of N (the environments' batched step)."""

cdef int step_engine(object eng, const double* targets, Py_ssize_t nl, long long span_ns,
                     double* x, double* v, signed char* contact, Py_ssize_t p) except -1
