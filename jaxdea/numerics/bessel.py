"""Entire Bessel combinations for the fluid coupling functions (docs/theory/axisymmetric.md §4(b), §4(c)).

For s = χ̂² r̂_i² (either sign) and an integer order ν ≥ 0 this module returns the pair

    N_ν(s) ∝ J_ν(x)/x^ν,  D_ν(s) ∝ x J_ν'(x)/x^ν,  x = sqrt(s)        (s > 0),
    N_ν(s) ∝ I_ν(x̃)/x̃^ν,  D_ν(s) ∝ x̃ I_ν'(x̃)/x̃^ν,  x̃ = sqrt(−s)     (s < 0),

both multiplied by the same positive factor. Both are entire in s, so the coupling B_ν = r̂_i N_ν/D_ν
never needs a division: the characteristic function only uses the direction of (N_ν, D_ν), which a
positive factor leaves alone.

The pair is built from one entire function, F_ν(s) = Σ_k ν!(−s/4)^k/(k!(k+ν)!) = 2^ν ν! J_ν(x)/x^ν
(= 2^ν ν! I_ν(x̃)/x̃^ν for s < 0), at two orders:

    N_ν = F_ν,   D_ν = ν F_ν − (s/2) F_{ν+1}/(ν+1)      (x J_ν' = ν J_ν − x J_{ν+1}),

times e^{g(s)}, g(s) = −sqrt(−s) for s < −SCALE_SWITCH and 0 elsewhere (:func:`coupling_log_factor`),
which keeps the modified Bessel functions finite. Derivatives follow dF_ν/ds = −F_{ν+1}/(4(ν+1)),
exactly and to any order (a ``jax.custom_jvp``: the slope of the pair evaluates F_ν, F_{ν+1},
F_{ν+2} in one pass, on the quadratures of order ν; each further order calls that triple one order up).

Small |s| (|s| ≤ (0.7ν + 8)², little cancellation) and −90² ≤ s < 0 (all terms positive): the
power series by Horner's rule. Otherwise Bessel's integrals J_ν(x) = (1/π)∫₀^π cos(νt − x sin t)dt
and e^{−x̃}I_ν(x̃) = (1/π)∫₀^π e^{x̃(cos t − 1)} cos νt dt by the trapezoidal rule, which on K points
of the full period is off by J_{K∓ν}(x), below 1e-17 while x + ν ≤ K − 12 K^{1/3} (against scipy the
bound holds with 11.6 at K = 1024). Each element takes the fewest points that meet this (``TIERS``,
64 … 512, nested: one loop adds the midpoints of each rule to the one before; I_ν only beyond
x̃ = 90, on 512). A scalar branches once (``lax.switch``); an array computes each branch only if
some element takes it (``lax.cond``; under ``jax.vmap`` a batching rule tests the whole batch at
once), so an element's value never depends on its neighbours. The
direction of (N_ν, D_ν) is within 1e-11 of scipy's for ν ≤ 40 over the whole range (tests);
beyond x + ν ≥ RANGE the result is NaN (reported, never wrong).
"""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.special import gammaln

NODES = 512
"""Points of the largest trapezoidal rule over the full period (the complex branch uses it alone)."""
TIERS = (64, 128, 256, 512)
SERIES_TERMS = 96
SERIES_UNROLL = 8
"""Horner steps per iteration of the series loop: a loop of 12, not 96 steps written out, which
took a fifth of the tracing of a first fluid-filled ``frequencies`` for no faster code."""
SCALE_SWITCH = 64.0
"""s < −SCALE_SWITCH: the pair carries the factor e^{−x̃} (the same for every order ν)."""
NEGATIVE_SERIES = 90.0**2
"""−NEGATIVE_SERIES ≤ s < 0: the series, whose terms are all positive there (no cancellation) and
converge to 1e-20 in SERIES_TERMS terms; the integral of I_ν cancels to e^{−ν²/2x̃} of its terms."""
DERIVATIVE_ORDERS = 8
"""Orders of s-derivatives kept inside the range: each one calls F one order up."""


def _tier_limit(nodes: int) -> float:
    """Largest x + ν at which the trapezoidal rule on ``nodes`` points is exact to 1e-17."""
    return nodes - 12.0 * nodes ** (1.0 / 3.0)


RANGE = _tier_limit(NODES) - DERIVATIVE_ORDERS
"""The pair is finite for x + ν < RANGE (≈ 408; x = sqrt(|s|)), NaN beyond, and so are its first
DERIVATIVE_ORDERS − 2 derivatives in s."""


def _switch(order):
    return jnp.maximum(8.0, 0.7 * order + 8.0) ** 2


def _series(s, order, count: int = 2):
    """(F_ν, …, F_{ν+count−1}) by Horner's rule on SERIES_TERMS terms: F_ν = 1 + z c₁(1 + z c₂(1 + …)),
    z = −s/4, c_k = 1/(k(k+ν))."""
    k = jnp.arange(SERIES_TERMS, 0, -1, dtype=jnp.float64)
    order = order[..., None]
    # independent of s: computed once for an unbatched ν (k + ν + j, not k + (ν + j): the same
    # integers, the same bits as before)
    recs = [1.0 / (k * (k + order))] + [1.0 / (k * (k + order + float(j))) for j in range(1, count)]
    z = -0.25 * s

    def horner(i, values):
        return tuple(1.0 + z * jax.lax.dynamic_index_in_dim(rec, i, -1, keepdims=False) * f
                     for rec, f in zip(recs, values, strict=True))

    return jax.lax.fori_loop(0, SERIES_TERMS, horner, (jnp.ones_like(s),) * count,
                             unroll=SERIES_UNROLL)


PIO2_HEAD, PIO2_TAIL = 1.57079632673412561417e+00, 6.07710050650619224932e-11  # π/2, 33 + 53 bits
SIN_TAYLOR = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(9))
COS_TAYLOR = tuple((-1) ** k / math.factorial(2 * k) for k in range(10))


def _sincos(b):
    """(sin b, cos b) for 0 ≤ b < 2^20: b = kπ/2 + r, |r| ≤ π/4 (Cody–Waite, exact k·PIO2_HEAD),
    Taylor polynomials in r to r^18, the quadrant k mod 4. Within 1.2e-16 of NumPy on [0, 500];
    one argument reduction and arithmetic only, 4× cheaper than ``jnp.sin`` and ``jnp.cos`` on CPU."""
    k = jnp.round(b * (2.0 / np.pi))
    r = (b - k * PIO2_HEAD) - k * PIO2_TAIL
    r2 = r * r
    sin_r, cos_r = SIN_TAYLOR[-1], COS_TAYLOR[-1]
    for c in SIN_TAYLOR[-2::-1]:
        sin_r = sin_r * r2 + c
    for c in COS_TAYLOR[-2::-1]:
        cos_r = cos_r * r2 + c
    sin_r = sin_r * r
    quadrant = jnp.mod(k, 4.0)
    sin_b = jnp.where(quadrant == 0, sin_r, jnp.where(quadrant == 1, cos_r,
                                                      jnp.where(quadrant == 2, -sin_r, -cos_r)))
    cos_b = jnp.where(quadrant == 0, cos_r, jnp.where(quadrant == 1, -sin_r,
                                                      jnp.where(quadrant == 2, -cos_r, sin_r)))
    return sin_b, cos_b


def _normalised(sums, x, order, count: int):
    """(F_ν, …, F_{ν+count−1}) from Bessel's integrals ``sums`` (π J_μ(x) or π e^{−x̃} I_μ(x̃) over
    π): F_μ = sum · 2^μ μ!/x^μ, each F_{μ+1} written from μ's factor (as the pair at μ has it)."""
    def factor(mu):  # 2^μ μ!/x^μ: the normalisation of the series (a positive factor)
        return jnp.exp(mu * np.log(2.0) + gammaln(mu + 1.0) - mu * jnp.log(x))

    mus = [order] + [order + float(j) for j in range(1, count)]
    return (sums[0] * factor(order),) + tuple(
        sums[j] * factor(mus[j - 1]) * 2.0 * (mus[j - 1] + 1.0) / x for j in range(1, count))


def _negative(s, order, count: int = 2):
    """(F_ν, …, F_{ν+count−1}) e^{g(s)} for negative s from e^{−x̃}I_ν(x̃) = (1/π)∫₀^π e^{x̃(cos t − 1)}
    cos νt dt on NODES points of the full period (NODES/2 + 1 on [0, π], the integrand being even
    about π)."""
    half = NODES // 2
    t = np.pi * np.arange(half + 1) / half
    weight = np.full(half + 1, 1.0 / half)
    weight[[0, -1]] *= 0.5
    t, weight = jnp.asarray(t), jnp.asarray(weight)
    x = jnp.sqrt(jnp.abs(s))
    damp = jnp.exp(x[..., None] * (jnp.cos(t) - 1.0)) * weight
    sums = [jnp.sum(damp * jnp.cos((order[..., None] + float(j)) * t), axis=-1)
            for j in range(count)]  # ν unbatched: the cosines once
    return _normalised(sums, x, order, count)


CHUNK_NODES = TIERS[0] // 2
"""Nodes on [0, π] of the smallest rule, and midpoints added per chunk by :func:`_positive`."""


def _positive(s, order, level, count: int = 2):
    """(F_ν, …, F_{ν+count−1}) e^{g(s)} for positive s from J_ν(x) = (1/π)∫₀^π cos(νt − x sin t) dt
    on the rule of ``TIERS[level]`` points of the full period (``level`` per element).

    The rules are nested, each adding the midpoints of the one before, so one loop over chunks of
    CHUNK_NODES midpoints serves every tier: a single program section instead of one per tier (the
    acoustic ``frequencies`` compiled 0.7–0.9 CPU s faster; values within 1.2e-14 of the separate
    rules, another order of summation). The base rule has the nodes πj/32, j = 0 … 32 (half weight
    at both ends); chunk c adds the nodes π(2i + 1)/(32·2^L), i = 32(c − 2^{L−1} + 1) + 0 … 31, of
    the level L = 1 + [c ≥ 1] + [c ≥ 3], and an element of level ℓ takes the first 2^ℓ − 1."""
    x = jnp.sqrt(jnp.abs(s))
    orders = [order + float(j) for j in range(count)]

    def integrand(t, weight=1.0):  # cos((ν + j)t − b) = cos (ν + j)t cos b + sin (ν + j)t sin b
        sin_b, cos_b = _sincos(x[..., None] * jnp.sin(t))  # b = x sin t
        sin_b, cos_b = sin_b * weight, cos_b * weight
        return [jnp.sum(cos_b * jnp.cos(o[..., None] * t) + sin_b * jnp.sin(o[..., None] * t),
                        axis=-1) for o in orders]

    ends = np.full(CHUNK_NODES + 1, 1.0)
    ends[[0, -1]] = 0.5
    base = integrand(jnp.asarray(np.pi * np.arange(CHUNK_NODES + 1) / CHUNK_NODES), jnp.asarray(ends))
    chunks = 2**level - 1
    lane = jnp.arange(CHUNK_NODES, dtype=jnp.float64)

    def add_chunk(c, sums):
        lev = 1 + (c >= 1).astype(jnp.int32) + (c >= 3).astype(jnp.int32)
        first = 2 ** (lev - 1) - 1
        t = np.pi * (2.0 * ((c - first) * CHUNK_NODES + lane) + 1.0) / (CHUNK_NODES * 2.0**lev)
        return [u + jnp.where(c < chunks, v, 0.0) for u, v in zip(sums, integrand(t), strict=True)]

    sums = jax.lax.fori_loop(0, jnp.max(chunks), add_chunk, base)
    half = CHUNK_NODES * 2.0**level
    return _normalised([u / half for u in sums], x, order, count)


def _rules(s, order):
    """For each element, the branch it takes and the level of its rule: branch 0 the series (below
    the switch, or −NEGATIVE_SERIES ≤ s < 0), 1 Bessel's integral of J_ν on TIERS[level] points
    (the fewest that are exact for F_{ν+1}: x + ν + 2 ≤ K − 12 K^{1/3}; :func:`_positive`), 2 that
    of I_ν on NODES points (x̃ > 90, :func:`_negative`), 3 beyond the largest rule (NaN); the
    level is 0 outside branch 1."""
    small = (jnp.abs(s) <= _switch(order)) | ((s < 0) & (s >= -NEGATIVE_SERIES))
    reach = jnp.sqrt(jnp.abs(s)) + order + 2.0
    level = sum((reach > _tier_limit(nodes)).astype(jnp.int32) for nodes in TIERS)
    positive = jnp.where(level < len(TIERS), 1, 3)
    negative = jnp.where(reach > _tier_limit(NODES), 3, 2)
    branch = jnp.where(small, 0, jnp.where(s > 0, positive, negative))
    return branch, jnp.where(branch == 1, level, 0)


def _values_of_any_shape(s, order, count: int):
    """(F_ν, …, F_{ν+count−1}) e^{g(s)} elementwise over arrays of any (broadcastable) shape. Every
    element takes its own quadrature (:func:`_rules`, those of order ν for all of them), so its
    value never depends on the others; a scalar branches once (``lax.switch``), an array computes
    each quadrature only if some element takes it (``lax.cond``; the series too, whose result XLA
    would otherwise recompute in every fusion that uses it)."""
    shape = jnp.broadcast_shapes(jnp.shape(s), jnp.shape(order))
    index, level = _rules(s, order)
    scale = jnp.exp(coupling_log_factor(s))
    stand_in = [0.0, 4.0 * _switch(order), -4.0 * _switch(order), 0.0]  # admissible s per branch

    def series(s):
        return tuple(jnp.broadcast_to(f * scale, shape) for f in _series(s, order, count))

    def positive(s):
        return _positive(s, order, level, count)

    def negative(s):
        return _negative(s, order, count)

    def constant(value):
        return lambda s: (jnp.full(shape, value),) * count

    branches = [series, positive, negative, constant(jnp.nan)]
    if shape == ():
        return jax.lax.switch(index, branches, s)
    values = (jnp.zeros(shape),) * count
    for i, branch in enumerate(branches):
        here = index == i
        taken = jax.lax.cond(jnp.any(here), branch, constant(0.0), jnp.where(here, s, stand_in[i]))
        values = tuple(jnp.where(here, t, v) for t, v in zip(taken, values, strict=True))
    return values


def _batched(count: int):
    """:func:`_values_of_any_shape` of ``count`` orders, whose ``jax.vmap`` is the same function on
    the whole batch, so that the tiers' conditionals test the batch at once (and an enclosing vmap
    does the same one level up)."""
    @jax.custom_batching.custom_vmap
    def values(s, order):
        return _values_of_any_shape(s, order, count)

    @values.def_vmap
    def rule(axis_size, in_batched, s, order):
        shape = jnp.broadcast_shapes(*(jnp.shape(a)[1:] if b else jnp.shape(a)
                                       for a, b in zip((s, order), in_batched, strict=True)))

        def lead(a, batched):  # the batch axis first, then the per-element shape broadcast to ``shape``
            if not batched:
                return a
            a = jnp.reshape(a, (axis_size,) + (1,) * (len(shape) - (jnp.ndim(a) - 1))
                            + jnp.shape(a)[1:])
            return jnp.broadcast_to(a, (axis_size, *shape))

        s, order = lead(s, in_batched[0]), lead(order, in_batched[1])
        if not in_batched[0]:
            s = jnp.broadcast_to(s, (axis_size, *shape))
        return values(s, order), (True,) * count

    return values


_pair_batched, _triple_batched = _batched(2), _batched(3)


@jax.custom_jvp
def _scaled_pair(s, order):
    """e^{g(s)} (F_ν(s), F_{ν+1}(s)) (module docstring)."""
    return _pair_batched(s, order)


def _slopes(s, order, values, last):
    """d/ds e^g F_μ = g' e^g F_μ − e^g F_{μ+1}/(4(μ+1)) for μ = ν, ν+1, … (``values`` = e^g F_μ,
    ``last`` the one after them); no derivative in ν."""
    g_slope = jax.jvp(coupling_log_factor, (s,), (jnp.ones_like(s),))[1]
    after = (*values[1:], last)
    return tuple(g_slope * f - f_after / (4.0 * (order + float(j + 1)))
                 for j, (f, f_after) in enumerate(zip(values, after, strict=True)))


@_scaled_pair.defjvp
def _scaled_pair_jvp(primals, tangents):
    """The derivative from one evaluation of three orders (:func:`_scaled_triple`): one program
    section where two pairs (ν and ν + 1) took two."""
    s, order = primals
    ds, _ = tangents
    f_nu, f_next, f_after = _scaled_triple(s, order)
    slopes = _slopes(s, order, (f_nu, f_next), f_after)
    return (f_nu, f_next), tuple(d * ds for d in slopes)


@jax.custom_jvp
def _scaled_triple(s, order):
    """e^{g(s)} (F_ν(s), F_{ν+1}(s), F_{ν+2}(s)), each element on the quadrature of order ν."""
    return _triple_batched(s, order)


@_scaled_triple.defjvp
def _scaled_triple_jvp(primals, tangents):
    s, order = primals
    ds, _ = tangents
    values = _scaled_triple(s, order)
    slopes = _slopes(s, order, values, _scaled_triple(s, order + 1.0)[2])
    return values, tuple(d * ds for d in slopes)


def _integrals_complex(s, order):
    """(N, D) for large |s| and complex s (complex Ω, :mod:`jaxdea.solve.counting`), series normalisation
    times a positive factor.

    Re s ≥ 0: J_ν, J_ν' from Bessel's integral at x = sqrt(s) (principal), scaled by e^{−|Im x|};
    Re s < 0: I_ν, I_ν' at x̃ = sqrt(−s) (principal), scaled by e^{−Re x̃}. J_ν(x)/x^ν and
    x J_ν'(x)/x^ν are even in x and equal I_ν(x̃)/x̃^ν, x̃ I_ν'(x̃)/x̃^ν at x = i x̃, so both branches are
    the same entire function of s up to a real positive factor: arg N, arg D and the direction of
    (N, D) are continuous across Re s = 0, and the trapezoidal rule on NODES points stays accurate
    for complex arguments while |x| + ν < RANGE (beyond: NaN). The factors are positive but not
    analytic, so they are held constant under differentiation: the derivative of (N, D) in s is
    the analytic one, times the factor.
    """
    theta = jnp.asarray(2.0 * np.pi * np.arange(NODES) / NODES)
    right = jnp.real(s) >= 0
    x = jnp.sqrt(jnp.where(right, s, -s))  # x (right) or x̃ (left), Re ≥ 0
    phase = order * theta - x * jnp.sin(theta)
    # the positive factors are held constant under differentiation (stop_gradient: the same value):
    # d/ds of N, D is then that of the entire function times a constant, so the log-derivative of
    # the characteristic function is the analytic one (complex Newton steps,
    # :mod:`jaxdea.physics.characteristic`)
    shrink = jax.lax.stop_gradient(jnp.exp(-jnp.abs(jnp.imag(x))))
    j_nu = jnp.mean(jnp.cos(phase)) * shrink
    xj_prime = x * jnp.mean(jnp.sin(phase) * jnp.sin(theta)) * shrink
    damp = jnp.exp(x * (jnp.cos(theta) - 1.0) + 1j * jax.lax.stop_gradient(jnp.imag(x)))  # e^{x̃ cos t − Re x̃}
    i_nu = jnp.mean(damp * jnp.cos(order * theta))
    xi_prime = x * jnp.mean(jnp.cos(theta) * damp * jnp.cos(order * theta))
    factor = jnp.exp(order * np.log(2.0) + gammaln(order + 1.0) - order * jnp.log(x))  # 2^ν ν!/x^ν
    n = jnp.where(right, j_nu, i_nu) * factor
    d = jnp.where(right, xj_prime, xi_prime) * factor
    in_range = jnp.abs(x) + order < RANGE
    return jnp.where(in_range, n, jnp.nan), jnp.where(in_range, d, jnp.nan)


def _complex_pair(s, order):
    """(N_ν, D_ν) for complex s: the series (:func:`_series`) below the switch, the integrals of
    :func:`_integrals_complex` above."""
    small = jnp.abs(s) <= _switch(order)
    s_small = jnp.where(small, s, 0.0)
    s_large = jnp.where(small, _switch(order) * 4.0, s)
    f_nu, f_next = _series(s_small, order)
    n_small, d_small = f_nu, order * f_nu - 0.5 * s_small * f_next / (order + 1.0)
    n_large, d_large = _integrals_complex(s_large, order)
    return jnp.where(small, n_small, n_large), jnp.where(small, d_small, d_large)


def coupling_pair(s, order):
    """(N_ν, D_ν) up to a common positive factor, entire in s = χ̂² r̂_i² (module docstring).

    Args:
        s: χ̂² r̂_i², any real value; or complex (complex Ω, :mod:`jaxdea.solve.counting`), where the
            large-|s| branch is :func:`_integrals_complex` and the common factor stays real and
            positive (so arg N, arg D are exact), though no longer analytic in s.
        order: Bessel order ν ≥ 0 (static int, or traced: sweeps over n or m).

    Returns:
        (n, d) with B_ν = r̂_i n/d (r̂_i n/d = r̂_i/ν at s = 0 for ν ≥ 1; D_0 = −s/2 + O(s²)); NaN
        where sqrt(|s|) + ν ≥ RANGE.
    """
    order = jnp.asarray(order, dtype=jnp.float64)
    if jnp.iscomplexobj(s):
        return _complex_pair(s, order)
    f_nu, f_next = _scaled_pair(s, order)
    inside = jnp.sqrt(jnp.abs(s)) + order < RANGE
    n, d = f_nu, order * f_nu - 0.5 * s * f_next / (order + 1.0)
    return jnp.where(inside, n, jnp.nan), jnp.where(inside, d, jnp.nan)


def coupling_log_factor(s):
    """log of the positive factor carried by :func:`coupling_pair` beyond 2^ν ν!, any order ν.

    ``coupling_pair(s, ν)`` is (N_ν, D_ν) with N_ν = 2^ν ν! e^{g(s)} J_ν(x)/x^ν (s > 0) or
    2^ν ν! e^{g(s)} I_ν(x̃)/x̃^ν (s < 0), g(s) = −x̃ = −sqrt(−s) for s < −SCALE_SWITCH (the
    exponentially scaled modified functions), g(s) = 0 elsewhere. Hence e^{−g(s)} N_ν is the plain
    (2^ν ν!-normalised) Bessel value and, for 0 ≤ |s'| ≤ |s|, the ratio of true values is
    N_ν(s')/N_ν(s) · e^{g(s) − g(s')} with g(s) − g(s') ≤ 0 (no overflow).

    Args:
        s: χ̂² r̂² (the argument of ``coupling_pair`` at radius r̂), any real value.

    Returns:
        g(s), with finite derivatives everywhere (double-where).
    """
    large_negative = s < -SCALE_SWITCH
    root = jnp.sqrt(jnp.where(large_negative, -s, 1.0))
    return jnp.where(large_negative, -root, 0.0)


# --- The outer face: K_m of an unbounded fluid (docs/theory/real_tubes.md §6) ----------------------

K_NODES = 32
"""Points of the trapezoidal rule of :func:`_k_ratio_01` on [0, T(y)], |y| > K_SERIES."""
K_COMPLEX_NODES = 96
"""Points of the rule of :func:`_k_ratio_01` for complex y (the rotated path needs them)."""
K_WIDE_NODES = 384
"""Points of the rules of :func:`_k_ratio_real` and :func:`scaled_k`, over every y > 0 and order."""
K_TAIL = 60.0
"""The rule stops at T with Re y (cosh T − 1) = K_TAIL: the integrand is e^{−60} of its peak there."""
ARG_MAX = 0.9 * np.pi
"""|arg y| < ARG_MAX for a complex y of :func:`outer_impedance` (the path of :func:`_k_ratio_01`
is checked to there)."""
OUTER_ORDER_MAX = 128
"""Orders m ≤ OUTER_ORDER_MAX of :func:`outer_impedance` (the forward recurrence runs that many
masked steps for a traced m); NaN beyond."""


def _k_ratio_01(y):
    """K_0(y)/K_1(y) for |arg y| < π: the series at |y| ≤ K_SERIES (:func:`_k_series_01`), else
    e^y K_ν(y) = ∫ e^{−y(cosh τ − 1)} cosh ντ dτ (ν = 0, 1; DLMF 10.32.9) on the path
    τ(s) = s − iφ tanh s, s ∈ [0, T], φ = arg y: the real axis for real y > 0, and for complex y a
    path along which y cosh τ turns real at large s, so that the integral converges and continues
    K analytically through |arg y| ≥ π/2 (the leaky side of the outer fluid). The trapezoidal rule
    on K_NODES + 1 points (K_COMPLEX_NODES + 1 for complex y) of the even, analytic integrand errs
    by e^{−2πd/h} (h = T/K_NODES ≤ 0.13, T from the tail bound K_TAIL). Within 3e-15 of SciPy for
    real y from 1e-8 to 1e6, 3e-12 for complex y to |y| = 1e4 and |arg y| ≤ 0.9π."""
    small = jnp.abs(y) <= K_SERIES
    k_0, k_1 = _k_series_01(jnp.where(small, y, 1.0))
    y = jnp.where(small, 2.0 * K_SERIES, y)
    nodes = K_COMPLEX_NODES if jnp.iscomplexobj(y) else K_NODES
    top = jnp.arccosh(1.0 + K_TAIL / jnp.abs(y))
    s = jnp.linspace(0.0, 1.0, nodes + 1) * top[..., None]
    weight = jnp.ones(nodes + 1).at[0].set(0.5)
    if jnp.iscomplexobj(y):
        phase = jnp.angle(y)[..., None]
        path = s - 1j * phase * jnp.tanh(s)
        weight = weight * (1.0 - 1j * phase / jnp.cosh(s) ** 2)
    else:
        path = s
    kernel = weight * jnp.exp(-y[..., None] * 2.0 * jnp.sinh(0.5 * path) ** 2)
    ratio = jnp.sum(kernel, axis=-1) / jnp.sum(kernel * jnp.cosh(path), axis=-1)
    return jnp.where(small, k_0 / k_1, ratio)


K_SERIES = 2.0
"""|y| ≤ K_SERIES: K_0, K_1 by their ascending series (:func:`_k_series_01`)."""
K_TERMS = 24
"""Terms of those series: (|y|²/4)^k/(k!)² < 1e-40 beyond."""


def _k_series_01(y):
    """(K_0(y), K_1(y)) by the ascending series (DLMF 10.31.1–10.31.2, principal log: analytic for
    |arg y| < π), with z = y²/4, H_k the harmonic numbers and γ Euler's constant:

        K_0 = −(ln(y/2) + γ) I_0 + Σ_{k≥1} H_k z^k/(k!)²,
        K_1 = 1/y + ln(y/2) I_1 − (y/4) Σ_{k≥0} (2H_k + 1/(k+1) − 2γ) z^k/(k!(k+1)!),

    I_0 = Σ z^k/(k!)², I_1 = (y/2) Σ z^k/(k!(k+1)!)."""
    k, harmonic, inverse_square, inverse_next = _K_SERIES
    z = (0.25 * y * y)[..., None] ** k
    log_half = jnp.log(0.5 * y)
    i_0 = jnp.sum(z * inverse_square, axis=-1)
    i_1 = 0.5 * y * jnp.sum(z * inverse_next, axis=-1)
    k_0 = -(log_half + np.euler_gamma) * i_0 + jnp.sum(z * harmonic * inverse_square, axis=-1)
    psi_sum = 2.0 * harmonic + 1.0 / (k + 1.0) - 2.0 * np.euler_gamma
    k_1 = 1.0 / y + log_half * i_1 - 0.25 * y * jnp.sum(z * psi_sum * inverse_next, axis=-1)
    return k_0, k_1


_FACTORIALS = np.array([math.factorial(k) for k in range(K_TERMS + 1)], dtype=np.float64)
_K_SERIES = (np.arange(K_TERMS),
             np.concatenate([[0.0], np.cumsum(1.0 / np.arange(1, K_TERMS))]),  # H_k
             1.0 / _FACTORIALS[:-1] ** 2,  # 1/(k!)²
             1.0 / (_FACTORIALS[:-1] * _FACTORIALS[1:]))  # 1/(k!(k+1)!)
"""(k, H_k, 1/(k!)², 1/(k!(k+1)!)) of :func:`_k_series_01`."""


def outer_impedance(y, m):
    """R_m(y) = y K_m'(y)/K_m(y) = −m − y K_{m−1}(y)/K_m(y) (K_{−1} = K_1), the outer fluid's face
    factor at y = γr̂_o, γ = sqrt(α̂² − Ω²/ĉ_o²) (subsonic: y > 0, R_m < 0: added mass).

    A static m (a Python number; the longitudinal family's 0): the ratios ρ_n = K_{n−1}/K_n by the
    forward recurrence ρ_{n+1} = 1/(ρ_n + 2n/y) (DLMF 10.29.1; K is the dominant solution, so the
    recurrence is stable), m steps from ρ_1 = K_0/K_1 (:func:`_k_ratio_01`, K_NODES points). A
    traced m: K_{|m−1|}/K_m in one quadrature of K_WIDE_NODES points for real y
    (:func:`_k_ratio_real`), the recurrence in OUTER_ORDER_MAX masked steps for complex y. Real
    y > 0 (subsonic), or complex y with |arg y| < ARG_MAX (analytic there: K_m continued through
    the upper or lower half-plane, the leaky side of :func:`jaxdea.physics.dispersion.outer_face`);
    NaN elsewhere and for m > OUTER_ORDER_MAX. The derivative in y is the exact
    dR_m/dy = (y² + m² − R_m²)/y (:func:`_impedance_slope`).

    Args:
        y: γr̂_o, real or complex, scalar.
        m: the circumferential order, an integer ≥ 0 (traced or not).
    """
    y = jnp.asarray(y)
    static = isinstance(m, (int, float)) and float(m) == int(m) and 0 <= m <= OUTER_ORDER_MAX
    if static:
        return _impedance_static(y, int(m))
    return _impedance_traced(y, jnp.asarray(m, dtype=jnp.float64))


def _impedance_slope(y, m, impedance):
    """dR_m/dy = (y² + m² − R_m²)/y: Bessel's equation y²K'' + yK' − (y² + m²)K = 0 in
    R = yK'/K (exact, analytic: the slope never differentiates a quadrature)."""
    return (y * y + m * m - impedance * impedance) / y


@functools.partial(jax.custom_jvp, nondiff_argnums=(1,))
def _impedance_static(y, order: int):
    """:func:`outer_impedance` of a static order: ``order`` recurrence steps from K_0/K_1."""
    m = float(order)
    if jnp.iscomplexobj(y):
        ok = (jnp.abs(jnp.angle(y)) < ARG_MAX) & (jnp.abs(y) > 0)
    else:
        ok = y > 0
    y_safe = jnp.where(ok, y, 1.0)
    first = _k_ratio_01(y_safe)
    ratio = 1.0 / first  # ρ_0 = K_{−1}/K_0 = K_1/K_0
    if order >= 1:
        ratio = first
        for n in range(1, order):
            ratio = 1.0 / (ratio + 2.0 * n / y_safe)
    return jnp.where(ok, -m - y_safe * ratio, jnp.nan)


@_impedance_static.defjvp
def _impedance_static_jvp(order, primals, tangents):
    (y,), (y_dot,) = primals, tangents
    impedance = _impedance_static(y, order)
    return impedance, _impedance_slope(y, float(order), impedance) * y_dot


@jax.custom_jvp
def _impedance_traced(y, m):
    """:func:`outer_impedance` of a traced order m."""
    ok = m <= OUTER_ORDER_MAX
    if not jnp.iscomplexobj(y):
        ok &= y > 0
        y_safe = jnp.where(ok, y, 1.0)
        return jnp.where(ok, -m - y_safe * _k_ratio_real(y_safe, m), jnp.nan)
    ok &= (jnp.abs(jnp.angle(y)) < ARG_MAX) & (jnp.abs(y) > 0)
    y_safe = jnp.where(ok, y, 1.0)
    first = _k_ratio_01(y_safe)

    def step(ratio, n):
        return jnp.where(n < m, 1.0 / (ratio + 2.0 * n / y_safe), ratio), None

    ratio, _ = jax.lax.scan(step, first, jnp.arange(1.0, OUTER_ORDER_MAX + 1.0))
    ratio = jnp.where(m == 0, 1.0 / first, ratio)
    return jnp.where(ok, -m - y_safe * ratio, jnp.nan)


@_impedance_traced.defjvp
def _impedance_traced_jvp(primals, tangents):
    (y, m), (y_dot, _) = primals, tangents
    impedance = _impedance_traced(y, m)
    return impedance, _impedance_slope(y, m, impedance) * y_dot


def _log_cosh(x):
    """log cosh x without overflow: |x| + log1p(e^{−2|x|}) − log 2."""
    x = jnp.abs(x)
    return x + jnp.log1p(jnp.exp(-2.0 * x)) - np.log(2.0)


def _k_ratio_real(y, m):
    """K_{|m−1|}(y)/K_m(y) for real y > 0 and a real order m ≥ 0 (traced), from
    e^y K_ν(y) = ∫_0^∞ e^{−y(cosh t − 1)} cosh νt dt (DLMF 10.32.9) at ν = |m − 1| and m on the same
    K_WIDE_NODES + 1 trapezoidal points of [0, T], T past the peak of the integrand (sinh t = m/y) by
    the tail bound K_TAIL, each integrand scaled by the largest of order m (no overflow at large m,
    small y): within 3e-14 of SciPy for m ≤ 128 and 1e-8 ≤ y ≤ 1e6."""
    peak = jnp.arcsinh(m / y)
    top = jnp.arccosh(1.0 + (K_TAIL + m * peak) / y)  # beyond the peak: y(cosh T − 1) > m·peak
    count = K_WIDE_NODES
    t = jnp.linspace(0.0, 1.0, count + 1) * top
    weight = jnp.ones(count + 1).at[0].set(0.5)
    base = -y * 2.0 * jnp.sinh(0.5 * t) ** 2  # −y(cosh t − 1) without cancellation
    upper = base + _log_cosh(m * t)
    lower = base + _log_cosh((m - 1.0) * t)
    shift = jnp.max(upper)
    return jnp.sum(weight * jnp.exp(lower - shift)) / jnp.sum(weight * jnp.exp(upper - shift))


def scaled_k(y, m):
    """e^y K_m(y) for real y > 0 and an order m ≥ 0 (traced or not): ∫_0^T e^{−y(cosh t − 1)}
    cosh mt dt (DLMF 10.32.9) by the trapezoidal rule on K_WIDE_NODES + 1 points, T past the peak of
    the integrand (sinh t = m/y) by the tail bound K_TAIL: within 3e-15 of SciPy's ``kve`` for
    m ≤ 20 and 1e-3 ≤ y ≤ 1e4 (the outer fluid's pressure field, :func:`jaxdea.outer_pressure`)."""
    y = jnp.asarray(y, jnp.float64)
    m = jnp.asarray(m, jnp.float64)
    peak = jnp.arcsinh(m / y)
    top = jnp.arccosh(1.0 + (K_TAIL + m * peak) / y)  # beyond the peak: y(cosh T − 1) > m·peak
    count = K_WIDE_NODES
    t = jnp.linspace(0.0, 1.0, count + 1) * top[..., None]
    weight = jnp.ones(count + 1).at[0].set(0.5) * (top / count)[..., None]
    exponent = -y[..., None] * 2.0 * jnp.sinh(0.5 * t) ** 2  # cosh t − 1 without cancellation
    return jnp.sum(weight * jnp.exp(exponent) * jnp.cosh(m[..., None] * t), axis=-1)
