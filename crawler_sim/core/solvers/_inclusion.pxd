# cython: language_level=3
"""The one-dimensional monotone inclusion behind every method (MODEL.md sections 2.3 and 3):

    0  in  c (u - u_ref) - force + sum_i dphi_i(u - k_i),
    phi_i(w) = f_plus_i max(w, 0) + f_minus_i max(-w, 0),

a convex, piecewise-quadratic minimisation in one variable, solved exactly by sorting the
kinks k_i. With c = M/h, u = V_{k+1} it is the implicit (Moreau-Jean) step; with c = M,
u = the centre-of-mass acceleration and k_i = -e_i'' it selects the contact mode of the bodies
at rest (the exact method). One function for both.
"""


cdef inline double inclusion(double c, double u_ref, double force, const double* kinks,
                             const double* fp, const double* fm, int n, int* idx,
                             double* s) noexcept nogil:
    """The solution u of the inclusion over entries 0..n-1; ``s`` receives the sum of the
    dphi selections of the entries with kinks[i] == u exactly [N] (0 when none is). ``idx`` is
    an int scratch array of n entries (the entries sorted by kink, ties in index order)."""
    cdef int i, j, v
    cdef double above = 0.0, below = 0.0, u, k, ga, gb, base, lo, hi
    for i in range(n):
        idx[i] = i
    for i in range(1, n):               # insertion sort: n is a number of bodies
        v = idx[i]
        j = i
        while j > 0 and kinks[idx[j - 1]] > kinks[v]:
            idx[j] = idx[j - 1]
            j -= 1
        idx[j] = v
    for i in range(n):
        above += fm[i]
    i = 0
    while True:
        u = u_ref + (force - below + above) / c      # root left of kink group i
        if i == n or u < kinks[idx[i]]:
            break
        k = kinks[idx[i]]
        ga = 0.0
        gb = 0.0
        j = i
        while j < n and kinks[idx[j]] == k:
            ga += fp[idx[j]]
            gb += fm[idx[j]]
            j += 1
        base = c * (k - u_ref) - force + below - (above - gb)
        if base + ga >= 0.0:
            s[0] = min(max(-base, -gb), ga)
            return k
        below += ga
        above -= gb
        i = j
    # a free solution: it may still round onto a kink exactly, and the bodies there then sit
    # at it (the selection sum from the same balance)
    base = c * (u - u_ref) - force
    lo = 0.0
    hi = 0.0
    v = 0
    for i in range(n):
        if kinks[i] < u:
            base += fp[i]
        elif kinks[i] > u:
            base -= fm[i]
        else:
            lo -= fm[i]
            hi += fp[i]
            v = 1
    s[0] = min(max(-base, lo), hi) if v else 0.0
    return u
