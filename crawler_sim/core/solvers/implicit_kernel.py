"""Compiled (numba, cached on disk) pieces of method "implicit" (MODEL.md sections 2.3 and 3).

The step is the Moreau-Jean (catching-up) step: one proximal problem in the centre-of-mass
velocity V, solved exactly by sorting the kinks. A step whose contact mode changes is split at
the transition: the transition time is located by bisection on the *instantaneous* mode of the
old mode's continuation (MODEL.md 2.3), to ``BISECT_REL`` of the step. Without the split, every
stick/slip transition lands on the step end; the O(h) velocity error this leaves has a sign and
size that depend on where the transition falls inside its step, and in a slide phase nothing
resets it, so it integrates into a position error whose size jumps from one dt to the next
(issue 14: -4.3e-4, +8.6e-4, -9.9e-5 ... for dt = 1e-3, 5e-4, 2.5e-4 ...). With the split the
remaining first-order error is the quadrature X_{k+1} = X_k + h V_{k+1}, about
(h / 2) (V(t) - V(0)): order 1 with a steady constant.

``implicit.py`` runs ``advance_fourier`` for ``Fourier`` and ``Sinusoid`` gaits (evaluated
inside the kernel), ``advance_table`` for any other gait (its rates at the step ends evaluated
beforehand), and calls the small helpers from its Python path; ``batch_step`` is
``ImplicitBatch``'s step.
Sign conventions: ``R[i]`` is the force of the ground on body i [N]; ``contact`` is +1 / 0 / -1.

(About 550 lines: numba functions that call each other are kept in one module, which is also
one unit of the on-disk cache; the two-body fast path repeats a few lines of the general step
on purpose, for speed.)
"""
from __future__ import annotations

import math

import numpy as np

try:
    INTERPRETED                 # set by ``implicit.py`` for its interpreted copy of this module
except NameError:
    INTERPRETED = False
if INTERPRETED:                 # the Python path: the same functions, run by the interpreter
    def njit(*args, **kwargs):
        return lambda f: f
else:
    from numba import njit

__all__ = ['prox', 'rel_rates', 'changed', 'new_mode', 'interval_friction', 'first_stuck',
           'slide_sum', 'fourier_rates', 'advance_fourier', 'MAX_DEPTH', 'BISECT_REL']

#: most transitions placed inside one step (more fall back to the plain Moreau-Jean step)
MAX_DEPTH = 8
#: bisection stops when the bracket is below this fraction of the step (about 1e-12 h)
BISECT_REL = 2.0 ** -40
_BISECT = 60


@njit(cache=True)
def prox(c, u_ref, force, kinks, fp, fm, n, idx):
    """Solve 0 in c (u - u_ref) - force + sum_i dphi_i(u - kinks[i]) for the first n entries.

    phi_i(w) = fp_i max(w, 0) + fm_i max(-w, 0). Returns (u, s): s is the sum of the dphi
    selections of the entries with kinks[i] == u (0 when none is); idx is an int scratch array.
    """
    for i in range(n):
        idx[i] = i
    for i in range(1, n):                       # insertion sort: n is the number of bodies
        v = idx[i]
        j = i
        while j > 0 and kinks[idx[j - 1]] > kinks[v]:
            idx[j] = idx[j - 1]
            j -= 1
        idx[j] = v
    above = 0.0
    for i in range(n):
        above += fm[i]
    below = 0.0
    i = 0
    while True:
        u = u_ref + (force - below + above) / c     # root left of kink group i
        if i == n:
            return u, 0.0
        k = kinks[idx[i]]
        if u < k:
            return u, 0.0
        ga = 0.0
        gb = 0.0
        j = i
        while j < n and kinks[idx[j]] == k:
            ga += fp[idx[j]]
            gb += fm[idx[j]]
            j += 1
        base = c * (k - u_ref) - force + below - (above - gb)
        if base + ga >= 0.0:
            s = -base
            s = min(max(s, -gb), ga)
            return k, s
        below += ga
        above -= gb
        i = j


@njit(cache=True)
def rel_rates(w, ld, out):
    """Body rates relative to the centre of mass from linkage rates: out_i = s_i - sum w_k s_k,
    s_0 = 0, s_i = ld_0 + ... + ld_{i-1}; w = masses / M. Used for e' and e''."""
    p = out.size
    mean = 0.0
    s = 0.0
    for i in range(p):
        if i > 0:
            s += ld[i - 1]
        mean += w[i] * s
    s = 0.0
    for i in range(p):
        if i > 0:
            s += ld[i - 1]
        out[i] = s - mean


@njit(cache=True)
def first_stuck(contact):
    for i in range(contact.size):
        if contact[i] == 0:
            return i
    return -1


@njit(cache=True)
def slide_sum(contact, fp, fm):
    """Total friction of the sliding bodies [N]."""
    s = 0.0
    for i in range(contact.size):
        if contact[i] > 0:
            s -= fp[i]
        elif contact[i] < 0:
            s += fm[i]
    return s


@njit(cache=True)
def _accel_mode(M, force, zmask, epp, fp, fm, kbuf, fpb, fmb, idx, out):
    """Instantaneous mode of the bodies in zmask (at zero velocity): solve the acceleration
    inclusion M a in force - sum dphi_i(a + e_i''), write out[i] for them; returns (a, s)."""
    n = 0
    for i in range(zmask.size):
        if zmask[i]:
            kbuf[n] = -epp[i]
            fpb[n] = fp[i]
            fmb[n] = fm[i]
            n += 1
    a, s = prox(M, 0.0, force, kbuf, fpb, fmb, n, idx)
    for i in range(zmask.size):
        if zmask[i]:
            d = a + epp[i]
            out[i] = 0 if a == -epp[i] else (1 if d > 0.0 else -1)
    return a, s


@njit(cache=True)
def changed(contact, V, ep, epp, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx, tmp):
    """Whether the mode ``contact`` no longer holds at an instant where the centre of mass
    moves at V (its continuation) and the bodies' relative rates are ep, epp."""
    p = contact.size
    for i in range(p):
        c = contact[i]
        if c > 0 and V + ep[i] <= 0.0:
            return True
        if c < 0 and V + ep[i] >= 0.0:
            return True
    j = first_stuck(contact)
    if j < 0:
        return False
    for i in range(p):
        zmask[i] = contact[i] == 0
        if zmask[i] and ep[i] != ep[j]:
            return True
    _accel_mode(M, fext + slide_sum(contact, fp, fm), zmask, epp, fp, fm, kbuf, fpb, fmb,
                idx, tmp)
    for i in range(p):
        if zmask[i] and tmp[i] != 0:
            return True
    return False


@njit(cache=True)
def new_mode(contact, V, ep, epp, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx, out):
    """The mode right after a transition of ``contact``'s continuation (V, ep, epp there):
    bodies that crossed zero join the stuck ones and the acceleration inclusion decides."""
    p = contact.size
    j = first_stuck(contact)
    force = fext
    for i in range(p):
        c = contact[i]
        v = V + ep[i]
        if c == 0:
            z = ep[i] == ep[j]
            sgn = 1 if v > 0.0 else -1
        else:
            z = (c > 0 and v <= 0.0) or (c < 0 and v >= 0.0)
            sgn = c
        zmask[i] = z
        if not z:
            out[i] = sgn
            force += -fp[i] if sgn > 0 else fm[i]
    _accel_mode(M, force, zmask, epp, fp, fm, kbuf, fpb, fmb, idx, out)


@njit(cache=True)
def interval_friction(contact, V0, V1, h, M, fext, fp, fm, R):
    """Mean friction [N] on an interval of length h > 0 from V0 to V1 in mode ``contact``:
    sliding bodies their Coulomb force, stuck ones share what momentum balance requires
    (each at the same fraction of its interval [-fp_i, fm_i]: only the total is unique)."""
    p = contact.size
    total = M * (V1 - V0) / h - fext
    lo = 0.0
    width = 0.0
    for i in range(p):
        c = contact[i]
        if c > 0:
            R[i] = -fp[i]
            total += fp[i]
        elif c < 0:
            R[i] = fm[i]
            total -= fm[i]
        else:
            lo -= fp[i]
            width += fp[i] + fm[i]
    theta = 0.0 if width <= 0.0 else min(max((total - lo) / width, 0.0), 1.0)
    for i in range(p):
        if contact[i] == 0:
            R[i] = -fp[i] + theta * (fp[i] + fm[i])


@njit(cache=True)
def fourier_rates(t, freq, ca, sb, w, ld, ldd, ep, epp):
    """e'(t), e''(t) of a Fourier gait (l = mean + sum a_jk cos k th + b_jk sin k th,
    th = 2 pi (f t mod 1)), evaluated in the kernel."""
    th = 2.0 * math.pi * ((freq * t) % 1.0)
    om = 2.0 * math.pi * freq
    n, K = ca.shape
    for j in range(n):
        ld[j] = 0.0
        ldd[j] = 0.0
    c1 = math.cos(th)
    s1 = math.sin(th)
    ck, sk = c1, s1
    for k in range(K):
        if k > 0:       # cos, sin of (k + 1) th by the angle-addition recurrence
            ck, sk = ck * c1 - sk * s1, sk * c1 + ck * s1
        wk = om * (k + 1)
        for j in range(n):
            a = ca[j, k]
            b = sb[j, k]
            ld[j] += wk * (b * ck - a * sk)
            ldd[j] -= wk * wk * (a * ck + b * sk)
    rel_rates(w, ld, ep)
    rel_rates(w, ldd, epp)


@njit(cache=True)
def fourier1(t, freq, ca, sb):
    """(l', l'') of linkage 0 of a Fourier gait at t, as floats: ``fourier_rates``' arithmetic
    for one linkage without its arrays (the two-body hot path)."""
    th = 2.0 * math.pi * ((freq * t) % 1.0)
    om = 2.0 * math.pi * freq
    c1 = math.cos(th)
    s1 = math.sin(th)
    ck, sk = c1, s1
    ld = 0.0
    ldd = 0.0
    for k in range(ca.shape[1]):
        if k > 0:
            ck, sk = ck * c1 - sk * s1, sk * c1 + ck * s1
        wk = om * (k + 1)
        a = ca[0, k]
        b = sb[0, k]
        ld += wk * (b * ck - a * sk)
        ldd -= wk * wk * (a * ck + b * sk)
    return ld, ldd


@njit(cache=True)
def prox2(c, u_ref, force, k0, k1, fp0, fp1, fm0, fm1):
    """``prox`` for two entries in scalars, with the same arithmetic (the two-body hot path)."""
    above = 0.0 + fm0 + fm1
    if k1 < k0:
        ka, kb, pa, pb, ma, mb = k1, k0, fp1, fp0, fm1, fm0
    else:
        ka, kb, pa, pb, ma, mb = k0, k1, fp0, fp1, fm0, fm1
    u = u_ref + (force - 0.0 + above) / c
    if u < ka:
        return u, 0.0
    if kb == ka:
        ga = 0.0 + pa + pb
        gb = 0.0 + ma + mb
        base = c * (ka - u_ref) - force + 0.0 - (above - gb)
        if base + ga >= 0.0:
            return ka, min(max(-base, -gb), ga)
        return u_ref + (force - ga + (above - gb)) / c, 0.0
    ga = 0.0 + pa
    gb = 0.0 + ma
    base = c * (ka - u_ref) - force + 0.0 - (above - gb)
    if base + ga >= 0.0:
        return ka, min(max(-base, -gb), ga)
    below = 0.0 + ga
    above -= gb
    u = u_ref + (force - below + above) / c
    if u < kb:
        return u, 0.0
    ga = 0.0 + pb
    gb = 0.0 + mb
    base = c * (kb - u_ref) - force + below - (above - gb)
    if base + ga >= 0.0:
        return kb, min(max(-base, -gb), ga)
    return u_ref + (force - (below + ga) + (above - gb)) / c, 0.0


@njit(cache=True)
def prox_mode(M, h, V, fext, epb, fp, fm, idx, kinks, contact, newc):
    """One implicit step of length h from V at rates ``epb``: (u, s, same) of ``prox``, with
    the contact it gives in ``newc`` (0 at a kink, else the sign of the body's velocity) and
    whether that equals ``contact``."""
    p = contact.size
    for i in range(p):
        kinks[i] = -epb[i]
    u, s = prox(M / h, V, fext, kinks, fp, fm, p, idx)
    same = True
    for i in range(p):
        newc[i] = 0 if u == kinks[i] else (1 if u + epb[i] > 0.0 else -1)
        same = same and newc[i] == contact[i]
    return u, s, same


@njit(cache=True)
def log_changes(t, contact, newc, ev_t, ev_b, ev_o, ev_n, n_ev):
    """Append an event (t, body, old, new) for each body whose contact differs in ``newc``,
    adopt ``newc`` into ``contact``; returns the new event count."""
    for i in range(contact.size):
        if newc[i] != contact[i]:
            ev_t[n_ev] = t
            ev_b[n_ev] = i
            ev_o[n_ev] = contact[i]
            ev_n[n_ev] = newc[i]
            n_ev += 1
            contact[i] = newc[i]
    return n_ev


@njit(cache=True)
def split_step(t, tb, V, X, contact, R, K, epb, eppb, w, M, fext, fp, fm, freq, ca, sb, dt,
               max_depth, ev_t, ev_b, ev_o, ev_n, n_ev, wf, idx, zmask, newc, tmp):
    """One step [t, tb] from (V, X, contact) with e', e'' = epb, eppb at tb: the Moreau-Jean
    step, split at each transition inside it (at most max_depth). Updates contact, R (mean
    friction of the last piece) and K in place, appends events; returns (V, X, n_ev).
    Scratch: wf float (8, p), idx int64 (p,), zmask bool (p,), newc and tmp int8 (p,)."""
    p = w.size
    ld, ldd = wf[0, :p - 1], wf[1, :p - 1]
    ep, epp, kinks, kbuf, fpb, fmb = wf[2], wf[3], wf[4], wf[5], wf[6], wf[7]
    lo = t
    u = V
    for depth in range(max_depth + 1):
        h = tb - lo
        if h <= 0.0:                    # a transition exactly at the step end
            u = V
            for i in range(p):
                newc[i] = contact[i]
            break
        u, s, same = prox_mode(M, h, V, fext, epb, fp, fm, idx, kinks, contact, newc)
        if same and (first_stuck(contact) < 0 or not changed(
                contact, u, epb, eppb, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx, tmp)):
            break
        if depth == max_depth or h <= BISECT_REL * dt:
            break
        j = first_stuck(contact)
        a_lo = (fext + slide_sum(contact, fp, fm)) / M
        uc = -epb[j] if j >= 0 else V + a_lo * h
        if not changed(contact, uc, epb, eppb, M, fext, fp, fm, zmask, kbuf, fpb, fmb,
                       idx, tmp):
            u = uc                      # the prox's change was its O(h) stick test
            for i in range(p):
                newc[i] = contact[i]
            break
        a, b = lo, tb
        for _ in range(_BISECT):
            if b - a <= BISECT_REL * dt:
                break
            mid = a + 0.5 * (b - a)
            fourier_rates(mid, freq, ca, sb, w, ld, ldd, ep, epp)
            vm = -ep[j] if j >= 0 else V + a_lo * (mid - lo)
            if changed(contact, vm, ep, epp, M, fext, fp, fm, zmask, kbuf, fpb, fmb,
                       idx, tmp):
                b = mid
            else:
                a = mid
        tau = b
        fourier_rates(tau, freq, ca, sb, w, ld, ldd, ep, epp)
        vt = -ep[j] if j >= 0 else V + a_lo * (tau - lo)
        new_mode(contact, vt, ep, epp, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx, newc)
        hh = tau - lo
        if hh > 0.0:
            interval_friction(contact, V, vt, hh, M, fext, fp, fm, R)
            X += hh * vt
            for i in range(p):
                K[i] += hh * R[i]
        n_ev = log_changes(tau, contact, newc, ev_t, ev_b, ev_o, ev_n, n_ev)
        V = vt
        lo = tau
    hh = tb - lo
    if hh > 0.0:
        interval_friction(newc, V, u, hh, M, fext, fp, fm, R)
    X += hh * u
    for i in range(p):
        K[i] += hh * R[i]
    n_ev = log_changes(tb, contact, newc, ev_t, ev_b, ev_o, ev_n, n_ev)
    return u, X, n_ev


@njit(cache=True)
def advance_fourier(st, contact, R, K, w, M, fext, fp, fm, freq, ca, sb, t1, dt, max_steps,
                    max_depth, ev_t, ev_b, ev_o, ev_n, ep_out, epp_out):
    """Steps of ``dt`` from st[0] to t1 (the last one shortened to land on t1), the gait a
    Fourier series evaluated here. st = [t, X, V, A] is updated in place with contact, R
    (friction of the last step) and K (impulse). Stops early after ``max_steps`` steps or when
    the event buffers (ev_*) may overflow; returns (steps, events written). ep_out, epp_out
    receive e', e'' at the last step end (as the step used them). max_depth: transitions placed
    inside one step (0: the plain Moreau-Jean step).

    Two bodies take a short path while the mode holds (no transition, at most one body stuck
    within its friction bounds): the same prox and the same tests as ``split_step``, inline."""
    p = w.size
    ld = np.empty(p - 1)
    ldd = np.empty(p - 1)
    epb = np.empty(p)
    eppb = np.empty(p)
    idx = np.empty(p, np.int64)
    wf = np.empty((8, p))
    zmask = np.empty(p, np.bool_)
    newc = np.empty(p, np.int8)
    tmp = np.empty(p, np.int8)
    t, X, V, A = st[0], st[1], st[2], st[3]
    cap = ev_t.size
    n_ev = 0
    steps = 0
    while t < t1 and steps < max_steps and n_ev + p * (MAX_DEPTH + 1) <= cap:
        tb = t1 if (t1 - t) / dt <= 1.0 + 1e-9 else t + dt
        V0 = V
        done = False
        if p == 2:
            l1, l2 = fourier1(tb, freq, ca, sb)
            mean = 0.0 + w[0] * 0.0 + w[1] * l1      # rel_rates' arithmetic
            ep0, ep1 = 0.0 - mean, l1 - mean
            mean2 = 0.0 + w[0] * 0.0 + w[1] * l2
            epp0, epp1 = 0.0 - mean2, l2 - mean2
            h = tb - t
            k0, k1 = -ep0, -ep1
            u, s = prox2(M / h, V, fext, k0, k1, fp[0], fp[1], fm[0], fm[1])
            c0 = 0 if u == k0 else (1 if u + ep0 > 0.0 else -1)
            c1 = 0 if u == k1 else (1 if u + ep1 > 0.0 else -1)
            if c0 == contact[0] and c1 == contact[1]:
                if c0 != 0 and c1 != 0:
                    done = True         # both slide: R is the two Coulomb forces already
                elif c0 != c1:
                    j = 0 if c0 == 0 else 1
                    i = 1 - j
                    # the stuck body's required force at tb (the acceleration test of changed)
                    ri = -fp[i] if contact[i] > 0 else fm[i]
                    rj = -M * (epp0 if j == 0 else epp1) - fext - ri
                    if -fp[j] <= rj <= fm[j]:
                        done = True
                        interval_friction(contact, V, u, h, M, fext, fp, fm, R)
            epb[0], epb[1], eppb[0], eppb[1] = ep0, ep1, epp0, epp1
            if done:
                X += h * u
                K[0] += h * R[0]
                K[1] += h * R[1]
                V = u
        else:
            fourier_rates(tb, freq, ca, sb, w, ld, ldd, epb, eppb)
        if not done:
            V, X, n_ev = split_step(t, tb, V, X, contact, R, K, epb, eppb, w, M, fext, fp, fm,
                                    freq, ca, sb, dt, max_depth, ev_t, ev_b, ev_o, ev_n, n_ev,
                                    wf, idx, zmask, newc, tmp)
        A = (V - V0) / (tb - t)
        t = tb
        steps += 1
    for i in range(p):
        ep_out[i] = epb[i]
        epp_out[i] = eppb[i]
    st[0] = t
    st[1] = X
    st[2] = V
    st[3] = A
    return steps, n_ev


@njit(cache=True)
def batch_step(h, rates, w, M, V, X, fext, fp, fm):
    """One plain Moreau-Jean step of B crawlers (``ImplicitBatch``): rates (1 or B, p - 1) are
    l'(t + h), shared when there is one row; V, X (B,) are updated in place."""
    B, p = fp.shape
    ep = np.empty(p)
    idx = np.empty(p, np.int64)
    shared = rates.shape[0] == 1
    for b in range(B):
        rel_rates(w[b], rates[0] if shared else rates[b], ep)
        for i in range(p):
            ep[i] = -ep[i]
        u, s = prox(M[b] / h, V[b], fext[b], ep, fp[b], fm[b], p, idx)
        V[b] = u
        X[b] += h * u


@njit(cache=True)
def advance_table(st, contact, R, K, w, M, fext, fp, fm, times, LD, LDD, k0, max_depth,
                  ep_out, epp_out, ev_t, ev_b, ev_o, ev_n):
    """Steps to times[k0], times[k0 + 1], ... with the gait's l', l'' there given in LD, LDD
    (N, p - 1) (any gait, evaluated by numpy beforehand). A step that needs the gait inside it
    (a transition to place) is left to the caller: returns (index of the first step not taken,
    events written). st = [t, X, V, A], contact, R, K are updated in place."""
    p = w.size
    epb = np.empty(p)
    eppb = np.empty(p)
    kinks = np.empty(p)
    kbuf = np.empty(p)
    fpb = np.empty(p)
    fmb = np.empty(p)
    idx = np.empty(p, np.int64)
    zmask = np.empty(p, np.bool_)
    newc = np.empty(p, np.int8)
    tmp = np.empty(p, np.int8)
    t, X, V, A = st[0], st[1], st[2], st[3]
    n_ev = 0
    k = k0
    while k < times.size and n_ev + p <= ev_t.size:
        tb = times[k]
        rel_rates(w, LD[k], epb)
        rel_rates(w, LDD[k], eppb)
        h = tb - t
        u, s, same = prox_mode(M, h, V, fext, epb, fp, fm, idx, kinks, contact, newc)
        ok = same and (first_stuck(contact) < 0 or not changed(
            contact, u, epb, eppb, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx, tmp))
        if not ok and max_depth > 0:
            j = first_stuck(contact)
            a_lo = (fext + slide_sum(contact, fp, fm)) / M
            uc = -epb[j] if j >= 0 else V + a_lo * h
            if changed(contact, uc, epb, eppb, M, fext, fp, fm, zmask, kbuf, fpb, fmb, idx,
                       tmp):
                break                       # a transition inside the step: the caller's
            u = uc
            for i in range(p):
                newc[i] = contact[i]
        interval_friction(newc, V, u, h, M, fext, fp, fm, R)
        X += h * u
        for i in range(p):
            K[i] += h * R[i]
            ep_out[i] = epb[i]
            epp_out[i] = eppb[i]
        n_ev = log_changes(tb, contact, newc, ev_t, ev_b, ev_o, ev_n, n_ev)
        A = (u - V) / h
        V = u
        t = tb
        k += 1
    st[0] = t
    st[1] = X
    st[2] = V
    st[3] = A
    return k, n_ev
