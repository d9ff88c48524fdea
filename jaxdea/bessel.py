"""Entire Bessel combinations for the fluid coupling functions (theory.md §4(b), §4(c)).

For s = χ̂² r̂_i² (either sign) and an integer order ν ≥ 0 this module returns the pair

    N_ν(s) ∝ J_ν(x)/x^ν,  D_ν(s) ∝ x J_ν'(x)/x^ν,  x = sqrt(s)        (s > 0),
    N_ν(s) ∝ I_ν(x̃)/x̃^ν,  D_ν(s) ∝ x̃ I_ν'(x̃)/x̃^ν,  x̃ = sqrt(−s)     (s < 0),

both multiplied by the same positive factor (2^ν ν! for small |s|, an extra e^{−x̃} for large
negative s). Both are entire in s, so the coupling B_ν = r̂_i N_ν/D_ν never needs a division: the
characteristic function only uses the direction of (N_ν, D_ν), which a positive factor leaves alone.

Small |s|: the power series Σ_k (−s/4)^k/(k!(k+ν)!) and D_ν = ν F_ν − s F_{ν+1} (no cancellation while
x ≲ 0.7ν + 8). Large |s|: Bessel's integrals J_ν(x) = (1/2π)∫cos(νt − x sin t)dt and
e^{−x̃}I_ν(x̃) = (1/2π)∫e^{x̃(cos t − 1)}cos νt dt by the trapezoidal rule on ``NODES`` points, which is
exponentially accurate for periodic integrands while x + ν < NODES − 40; beyond that the result is
NaN (reported, never wrong).

The positive factor is 2^ν ν! times e^{coupling_log_factor(s, ν)} (:func:`coupling_log_factor`), so
the true Bessel values can be recovered where they are needed, e.g. for the acoustic pressure
profile p̂*(r̂) ∝ J_0(χ̂ r̂) inside the cavity (:func:`jaxdea.modes.fluid_pressure`).
"""

import jax.numpy as jnp
import numpy as np
from jax.scipy.special import gammaln

NODES = 512
SERIES_TERMS = 96


def _switch(order):
    return jnp.maximum(8.0, 0.7 * order + 8.0) ** 2


def _series(s, order):
    """(Σ_k t_k, Σ_k u_k): t_k = ν!(−s/4)^k/(k!(k+ν)!), u_k = ν!(−s/4)^k/(k!(k+ν+1)!)."""
    k = jnp.arange(1, SERIES_TERMS + 1, dtype=jnp.float64)
    z = -0.25 * s
    t = jnp.cumprod(z / (k * (k + order)))
    u = jnp.cumprod(z / (k * (k + order + 1.0))) / (order + 1.0)
    return 1.0 + jnp.sum(t), 1.0 / (order + 1.0) + jnp.sum(u)


def _integrals(s, order):
    """(N, D) for large |s| from the trapezoidal Bessel integrals, in the series normalisation."""
    theta = jnp.asarray(2.0 * np.pi * np.arange(NODES) / NODES)
    x = jnp.sqrt(jnp.abs(s))
    phase = order * theta - x * jnp.sin(theta)
    j_nu = jnp.mean(jnp.cos(phase))
    xj_prime = x * jnp.mean(jnp.sin(phase) * jnp.sin(theta))
    damp = jnp.exp(x * (jnp.cos(theta) - 1.0))
    i_nu = jnp.mean(damp * jnp.cos(order * theta))
    xi_prime = x * jnp.mean(jnp.cos(theta) * damp * jnp.cos(order * theta))
    # 2^ν ν!/x^ν brings both branches to the normalisation of the series (a positive factor)
    factor = jnp.exp(order * np.log(2.0) + gammaln(order + 1.0) - order * jnp.log(x))
    positive = s > 0
    n = jnp.where(positive, j_nu, i_nu) * factor
    d = jnp.where(positive, xj_prime, xi_prime) * factor
    in_range = x + order < NODES - 40
    return jnp.where(in_range, n, jnp.nan), jnp.where(in_range, d, jnp.nan)


def _integrals_complex(s, order):
    """(N, D) for large |s| and complex s (complex Ω, :mod:`jaxdea.counting`), series normalisation
    times a positive factor.

    Re s ≥ 0: J_ν, J_ν' from Bessel's integral at x = sqrt(s) (principal), scaled by e^{−|Im x|};
    Re s < 0: I_ν, I_ν' at x̃ = sqrt(−s) (principal), scaled by e^{−Re x̃}. J_ν(x)/x^ν and
    x J_ν'(x)/x^ν are even in x and equal I_ν(x̃)/x̃^ν, x̃ I_ν'(x̃)/x̃^ν at x = i x̃, so both branches are
    the same entire function of s up to a real positive factor: arg N, arg D and the direction of
    (N, D) are continuous across Re s = 0, and the trapezoidal rule stays exponentially accurate for
    complex arguments while |x| + ν < NODES − 40 (beyond: NaN). The factors are positive but not
    analytic: only the arguments of N, D (and of the characteristic function) are meaningful.
    """
    theta = jnp.asarray(2.0 * np.pi * np.arange(NODES) / NODES)
    right = jnp.real(s) >= 0
    x = jnp.sqrt(jnp.where(right, s, -s))  # x (right) or x̃ (left), Re ≥ 0
    phase = order * theta - x * jnp.sin(theta)
    shrink = jnp.exp(-jnp.abs(jnp.imag(x)))
    j_nu = jnp.mean(jnp.cos(phase)) * shrink
    xj_prime = x * jnp.mean(jnp.sin(phase) * jnp.sin(theta)) * shrink
    damp = jnp.exp(x * (jnp.cos(theta) - 1.0) + 1j * jnp.imag(x))  # e^{x̃ cos t − Re x̃}
    i_nu = jnp.mean(damp * jnp.cos(order * theta))
    xi_prime = x * jnp.mean(jnp.cos(theta) * damp * jnp.cos(order * theta))
    factor = jnp.exp(order * np.log(2.0) + gammaln(order + 1.0) - order * jnp.log(x))  # 2^ν ν!/x^ν
    n = jnp.where(right, j_nu, i_nu) * factor
    d = jnp.where(right, xj_prime, xi_prime) * factor
    in_range = jnp.abs(x) + order < NODES - 40
    return jnp.where(in_range, n, jnp.nan), jnp.where(in_range, d, jnp.nan)


def coupling_pair(s, order):
    """(N_ν, D_ν) up to a common positive factor, entire in s = χ̂² r̂_i² (module docstring).

    Args:
        s: χ̂² r̂_i², any real value; or complex (complex Ω, :mod:`jaxdea.counting`), where the
            large-|s| branch is :func:`_integrals_complex` and the common factor stays real and
            positive (so arg N, arg D are exact), though no longer analytic in s.
        order: Bessel order ν ≥ 0 (static int).

    Returns:
        (n, d) with B_ν = r̂_i n/d (r̂_i n/d = r̂_i/ν at s = 0 for ν ≥ 1; D_0 = −s/2 + O(s²)).
    """
    order = jnp.asarray(order, dtype=jnp.float64)  # static int or traced (sweeps over n)
    small = jnp.abs(s) <= _switch(order)
    s_small = jnp.where(small, s, 0.0)  # double-where: clean derivatives in each branch
    s_large = jnp.where(small, _switch(order) * 4.0, s)
    f_nu, f_next = _series(s_small, order)
    n_small, d_small = f_nu, order * f_nu - 0.5 * s_small * f_next
    integrals = _integrals_complex if jnp.iscomplexobj(s) else _integrals  # real s: unchanged
    n_large, d_large = integrals(s_large, order)
    return jnp.where(small, n_small, n_large), jnp.where(small, d_small, d_large)


def coupling_log_factor(s, order):
    """log of the extra positive factor carried by :func:`coupling_pair` beyond 2^ν ν!.

    ``coupling_pair(s, ν)`` is (N_ν, D_ν) with N_ν = 2^ν ν! e^{g(s)} J_ν(x)/x^ν (s > 0) or
    2^ν ν! e^{g(s)} I_ν(x̃)/x̃^ν (s < 0), and g(s) = −x̃ = −sqrt(−s) on the large negative-s branch
    (the exponentially scaled integral of e^{−x̃}I_ν, module docstring), g(s) = 0 elsewhere. Hence
    e^{−g(s)} N_ν is the plain (2^ν ν!-normalised) Bessel value and, for 0 ≤ |s'| ≤ |s|, the ratio
    of true values is N_ν(s')/N_ν(s) · e^{g(s) − g(s')} with g(s) − g(s') ≤ 0 (no overflow).

    Args:
        s: χ̂² r̂² (the argument of ``coupling_pair`` at radius r̂), any real value.
        order: Bessel order ν ≥ 0, the same as in ``coupling_pair``.

    Returns:
        g(s): −sqrt(−s) where s < −switch(ν) (the branch of ``coupling_pair``), else 0; finite
        derivatives everywhere (double-where).
    """
    order = jnp.asarray(order, dtype=jnp.float64)  # static int or traced (sweeps over n)
    large_negative = s < -_switch(order)
    root = jnp.sqrt(jnp.where(large_negative, -s, 1.0))
    return jnp.where(large_negative, -root, 0.0)
