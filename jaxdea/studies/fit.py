"""Inverse characterisation: material and geometry of the tube from measured resonances (SI units).

The model of a measured peak at voltage V of order m, axial mode n and branch k is

    f_model = Ω_k(m; V̂, α̂_n) c_s/(2π R_i),   c_s = sqrt(μ/ρ_s),   V̂ = V sqrt(ε/μ)/R_i,
    α̂_n = 2nπ R_i/(λ_z L)   (= 2nπη/(length_ratio λ_z) with length_ratio = L/R_o = Lη/R_i),

with Ω_k the k-th lowest positive root of order m (:func:`jaxdea.frequencies`, docs/theory/axisymmetric.md and
docs/theory/order_m.md), refined by :func:`jaxdea.frequency` from the current root and converted to Hz
(:mod:`jaxdea.physics.units`). :func:`fit` minimises ½ Σ r_j², r_j = (f_model − f_data)_j/σ_j, over the free
parameters θ mapped onto their bounds, θ = lo + (hi − lo)·sigmoid(u).

Solver. A small Levenberg–Marquardt loop in NumPy (Marquardt's diagonal scaling; the damping is
divided by 3 after an accepted step and multiplied by 4 after a rejected one) on the unconstrained u,
with the exact Jacobian ∂r/∂θ from ``jax.jacfwd`` through the implicit root derivatives (never
finite differences). It is written here rather than taken from optimistix
because every iteration has host-side steps that a jitted solver cannot hold: the roots are
re-seeded from the accepted iterate (the Newton guesses of the next residual), branches are
re-checked with the global root scan, and unlabelled peaks are re-assigned to modes with
:func:`scipy.optimize.linear_sum_assignment`; the problem is tiny (≤ 11 parameters) and its cost
is the residual/Jacobian evaluation, so a NumPy loop adds nothing measurable (and no dependency
beyond scipy).
A coarse grid of starts inside the bounds (best ``n_starts`` by initial cost, plus ``initial``
when given) guards against a poor initial guess.

Uncertainty. At the optimum, cov(θ) = s² (JᵀJ)⁻¹ with J = ∂r/∂θ in the physical parameters; s² = 1
when ``sigma_Hz`` is given (the 95 % interval is θ ± 1.95996 √cov, normal quantile), otherwise
s² = Σr²/(N − p) and the interval uses Student's t with N − p degrees of freedom. A Jacobian
whose log-scaled singular values fall below 1e-8 of the largest is rank-deficient: the data do not
determine the combination of parameters given by the null vector (e.g. μ, ρ_s and ε scaled
together leave every f and V̂ unchanged; at V = 0 alone, μ and ρ_s enter only as μ/ρ_s); a
:class:`IdentifiabilityWarning` names it and the intervals of the parameters in it are NaN.
"""

from __future__ import annotations

import enum
import math
import os
import warnings
from collections.abc import Mapping
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..params import Fluid, Tube, require_x64
from ..solve.roots import frequencies, frequency

NAMES = ("shear_modulus", "density", "permittivity", "inner_radius", "length", "eta", "lambda_i",
         "lambda_z", "gent", "fluid_density", "fluid_speed")
"""Every parameter :func:`fit` knows, in the order of its internal vector (SI units)."""
FLUID_NAMES = ("fluid_density", "fluid_speed")
UNITS = dict(shear_modulus="Pa", density="kg/m^3", permittivity="F/m", inner_radius="m",
             length="m", eta="", lambda_i="", lambda_z="", gent="", fluid_density="kg/m^3",
             fluid_speed="m/s")
RANK_TOLERANCE = 1e-8
"""Relative singular value of the log-scaled Jacobian below which it counts as rank-deficient."""
CURVE_CHUNK = 8
"""Points per compiled batch of :func:`fitted_frequencies` (the smallest batch of :func:`fit`)."""


class FitStatus(enum.IntEnum):
    """Outcome of :func:`fit`."""

    CONVERGED = 0  # the step (or the cost, at the rounding floor) stopped changing
    MAX_ITERATIONS = 1  # the iteration limit was reached first
    NOT_FINITE = 2  # no start gave a finite model (a labelled branch missing, an unstable state)
    ASSIGNMENT_CHANGING = 3  # the mode assignment of unlabelled peaks did not settle


class IdentifiabilityWarning(UserWarning):
    """The data do not determine some combination of the free parameters (rank-deficient J)."""


class FitResult(NamedTuple):
    """Result of :func:`fit` (physical units throughout).

    Attributes:
        estimate: {name: value} of the free parameters.
        interval: {name: (low, high)}, 95 % confidence intervals (NaN where not identifiable).
        covariance: (p, p) covariance of the free parameters, in ``names`` order.
        correlation: (p, p) correlation matrix.
        residuals: (f_model − f_data)/σ per data point (Hz when no σ given; NaN if unmatched).
        assignment: (N, 3) int array of (m, n, branch) per data point; (−1, −1, −1) for a peak
            that matches no mode (excluded from the fit).
        status: :class:`FitStatus`.
        iterations: Levenberg–Marquardt iterations of the chosen start (all its rounds of
            branch re-checks and re-assignments).
        names: the free parameter names, in the order of ``covariance``.
        parameters: {name: value} of every parameter of the model, free (the estimates) and fixed.
        settings: the model's discretisation and fluid: {"n_layers", "coupling" (None: empty
            tube), "bessel_order"} (:func:`fitted_frequencies` evaluates the fitted model with it).
    """

    estimate: dict
    interval: dict
    covariance: np.ndarray
    correlation: np.ndarray
    residuals: np.ndarray
    assignment: np.ndarray
    status: FitStatus
    iterations: int
    names: tuple
    parameters: dict
    settings: dict


# ---------------------------------------------------------------------------------------------
# model


def dimensionless(values, voltage_V, n, coupling=None, bessel_order=None):
    """(Tube, α̂_n, Fluid or None, Hz per unit Ω) of a parameter vector in ``NAMES`` order.

    V̂ = V sqrt(ε/μ)/R_i, length_ratio = L/R_o = Lη/R_i, α̂_n = 2nπ R_i/(λ_z L),
    ρ̂_f = ρ_f/ρ_s, ĉ_f = c_f/c_s, f = Ω c_s/(2π R_i) (docs/theory/axisymmetric.md §0).
    """
    mu, rho, eps, ri, length, eta, li, lz, gent, rho_f, c_f = (values[i] for i in range(11))
    tube = Tube(voltage=voltage_V * jnp.sqrt(eps / mu) / ri, lambda_i=li, lambda_z=lz, eta=eta,
                gent=gent, length_ratio=length * eta / ri)
    alpha = 2.0 * math.pi * n * ri / (lz * length)
    speed = jnp.sqrt(mu / rho)
    fluid = None if coupling is None else Fluid(density_ratio=rho_f / rho, speed_ratio=c_f / speed,
                                                coupling=coupling, bessel_order=bessel_order)
    return tube, alpha, fluid, speed / (2.0 * math.pi * ri)


@partial(jax.jit, static_argnames=("n_roots", "n_layers", "coupling", "bessel_order", "axisymmetric"))
def mode_roots(values, voltage_V, n, m, n_roots, n_layers, coupling, bessel_order, axisymmetric):
    """Ω of the ``n_roots`` lowest positive roots of order m at α̂_n, per point: (points, n_roots).

    ``axisymmetric``: every m is 0 (the longitudinal family); otherwise m ≥ 1, traced."""
    def one(v, k, order):
        tube, alpha, fluid, _ = dimensionless(values, v, k, coupling, bessel_order)
        return frequencies(tube, alpha, fluid, n_roots, n_layers=n_layers,
                           m=0 if axisymmetric else order)
    return jax.vmap(one)(voltage_V, n, m)


@partial(jax.jit, static_argnames=("n_layers", "coupling", "bessel_order", "axisymmetric"))
def model_and_jacobian(values, voltage_V, n, m, guess, n_layers, coupling, bessel_order,
                       axisymmetric):
    """(Ω, f in Hz, ∂f/∂values) per point, Ω by Newton from ``guess`` (implicit derivatives).

    The Jacobian is ``jax.jacfwd`` with respect to all 11 values (one program whatever is free)."""
    def hz(vals):
        def one(v, k, order, g):
            tube, alpha, fluid, scale = dimensionless(vals, v, k, coupling, bessel_order)
            omega = frequency(tube, alpha, g, fluid, n_layers, m=0 if axisymmetric else order)
            return jnp.stack([omega * scale, omega])
        out = jax.vmap(one)(voltage_V, n, m, guess)
        return out[:, 0], (out[:, 0], out[:, 1])

    jac, (f, omega) = jax.jacfwd(hz, has_aux=True)(values)
    return omega, f, jac


def _padded(size: int) -> int:
    """Batch size rounded up to a power of two (≥ 8), so that data sets share compiled programs."""
    return max(8, 1 << (size - 1).bit_length())


def _by_family(m, fun):
    """Apply ``fun(index, axisymmetric)`` to the points with m = 0 and m ≥ 1 (padded batches)."""
    out = []
    for axisymmetric in (True, False):
        index = np.flatnonzero((m == 0) if axisymmetric else (m > 0))
        if index.size:
            padded = np.concatenate([index, np.full(_padded(index.size) - index.size, index[0])])
            out.append((index, fun(padded, axisymmetric)))
    return out


class _Problem(NamedTuple):
    """The fixed part of a fit: data, names, bounds, discretisation."""

    voltage: np.ndarray
    frequency: np.ndarray
    sigma: np.ndarray
    has_sigma: bool
    free: tuple
    lower: np.ndarray
    upper: np.ndarray
    base: np.ndarray  # the full value vector (fixed values; free entries overwritten)
    free_index: np.ndarray
    n_layers: int
    coupling: str | None
    bessel_order: int | None


def _values(problem: _Problem, theta):
    values = problem.base.copy()
    values[problem.free_index] = theta
    return values


def _roots(problem: _Problem, theta, voltage, n, m, n_roots):
    """Ω (points, n_roots) of order m at α̂_n and voltage, NaN-padded."""
    out = np.full((voltage.size, n_roots), np.nan)
    values = jnp.asarray(_values(problem, theta))
    for index, found in _by_family(m, lambda p, axi: mode_roots(
            values, jnp.asarray(voltage[p]), jnp.asarray(n[p], float), jnp.asarray(m[p], float),
            n_roots, problem.n_layers, problem.coupling, problem.bessel_order, axi)):
        out[index] = np.asarray(found)[:index.size]
    return out


def _evaluate(problem: _Problem, theta, labels, guess):
    """(Ω, f_model in Hz, ∂f/∂θ free columns) at the labelled points (rows with m < 0 are NaN)."""
    omega = np.full(labels.shape[0], np.nan)
    f = np.full(labels.shape[0], np.nan)
    jac = np.full((labels.shape[0], len(problem.free)), np.nan)
    active = labels[:, 0] >= 0
    values = jnp.asarray(_values(problem, theta))
    where = np.flatnonzero(active)
    m = labels[where, 0]
    for index, (w, hz, j) in _by_family(m, lambda p, axi: model_and_jacobian(
            values, jnp.asarray(problem.voltage[where[p]]), jnp.asarray(labels[where[p], 1], float),
            jnp.asarray(m[p], float), jnp.asarray(guess[where[p]]), problem.n_layers,
            problem.coupling, problem.bessel_order, axi)):
        rows = where[index]
        omega[rows] = np.asarray(w)[:index.size]
        f[rows] = np.asarray(hz)[:index.size]
        jac[rows] = np.asarray(j)[:index.size][:, problem.free_index]
    return omega, f, jac


def _seed(problem: _Problem, theta, labels):
    """Ω of each labelled branch from the global root scan (NaN for unmatched rows)."""
    seed = np.full(labels.shape[0], np.nan)
    active = np.flatnonzero(labels[:, 0] >= 0)
    if active.size:
        roots = _roots(problem, theta, problem.voltage[active], labels[active, 1],
                       labels[active, 0], int(labels[active, 2].max()) + 1)
        seed[active] = roots[np.arange(active.size), labels[active, 2]]
    return seed


# ---------------------------------------------------------------------------------------------
# mode identification


def assign_modes(problem: _Problem, theta, m_max: int, n_max: int, n_branches: int,
                 threshold: float | None):
    """Labels (m, n, branch) of the peaks: at each voltage, the minimum-cost one-to-one matching of
    the peaks to the model modes (m ≤ m_max, 1 ≤ n ≤ n_max, branch < n_branches) with cost
    |log f_model − log f_data| (:func:`scipy.optimize.linear_sum_assignment`). A peak whose cost
    exceeds ``threshold`` matches no mode: (−1, −1, −1).

    Returns:
        (labels (N, 3) int, cost (N,)).
    """
    from scipy.optimize import linear_sum_assignment  # scipy: imported where it is used

    voltages = np.unique(problem.voltage)
    grid = np.array([(v, n, m) for v in voltages for m in range(m_max + 1)
                     for n in range(1, n_max + 1)])
    roots = _roots(problem, theta, grid[:, 0], grid[:, 1], grid[:, 2].astype(int), n_branches)
    scale = float(np.asarray(dimensionless(_values(problem, theta), 0.0, 1.0)[3]))
    labels = np.full((problem.voltage.size, 3), -1, dtype=int)
    cost = np.full(problem.voltage.size, np.inf)
    for v in voltages:
        peaks = np.flatnonzero(problem.voltage == v)
        rows = np.flatnonzero(grid[:, 0] == v)
        modes = [(int(grid[r, 2]), int(grid[r, 1]), k, roots[r, k] * scale)
                 for r in rows for k in range(n_branches) if np.isfinite(roots[r, k])]
        if not modes:
            continue
        model = np.log([mode[3] for mode in modes])
        table = np.abs(np.log(problem.frequency[peaks])[:, None] - model[None, :])
        pick, chosen = linear_sum_assignment(table)
        for p, c in zip(pick, chosen, strict=True):
            cost[peaks[p]] = table[p, c]
            if threshold is None or table[p, c] <= threshold:
                labels[peaks[p]] = modes[c][:3]
    return labels, cost


# ---------------------------------------------------------------------------------------------
# solver


def _to_free(problem, u):
    s = 0.5 + 0.5 * np.tanh(0.5 * u)  # sigmoid(u), without overflow for large |u|
    span = problem.upper - problem.lower
    return problem.lower + span * s, span * s * (1.0 - s)


def _to_unconstrained(problem, theta):
    s = np.clip((theta - problem.lower) / (problem.upper - problem.lower), 1e-15, 1.0 - 1e-15)
    return np.log(s) - np.log1p(-s)  # a θ on its bound (sigmoid saturated) gives |u| ≈ 34.5


def levenberg_marquardt(problem: _Problem, theta0, labels, max_iterations=100, xtol=1e-13,
                        ftol=1e-12):
    """Minimise ½‖r‖² from θ0 for fixed labels: LM on u (θ = lo + (hi − lo) sigmoid(u)), the exact
    J = ∂r/∂θ · dθ/du, step (JᵀJ + λ diag JᵀJ) δ = −Jᵀr, roots re-seeded from each accepted iterate.

    Converged when a step changes no θ by more than ``xtol`` relatively, when the predicted
    decrease −Jᵀr·δ − ½ δᵀJᵀJδ of a step is below ``ftol`` times the cost (the estimate is then
    within sqrt(2 ftol · cost) standard deviations of the minimum, 5e-6 for a cost of 15), or when
    no damping decreases the cost (its rounding floor).

    Returns:
        (θ, Ω, residuals, ∂r/∂θ, iterations, status).
    """
    u = _to_unconstrained(problem, theta0)
    theta, dtheta = _to_free(problem, u)
    omega, f, jac = _evaluate(problem, theta, labels, _seed(problem, theta, labels))
    active = labels[:, 0] >= 0
    sigma = problem.sigma

    def residual(f):
        return ((f - problem.frequency) / sigma)[active]

    r = residual(f)
    if not np.all(np.isfinite(r)) or not np.all(np.isfinite(jac[active])):
        return theta, omega, r, jac[active] / sigma[active, None], 0, FitStatus.NOT_FINITE
    cost, damping, iterations = 0.5 * r @ r, 1e-3, 0
    status = FitStatus.MAX_ITERATIONS
    while iterations < max_iterations:
        iterations += 1
        ju = jac[active] / sigma[active, None] * dtheta[None, :]
        a, g = ju.T @ ju, ju.T @ r
        diag = np.maximum(np.diag(a), 1e-30 * max(np.max(np.diag(a)), 1e-300))
        accepted = False
        while damping < 1e20:
            step = np.linalg.solve(a + damping * np.diag(diag), -g)
            if -(g @ step) - 0.5 * step @ a @ step <= ftol * cost:
                break  # nothing left to gain that the rounding of the cost could show
            trial_theta, trial_dtheta = _to_free(problem, u + step)
            trial = _evaluate(problem, trial_theta, labels, omega)
            r_trial = residual(trial[1])
            cost_trial = 0.5 * r_trial @ r_trial
            if np.all(np.isfinite(r_trial)) and cost_trial <= cost:
                accepted = True
                break
            damping *= 4.0
        if not accepted:  # no decrease worth a step, or none at any damping: converged
            status = FitStatus.CONVERGED
            break
        small = np.all(np.abs(trial_theta - theta) <= xtol * np.maximum(np.abs(theta), 1e-300))
        u, theta, dtheta, r, cost = u + step, trial_theta, trial_dtheta, r_trial, cost_trial
        omega, f, jac = trial
        damping = max(damping / 3.0, 1e-12)
        if small or cost == 0.0:
            status = FitStatus.CONVERGED
            break
    return theta, omega, r, jac[active] / sigma[active, None], iterations, status


def _fit_labelled(problem, theta0, labels, max_iterations, max_outer=5):
    """LM with the branches re-checked by the global scan until the tracked roots are the
    labelled ones (Newton may have slid onto a neighbouring branch)."""
    iterations = 0
    for _ in range(max_outer):
        theta, omega, r, jac, its, status = levenberg_marquardt(problem, theta0, labels,
                                                                max_iterations)
        iterations += its
        if status == FitStatus.NOT_FINITE:
            return theta, r, jac, iterations, status
        seed = _seed(problem, theta, labels)
        active = labels[:, 0] >= 0
        if np.allclose(seed[active], omega[active], rtol=1e-7, atol=0.0):
            return theta, r, jac, iterations, status
        theta0 = theta
    return theta, r, jac, iterations, status


# ---------------------------------------------------------------------------------------------
# uncertainty


def uncertainty(problem: _Problem, theta, r, jac):
    """(covariance, correlation, intervals, null combination or None) at the optimum."""
    from scipy.stats import norm, t  # scipy: imported where it is used

    p = theta.size
    dof = max(r.size - p, 1)
    variance = 1.0 if problem.has_sigma else float(r @ r) / dof
    quantile = norm.ppf(0.975) if problem.has_sigma else t.ppf(0.975, dof)
    scaled = jac * np.abs(theta)[None, :]  # ∂r/∂log θ
    _, singular, vt = np.linalg.svd(scaled, full_matrices=False)
    deficient = singular.size < p or singular[-1] <= RANK_TOLERANCE * singular[0]
    with np.errstate(all="ignore"):
        if deficient:
            keep = singular > RANK_TOLERANCE * singular[0]
            inv = (vt[keep].T / singular[keep] ** 2) @ vt[keep]
            covariance = variance * inv * np.outer(np.abs(theta), np.abs(theta))
            null = vt[-1]
            involved = np.abs(null) > 0.1 if singular.size == p else np.ones(p, bool)
            covariance[involved, :] = np.nan
            covariance[:, involved] = np.nan
        else:
            null, covariance = None, variance * np.linalg.inv(jac.T @ jac)
        std = np.sqrt(np.diag(covariance))
        correlation = covariance / np.outer(std, std)
    intervals = {name: (theta[i] - quantile * std[i], theta[i] + quantile * std[i])
                 for i, name in enumerate(problem.free)}
    return covariance, correlation, intervals, null


def _warn_null(names, null):
    terms = " · ".join(f"{name}^{c:+.3f}" for name, c in zip(names, null, strict=True)
                       if abs(c) > 0.1)
    warnings.warn(f"the Jacobian is rank-deficient: the data do not determine the combination "
                  f"{terms} (null vector of ∂r/∂log θ); the intervals of those parameters are NaN "
                  f"(fix one of them)", IdentifiabilityWarning, stacklevel=3)


# ---------------------------------------------------------------------------------------------
# validation


_RANGE = ("(0, inf)", "the open interval (0, 1)")


def _admissible(name, value):
    """Every parameter is > 0; η = R_i/R_o is < 1 as well."""
    return value > 0 and (name != "eta" or value < 1)


def _column(data, name, required=True):
    try:
        present = name in data
    except TypeError:
        present = False
    if not present:
        if required:
            raise ValueError(f"data is missing the column {name!r} (needs voltage_V, "
                             f"frequency_Hz; optional sigma_Hz, m, n, branch)")
        return None
    try:
        values = np.asarray(data[name], dtype=np.float64).ravel()
    except (TypeError, ValueError) as exc:
        raise ValueError(f"data column {name!r} must hold real numbers") from exc
    if not np.all(np.isfinite(values)):
        raise ValueError(f"data column {name!r} must be finite, got non-finite values")
    return values


def _integer_column(data, name, low):
    values = _column(data, name, required=False)
    if values is None:
        return None
    if np.any(values != np.round(values)) or np.any(values < low):
        raise ValueError(f"data column {name!r} must hold integers >= {low}")
    return values.astype(int)


def _validate(data, free, fixed, fluid):
    if not isinstance(data, Mapping) and not hasattr(data, "columns"):
        raise ValueError(f"data must be a mapping of columns (dict, DataFrame), got "
                         f"{type(data).__name__}")
    if not isinstance(free, Mapping) or not isinstance(fixed, Mapping):
        raise ValueError("free must be a mapping {name: (lower, upper)} and fixed {name: value}")
    if fluid is None:
        coupling, bessel_order = None, None
    elif isinstance(fluid, Fluid):
        coupling, bessel_order = fluid.coupling, fluid.bessel_order
    elif fluid in ("acoustic", "paper"):
        coupling, bessel_order = fluid, None
    else:
        raise ValueError(f"fluid must be None, 'acoustic', 'paper' or a jaxdea.Fluid, got {fluid!r}")
    if coupling == "paper" and bessel_order is None:
        raise ValueError("fluid with the 'paper' coupling needs an explicit bessel_order")
    known = NAMES if coupling is not None else NAMES[:-2]
    for name in list(free) + list(fixed):
        if name not in known:
            extra = " (fluid parameters need fluid=...)" if name in FLUID_NAMES else ""
            raise ValueError(f"unknown parameter {name!r}{extra}; known: {', '.join(known)}")
        if name in free and name in fixed:
            raise ValueError(f"parameter {name!r} is both free and fixed")
    missing = [name for name in known if name not in free and name not in fixed]
    if missing:
        raise ValueError(f"parameters {', '.join(missing)} are neither free nor fixed")
    if not free:
        raise ValueError("free must name at least one parameter")
    lower, upper = [], []
    for name, bounds in free.items():
        try:
            low, high = (float(b) for b in bounds)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"free[{name!r}] must be (lower, upper), got {bounds!r}") from exc
        if not (np.isfinite(low) and np.isfinite(high) and low < high):
            raise ValueError(f"free[{name!r}] bounds must be finite with lower < upper, "
                             f"got {bounds!r}")
        if not (_admissible(name, low) and _admissible(name, high)):
            raise ValueError(f"free[{name!r}] bounds must lie in {_RANGE[name == 'eta']}, "
                             f"got {bounds!r}")
        lower.append(low)
        upper.append(high)
    base = np.ones(len(NAMES))
    for name, value in fixed.items():
        try:
            value = float(value)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"fixed[{name!r}] must be a real number, got {value!r}") from exc
        if not (np.isfinite(value) or (name == "gent" and value == np.inf)):
            raise ValueError(f"fixed[{name!r}] must be finite, got {value!r}")
        if not _admissible(name, value):
            raise ValueError(f"fixed[{name!r}] must be in {_RANGE[name == 'eta']}, got {value!r}")
        base[NAMES.index(name)] = value
    voltage = _column(data, "voltage_V")
    frequency_hz = _column(data, "frequency_Hz")
    if np.any(frequency_hz <= 0):
        raise ValueError("data column 'frequency_Hz' must be > 0")
    sigma = _column(data, "sigma_Hz", required=False)
    if sigma is not None and np.any(sigma <= 0):
        raise ValueError("data column 'sigma_Hz' must be > 0")
    m, n, branch = (_integer_column(data, "m", 0), _integer_column(data, "n", 1),
                    _integer_column(data, "branch", 0))
    columns = dict(voltage_V=voltage, frequency_Hz=frequency_hz, sigma_Hz=sigma, m=m, n=n,
                   branch=branch)
    for name, column in columns.items():
        if column is not None and column.size != voltage.size:
            raise ValueError(f"data column {name!r} has {column.size} rows, voltage_V "
                             f"{voltage.size}")
    if (m is None) != (n is None):
        raise ValueError("data columns 'm' and 'n' must be given together (or neither)")
    if branch is not None and m is None:
        raise ValueError("data column 'branch' needs the labels 'm' and 'n'")
    if voltage.size <= len(free):
        raise ValueError(f"data has {voltage.size} rows: more than {len(free)} (the number of "
                         f"free parameters) are needed")
    labels = None
    if m is not None:
        labels = np.stack([m, n, np.zeros_like(m) if branch is None else branch], axis=1)
    names = tuple(free)
    problem = _Problem(voltage, frequency_hz, np.ones_like(voltage) if sigma is None else sigma,
                       sigma is not None, names, np.array(lower), np.array(upper), base,
                       np.array([NAMES.index(k) for k in names]), 0, coupling, bessel_order)
    return problem, labels


# ---------------------------------------------------------------------------------------------
# public


def fit(data, free: Mapping, fixed: Mapping, fluid=None, *, initial: Mapping | None = None,
        n_layers: int = 30, m_max: int = 2, n_max: int = 3, n_branches: int = 2,
        threshold: float = 0.1, n_starts: int = 3, grid_points: int = 3,
        max_iterations: int = 100, max_reassignments: int = 10) -> FitResult:
    """Material and geometry parameters from measured resonance frequencies (SI units).

    Minimises Σ ((f_model − f_data)/σ)² with f_model = Ω c_s/(2π R_i) of the labelled (or assigned)
    mode, c_s = sqrt(μ/ρ_s), V̂ = V sqrt(ε/μ)/R_i, α̂_n = 2nπ R_i/(λ_z L) (module docstring).

    Args:
        data: the path of a CSV file of peaks (:func:`jaxdea.read_peaks`), or a mapping (dict of
            arrays, DataFrame) with columns ``voltage_V``, ``frequency_Hz``,
            optional ``sigma_Hz`` (> 0) and optional integer labels ``m`` (≥ 0), ``n`` (≥ 1) and
            ``branch`` (≥ 0, default 0: the lowest root of that (m, n)). Without labels each peak is
            assigned to a mode (m ≤ m_max, n ≤ n_max, branch < n_branches) and the assignment is
            redone as the parameters move until it settles.
        free: {name: (lower, upper)} of the parameters to estimate (names in ``NAMES``).
        fixed: {name: value} of the others; every name must be free or fixed (the fluid names
            only with a fluid; ``gent`` may be ``inf``).
        fluid: None (empty tube), ``"acoustic"``, or a :class:`~jaxdea.Fluid` whose coupling and
            bessel_order are used (its ratios come from ``fluid_density``, ``fluid_speed``).
        initial: optional {name: value} start for free parameters (tried besides the grid).
        n_layers: sublayers N of the model (static).
        m_max, n_max, n_branches: the modes unlabelled peaks may be assigned to.
        threshold: a peak whose |log f_model − log f_data| exceeds this after the first fit
            matches no mode (assignment (−1, −1, −1), left out of the fit).
        n_starts: the number of grid starts (the lowest initial cost) that are fitted; 0 (with
            ``initial``): ``initial`` only.
        grid_points: grid starts per free parameter (at fractions (k + ½)/grid_points of each
            bound interval, in the logit-scaled coordinates).
        max_iterations: Levenberg–Marquardt iterations per fit.
        max_reassignments: outer assign–fit rounds for unlabelled peaks.

    Returns:
        An instance of :class:`FitResult`.

    Raises:
        ValueError: naming the parameter or column: unknown names, a name both free and fixed or
            neither, bounds not finite with lower < upper, missing or non-finite columns,
            frequencies or σ ≤ 0, no more data rows than free parameters, an ``initial`` value
            outside its bounds.

    Warns:
        IdentifiabilityWarning: when the Jacobian is rank-deficient, naming the combination.

    Examples:
        >>> result = fit({"voltage_V": v, "frequency_Hz": f, "m": m, "n": n},
        ...              free={"shear_modulus": (5e4, 2e5), "lambda_i": (0.8, 1.2)},
        ...              fixed={"density": 1000.0, "permittivity": 4.16e-11, "gent": 97.2,
        ...                     "lambda_z": 1.2, "eta": 0.85, "inner_radius": 5e-3,
        ...                     "length": 5e-2})
        >>> result.estimate["shear_modulus"], result.interval["shear_modulus"]
    """
    require_x64()
    if isinstance(data, (str, os.PathLike)):
        from .peaks import read_peaks

        data = read_peaks(data)
    problem, labels = _validate(data, free, fixed, fluid)
    if not isinstance(n_layers, (int, np.integer)) or n_layers < 1:
        raise ValueError(f"n_layers must be an integer >= 1, got {n_layers!r}")
    for name, value, low in (("m_max", m_max, 0), ("n_max", n_max, 1), ("n_branches", n_branches, 1),
                             ("n_starts", n_starts, 0 if initial is not None else 1),
                             ("grid_points", grid_points, 1),
                             ("max_iterations", max_iterations, 1),
                             ("max_reassignments", max_reassignments, 1)):
        if not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if not (threshold > 0):
        raise ValueError(f"threshold must be > 0, got {threshold!r}")
    problem = problem._replace(n_layers=int(n_layers))
    starts = _starts(problem, initial, grid_points)

    def run(theta0):
        """(θ, r, J, iterations, status, labels) of one start."""
        if labels is not None:
            return (*_fit_labelled(problem, theta0, labels, max_iterations), labels)
        current, _ = assign_modes(problem, theta0, m_max, n_max, n_branches, None)
        iterations, outcome = 0, None
        for round_ in range(max_reassignments):
            outcome = _fit_labelled(problem, theta0, current, max_iterations)
            iterations += outcome[3]
            if outcome[4] == FitStatus.NOT_FINITE:
                break
            theta0 = outcome[0]
            new, _ = assign_modes(problem, theta0, m_max, n_max, n_branches, threshold)
            if np.array_equal(new, current):
                return (*outcome[:3], iterations, outcome[4], current)
            current = new
        status = outcome[4] if outcome[4] == FitStatus.NOT_FINITE else \
            FitStatus.ASSIGNMENT_CHANGING
        return (*outcome[:3], iterations, status, current)

    best = None
    for theta0 in _best_starts(problem, starts, labels, n_starts, m_max, n_max, n_branches):
        outcome = run(theta0)
        r = outcome[1]
        cost = 0.5 * float(r @ r) if np.all(np.isfinite(r)) else np.inf
        if best is None or cost < best[0] or (best[2][4] != FitStatus.CONVERGED
                                              and outcome[4] == FitStatus.CONVERGED
                                              and cost <= best[0]):
            best = (cost, theta0, outcome)
    theta, r, jac, iterations, status, final_labels = best[2]
    active = final_labels[:, 0] >= 0
    residuals = np.full(problem.voltage.size, np.nan)
    residuals[active] = r if r.size == active.sum() else np.nan
    p = theta.size
    known = NAMES if problem.coupling is not None else NAMES[:-2]
    parameters = {k: float(v) for k, v in zip(NAMES, _values(problem, theta), strict=True)
                  if k in known}
    settings = dict(n_layers=problem.n_layers, coupling=problem.coupling,
                    bessel_order=problem.bessel_order)
    if status == FitStatus.NOT_FINITE or not np.all(np.isfinite(jac)):
        nan = np.full((p, p), np.nan)
        return FitResult(dict(zip(problem.free, theta.tolist(), strict=True)),
                         {k: (np.nan, np.nan) for k in problem.free}, nan, nan, residuals,
                         final_labels, FitStatus.NOT_FINITE, iterations, problem.free, parameters,
                         settings)
    covariance, correlation, intervals, null = uncertainty(problem, theta, r, jac)
    if null is not None:
        _warn_null(problem.free, null)
    return FitResult(dict(zip(problem.free, theta.tolist(), strict=True)), intervals, covariance,
                     correlation, residuals, final_labels, status, iterations, problem.free,
                     parameters, settings)


def _starts(problem: _Problem, initial, grid_points):
    """Candidate starts: ``initial`` (validated inside the bounds) and a grid in u."""
    starts = []
    if initial is not None:
        if not isinstance(initial, Mapping):
            raise ValueError(f"initial must be a mapping {{name: value}}, got {initial!r}")
        for name in initial:
            if name not in problem.free:
                raise ValueError(f"initial names {name!r}, which is not a free parameter "
                                 f"(free: {', '.join(problem.free)})")
        theta = []
        for i, name in enumerate(problem.free):
            if name not in initial:
                raise ValueError(f"initial is missing the free parameter {name!r}")
            try:
                value = float(initial[name])
            except (TypeError, ValueError) as exc:
                raise ValueError(f"initial[{name!r}] must be a real number, got "
                                 f"{initial[name]!r}") from exc
            if not (problem.lower[i] < value < problem.upper[i]):
                raise ValueError(f"initial[{name!r}] = {value!r} must lie strictly inside "
                                 f"({problem.lower[i]!r}, {problem.upper[i]!r})")
            theta.append(value)
        starts.append(np.array(theta))
    fractions = (np.arange(grid_points) + 0.5) / grid_points
    axes = [problem.lower[i] + (problem.upper[i] - problem.lower[i]) * fractions
            for i in range(len(problem.free))]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(problem.free))
    return starts, list(grid)


def _best_starts(problem, starts, labels, n_starts, m_max, n_max, n_branches):
    """``initial`` (first, if given) and the ``n_starts`` grid starts of lowest initial cost
    (assignment cost for unlabelled peaks, Σ r² of the seeded branches otherwise)."""
    initial, starts = starts
    if n_starts == 0:
        return initial
    costs = []
    for theta in starts:
        if labels is None:
            _, cost = assign_modes(problem, theta, m_max, n_max, n_branches, None)
            costs.append(float(np.sum(cost)))
        else:
            seed = _seed(problem, theta, labels)
            scale = float(np.asarray(dimensionless(_values(problem, theta), 0.0, 1.0)[3]))
            r = (seed * scale - problem.frequency) / problem.sigma
            costs.append(float(r @ r) if np.all(np.isfinite(r)) else np.inf)
    costs = np.array(costs)
    order = np.argsort(costs, kind="stable")
    chosen = [starts[i] for i in order[:n_starts] if np.isfinite(costs[i])]
    return initial + (chosen if chosen or initial else [starts[order[0]]])


def fitted_frequencies(result: FitResult, voltage_V, m, n, branch=0) -> np.ndarray:
    """Frequencies in Hz of the fitted model: f = Ω_k(m; V̂, α̂_n) c_s/(2π R_i) at the parameters
    of ``result`` (``result.parameters``, ``result.settings``), per point.

    Ω_k is the k-th lowest positive root (k = ``branch``) of the global root scan (the definition
    of a branch in :func:`fit`); NaN where that root does not exist. The arguments broadcast.

    Examples:
        >>> voltage = np.linspace(0.0, 5e3, 21)
        >>> f_01 = fitted_frequencies(result, voltage, m=0, n=1)        # (21,) Hz
        >>> f_11 = fitted_frequencies(result, voltage, m=1, n=1, branch=1)
    """
    require_x64()
    voltage, m, n, branch = np.broadcast_arrays(np.asarray(voltage_V, dtype=np.float64),
                                                np.asarray(m), np.asarray(n), np.asarray(branch))
    shape = voltage.shape
    voltage, m, n, branch = (x.ravel() for x in (voltage, m, n, branch))
    if not np.all(np.isfinite(voltage)):
        raise ValueError("voltage_V must be finite")
    for name, values, low in (("m", m, 0), ("n", n, 1), ("branch", branch, 0)):
        if np.any(values != np.round(values)) or np.any(values < low):
            raise ValueError(f"{name} must hold integers >= {low}")
    m, n, branch = m.astype(int), n.astype(int), branch.astype(int)
    settings = result.settings
    base = np.array([result.parameters.get(k, 1.0) for k in NAMES], dtype=np.float64)
    problem = _Problem(voltage, np.ones_like(voltage), np.ones_like(voltage), False, (),
                       np.zeros(0), np.zeros(0), base, np.zeros(0, int), settings["n_layers"],
                       settings["coupling"], settings["bessel_order"])
    out = np.full(voltage.size, np.nan)
    if voltage.size:
        n_roots = int(branch.max()) + 1
        scale = float(np.asarray(dimensionless(base, 0.0, 1.0)[3]))
        for start in range(0, voltage.size, CURVE_CHUNK):  # one compiled batch size
            part = slice(start, start + CURVE_CHUNK)
            roots = _roots(problem, np.zeros(0), voltage[part], n[part], m[part], n_roots)
            out[part] = roots[np.arange(roots.shape[0]), branch[part]] * scale
    return out.reshape(shape)
