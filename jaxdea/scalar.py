"""Scalar root tools shared by every solver: status codes, sign-change bracketing on a grid,
safeguarded Newton, and implicit-function derivatives.

All functions are written for one case and are jit/vmap safe: no Python control flow on values,
failures give NaN and a status code instead of an exception.
"""

import enum

import jax
import jax.numpy as jnp


class Status(enum.IntEnum):
    """Status code of a solve (stored as int32 arrays)."""

    CONVERGED = 0  # a root, refined to full precision
    NO_ROOT = 1  # no (further) root in the searched range
    NOT_FINITE = 2  # a non-finite function value (overflow, expm failure, locking) stopped the search
    MAX_ITER = 3  # the iteration limit was reached before convergence


def value_and_slope(fun, x):
    """(f(x), f'(x)) with one forward-mode pass."""
    return jax.jvp(fun, (x,), (jnp.ones_like(x),))


def newton_bracketed(fun, lo, hi, f_lo, f_hi, rtol=1e-15, max_iter=200):
    """Root of ``fun`` in [lo, hi] given f(lo)·f(hi) ≤ 0, by Newton safeguarded with bisection.

    A Newton step that leaves the bracket, or that does not halve the previous step, is replaced
    by a bisection (Numerical Recipes' rtsafe), so convergence is guaranteed and quadratic near a
    simple root.

    Args:
        fun: x -> f(x), differentiable (the slope comes from ``jax.jvp``).
        lo, hi: the bracket; f_lo, f_hi: f there.
        rtol: stop when the step is below rtol·max(|x|, hi − lo of the initial bracket·1e-3).
        max_iter: iteration limit.

    Returns:
        (x, status): the root (NaN unless converged) and a :class:`Status` code.
    """
    dtype = jnp.result_type(lo, float)
    lo, hi, f_lo, f_hi = (jnp.asarray(v, dtype) for v in (lo, hi, f_lo, f_hi))
    # orient so that f(neg) < 0 < f(pos)
    neg = jnp.where(f_lo < 0, lo, hi)
    pos = jnp.where(f_lo < 0, hi, lo)
    width0 = jnp.abs(hi - lo)
    x0 = jnp.where(f_hi != f_lo, lo - f_lo * (hi - lo) / (f_hi - f_lo), 0.5 * (lo + hi))
    x0 = jnp.where((x0 > jnp.minimum(lo, hi)) & (x0 < jnp.maximum(lo, hi)), x0, 0.5 * (lo + hi))
    fx, dfx = value_and_slope(fun, x0)
    scale = jnp.maximum(jnp.abs(x0), 1e-3 * width0)

    def cond(s):
        _, _, _, fx, _, step, _, it, done = s
        return (~done) & (it < max_iter) & jnp.isfinite(fx)

    def body(s):
        neg, pos, x, fx, dfx, step, step_old, it, _ = s
        newton = x - fx / dfx
        lo_, hi_ = jnp.minimum(neg, pos), jnp.maximum(neg, pos)
        use_newton = (newton > lo_) & (newton < hi_) & jnp.isfinite(newton)
        use_newton &= jnp.abs(2.0 * fx) <= jnp.abs(step_old * dfx)
        x_new = jnp.where(use_newton, newton, 0.5 * (neg + pos))
        step_new = jnp.abs(x_new - x)
        f_new, df_new = value_and_slope(fun, x_new)
        neg = jnp.where(f_new < 0, x_new, neg)
        pos = jnp.where(f_new > 0, x_new, pos)
        tol = rtol * jnp.maximum(jnp.abs(x_new), scale)
        done = (step_new <= tol) | (f_new == 0) | (jnp.abs(pos - neg) <= tol)
        return neg, pos, x_new, f_new, df_new, step_new, step, it + 1, done

    bracketed = jnp.sign(f_lo) * jnp.sign(f_hi) <= 0
    finite = jnp.isfinite(f_lo) & jnp.isfinite(f_hi) & jnp.isfinite(lo) & jnp.isfinite(hi)
    init = (neg, pos, x0, fx, dfx, width0, 2.0 * width0, 0, (fx == 0) | ~bracketed | ~finite)
    neg, pos, x, fx, _, _, _, _, done = jax.lax.while_loop(cond, body, init)
    status = jnp.where(
        done, Status.CONVERGED, jnp.where(jnp.isfinite(fx), Status.MAX_ITER, Status.NOT_FINITE)
    )
    status = jnp.where(bracketed, status, Status.NO_ROOT)
    status = jnp.where(finite, status, Status.NOT_FINITE)
    done &= bracketed & finite
    return jnp.where(done, x, jnp.nan), status.astype(jnp.int32)


def illinois(fun, lo, hi, f_lo, f_hi, rtol=1e-13, max_iter=100):
    """Root of ``fun`` in [lo, hi] (f(lo)·f(hi) ≤ 0) by the Illinois variant of regula falsi.

    Needs values only (used on f' to locate extrema without second derivatives); superlinear, and
    the bracket always shrinks. Returns (x, status) like :func:`newton_bracketed`.
    """
    dtype = jnp.result_type(lo, float)
    lo, hi, f_lo, f_hi = (jnp.asarray(v, dtype) for v in (lo, hi, f_lo, f_hi))
    bracketed = (jnp.sign(f_lo) * jnp.sign(f_hi) <= 0) & jnp.isfinite(f_lo) & jnp.isfinite(f_hi)
    width0 = jnp.abs(hi - lo)

    def cond(s):
        a, b, fa, fb, _, it = s
        tol = rtol * jnp.maximum(jnp.maximum(jnp.abs(a), jnp.abs(b)), 1e-3 * width0)
        return (jnp.abs(b - a) > tol) & (it < max_iter) & (fa != 0) & (fb != 0)

    def body(s):
        a, b, fa, fb, side, it = s
        x = jnp.where(fb != fa, b - fb * (b - a) / (fb - fa), 0.5 * (a + b))
        x = jnp.where((x > jnp.minimum(a, b)) & (x < jnp.maximum(a, b)), x, 0.5 * (a + b))
        fx = fun(x)
        same_as_b = jnp.sign(fx) == jnp.sign(fb)
        # replace b by x; if x is on b's side the old a stays and its value is halved when the
        # same side was kept twice in a row (Illinois)
        a_new = jnp.where(same_as_b, a, b)
        fa_new = jnp.where(same_as_b, jnp.where(side == 1, 0.5 * fa, fa), fb)
        side = jnp.where(same_as_b, 1, -1)
        return a_new, x, fa_new, fx, side, it + 1

    a, b, fa, fb, _, it = jax.lax.while_loop(
        cond, body, (lo, hi, jnp.where(bracketed, f_lo, 0.0), f_hi, 0, 0))
    x = jnp.where(fa == 0, a, b)
    ok = bracketed & jnp.isfinite(fb)
    status = jnp.where(ok, jnp.where(it < max_iter, Status.CONVERGED, Status.MAX_ITER),
                       jnp.where(jnp.isfinite(f_lo) & jnp.isfinite(f_hi), Status.NO_ROOT,
                                 Status.NOT_FINITE))
    return jnp.where(status == Status.CONVERGED, x, jnp.nan), status.astype(jnp.int32)


def first_sign_change(values, after=None):
    """Index j of the first interval [j, j+1] with a sign change (values finite at both ends).

    Args:
        values: (M,) function values on an ascending grid.
        after: optional boolean mask (M − 1,) of admissible intervals.

    Returns:
        (j, found, blocked): j (0 if none), whether one was found, and whether a non-finite value
        occurs before it (or anywhere, when none was found).
    """
    a, b = values[:-1], values[1:]
    finite = jnp.isfinite(a) & jnp.isfinite(b)
    change = finite & (jnp.sign(a) * jnp.sign(b) <= 0)
    if after is not None:
        change &= after
    found = jnp.any(change)
    j = jnp.argmax(change)
    bad = ~finite
    blocked = jnp.where(found, jnp.any(bad & (jnp.arange(a.size) < j)), jnp.any(bad))
    return j, found, blocked


def implicit_root(fun, solve, x0):
    """A root x* of ``fun`` with implicit-function derivatives, dx*/dθ = −(∂f/∂θ)/(∂f/∂x).

    ``fun`` may close over traced parameters θ; ``solve()`` returns ``(x*, status)`` (its own
    derivatives are never used: no differentiation through the iterations). Built on
    ``jax.lax.custom_root``; ``x0`` only fixes the shape and dtype.

    Returns:
        (x*, status).
    """
    def solver(f, guess):
        del f, guess
        x, status = solve()
        return x, jnp.asarray(status, x.dtype)  # an integer aux has no tangent space here

    x, status = jax.lax.custom_root(
        fun, x0, solver, lambda g, y: y / g(jnp.ones_like(y)), has_aux=True
    )
    return x, jax.lax.stop_gradient(status).astype(jnp.int32)
