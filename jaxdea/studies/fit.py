"""Inverse characterisation: material and geometry of the tube from measured resonances (SI units).

The model of a measured peak at voltage V of order m, axial mode n and branch k is

    f_model = Ω_k(m; V̂, α̂_n) c_s/(2π R_i),   c_s = sqrt(μ/ρ_s),   V̂ = V sqrt(ε/μ)/R_i,
    α̂_n = 2nπ R_i/(λ_z L)   (= 2nπη/(length_ratio λ_z) with length_ratio = L/R_o = Lη/R_i),

with Ω_k the k-th lowest positive root of order m (:func:`jaxdea.frequencies`, docs/theory/axisymmetric.md and
docs/theory/order_m.md), refined by :func:`jaxdea.frequency` from the current root and converted to Hz
(:mod:`jaxdea.physics.units`). :func:`fit` minimises ½ Σ r_j², r_j = (f_model − f_data)_j/σ_j, over the free
parameters θ mapped onto their bounds, θ = lo + (hi − lo)·sigmoid(u).

Discretisation. By default the model is the library's accurate one (graded sixth-order Magnus
sublayers, N from :func:`jaxdea.physics.transfer.auto_layer_count` for the data's largest α̂, m and
branch, roots to ≤ 1e-8 and in practice ~1e-12), chosen at the starts and checked again at the
estimate. The laminate error is a systematic error of the model, and a weakly determined
parameter absorbs it: the paper's midpoint laminate (N = 30, errors ~1e-6 relative) moved the
Gent constant of a silicone tube by 0.2–0.4 % on exact data, where its own sensitivity is ~1e-3.

Loading. The tube is held by its inner stretch λ_i or by its pressure difference ΔP = P_i − P_o
(``pressure``, Pa): then λ_i is the inner stretch that ΔP̂ = ΔP/μ holds at each V̂ and λ_z
(:func:`jaxdea.inner_stretch`, docs/theory/axisymmetric.md Eq. 1.1, implicit derivatives), so the
inflation grows with the voltage as in a lab. Optional data columns ``pressure_Pa``, ``lambda_i``,
``lambda_z`` give each peak its own loading (joint fits over several pressures or pre-stretches);
the peaks of one voltage and loading share the model's modes. Torsional modes (m = 0, the
torsional family) are candidates with ``torsional=True`` and labels with a 0/1 column
``torsional``.

Damping and peak widths. With a damping law (``damping=``, :mod:`jaxdea.materials`) the model of
a labelled peak is the complex root Ω near it (time factor e^{iΩt}, a decaying mode has Im Ω > 0;
:mod:`jaxdea.solve.complex_frequencies`): the elastic root of the undamped tube continued by Newton
as η* grows from 0 to its value (:func:`_seed`), then :func:`jaxdea.solve_complex_frequency` from
the last iterate, with the implicit derivatives of Re Ω and Im Ω for the Jacobian. Its frequency
is f = Re Ω c_s/(2π R_i) and its half-power width (FWHM) Δf = 2 Im Ω c_s/(2π R_i): near the
resonance the response ∝ 1/(ω − Ω) has |·|² at half its peak at Re Ω ± Im Ω; Q = f/Δf =
Re Ω/(2 Im Ω). A ``width_Hz`` or ``quality_factor`` column adds the residuals
(w_model − w_data)/σ_w after the frequencies' (:data:`WIDTH_COLUMNS`); the damping parameters are
wall parameters by name (``damping_moduli_0``, ``damping_times_1``, ``damping_viscosity``,
:func:`jaxdea.physics.leaves.damping_names`).

Solver. A small Levenberg–Marquardt loop in NumPy (Marquardt's diagonal scaling; the damping is
divided by 3 after an accepted step and multiplied by 4 after a rejected one) on the unconstrained u,
with the exact Jacobian ∂r/∂θ from ``jax.jacfwd`` through the implicit root derivatives (never
finite differences). It is written here rather than taken from optimistix
because every iteration has host-side steps that a jitted solver cannot hold: the roots are
re-seeded from the accepted iterate (the Newton guesses of the next residual), branches are
re-checked with the global root scan, and unlabelled peaks are re-assigned to modes with
:func:`scipy.optimize.linear_sum_assignment`; the problem is tiny (≤ 11 parameters) and its cost
is the residual/Jacobian evaluation, so a NumPy loop adds nothing measurable (and no dependency
beyond scipy). The Gent constant is iterated as θ = 1/G (:data:`RECIPROCAL`): the frequencies are
nearly linear in 1/G, far from linear in G. Starts: ``initial`` when given, and the best (by
initial cost) of a grid inside the bounds (spaced in log for the scales of :data:`LOG_STARTS`), or
of a Latin hypercube where the grid would exceed :data:`MAX_GRID` points; for unlabelled peaks each
start is first moved to the frequency scale (μ, or else ρ_s) that best matches the peaks
(:func:`_scaled_start`); a free parameter of the wall (``material_beta``, ``layer0_shear_ratio``,
the names of :func:`jaxdea.physics.leaves.wall_names`) is not gridded but starts at its value on
the given wall, and its values follow the 12 of ``NAMES`` in the parameter vector. A parameter
that stops on a bound (where the sigmoid's slope vanishes) is
restarted from inside its bounds, and the lower cost is kept.

Unlabelled peaks. Given θ, each peak is matched to a mode (m ≤ m_max, 1 ≤ n ≤ n_max, branch <
n_branches) or declared an outlier, minimising the total cost Σ min(r², τ²) (τ = ``outlier_sigma``
with σ given, otherwise |log f_model/f_data| ≤ ``threshold``), one peak per mode and voltage
(:func:`assign_modes`). The model's curves carry each branch across the voltages, and the total
separates by voltage once θ is given, so the per-voltage matchings are the global one. The first
assignment of a start uses the wide relative tolerance ``threshold``, the later ones τ; assignment
and fit alternate until the labels settle (the robust cost never increases), and the starts are
compared by that robust cost, so that leaving peaks unmatched is never free.

Uncertainty. At the optimum, cov(θ) = s² (JᵀJ)⁻¹ with J = ∂r/∂θ (θ the physical parameters, 1/G
for the Gent constant); s² = 1 when ``sigma_Hz`` is given (the 95 % interval is θ ± 1.95996 √cov,
normal quantile), otherwise s² = Σr²/(N − p) and the interval uses Student's t with N − p degrees
of freedom; G's interval is that of 1/G mapped (asymmetric), its covariance by the delta method.
Where that
interval would leave the bounds, the side is replaced by the profile-likelihood one (the others
re-fitted at each value, the end where Σr² rises by q² s²), which is the bound itself when the
profile stays below: intervals never leave the bounds, and may be one-sided. A Jacobian whose
log-scaled singular values fall below 1e-8 of the largest is rank-deficient: the data do not
determine the combination of parameters given by the null vector (e.g. μ, ρ_s and ε scaled
together leave every f and V̂ unchanged; at V = 0 alone, μ and ρ_s enter only as μ/ρ_s); the
intervals of the parameters in it are NaN. An :class:`IdentifiabilityWarning` names that
combination, every parameter whose interval covers half its bound range or more, and every pair
correlated beyond :data:`CORRELATION_LIMIT`, and says which data would help.

Quality. The result reports χ²/dof and the unmatched fraction; a fit that leaves more than
``max_unmatched`` of the peaks unmatched (:attr:`FitStatus.TOO_FEW_MATCHED`) or, with σ given, whose
χ² exceeds its upper 1e-4 quantile (:attr:`FitStatus.POOR_FIT`) is not CONVERGED, and a
:class:`FitQualityWarning` says so in words, as it does for a parameter stopped on a bound.
"""

from __future__ import annotations

import dataclasses
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

from ..materials import Gent
from ..numerics.scalar import Status
from ..params import (
    Fluid,
    Tube,
    require_x64,
    validate_damping,
    validate_material,
    validate_wall_layers,
)
from ..physics.base_state import inner_stretch_traced
from ..physics.families import Face, Family
from ..physics.leaves import get_parameter, wall_hint, wall_names, with_wall
from ..physics.transfer import Layers, laminate, validate_scheme
from ..solve.complex_frequencies import solve_complex_frequency
from ..solve.roots import frequencies, frequency
from .sweeps import wall_from_settings, wall_settings

NAMES = ("shear_modulus", "density", "permittivity", "inner_radius", "length", "eta", "lambda_i",
         "lambda_z", "gent", "pressure", "fluid_density", "fluid_speed")
"""Every parameter :func:`fit` knows, in the order of its internal vector (SI units). A tube is
held either by its inner stretch ``lambda_i`` or by its pressure difference ``pressure`` = P_i − P_o
(Pa), from which λ_i follows at every voltage (:func:`jaxdea.inner_stretch`)."""
FLUID_NAMES = ("fluid_density", "fluid_speed")
LOADING_NAMES = ("lambda_i", "pressure")
"""The two ways a tube's inflation is held: one of them is free or fixed (or a data column)."""
LOAD_COLUMNS = ("lambda_i", "lambda_z", "pressure_Pa")
"""Optional per-peak data columns (joint fits over several loadings): each replaces the parameter
``lambda_i``, ``lambda_z``, ``pressure`` at its peaks."""
UNITS = dict(shear_modulus="Pa", density="kg/m^3", permittivity="F/m", inner_radius="m",
             length="m", eta="", lambda_i="", lambda_z="", gent="", pressure="Pa",
             fluid_density="kg/m^3", fluid_speed="m/s")
RANK_TOLERANCE = 1e-8
"""Relative singular value of the log-scaled Jacobian below which it counts as rank-deficient."""
CORRELATION_LIMIT = 0.99
"""|correlation| of two estimates beyond which :class:`IdentifiabilityWarning` names the pair."""
POOR_FIT_PROBABILITY = 1e-4
"""With σ given, a χ² whose upper tail probability is below this is :attr:`FitStatus.POOR_FIT`."""
BOUND_TOLERANCE = 1e-6
"""A parameter within this fraction of its bound range from a bound has stopped on that bound."""
MAX_GRID = 81
"""Largest grid of starts; beyond it (grid_points^p) the starts are a Latin hypercube of this size."""
RECIPROCAL = ("gent",)
"""Parameters fitted as their reciprocal θ = 1/value: the Gent constant enters the energy through
(I₁ − 3)/G, so the frequencies are nearly linear in 1/G (the neo-Hookean limit 1/G = 0), and a
weakly determined G is fitted, and its interval computed, where the model is nearly linear."""
LOG_STARTS = ("shear_modulus", "density", "permittivity", "inner_radius", "length", "gent",
              "fluid_density", "fluid_speed")
"""Parameters whose grid of starts is spaced evenly in log (scales: f ∝ sqrt(μ/ρ_s)/R_i); the
others' evenly."""
CURVE_CHUNK = 8
"""Points per compiled batch of :func:`fitted_frequencies` (the smallest batch of :func:`fit`)."""
HELP = dict(
    shear_modulus="peaks at non-zero voltages (at V = 0 only μ/ρ_s enters) or a fixed density",
    density="a fixed shear modulus, or peaks at several voltages (V̂ ∝ V sqrt(ε/μ) separates μ "
            "from ρ_s)",
    permittivity="peaks over a wider voltage range, nearer the first instability (ε enters only "
                 "through V̂ ∝ V sqrt(ε/μ))",
    inner_radius="modes of several orders m and axial numbers n, or a measured radius",
    length="several axial modes n (L enters only through α̂_n = 2nπR_i/(λ_z L)), or a measured "
           "length",
    eta="ring modes (m = 2, 3) beside axisymmetric ones and several n (the wall sets their ratio), "
        "or a measured wall",
    lambda_i="ring modes (m ≥ 1) and peaks at several voltages, or a measured inflation",
    lambda_z="several axial modes n and voltages, or a measured axial stretch",
    gent="larger stretches or voltages nearer the first instability (the Gent stiffening grows "
         "with I_1 − 3)",
    pressure="ring modes (m ≥ 1) and peaks at several voltages (the inflation the pressure holds "
             "grows with V), or a measured pressure",
    fluid_density="modes of several n (the fluid's added mass depends on α̂)",
    fluid_speed="modes of higher frequency (compressibility shows as Ω/α̂ nears ĉ_f)",
)
"""What data would pin each parameter down (the text of :class:`IdentifiabilityWarning`)."""
WALL_HELP = ("modes that the wall parameter moves unlike μ does (several orders m and axial numbers "
             "n, peaks at several voltages or stretches), or a measured value")
""":data:`HELP` of a free wall parameter (``material_beta``, ``layer0_shear_ratio``, …)."""


DAMPING_HELP = ("peak widths (width_Hz or quality_factor) of modes whose frequencies span the law's "
                "relaxation times (a Prony branch far below or above them acts as a viscosity or a "
                "stiffness alone), or a measured value")
""":data:`HELP` of a free damping parameter (``damping_moduli_0``, ``damping_viscosity``, …)."""


def _help(name):
    return HELP.get(name, DAMPING_HELP if name.startswith("damping_") else WALL_HELP)


class FitStatus(enum.IntEnum):
    """Outcome of :func:`fit`."""

    CONVERGED = 0  # the step (or the cost, at the rounding floor) stopped changing
    MAX_ITERATIONS = 1  # the iteration limit was reached first
    NOT_FINITE = 2  # no start gave a finite model (a labelled branch missing, an unstable state)
    ASSIGNMENT_CHANGING = 3  # the mode assignment of unlabelled peaks did not settle
    TOO_FEW_MATCHED = 4  # more than max_unmatched of the peaks match no mode
    POOR_FIT = 5  # σ given and χ² beyond its upper POOR_FIT_PROBABILITY quantile


class IdentifiabilityWarning(UserWarning):
    """The data do not determine some parameters or combinations of them (rank-deficient J, an
    interval over half the bound range, a correlation beyond :data:`CORRELATION_LIMIT`)."""


class FitQualityWarning(UserWarning):
    """The fit does not explain the data (too few peaks matched, χ² far above its degrees of
    freedom) or a parameter stopped on a bound."""


class FitResult(NamedTuple):
    """Result of :func:`fit` (physical units throughout).

    Attributes:
        estimate: {name: value} of the free parameters.
        interval: {name: (low, high)}, 95 % confidence intervals inside the bounds (NaN where not
            identifiable; a bound where the profile stays below the 95 % level there).
        covariance: (p, p) covariance of the free parameters, in ``names`` order.
        correlation: (p, p) correlation matrix.
        residuals: (f_model − f_data)/σ per data point (Hz when no σ given; NaN if unmatched).
        assignment: (N, 3) int array of (m, n, branch) per data point; (−1, −1, −1) for a peak
            that matches no mode (an outlier, excluded from the fit).
        status: :class:`FitStatus`.
        iterations: Levenberg–Marquardt iterations of the chosen start (all its rounds of
            branch re-checks and re-assignments).
        names: the free parameter names, in the order of ``covariance``.
        parameters: {name: value} of every parameter of the model, free (the estimates) and fixed
            (``pressure`` in Pa where the tube is held by pressure, ``lambda_i`` where it is held
            by stretch; none of those given as data columns).
        settings: the model's discretisation, fluid and loading: {"n_layers", "scheme", "graded",
            "coupling" (None: empty tube), "bessel_order", "loading" ("stretch": λ_i held;
            "pressure": λ_i follows from ΔP at every voltage)} (:func:`fitted_frequencies`
            evaluates the fitted model with it).
        chi2: Σ r² over the matched peaks.
        dof: matched peaks minus free parameters.
        chi2_per_dof: chi2/dof (Hz² without σ: the residual variance s²).
        unmatched_fraction: the share of peaks assigned to no mode.
        at_bound: {name: "lower" or "upper"} of the parameters stopped on a bound.
        torsional: (N,) bool, True where the peak is assigned to a torsional mode (m = 0 of the
            torsional family; its ``assignment`` row is (0, n, branch)).
        width_residuals: with a ``width_Hz`` or ``quality_factor`` column, (w_model − w_data)/σ_w
            per data point (w the width in Hz or Q as given; without σ in Hz, a Q column compared
            as the width f/Q); else None.
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
    chi2: float = math.nan
    dof: int = 0
    chi2_per_dof: float = math.nan
    unmatched_fraction: float = math.nan
    at_bound: dict | None = None
    torsional: np.ndarray | None = None
    width_residuals: np.ndarray | None = None


# ---------------------------------------------------------------------------------------------
# model


def dimensionless(values, voltage_V, n, coupling=None, bessel_order=None, load=None,
                  by_pressure=False, outer=None, wall=None, wall_leaves=()):
    """(Tube, α̂_n, Fluid or None, Hz per unit Ω) of a parameter vector in ``NAMES`` order
    (followed by the values of ``wall_leaves``).

    V̂ = V sqrt(ε/μ)/R_i, length_ratio = L/R_o = Lη/R_i, α̂_n = 2nπ R_i/(λ_z L),
    ρ̂_f = ρ_f/ρ_s, ĉ_f = c_f/c_s, f = Ω c_s/(2π R_i) (docs/theory/axisymmetric.md §0).
    ``load``: optional (λ_i, λ_z, ΔP in Pa) of this point, NaN entries taken from ``values``.
    ``by_pressure``: λ_i is the inner stretch that ΔP̂ = ΔP/μ holds at V̂, λ_z
    (:func:`jaxdea.inner_stretch`, docs/theory/axisymmetric.md Eq. 1.1; implicit derivatives).
    ``outer``: None, or (ρ_o, c_o) in SI of a surrounding fluid: ρ̂_o = ρ_o/ρ_s, ĉ_o = c_o/c_s.
    ``wall``: None (the Gent wall of ``gent``), or a :class:`~jaxdea.Tube` whose material and layers
    the model takes (:func:`fit`'s ``material``, ``layers``); ``wall_leaves``: the names of the
    wall's free parameters (:func:`jaxdea.physics.leaves.wall_names`) whose values follow the 12 of
    ``NAMES`` in ``values`` (:func:`jaxdea.physics.leaves.with_wall` sets them on ``wall``).
    """
    mu, rho, eps, ri, length, eta, li, lz, gent, dp, rho_f, c_f = (values[i] for i in range(12))
    if load is not None:
        li, lz, dp = (jnp.where(jnp.isnan(load[i]), x, load[i]) for i, x in enumerate((li, lz, dp)))
    fields = dict(voltage=voltage_V * jnp.sqrt(eps / mu) / ri, lambda_i=li, lambda_z=lz, eta=eta,
                  gent=gent, length_ratio=length * eta / ri)
    tube = Tube(**fields) if wall is None else wall.replace(**fields)
    if wall_leaves:
        tube = with_wall(tube, {name: values[len(NAMES) + i] for i, name in enumerate(wall_leaves)})
    if by_pressure:
        tube = tube.replace(lambda_i=inner_stretch_traced(tube, dp / mu)[0])
    alpha = 2.0 * math.pi * n * ri / (lz * length)
    if outer is not None:
        tube = tube.replace(outer=Fluid(density_ratio=outer[0] / rho,
                                        speed_ratio=outer[1] / jnp.sqrt(mu / rho)))
    fluid = None if coupling is None else Fluid(density_ratio=rho_f / rho,
                                                speed_ratio=c_f / jnp.sqrt(mu / rho),
                                                coupling=coupling, bessel_order=bessel_order)
    return tube, alpha, fluid, hz_per_omega(values)


def hz_per_omega(values):
    """c_s/(2π R_i) of a parameter vector: f in Hz = Ω times this."""
    return jnp.sqrt(values[0] / values[1]) / (2.0 * math.pi * values[3])


FAMILIES = (Family.LONGITUDINAL, Family.ORDER_M, Family.TORSIONAL)
"""The static mode families of the model: m = 0 longitudinal, m ≥ 1 (traced m), m = 0 torsional."""


def _solver_family(family, order):
    """(m, torsional) arguments of the solvers for a family."""
    return (order if family.reads_m else 0), family is Family.TORSIONAL


@partial(jax.jit, static_argnames=("n_roots", "n_layers", "coupling", "bessel_order", "family",
                                   "by_pressure", "wall_leaves"))
def mode_roots(values, voltage_V, n, m, n_roots, n_layers, coupling, bessel_order, family,
               by_pressure=False, load=None, outer=None, wall=None, wall_leaves=()):
    """Ω of the ``n_roots`` lowest positive roots of order m at α̂_n, per point: (points, n_roots).

    ``family``: one of :data:`FAMILIES` (every m is 0 but for ``ORDER_M``, m ≥ 1, traced);
    ``load``: (points, 3) of (λ_i, λ_z, ΔP) per point, NaN where ``values`` holds it (None: all);
    ``outer``: (ρ_o, c_o) in SI of a surrounding fluid, or None; ``wall``: the material and layers
    (:func:`dimensionless`); ``wall_leaves``: the free wall parameters at the end of ``values``.
    """
    load = jnp.full((voltage_V.shape[0], 3), jnp.nan) if load is None else load
    def one(v, k, order, point):
        tube, alpha, fluid, _ = dimensionless(values, v, k, coupling, bessel_order, point,
                                              by_pressure, outer, wall, wall_leaves)
        m, torsional = _solver_family(family, order)
        return frequencies(tube.replace(damping=None), alpha, fluid, n_roots, n_layers=n_layers,
                           m=m, torsional=torsional)
    return jax.vmap(one)(voltage_V, n, m, load)


@partial(jax.jit, static_argnames=("n_layers", "coupling", "bessel_order", "family", "by_pressure",
                                   "wall_leaves"))
def model_and_jacobian(values, voltage_V, n, m, guess, n_layers, coupling, bessel_order,
                       family, by_pressure=False, load=None, outer=None, wall=None, wall_leaves=()):
    """(Ω, f in Hz, ∂f/∂values) per point, Ω by Newton from ``guess`` (implicit derivatives);
    ``family``, ``by_pressure``, ``load``, ``outer``, ``wall``, ``wall_leaves`` as in
    :func:`mode_roots`.

    The Jacobian is ``jax.jacfwd`` with respect to all 12 values and the free wall parameters'
    (one program whatever is free among the 12)."""
    load = jnp.full((voltage_V.shape[0], 3), jnp.nan) if load is None else load
    def hz(vals):
        def one(v, k, order, point, g):
            tube, alpha, fluid, scale = dimensionless(vals, v, k, coupling, bessel_order, point,
                                                      by_pressure, outer, wall, wall_leaves)
            m, torsional = _solver_family(family, order)
            omega = frequency(tube, alpha, g, fluid, n_layers, m=m, torsional=torsional)
            return jnp.stack([omega * scale, omega])
        out = jax.vmap(one)(voltage_V, n, m, load, guess)
        return out[:, 0], (out[:, 0], out[:, 1])

    jac, (f, omega) = jax.jacfwd(hz, has_aux=True)(values)
    return omega, f, jac


def _scaled_damping(damping, scale):
    """The damping law with η*(Ω) multiplied by ``scale`` (its moduli, viscosity or loss): the
    homotopy from the elastic tube (0) to the damped one (1) of :func:`_seed`."""
    field = {"Prony": "moduli", "FractionalKelvinVoigt": "modulus", "KelvinVoigt": "viscosity",
             "Hysteretic": "loss"}[type(damping).__name__]
    value = getattr(damping, field)
    value = tuple(scale * g for g in value) if isinstance(value, tuple) else scale * value
    return dataclasses.replace(damping, **{field: value})


@partial(jax.jit, static_argnames=("n_layers", "coupling", "bessel_order", "family", "by_pressure",
                                   "wall_leaves"))
def damped_model_and_jacobian(values, voltage_V, n, m, guess, homotopy, n_layers, coupling,
                              bessel_order, family, by_pressure=False, load=None, outer=None,
                              wall=None, wall_leaves=()):
    """(Ω complex, (f, Δf) in Hz, ∂(f, Δf)/∂values) per point of a damped wall: Ω the complex
    root by Newton from ``guess`` (:func:`jaxdea.solve_complex_frequency`, implicit derivatives;
    NaN unless it converged), f = Re Ω c_s/(2π R_i) and the half-power width (FWHM)
    Δf = 2 Im Ω c_s/(2π R_i) (time factor e^{iΩt}, a decaying mode has Im Ω > 0; the resonance
    |1/(Ω − Ω_r)|² falls to half at Re Ω ± Im Ω; Q = f/Δf = Re Ω/(2 Im Ω),
    :func:`jaxdea.solve.complex_frequencies.quality_factor`). ``homotopy``: η* scaled by it
    (:func:`_scaled_damping`; 1 the model). Shapes (P,), (P, 2), (P, 2, len(values))."""
    load = jnp.full((voltage_V.shape[0], 3), jnp.nan) if load is None else load

    def hz(vals):
        def one(v, k, order, point, g):
            tube, alpha, fluid, scale = dimensionless(vals, v, k, coupling, bessel_order, point,
                                                      by_pressure, outer, wall, wall_leaves)
            tube = tube.replace(damping=_scaled_damping(tube.damping, homotopy))
            m, torsional = _solver_family(family, order)
            omega, status = solve_complex_frequency(tube, alpha, g, fluid, m=m,
                                                    n_layers=n_layers, torsional=torsional)
            omega = jnp.where(status == Status.CONVERGED, omega, jnp.nan)
            return jnp.stack([omega.real * scale, 2.0 * omega.imag * scale]), omega
        out, omega = jax.vmap(one)(voltage_V, n, m, load, guess)
        return out, (out, omega)

    jac, (f, omega) = jax.jacfwd(hz, has_aux=True)(values)
    return omega, f, jac


def _padded(size: int) -> int:
    """Batch size rounded up to a power of two (≥ 8), so that data sets share compiled programs."""
    return max(8, 1 << (size - 1).bit_length())


def _by_family(m, torsional, fun):
    """Apply ``fun(index, family)`` to the points of each family of :data:`FAMILIES` (padded
    batches): m = 0 longitudinal, m ≥ 1, and the torsional points (m = 0, ``torsional``)."""
    out = []
    for family, chosen in zip(FAMILIES, ((m == 0) & ~torsional, m > 0, (m == 0) & torsional),
                              strict=True):
        index = np.flatnonzero(chosen)
        if index.size:
            padded = np.concatenate([index, np.full(_padded(index.size) - index.size, index[0])])
            out.append((index, fun(padded, family)))
    return out


class _Problem(NamedTuple):
    """The fixed part of a fit: data, names, bounds, discretisation, outlier thresholds, loading."""

    voltage: np.ndarray
    frequency: np.ndarray
    sigma: np.ndarray
    has_sigma: bool
    free: tuple
    lower: np.ndarray
    upper: np.ndarray
    base: np.ndarray  # the full value vector (fixed values; free entries overwritten)
    free_index: np.ndarray
    n_layers: object  # int (equal midpoint sublayers) or transfer.Layers
    coupling: str | None
    bessel_order: int | None
    threshold: float = 0.1  # relative tolerance of a match (|log f_model/f_data|)
    outlier: float = 5.0  # τ, the residual in σ beyond which a peak is an outlier (σ given)
    load: np.ndarray | None = None  # (N, 3) per-peak (λ_i, λ_z, ΔP), NaN: the parameter's value
    by_pressure: bool = False  # λ_i follows from ΔP at every voltage
    condition: np.ndarray | None = None  # (N,) index of each peak's (V, load): peaks measured together
    reciprocal: np.ndarray | None = None  # (p,) bool: θ_k is 1/value (:data:`RECIPROCAL`)
    bounds: np.ndarray | None = None  # (p, 2) the bounds as given (lower, upper are internal)
    outer: tuple | None = None  # (ρ_o, c_o) in SI of a surrounding fluid, or None
    wall: Tube | None = None  # the material and layers of the model (None: the Gent wall of gent)
    wall_leaves: tuple = ()  # the free wall parameters, whose values follow NAMES' in ``base``
    width: np.ndarray | None = None  # (N,) measured widths (Hz) or quality factors, or None
    width_sigma: np.ndarray | None = None  # (N,) their σ (1 without σ)
    width_kind: str | None = None  # "width" (FWHM in Hz) or "quality" (Q), None without widths


def _damped(problem: _Problem) -> bool:
    """Whether the model's wall carries a damping law (its roots are complex)."""
    return problem.wall is not None and problem.wall.damping is not None


def _outer_si(outer) -> tuple | None:
    """(ρ_o, c_o) of ``fit``'s ``outer`` (a FluidSI or a pair, SI), validated; None for none.

    Raises:
        ValueError: naming ``outer``: not a pair of finite numbers > 0.
    """
    if outer is None:
        return None
    try:
        density, speed = (float(x) for x in outer)
    except (TypeError, ValueError):
        raise ValueError("outer must be None, a jaxdea.units.FluidSI (e.g. jaxdea.units.WATER) or "
                         f"(density kg/m^3, sound speed m/s), got {outer!r}") from None
    for name, value in (("density", density), ("sound speed", speed)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"outer: the {name} must be a finite number > 0, got {value!r}")
    return density, speed


def _wall(material, layers, damping=None) -> Tube | None:
    """The wall of ``fit``'s ``material`` and ``layers`` (a :class:`~jaxdea.Tube` that carries them),
    validated; None for neither (the Gent wall of the parameter ``gent``).

    Raises:
        ValueError: naming ``material`` or ``layers`` (:func:`jaxdea.params.validate_material`,
            :func:`jaxdea.params.validate_wall_layers`); ``material=Gent(G)``, whose G is the
            parameter ``gent``.
    """
    if material is None and layers is None and damping is None:
        return None
    if damping is not None:
        validate_damping(damping)
        if layers is not None:
            raise ValueError("damping with layers: a layered wall's damping is its layers' "
                             "(Layer(damping=...)), which fit does not take yet; give damping= "
                             "with a one-material wall")
    if isinstance(material, Gent):
        raise ValueError("material=Gent(G): leave material out and give the Gent constant as the "
                         "parameter 'gent' (free or fixed)")
    wall = Tube(material="gent" if material is None else material, layers=layers, damping=damping)
    validate_material(wall.material)
    validate_wall_layers(wall)
    return wall


def _uses_gent(wall) -> bool:
    """Whether the model's energy is the Gent wall of the parameter ``gent``."""
    return wall is None or (wall.layers is None and wall.material == "gent")


def _outer(problem: _Problem):
    """The surrounding fluid (ρ_o, c_o) as a JAX array, or None."""
    return None if problem.outer is None else jnp.asarray(problem.outer, jnp.float64)


def _load(problem: _Problem, index=None):
    """(points, 3) per-point (λ_i, λ_z, ΔP) of the peaks ``index`` (all NaN without columns)."""
    size = problem.voltage.size if index is None else np.size(index)
    if problem.load is None:
        return np.full((size, 3), np.nan)
    return problem.load if index is None else problem.load[index]


def _recip(problem: _Problem):
    return np.zeros(len(problem.free), bool) if problem.reciprocal is None else problem.reciprocal


def _physical(problem: _Problem, theta):
    """The free parameters' values of the internal vector θ (1/θ_k where :data:`RECIPROCAL`)."""
    theta = np.asarray(theta, float)
    with np.errstate(divide="ignore"):
        return np.where(_recip(problem), 1.0 / theta, theta)


def _internal(problem: _Problem, value):
    """θ of the free parameters' values (the inverse of :func:`_physical`)."""
    return _physical(problem, value)


def _chain(problem: _Problem, theta):
    """d value/dθ per free parameter: −1/θ² where :data:`RECIPROCAL`, 1 elsewhere."""
    theta = np.asarray(theta, float)
    return np.where(_recip(problem), -1.0 / theta**2, 1.0)


def _values(problem: _Problem, theta):
    values = problem.base.copy()
    values[problem.free_index] = _physical(problem, theta)
    return values


def _roots(problem: _Problem, theta, voltage, n, m, n_roots, load, torsional=None):
    """Ω (points, n_roots) of order m at α̂_n, voltage and per-point load, NaN-padded."""
    out = np.full((voltage.size, n_roots), np.nan)
    torsional = np.zeros(voltage.size, bool) if torsional is None else torsional
    values = jnp.asarray(_values(problem, theta))
    for index, found in _by_family(m, torsional, lambda p, family: mode_roots(
            values, jnp.asarray(voltage[p]), jnp.asarray(n[p], float), jnp.asarray(m[p], float),
            n_roots, problem.n_layers, problem.coupling, problem.bessel_order, family,
            problem.by_pressure, jnp.asarray(load[p]), _outer(problem), problem.wall,
            problem.wall_leaves)):
        out[index] = np.asarray(found)[:index.size]
    return out


def _evaluate(problem: _Problem, theta, labels, guess, homotopy=1.0):
    """(Ω, f_model in Hz, ∂f/∂θ free columns) at the labelled points (rows with m < 0 are NaN).

    ``labels``: (N, 4) rows (m, n, branch, torsional). A damped wall (:func:`_damped`): Ω complex,
    the model (N, 2) of (f, the width Δf in Hz or Q = f/Δf as ``problem.width_kind``; Δf where no
    widths are given) and ∂/∂θ (N, 2, p) (:func:`damped_model_and_jacobian`)."""
    if _damped(problem):
        return _evaluate_damped(problem, theta, labels, guess, homotopy)
    omega = np.full(labels.shape[0], np.nan)
    f = np.full(labels.shape[0], np.nan)
    jac = np.full((labels.shape[0], len(problem.free)), np.nan)
    active = labels[:, 0] >= 0
    values = jnp.asarray(_values(problem, theta))
    where = np.flatnonzero(active)
    m = labels[where, 0]
    load = _load(problem)
    for index, (w, hz, j) in _by_family(m, labels[where, 3] > 0, lambda p, family:
                                        model_and_jacobian(
            values, jnp.asarray(problem.voltage[where[p]]), jnp.asarray(labels[where[p], 1], float),
            jnp.asarray(m[p], float), jnp.asarray(guess[where[p]]), problem.n_layers,
            problem.coupling, problem.bessel_order, family, problem.by_pressure,
            jnp.asarray(load[where[p]]), _outer(problem), problem.wall, problem.wall_leaves)):
        rows = where[index]
        omega[rows] = np.asarray(w)[:index.size]
        f[rows] = np.asarray(hz)[:index.size]
        jac[rows] = np.asarray(j)[:index.size][:, problem.free_index]
    return omega, f, jac * _chain(problem, theta)[None, :]


def _evaluate_damped(problem: _Problem, theta, labels, guess, homotopy):
    """:func:`_evaluate` of a damped wall."""
    size = labels.shape[0]
    omega = np.full(size, complex(np.nan, np.nan))
    out = np.full((size, 2), np.nan)
    jac = np.full((size, 2, len(problem.free)), np.nan)
    active = labels[:, 0] >= 0
    values = jnp.asarray(_values(problem, theta))
    where = np.flatnonzero(active)
    m = labels[where, 0]
    load = _load(problem)
    guess = np.asarray(guess, complex)
    for index, (w, obs, j) in _by_family(m, labels[where, 3] > 0, lambda p, family:
                                         damped_model_and_jacobian(
            values, jnp.asarray(problem.voltage[where[p]]), jnp.asarray(labels[where[p], 1], float),
            jnp.asarray(m[p], float), jnp.asarray(guess[where[p]]), float(homotopy),
            problem.n_layers, problem.coupling, problem.bessel_order, family, problem.by_pressure,
            jnp.asarray(load[where[p]]), _outer(problem), problem.wall, problem.wall_leaves)):
        rows = where[index]
        omega[rows] = np.asarray(w)[:index.size]
        out[rows] = np.asarray(obs)[:index.size]
        jac[rows] = np.asarray(j)[:index.size][:, :, problem.free_index]
    jac = jac * _chain(problem, theta)[None, None, :]
    if problem.width_kind == "quality":  # Q = f/Δf, dQ = (df Δf − f dΔf)/Δf²
        f, width = out[:, 0], out[:, 1]
        jac[:, 1] = (jac[:, 0] * width[:, None] - f[:, None] * jac[:, 1]) / width[:, None] ** 2
        out[:, 1] = f / width
    return omega, out, jac


HOMOTOPY_STEPS = 4
"""Steps of the continuation from the elastic root to the damped one (:func:`_seed`)."""


def _seed(problem: _Problem, theta, labels):
    """Ω of each labelled branch from the global root scan (NaN for unmatched rows). A damped wall:
    that elastic root continued to the complex root by Newton as η* grows from 0 to its value in
    :data:`HOMOTOPY_STEPS` equal steps (:func:`_scaled_damping`): the branch of a damped mode is
    the elastic branch it comes from."""
    seed = _elastic_seed(problem, theta, labels)
    if not _damped(problem):
        return seed
    seed = seed.astype(complex)
    for step in range(1, HOMOTOPY_STEPS + 1):
        seed = _evaluate_damped(problem, theta, labels, seed, step / HOMOTOPY_STEPS)[0]
    return seed


def _elastic_seed(problem: _Problem, theta, labels):
    """Ω of each labelled branch of the elastic (undamped) tube from the global root scan."""
    seed = np.full(labels.shape[0], np.nan)
    active = np.flatnonzero(labels[:, 0] >= 0)
    if active.size:
        roots = _roots(problem, theta, problem.voltage[active], labels[active, 1],
                       labels[active, 0], int(labels[active, 2].max()) + 1, _load(problem, active),
                       labels[active, 3] > 0)
        seed[active] = roots[np.arange(active.size), labels[active, 2]]
    return seed


# ---------------------------------------------------------------------------------------------
# mode identification


def _conditions(problem: _Problem):
    """(per-peak condition index, one peak of each condition): the peaks measured at one voltage
    and one loading (the same per-peak λ_i, λ_z, ΔP), which share the model's modes."""
    if problem.condition is not None:
        ids = problem.condition
    else:
        _, ids = np.unique(problem.voltage, return_inverse=True)
    _, first = np.unique(ids, return_index=True)
    return ids, first


def _mode_table(problem: _Problem, theta, modes):
    """(grid rows (condition, n, m, torsional), roots (rows, n_branches), Hz per unit Ω) of every
    candidate mode of ``modes`` = (m_max, n_max, n_branches, torsional) at every condition of the
    data (:func:`_conditions`); torsional candidates are m = 0."""
    m_max, n_max, n_branches, torsional = modes
    _, first = _conditions(problem)
    families = [(m, 0) for m in range(m_max + 1)] + ([(0, 1)] if torsional else [])
    grid = np.array([(c, n, m, tors) for c in range(first.size) for m, tors in families
                     for n in range(1, n_max + 1)])
    peak = first[grid[:, 0]]
    roots = _roots(problem, theta, problem.voltage[peak], grid[:, 1], grid[:, 2], n_branches,
                   _load(problem, peak), grid[:, 3] > 0)
    return grid, roots, float(hz_per_omega(_values(problem, theta)))


def assign_modes(problem: _Problem, theta, modes, wide: bool = False):
    """Labels (m, n, branch, torsional) of the peaks that minimise Σ min(c, τ²) at θ (module
    docstring), among ``modes`` = (m_max, n_max, n_branches, torsional).

    At each voltage and loading, the peaks are matched one-to-one to the model modes (m ≤ m_max,
    1 ≤ n ≤ n_max, branch < n_branches, and with ``torsional`` the torsional modes) or to an
    outlier slot of their own
    (:func:`scipy.optimize.linear_sum_assignment` on the table [c | diag τ²]). The cost of a
    match is c = ((f_model − f_data)/σ)² with τ = ``problem.outlier`` when σ is given and not
    ``wide``; otherwise c = (log(f_model/f_data)/threshold)² with τ = 1 (a peak further than
    ``threshold`` in |log f| is an outlier).

    Returns:
        (labels (N, 4) int, (−1, −1, −1, 0) for an outlier; the robust cost Σ min(c, τ²)).
    """
    return _match(problem, _mode_table(problem, theta, modes), modes[2], wide)


def _match(problem: _Problem, table, n_branches, wide, factor=1.0):
    """:func:`assign_modes` on a mode table (:func:`_mode_table`) whose frequencies are multiplied by
    ``factor``."""
    from scipy.optimize import linear_sum_assignment  # scipy: imported where it is used

    grid, roots, scale = table
    scale = scale * factor
    relative = wide or not problem.has_sigma
    tau2 = 1.0 if relative else problem.outlier**2
    labels = np.full((problem.voltage.size, 4), -1, dtype=int)
    labels[:, 3] = 0
    total = 0.0
    ids, first = _conditions(problem)
    for condition in range(first.size):
        peaks = np.flatnonzero(ids == condition)
        rows = np.flatnonzero(grid[:, 0] == condition)
        found = [(int(grid[r, 2]), int(grid[r, 1]), k, int(grid[r, 3]), roots[r, k] * scale)
                 for r in rows for k in range(n_branches) if np.isfinite(roots[r, k])]
        model = np.array([mode[4] for mode in found])
        data = problem.frequency[peaks]
        if relative:
            table = (np.log(model)[None, :] - np.log(data)[:, None]) ** 2 / problem.threshold**2
        else:
            table = ((model[None, :] - data[:, None]) / problem.sigma[peaks][:, None]) ** 2
        slots = np.full((peaks.size, peaks.size), 1e30)
        np.fill_diagonal(slots, tau2)
        pick, chosen = linear_sum_assignment(np.hstack([table.reshape(peaks.size, -1), slots]))
        for p, c in zip(pick, chosen, strict=True):
            if c < len(found):
                labels[peaks[p]] = found[c][:4]
                total += table[p, c]
            else:
                total += tau2
    return labels, total


def _robust_cost(problem: _Problem, r, labels):
    """Σ min(c, τ²) of a fit (:func:`assign_modes`, not wide) from its residuals ``r`` of the
    matched peaks: what the starts and rounds of an unlabelled fit are compared by."""
    active = labels[:, 0] >= 0
    unmatched = int(np.sum(~active))
    if problem.has_sigma:
        return float(r @ r) + unmatched * problem.outlier**2
    f_model = problem.frequency[active] + r  # σ = 1 Hz: r is f_model − f_data in Hz
    with np.errstate(invalid="ignore"):
        ratio = np.log(f_model / problem.frequency[active]) / problem.threshold
    return float(ratio @ ratio) + unmatched


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

    def residual(f):
        return _residual(problem, f, active)

    r = residual(f)
    scaled = _scaled_jacobian(problem, jac, active)
    if not np.all(np.isfinite(r)) or not np.all(np.isfinite(scaled)):
        return theta, omega, r, scaled, 0, FitStatus.NOT_FINITE
    if theta.size == 0:  # every parameter held (a profile of a one-parameter fit)
        return theta, omega, r, scaled, 0, FitStatus.CONVERGED
    cost, damping, iterations = 0.5 * r @ r, 1e-3, 0
    status = FitStatus.MAX_ITERATIONS
    while iterations < max_iterations:
        iterations += 1
        ju = _scaled_jacobian(problem, jac, active) * dtheta[None, :]
        a, g = ju.T @ ju, ju.T @ r
        diag = np.maximum(np.diag(a), 1e-30 * max(np.max(np.diag(a)), 1e-300))
        accepted = False
        while damping < 1e20:
            try:
                step = np.linalg.solve(a + damping * np.diag(diag), -g)
            except np.linalg.LinAlgError:  # every free column vanished (parameters on their bounds)
                step = np.zeros_like(g)
            if -(g @ step) - 0.5 * step @ a @ step <= ftol * cost:
                break  # nothing left to gain that the rounding of the cost could show
            trial_theta, trial_dtheta = _to_free(problem, u + step)
            trial = _evaluate(problem, trial_theta, labels, omega)
            r_trial = residual(trial[1])
            cost_trial = 0.5 * r_trial @ r_trial
            finite = np.all(np.isfinite(r_trial)) and np.all(np.isfinite(
                _scaled_jacobian(problem, trial[2], active)))  # the next step needs J too
            if finite and cost_trial <= cost:
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
    return theta, omega, r, _scaled_jacobian(problem, jac, active), iterations, status


def _residual(problem: _Problem, model, active):
    """r of the matched peaks: (f_model − f_data)/σ, then with widths (w_model − w_data)/σ_w (w the
    width Δf in Hz or Q, ``problem.width_kind``). ``model``: (N,) f, or (N, 2) (f, w)."""
    if model.ndim == 1:
        return ((model - problem.frequency) / problem.sigma)[active]
    r = ((model[:, 0] - problem.frequency) / problem.sigma)[active]
    if problem.width is None:
        return r
    return np.concatenate([r, ((model[:, 1] - problem.width) / problem.width_sigma)[active]])


def _scaled_jacobian(problem: _Problem, jac, active):
    """∂r/∂θ of :func:`_residual` from ∂model/∂θ ((N, p), or (N, 2, p))."""
    if jac.ndim == 2:
        return jac[active] / problem.sigma[active, None]
    top = jac[active, 0] / problem.sigma[active, None]
    if problem.width is None:
        return top
    return np.concatenate([top, jac[active, 1] / problem.width_sigma[active, None]])


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
    """(covariance, correlation, Wald intervals, null combination or None, quantile q, s²) at the
    optimum."""
    from scipy.stats import norm, t  # scipy: imported where it is used

    p = theta.size
    dof = max(r.size - p, 1)
    variance = 1.0 if problem.has_sigma else float(r @ r) / dof
    quantile = norm.ppf(0.975) if problem.has_sigma else t.ppf(0.975, dof)
    # ∂r/∂log θ; a parameter that may be 0 (the pressure difference) on the scale of its bounds
    scale = np.maximum(np.abs(theta), 1e-6 * (problem.upper - problem.lower))
    scaled = jac * scale[None, :]
    _, singular, vt = np.linalg.svd(scaled, full_matrices=False)
    deficient = singular.size < p or singular[-1] <= RANK_TOLERANCE * singular[0]
    with np.errstate(all="ignore"):
        if deficient:
            keep = singular > RANK_TOLERANCE * singular[0]
            inv = (vt[keep].T / singular[keep] ** 2) @ vt[keep]
            covariance = variance * inv * np.outer(scale, scale)
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
    return covariance, correlation, intervals, null, float(quantile), variance


def _bounds(problem: _Problem):
    """(p, 2) bounds of the free parameters as given (``problem.lower``, ``upper`` are of θ)."""
    if problem.bounds is not None:
        return problem.bounds
    return np.stack([problem.lower, problem.upper], axis=1)


def _pinned(problem: _Problem, k: int, value: float) -> _Problem:
    """``problem`` with free parameter k held at ``value`` (the others free)."""
    keep = np.arange(len(problem.free)) != k
    base = problem.base.copy()
    base[problem.free_index[k]] = 1.0 / value if _recip(problem)[k] else value
    return problem._replace(free=tuple(n for i, n in enumerate(problem.free) if keep[i]),
                            lower=problem.lower[keep], upper=problem.upper[keep], base=base,
                            free_index=problem.free_index[keep],
                            reciprocal=_recip(problem)[keep],
                            bounds=None if problem.bounds is None else problem.bounds[keep])


def profile_end(problem: _Problem, theta, labels, k: int, side: int, rise: float,
                max_iterations: int, max_evaluations: int = 10):
    """The end on ``side`` (−1 lower, +1 upper) of the profile-likelihood interval of parameter k.

    P(t) = min over the other free parameters of χ² = Σr² with θ_k = t (Levenberg–Marquardt from
    the last profile point); the end is where P rises by ``rise`` = q² s² above P(θ̂), found by
    regula falsi (Illinois) on sqrt(P − P̂) − q s, which is linear in t for a quadratic profile,
    between θ̂ and the bound. Where P at the bound stays below, the end is the bound: the interval is
    one-sided. NaN if the profile is not finite.
    """
    bound = problem.lower[k] if side < 0 else problem.upper[k]
    best = _profile_cost(problem, theta, labels, k, theta[k], max_iterations)[0]
    level = math.sqrt(rise)
    others = np.delete(theta, k)

    def gap(t):
        nonlocal others
        cost, fitted = _profile_cost(problem, np.insert(others, k, t), labels, k, t,
                                     max_iterations)
        if np.isfinite(cost):
            others = fitted
        return math.sqrt(max(cost - best, 0.0)) - level if np.isfinite(cost) else np.nan

    g_bound = gap(bound)
    if not np.isfinite(g_bound):
        return np.nan
    if g_bound <= 0.0:
        return float(bound)
    a, g_a, b, g_b, last = float(theta[k]), -level, float(bound), g_bound, 0
    for _ in range(max_evaluations):
        x = b - g_b * (b - a) / (g_b - g_a)
        g_x = gap(x)
        if not np.isfinite(g_x):
            return np.nan
        if abs(g_x) <= 1e-3 * level:
            return x
        if g_x > 0:  # the end lies between a and x
            b, g_b = x, g_x
            if last > 0:
                g_a *= 0.5
            last = 1
        else:
            a, g_a = x, g_x
            if last < 0:
                g_b *= 0.5
            last = -1
    return b - g_b * (b - a) / (g_b - g_a)


def _profile_cost(problem, theta, labels, k, value, max_iterations):
    """(Σr², the other parameters) of the fit with θ_k held at ``value``, from ``theta``."""
    sub = _pinned(problem, k, value)
    others = np.delete(theta, k)
    lower, upper = sub.lower, sub.upper
    start = np.clip(others, lower + 1e-9 * (upper - lower), upper - 1e-9 * (upper - lower))
    fitted, _, r, _, _, status = levenberg_marquardt(sub, start, labels, max_iterations)
    if status == FitStatus.NOT_FINITE or not np.all(np.isfinite(r)):
        return np.nan, others
    return float(r @ r), fitted


def readable_intervals(problem: _Problem, theta, labels, intervals, quantile, variance,
                       max_iterations):
    """The Wald intervals, each side that leaves the bounds replaced by the profile-likelihood end
    (:func:`profile_end`, a bound where the profile stays below the 95 % level)."""
    out = {}
    rise = quantile**2 * variance
    for k, name in enumerate(problem.free):
        low, high = intervals[name]
        if not (np.isfinite(low) and np.isfinite(high)):
            out[name] = (low, high)
            continue
        if low < problem.lower[k]:
            low = profile_end(problem, theta, labels, k, -1, rise, max_iterations)
        if high > problem.upper[k]:
            high = profile_end(problem, theta, labels, k, +1, rise, max_iterations)
        out[name] = (float(low), float(high))
    return out


def identifiability_messages(problem: _Problem, null, intervals, correlation):
    """The sentences of :class:`IdentifiabilityWarning` (empty: every parameter is determined);
    ``intervals`` and ``correlation`` of the parameters as given (not internal)."""
    names, parts, involved = problem.free, [], set()
    if null is not None:
        terms = " · ".join(f"{name}^{c:+.3f}" for name, c in zip(names, null, strict=True)
                           if abs(c) > 0.1)
        parts.append(f"the Jacobian is rank-deficient: the data do not determine the combination "
                     f"{terms} (null vector of ∂r/∂log θ); the intervals of those parameters are "
                     f"NaN (fix one of them)")
        involved |= {name for name, c in zip(names, null, strict=True) if abs(c) > 0.1}
    loose = []
    bounds = _bounds(problem)
    for k, name in enumerate(names):
        low, high = intervals[name]
        if np.isfinite(low) and np.isfinite(high) and \
                high - low >= 0.5 * (bounds[k, 1] - bounds[k, 0]):
            loose.append(f"{name} (95 % interval [{low:.4g}, {high:.4g}] within bounds "
                         f"[{bounds[k, 0]:.4g}, {bounds[k, 1]:.4g}])")
            involved.add(name)
    if loose:
        parts.append("the data do not pin down " + "; ".join(loose))
    pairs = []
    with np.errstate(invalid="ignore"):
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                if abs(correlation[i, j]) > CORRELATION_LIMIT:
                    pairs.append(f"{names[i]} and {names[j]} ({correlation[i, j]:+.4f})")
                    involved |= {names[i], names[j]}
    if pairs:
        parts.append(f"estimates correlated beyond ±{CORRELATION_LIMIT}: " + ", ".join(pairs)
                     + " (the data determine a combination of them)")
    if parts:
        parts.append("what would help: " + "; ".join(f"{name}: {_help(name)}" for name in names
                                                     if name in involved))
    return parts


# ---------------------------------------------------------------------------------------------
# validation


def _allowed(name):
    """The allowed range of a parameter, in words (:func:`_admissible`)."""
    return dict(eta="the open interval (0, 1)", pressure="(-inf, inf) (a finite pressure "
                "difference P_i - P_o in Pa)").get(name, "(0, inf)")


def _admissible(name, value):
    """Every parameter is > 0 but the pressure difference (any finite value); η = R_i/R_o is < 1
    as well."""
    if name == "pressure":
        return bool(np.isfinite(value))
    return value > 0 and (name != "eta" or value < 1)


def _column(data, name, required=True):
    try:
        present = name in data
    except TypeError:
        present = False
    if not present:
        if required:
            raise ValueError(f"data is missing the column {name!r} (needs voltage_V, "
                             f"frequency_Hz; optional sigma_Hz, m, n, branch, torsional, "
                             f"lambda_i, lambda_z, pressure_Pa, width_Hz or quality_factor "
                             f"with sigma_width_Hz or sigma_quality_factor)")
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


def _fit_wall_hint(name, wall):
    """:func:`jaxdea.physics.leaves.wall_hint` in :func:`fit`'s terms ('' for no wall name)."""
    hint = wall_hint(name, wall)
    if name.startswith("material_") and (wall is None or isinstance(wall.material, str)):
        return (" (material_ names need a material object, e.g. material=jaxdea.MooneyRivlin(0.2); "
                "the default wall's Gent constant is 'gent')")
    return hint.replace("Tube(layers=...)", "layers=...")


def _check_wall_bounds(wall, name, bounds, low, high):
    """Raise ValueError unless the wall is valid with the parameter ``name`` at both bounds
    (:func:`jaxdea.params.validate_material`, :func:`jaxdea.params.validate_wall_layers`: β of
    Mooney–Rivlin in [0, 1], ratios > 0, fractions > 0 with the active layer's 1 − Σ f_passive > 0)."""
    for value in (low, high):
        try:
            tube = with_wall(wall, {name: value})
            validate_material(tube.material)
            validate_wall_layers(tube)
            for layer in tube.layers or ():
                validate_material(layer.material)
            validate_damping(tube.damping)
            if name.startswith("damping_") and not name.endswith("stretch_coupling") and value <= 0:
                raise ValueError("a damping parameter's bounds must be > 0")
        except ValueError as exc:
            raise ValueError(f"free[{name!r}] bounds must keep the wall valid, got {bounds!r}: at "
                             f"{value!r}, {exc}") from None


def _validate(data, free, fixed, fluid, wall=None):
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
    if coupling is not None and Face(coupling).has_poles and bessel_order is None:
        raise ValueError("fluid with the 'paper' coupling needs an explicit bessel_order")
    known = NAMES if coupling is not None else NAMES[:-2]
    if not _uses_gent(wall):
        if "gent" in free or "gent" in fixed:
            raise ValueError("parameter 'gent' is the Gent constant of the default wall: this "
                             "wall's energy is its material's (material=...) or its layers'")
        known = tuple(name for name in known if name != "gent")
    walls = wall_names(wall)  # the wall's own parameters, which may be free (not fixed)
    for name in list(free) + list(fixed):
        if name in walls and name in fixed:
            raise ValueError(f"fixed[{name!r}]: a wall parameter is held at its value on material= "
                             f"or layers= (change it there), or free it")
        if name not in known and name not in walls:
            extra = " (fluid parameters need fluid=...)" if name in FLUID_NAMES else ""
            extra = extra or _fit_wall_hint(name, wall)
            raise ValueError(f"unknown parameter {name!r}{extra}; known: "
                             f"{', '.join(known + walls)}")
        if name in free and name in fixed:
            raise ValueError(f"parameter {name!r} is both free and fixed")
    columns = {name: _column(data, name, required=False) for name in LOAD_COLUMNS}
    given = {name for name in LOADING_NAMES if name in free or name in fixed}
    if len(given) == 2:
        raise ValueError("lambda_i and pressure both given: a tube is held either by its inner "
                         "stretch lambda_i or by its pressure difference pressure (Pa), not both")
    for column, name in (("lambda_i", "lambda_i"), ("lambda_z", "lambda_z"),
                         ("pressure_Pa", "pressure")):
        if columns[column] is not None and (name in free or name in fixed):
            raise ValueError(f"parameter {name!r} is given both in free/fixed and as the data "
                             f"column {column!r}: give it one way")
    if columns["lambda_i"] is not None and columns["pressure_Pa"] is not None:
        raise ValueError("data columns 'lambda_i' and 'pressure_Pa' both given: a tube is held "
                         "either by its inner stretch or by its pressure difference")
    if columns["lambda_i"] is not None and "pressure" in given:
        raise ValueError("data column 'lambda_i' with the parameter 'pressure': a tube is held "
                         "either by its inner stretch or by its pressure difference")
    by_pressure = "pressure" in given or columns["pressure_Pa"] is not None
    held = {"lambda_z": columns["lambda_z"] is not None,
            "lambda_i": by_pressure or columns["lambda_i"] is not None,
            "pressure": not by_pressure or columns["pressure_Pa"] is not None}
    missing = [name for name in known
               if name not in free and name not in fixed and not held.get(name, False)]
    if missing:
        if "lambda_i" in missing:
            missing[missing.index("lambda_i")] = "lambda_i (or pressure, in Pa)"
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
        if name in walls:
            _check_wall_bounds(wall, name, bounds, low, high)
        elif not (_admissible(name, low) and _admissible(name, high)):
            raise ValueError(f"free[{name!r}] bounds must lie in {_allowed(name)}, "
                             f"got {bounds!r}")
        lower.append(low)
        upper.append(high)
    wall_leaves = tuple(name for name in free if name in walls)
    base = np.ones(len(NAMES) + len(wall_leaves))
    base[NAMES.index("gent")] = Tube.gent  # unused where the wall is not the Gent one
    for i, name in enumerate(wall_leaves):  # the wall's own values: the starts of its parameters
        base[len(NAMES) + i] = float(get_parameter(wall, None, None, name))
    for name, value in fixed.items():
        try:
            value = float(value)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"fixed[{name!r}] must be a real number, got {value!r}") from exc
        if not (np.isfinite(value) or (name == "gent" and value == np.inf)):
            raise ValueError(f"fixed[{name!r}] must be finite, got {value!r}")
        if not _admissible(name, value):
            raise ValueError(f"fixed[{name!r}] must be in {_allowed(name)}, got {value!r}")
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
    torsional = _integer_column(data, "torsional", 0)
    if torsional is not None and np.any(torsional > 1):
        raise ValueError("data column 'torsional' must hold 0 or 1 (1: a torsional mode, m = 0)")
    for name in ("lambda_i", "lambda_z"):
        if columns[name] is not None and np.any(columns[name] <= 0):
            raise ValueError(f"data column {name!r} must be > 0")
    columns = dict(voltage_V=voltage, frequency_Hz=frequency_hz, sigma_Hz=sigma, m=m, n=n,
                   branch=branch, torsional=torsional, **columns)
    for name, column in columns.items():
        if column is not None and column.size != voltage.size:
            raise ValueError(f"data column {name!r} has {column.size} rows, voltage_V "
                             f"{voltage.size}")
    if (m is None) != (n is None):
        raise ValueError("data columns 'm' and 'n' must be given together (or neither)")
    for name in ("branch", "torsional"):
        if columns[name] is not None and m is None:
            raise ValueError(f"data column {name!r} needs the labels 'm' and 'n'")
    if torsional is not None and np.any((torsional == 1) & (m != 0)):
        raise ValueError("data column 'torsional' is 1 where m != 0: torsional modes are m = 0")
    width, width_sigma, width_kind = _widths(data, frequency_hz, sigma, wall, m)
    observations = voltage.size * (1 if width is None else 2)
    if observations <= len(free):
        widths = "" if width is None else f" of frequency and width, {observations} observations"
        raise ValueError(f"data has {voltage.size} rows{widths}: more than {len(free)} (the "
                         f"number of free parameters) are needed")
    labels = None
    if m is not None:
        labels = np.stack([m, n, np.zeros_like(m) if branch is None else branch,
                           np.zeros_like(m) if torsional is None else torsional], axis=1)
    load = np.stack([np.full(voltage.size, np.nan) if columns[k] is None else columns[k]
                     for k in LOAD_COLUMNS], axis=1)
    _, condition = np.unique(np.column_stack([voltage, np.nan_to_num(load, nan=np.inf)]), axis=0,
                             return_inverse=True)
    names = tuple(free)
    reciprocal = np.array([name in RECIPROCAL for name in names])
    bounds = np.stack([lower, upper], axis=1)
    with np.errstate(divide="ignore"):  # a bound 0 of a parameter that is not reciprocal
        inside = np.where(reciprocal[:, None], 1.0 / bounds[:, ::-1], bounds)  # θ's bounds
    problem = _Problem(voltage, frequency_hz, np.ones_like(voltage) if sigma is None else sigma,
                       sigma is not None, names, inside[:, 0].copy(), inside[:, 1].copy(), base,
                       np.array([NAMES.index(k) if k in NAMES else
                                 len(NAMES) + wall_leaves.index(k) for k in names]),
                       0, coupling, bessel_order,
                       load=load, by_pressure=by_pressure, condition=condition.ravel(),
                       reciprocal=reciprocal, bounds=bounds, wall=wall, wall_leaves=wall_leaves,
                       width=width, width_sigma=width_sigma, width_kind=width_kind)
    return problem, labels


WIDTH_COLUMNS = ("width_Hz", "quality_factor", "sigma_width_Hz", "sigma_quality_factor")
"""Optional peak-width columns of :func:`fit`: the half-power width Δf (FWHM, Hz) or the quality
factor Q = f/Δf of each peak, and their standard deviations."""


def _widths(data, frequency_hz, sigma, wall, labels):
    """(w, σ_w, kind) of the width columns (:data:`WIDTH_COLUMNS`), or (None, None, None).

    kind "width": w = Δf in Hz; "quality": w = Q (with ``sigma_quality_factor``; without σ a Q
    column is compared as the width f/Q in Hz, in the units of the frequency residuals).

    Raises:
        ValueError: naming the column: both widths and Q, a σ column without its column or σ given
            for the frequencies and not the widths (or the reverse), values ≤ 0, widths without a
            damping law or without the labels m, n.
    """
    columns = {name: _column(data, name, required=False) for name in WIDTH_COLUMNS}
    width, quality, sigma_width, sigma_quality = (columns[k] for k in WIDTH_COLUMNS)
    if width is not None and quality is not None:
        raise ValueError("data columns 'width_Hz' and 'quality_factor' both given: give the peak "
                         "widths one way")
    for column, owner in (("sigma_width_Hz", "width_Hz"), ("sigma_quality_factor",
                                                           "quality_factor")):
        if columns[column] is not None and columns[owner] is None:
            raise ValueError(f"data column {column!r} needs the column {owner!r}")
    for name, values in columns.items():
        if values is not None and np.any(values <= 0):
            raise ValueError(f"data column {name!r} must be > 0")
        if values is not None and values.size != frequency_hz.size:
            raise ValueError(f"data column {name!r} has {values.size} rows, voltage_V "
                             f"{frequency_hz.size}")
    if width is None and quality is None:
        return None, None, None
    given = "width_Hz" if width is not None else "quality_factor"
    if wall is None or wall.damping is None:
        raise ValueError(f"data column {given!r}: peak widths need a damping law (damping="
                         f"jaxdea.Prony(...), KelvinVoigt, Hysteretic or FractionalKelvinVoigt; "
                         f"[damping] in a fit TOML): the undamped tube's resonances have no width")
    if labels is None:
        raise ValueError(f"data column {given!r} needs the labels 'm' and 'n' (peak widths are "
                         f"fitted to labelled modes)")
    own_sigma = sigma_width if width is not None else sigma_quality
    if (sigma is None) != (own_sigma is None):
        missing = ("sigma_width_Hz" if width is not None else "sigma_quality_factor") \
            if own_sigma is None else "sigma_Hz"
        raise ValueError(f"data column {missing!r} is needed: σ is given for "
                         f"{'the frequencies' if own_sigma is None else 'the widths'} only")
    if width is not None:
        return width, np.ones_like(width) if sigma_width is None else sigma_width, "width"
    if sigma_quality is not None:
        return quality, sigma_quality, "quality"
    return frequency_hz / quality, np.ones_like(quality), "width"


# ---------------------------------------------------------------------------------------------
# public


class _Outcome(NamedTuple):
    """One start's fit."""

    theta: np.ndarray
    r: np.ndarray
    jac: np.ndarray
    iterations: int
    status: FitStatus
    labels: np.ndarray
    cost: float  # what starts are compared by: ½Σr² (labelled) or the robust cost (unlabelled)


def fit(data, free: Mapping, fixed: Mapping, fluid=None, *, initial: Mapping | None = None,
        n_layers: int | None = None, scheme: str | None = None, m_max: int = 2, n_max: int = 3,
        n_branches: int = 2, torsional: bool = False, threshold: float = 0.1, outlier_sigma: float = 5.0,
        max_unmatched: float = 0.25, n_starts: int = 3, grid_points: int = 3,
        max_iterations: int = 100, max_reassignments: int = 10, outer=None, material=None,
        layers=None, damping=None) -> FitResult:
    """Material and geometry parameters from measured resonance frequencies (SI units).

    Minimises Σ ((f_model − f_data)/σ)² with f_model = Ω c_s/(2π R_i) of the labelled (or assigned)
    mode, c_s = sqrt(μ/ρ_s), V̂ = V sqrt(ε/μ)/R_i, α̂_n = 2nπ R_i/(λ_z L) (module docstring).

    Args:
        data: the path of a CSV file of peaks (:func:`jaxdea.read_peaks`), or a mapping (dict of
            arrays, DataFrame) with columns ``voltage_V``, ``frequency_Hz``,
            optional ``sigma_Hz`` (> 0) and optional integer labels ``m`` (≥ 0), ``n`` (≥ 1) and
            ``branch`` (≥ 0, default 0: the lowest root of that (m, n)). Without labels each peak is
            assigned to a mode (m ≤ m_max, n ≤ n_max, branch < n_branches) or left unmatched as an
            outlier, and the assignment is redone as the parameters move until it settles.
            Optional ``torsional`` (0/1, with the labels: a torsional mode, m = 0) and the
            loading of each peak, ``pressure_Pa`` (Pa), ``lambda_i`` or ``lambda_z`` (each
            replaces the parameter of that name: joint fits over several loadings).
            Optional peak widths (with ``damping`` and the labels ``m``, ``n``): ``width_Hz``
            (the half-power width, FWHM, Δf = 2 Im Ω c_s/(2π R_i)) or ``quality_factor``
            (Q = f/Δf = Re Ω/(2 Im Ω)), with ``sigma_width_Hz`` or ``sigma_quality_factor``
            exactly when ``sigma_Hz`` is given; each width adds the residual
            (w_model − w_data)/σ_w (without σ: in Hz, a Q column compared as the width f/Q).
        free: {name: (lower, upper)} of the parameters to estimate (names in ``NAMES``; the
            tube is held by ``lambda_i`` or by ``pressure`` = P_i − P_o in Pa, one of the two).
            With ``material`` or ``layers``, also the wall's own parameters by their sweep names
            (:func:`jaxdea.physics.leaves.wall_names`): ``material_beta`` of a Mooney–Rivlin wall,
            ``layer<k>_shear_ratio``, ``layer<k>_density_ratio``, ``layer<k>_fraction`` of a
            passive layer (the active layer absorbs the change, η held) and
            ``layer<k>_material_<field>``. Such a parameter starts at its value on the given wall
            in every start (it is not gridded; ``initial`` may leave it out), its bounds must keep
            the wall valid, and its Jacobian column is the implicit derivative like the others'.
        fixed: {name: value} of the others; every name must be free or fixed (the fluid names
            only with a fluid; ``gent`` may be ``inf``).
        fluid: None (empty tube), ``"acoustic"``, or a :class:`~jaxdea.Fluid` whose coupling and
            bessel_order are used (its ratios come from ``fluid_density``, ``fluid_speed``).
        initial: optional {name: value} start for free parameters (tried besides the grid).
        n_layers, scheme: the model's discretisation, as in :func:`jaxdea.frequencies`: None, None
            (default): graded sixth-order Magnus with N for roots to ≤ 1e-8 at the data's largest
            α̂, m and branch (checked again at the estimate); an integer N alone: N equal midpoint
            sublayers (the paper's laminate at N = 30).
        m_max, n_max, n_branches, torsional: the modes unlabelled peaks may be assigned to
            (with ``torsional``, also the torsional modes n ≤ n_max, branch < n_branches).
        threshold: the relative tolerance |log f_model − log f_data| of a match: of the first
            assignment of each start, and of every assignment without σ (beyond it a peak is an
            outlier: assignment (−1, −1, −1), left out of the fit).
        outlier_sigma: with σ given, the residual |f_model − f_data|/σ beyond which a peak is an
            outlier (after the first assignment); its cost τ² in the robust criterion.
        max_unmatched: the largest share of unmatched peaks of a CONVERGED fit (beyond it:
            :attr:`FitStatus.TOO_FEW_MATCHED`).
        n_starts: the number of starts (the lowest initial cost) that are fitted; 0 (with
            ``initial``): ``initial`` only.
        grid_points: candidate starts per free parameter (at fractions (k + ½)/grid_points of
            each bound interval, in log for :data:`LOG_STARTS`); beyond :data:`MAX_GRID`
            candidates in all, a Latin hypercube of :data:`MAX_GRID` points instead (fixed seed).
        max_iterations: Levenberg–Marquardt iterations per fit.
        max_reassignments: outer assign–fit rounds for unlabelled peaks.
        outer: None (the tube in vacuum or air), or the known surrounding fluid in SI: a
            :class:`jaxdea.units.FluidSI` such as :data:`jaxdea.units.WATER`, or
            (density kg/m³, sound speed m/s). Its ratios ρ_o/ρ_s, c_o/c_s follow the fitted μ, ρ_s.
        material: None (Gent, of the parameter ``gent``), or the wall's material object
            (``jaxdea.MooneyRivlin(0.2)``, ``NeoHookean()``, …; fixed but for the parameters
            named in ``free``), as ``Tube(material=...)``.
            Then ``gent`` is no parameter, and μ is the material's small-strain shear modulus.
        layers: None, or the layered wall as ``Tube(layers=...)`` (fixed but for the parameters
            named in ``free``): μ, ρ_s and ε are the active layer's, and ``gent`` is no parameter.
        damping: None (elastic), or the wall's damping law as ``Tube(damping=...)``
            (:class:`jaxdea.Prony`, ``FractionalKelvinVoigt``, ``KelvinVoigt``, ``Hysteretic``;
            parameters in units of μ and R_i/c_s; fixed but for those named in ``free``:
            ``damping_moduli_<i>``, ``damping_times_<i>`` (Prony branch i),
            ``damping_viscosity``, ``damping_loss``, ``damping_modulus``, ``damping_time``,
            ``damping_order``, ``damping_stretch_coupling``, with bounds > 0 but the last).
            The model of a peak is then the complex root Ω near it (e^{iΩt}, Im Ω > 0 decays),
            continued from the elastic root of the undamped tube (:func:`_seed`) and refined by
            :func:`jaxdea.solve_complex_frequency` (implicit derivatives): f = Re Ω c_s/(2πR_i),
            width Δf = 2 Im Ω c_s/(2πR_i) (FWHM), Q = f/Δf. Not with ``layers``.

    Returns:
        An instance of :class:`FitResult` (free wall parameters by their names in ``estimate``,
        ``interval``, ``parameters``; ``settings`` holds the fitted wall).

    Raises:
        ValueError: naming the parameter or column: unknown names (a wall name this wall lacks:
            why, and the valid names), a wall parameter in ``fixed``, wall bounds that make the
            wall invalid, a name both free and fixed or
            neither, bounds not finite with lower < upper, missing or non-finite columns,
            frequencies or σ ≤ 0, no more data rows than free parameters, an ``initial`` value
            outside its bounds, bad options; a width column without a damping law (the undamped
            tube's peaks have no width), without the labels, or with σ for frequencies or widths
            only.

    Warns:
        IdentifiabilityWarning: naming a rank-deficient combination, a parameter whose interval
            covers half its bounds or more, a pair correlated beyond :data:`CORRELATION_LIMIT`, and
            the data that would help.
        FitQualityWarning: status TOO_FEW_MATCHED or POOR_FIT, or a parameter stopped on a bound,
            in words.

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
    wall = _wall(material, layers, damping)
    problem, labels = _validate(data, free, fixed, fluid, wall)
    if n_layers is not None and (not isinstance(n_layers, (int, np.integer))
                                 or isinstance(n_layers, bool) or n_layers < 1):
        raise ValueError(f"n_layers must be None or an integer >= 1, got {n_layers!r}")
    validate_scheme(scheme)
    for name, value, low in (("m_max", m_max, 0), ("n_max", n_max, 1), ("n_branches", n_branches, 1),
                             ("n_starts", n_starts, 0 if initial is not None else 1),
                             ("grid_points", grid_points, 1),
                             ("max_iterations", max_iterations, 1),
                             ("max_reassignments", max_reassignments, 1)):
        if not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    for name, value in (("threshold", threshold), ("outlier_sigma", outlier_sigma)):
        if not (isinstance(value, (int, float, np.floating)) and 0 < value < np.inf):
            raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    if not (isinstance(max_unmatched, (int, float, np.floating)) and 0 <= max_unmatched <= 1):
        raise ValueError(f"max_unmatched must be a number in [0, 1], got {max_unmatched!r}")
    problem = problem._replace(threshold=float(threshold), outlier=float(outlier_sigma),
                               outer=_outer_si(outer), wall=wall)
    initial_starts, candidates = _starts(problem, initial, grid_points)
    if not isinstance(torsional, (bool, np.bool_)):
        raise ValueError(f"torsional must be True or False, got {torsional!r}")
    modes = (m_max, n_max, n_branches, bool(torsional))
    if labels is None:
        reach = (n_max, m_max, n_branches)
    else:
        reach = (int(labels[:, 1].max()), int(labels[:, 0].max()), int(labels[:, 2].max()) + 1)
    problem = problem._replace(n_layers=_discretisation(
        problem, initial_starts + candidates, reach, n_layers, scheme))

    def run(problem, theta0):
        if labels is not None:
            theta, r, jac, its, status = _fit_labelled(problem, theta0, labels, max_iterations)
            cost = 0.5 * float(r @ r) if np.all(np.isfinite(r)) else np.inf
            return _Outcome(theta, r, jac, its, status, labels, cost)
        return _fit_unlabelled(problem, theta0, modes, max_iterations,
                               max_reassignments)

    best = None
    for theta0 in _best_starts(problem, (initial_starts, candidates), labels, n_starts, modes):
        best = _better(best, run(problem, theta0))
    best = _from_inside(problem, best, run)
    final = _discretisation(problem, [best.theta], reach, n_layers, scheme)
    if final != problem.n_layers:  # the estimate needs more sublayers than the starts did
        problem = problem._replace(n_layers=final)
        best = _from_inside(problem, _better(None, run(problem, best.theta)), run)
    return _result(problem, best, max_unmatched, max_iterations)


def _better(best, outcome):
    """The lower-cost outcome (a CONVERGED one wins a tie)."""
    if best is None or outcome.cost < best.cost or (
            best.status != FitStatus.CONVERGED and outcome.status == FitStatus.CONVERGED
            and outcome.cost <= best.cost):
        return outcome
    return best


def _on_bound(problem, theta):
    """{index: "lower"/"upper"} of the parameters within BOUND_TOLERANCE of their bound range."""
    span = problem.upper - problem.lower
    out = {}
    for k in range(theta.size):
        if theta[k] - problem.lower[k] <= BOUND_TOLERANCE * span[k]:
            out[k] = "lower"
        elif problem.upper[k] - theta[k] <= BOUND_TOLERANCE * span[k]:
            out[k] = "upper"
    return out


def _from_inside(problem, best, run, fractions=(0.25, 0.5, 0.75), passes=2):
    """Restart each parameter stopped on a bound from inside (θ_k at ``fractions`` of its bound
    range, the others at the estimate) and keep the lowest cost: on a bound the sigmoid's slope
    vanishes, so the iteration stalls there even where the cost falls inside."""
    for _ in range(passes):
        if best.status == FitStatus.NOT_FINITE:
            return best
        stuck = _on_bound(problem, best.theta)
        if not stuck:
            return best
        previous = best
        for k in stuck:
            for fraction in fractions:
                theta0 = best.theta.copy()
                theta0[k] = problem.lower[k] + fraction * (problem.upper[k] - problem.lower[k])
                best = _better(best, run(problem, theta0))
        if best is previous:
            return best
    return best


def _fit_unlabelled(problem, theta0, modes, max_iterations, max_reassignments):
    """Alternate assignment (:func:`assign_modes`; the first wide, then with τ) and fit until the
    labels settle: the robust cost decreases at every step."""
    current, _ = assign_modes(problem, theta0, modes, wide=True)
    iterations, outcome = 0, None
    for _ in range(max_reassignments):
        if not np.any(current[:, 0] >= 0):
            break
        theta, r, jac, its, status = _fit_labelled(problem, theta0, current, max_iterations)
        iterations += its
        outcome = (theta, r, jac, status, current)
        if status == FitStatus.NOT_FINITE:
            break
        theta0 = theta
        new, _ = assign_modes(problem, theta0, modes)
        if np.array_equal(new, current):
            return _Outcome(theta, r, jac, iterations, status, current,
                            _robust_cost(problem, r, current))
        current = new
    if outcome is None:  # nothing matched at this start
        return _Outcome(theta0, np.full(0, np.nan), np.full((0, theta0.size), np.nan), iterations,
                        FitStatus.NOT_FINITE, current, np.inf)
    theta, r, jac, status, fitted = outcome
    status = status if status == FitStatus.NOT_FINITE else FitStatus.ASSIGNMENT_CHANGING
    cost = _robust_cost(problem, r, fitted) if np.all(np.isfinite(r)) else np.inf
    return _Outcome(theta, r, jac, iterations, status, fitted, cost)


def _discretisation(problem, thetas, reach, n_layers, scheme):
    """The static discretisation of the model: :func:`jaxdea.physics.transfer.laminate` of ``n_layers``,
    ``scheme``; for the accurate default the largest N over ``thetas`` at the largest n, m and
    branch count of ``reach`` = (n, m, roots), over the data's loadings (at V = 0 and, held by
    pressure, at the largest voltage too: λ_i grows with V)."""
    n_top, m_top, n_roots = reach
    loads = np.unique(np.nan_to_num(_load(problem), nan=np.inf), axis=0)
    loads[np.isinf(loads)] = np.nan
    voltages = (0.0, float(np.max(np.abs(problem.voltage)))) if problem.by_pressure else (0.0,)
    chosen = None
    for theta in thetas:
        for load in loads:
            for voltage in voltages:
                tube, alpha, _, _ = dimensionless(_values(problem, theta), voltage, float(n_top),
                                                  load=load, by_pressure=problem.by_pressure,
                                                  wall=problem.wall,
                                                  wall_leaves=problem.wall_leaves)
                if not np.isfinite(float(tube.lambda_i)):
                    continue  # no static state there (beyond pull-in): the fit reports it
                layers = laminate(n_layers, scheme, tube.replace(damping=None), float(alpha),
                                  n_roots, m_top)
                if not isinstance(layers, Layers):
                    return layers  # an explicit midpoint N
                if chosen is None or layers.count > chosen.count:
                    chosen = layers
    if chosen is None:  # no start had a static state: the accurate default at the first one
        tube, alpha, _, _ = dimensionless(_values(problem, thetas[0]), 0.0, float(n_top),
                                          wall=problem.wall, wall_leaves=problem.wall_leaves)
        chosen = laminate(n_layers, scheme, tube.replace(lambda_i=1.0, damping=None), float(alpha),
                          n_roots,
                          m_top)
    return chosen


def _result(problem, best, max_unmatched, max_iterations):
    """The :class:`FitResult` of the chosen outcome: uncertainty, readable intervals, quality
    status and the warnings."""
    theta, r, jac, iterations, status, final_labels, _ = best
    active = final_labels[:, 0] >= 0
    residuals = np.full(problem.voltage.size, np.nan)
    matched = int(active.sum())
    residuals[active] = r[:matched] if r.size >= matched else np.nan
    width_residuals = None
    if problem.width is not None:
        width_residuals = np.full(problem.voltage.size, np.nan)
        width_residuals[active] = r[matched:] if r.size == 2 * matched else np.nan
    p = theta.size
    known = set(NAMES if problem.coupling is not None else NAMES[:-2])
    known -= set() if _uses_gent(problem.wall) else {"gent"}
    load = _load(problem)
    known -= {name for name, given in zip(("lambda_i", "lambda_z", "pressure"),
                                          np.all(np.isfinite(load), axis=0), strict=True) if given}
    known -= {"lambda_i"} if problem.by_pressure else {"pressure"}
    values = _values(problem, theta)
    parameters = {k: float(v) for k, v in zip(NAMES, values[:len(NAMES)], strict=True)
                  if k in known}
    fitted_wall = problem.wall
    if problem.wall_leaves:  # the wall at the estimate: its settings rebuild the fitted model
        leaves = {name: float(values[len(NAMES) + i])
                  for i, name in enumerate(problem.wall_leaves)}
        parameters.update(leaves)
        fitted_wall = with_wall(problem.wall, leaves)
    layers = problem.n_layers
    settings = dict(n_layers=int(getattr(layers, "count", layers)),
                    scheme=getattr(layers, "scheme", "midpoint"),
                    graded=bool(getattr(layers, "graded", False)), coupling=problem.coupling,
                    bessel_order=problem.bessel_order,
                    loading="pressure" if problem.by_pressure else "stretch",
                    outer=None if problem.outer is None else list(problem.outer),
                    **wall_settings(fitted_wall))
    torsional = final_labels[:, 3] > 0
    final_labels = final_labels[:, :3]
    bounds = _bounds(problem)
    value = np.clip(_physical(problem, theta), bounds[:, 0], bounds[:, 1])
    estimate = dict(zip(problem.free, value.tolist(), strict=True))
    unmatched = float(np.mean(~active))
    dof = int(active.sum()) * (1 if problem.width is None else 2) - p
    chi2 = float(r @ r) if r.size and np.all(np.isfinite(r)) else np.nan
    chi2_per_dof = chi2 / dof if dof > 0 else np.nan
    flip = dict(lower="upper", upper="lower")
    at_bound = {problem.free[k]: flip[side] if _recip(problem)[k] else side
                for k, side in _on_bound(problem, theta).items()}
    if status == FitStatus.NOT_FINITE or not np.all(np.isfinite(jac)) or r.size == 0:
        nan = np.full((p, p), np.nan)
        return FitResult(estimate, {k: (np.nan, np.nan) for k in problem.free}, nan, nan,
                         residuals, final_labels, FitStatus.NOT_FINITE, iterations, problem.free,
                         parameters, settings, chi2, dof, chi2_per_dof, unmatched, at_bound,
                         torsional, width_residuals)
    covariance, correlation, intervals, null, quantile, variance = uncertainty(problem, theta, r,
                                                                                jac)
    intervals = readable_intervals(problem, theta, best.labels, intervals, quantile, variance,
                                   max_iterations)
    covariance, correlation, intervals = _as_given(problem, theta, covariance, intervals)
    messages = identifiability_messages(problem, null, intervals, correlation)
    if messages:
        warnings.warn("; ".join(messages), IdentifiabilityWarning, stacklevel=3)
    quality = []
    if status == FitStatus.CONVERGED and unmatched > max_unmatched:
        status = FitStatus.TOO_FEW_MATCHED
        quality.append(f"only {int(active.sum())} of {active.size} peaks match a mode "
                       f"({100 * unmatched:.0f} % unmatched, more than max_unmatched = "
                       f"{100 * max_unmatched:.0f} %): the modes searched (m_max, n_max, "
                       f"n_branches), the bounds or outlier_sigma may not fit these data")
    if status == FitStatus.CONVERGED and problem.has_sigma and dof > 0:
        from scipy.stats import chi2 as chi2_distribution  # scipy: imported where it is used

        tail = float(chi2_distribution.sf(chi2, dof))
        if tail < POOR_FIT_PROBABILITY:
            status = FitStatus.POOR_FIT
            quality.append(f"χ²/dof = {chi2_per_dof:.3g} with {dof} degrees of freedom "
                           f"(probability {tail:.2g} for the model with the σ given): the model "
                           f"does not explain the data within σ (σ too small, a wrong mode "
                           f"assignment, a parameter held at a wrong value)")
    for name, side in at_bound.items():
        k = problem.free.index(name)
        value = bounds[k, 0] if side == "lower" else bounds[k, 1]
        quality.append(f"{name} stopped on its {side} bound {value:.6g}: the data pull it beyond "
                       f"(restarts inside the bounds found no lower χ²); widen the bound or fix "
                       f"the parameter")
    if quality:
        warnings.warn("; ".join(quality), FitQualityWarning, stacklevel=3)
    return FitResult(estimate, intervals, covariance, correlation, residuals, final_labels,
                     status, iterations, problem.free, parameters, settings, chi2, dof,
                     chi2_per_dof, unmatched, at_bound, torsional, width_residuals)


def _as_given(problem: _Problem, theta, covariance, intervals):
    """(covariance, correlation, intervals) of the parameters as given from those of the internal θ
    (:data:`RECIPROCAL`): cov by the delta method, each interval's ends mapped (and swapped where
    θ = 1/value), inside the bounds as given."""
    d = _chain(problem, theta)
    covariance = covariance * np.outer(d, d)
    with np.errstate(all="ignore"):
        std = np.sqrt(np.diag(covariance))
        correlation = covariance / np.outer(std, std)
    bounds, out = _bounds(problem), {}
    for k, name in enumerate(problem.free):
        ends = np.asarray(intervals[name], float)
        if _recip(problem)[k]:
            with np.errstate(divide="ignore"):
                ends = 1.0 / ends[::-1]
        ends = np.where(np.isnan(ends), ends, np.clip(ends, bounds[k, 0], bounds[k, 1]))
        out[name] = (float(ends[0]), float(ends[1]))
    return covariance, correlation, out


def _wall_starts(problem: _Problem):
    """{name: start} of the free wall parameters: the value on the given wall, moved inside its
    bounds by 1e-3 of their range where it lies on or beyond one."""
    bounds = _bounds(problem)
    out = {}
    for i, name in enumerate(problem.free):
        if name in problem.wall_leaves:
            low, high = bounds[i]
            value = problem.base[problem.free_index[i]]
            out[name] = float(np.clip(value, low + 1e-3 * (high - low), high - 1e-3 * (high - low)))
    return out


def _starts(problem: _Problem, initial, grid_points):
    """Candidate starts (internal θ): ``initial`` (validated inside the bounds), and a grid of
    ``grid_points`` per parameter or, beyond :data:`MAX_GRID` points, a Latin hypercube of MAX_GRID
    points, spaced evenly in log for the scales of :data:`LOG_STARTS`, evenly for the others.
    A free wall parameter is not gridded: every start takes its value on the given wall
    (:func:`_wall_starts`), and ``initial`` may leave it out."""
    starts = []
    wall_start = _wall_starts(problem)
    if initial is not None:
        if not isinstance(initial, Mapping):
            raise ValueError(f"initial must be a mapping {{name: value}}, got {initial!r}")
        for name in initial:
            if name not in problem.free:
                raise ValueError(f"initial names {name!r}, which is not a free parameter "
                                 f"(free: {', '.join(problem.free)})")
        theta = []
        for i, name in enumerate(problem.free):
            if name not in initial and name in wall_start:
                theta.append(wall_start[name])
                continue
            if name not in initial:
                raise ValueError(f"initial is missing the free parameter {name!r}")
            try:
                value = float(initial[name])
            except (TypeError, ValueError) as exc:
                raise ValueError(f"initial[{name!r}] must be a real number, got "
                                 f"{initial[name]!r}") from exc
            low, high = _bounds(problem)[i]
            if not (low < value < high):
                raise ValueError(f"initial[{name!r}] = {value!r} must lie strictly inside "
                                 f"({low!r}, {high!r})")
            theta.append(value)
        starts.append(_internal(problem, np.array(theta)))
    gridded = np.array([name not in wall_start for name in problem.free])
    p = int(gridded.sum())
    if p == 0:  # only wall parameters free: the one start of their given values
        grid = np.zeros((1, 0))
    elif grid_points**p <= MAX_GRID:
        fractions = (np.arange(grid_points) + 0.5) / grid_points
        grid = np.stack(np.meshgrid(*[fractions] * p, indexing="ij"), axis=-1).reshape(-1, p)
    else:  # Latin hypercube: each parameter's range cut in MAX_GRID strata, one point in each
        rng = np.random.default_rng(0)
        grid = np.stack([(rng.permutation(MAX_GRID) + rng.uniform(size=MAX_GRID)) / MAX_GRID
                         for _ in range(p)], axis=1)
    low, high = _bounds(problem)[gridded].T
    names = [name for name, g in zip(problem.free, gridded, strict=True) if g]
    log = np.array([name in LOG_STARTS and low[i] > 0 for i, name in enumerate(names)], dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        spaced = np.where(log, low * (high / low) ** grid, low + (high - low) * grid)
    if wall_start:  # the wall's parameters at their given values in every start
        full = np.empty((spaced.shape[0], len(problem.free)))
        full[:, gridded] = spaced
        for i, name in enumerate(problem.free):
            if name in wall_start:
                full[:, i] = wall_start[name]
        spaced = full
    return starts, list(_internal(problem, spaced))


SCALE_FACTORS = 121
"""Frequency factors tried per start of unlabelled peaks (:func:`_scaled_start`)."""


def _scaled_start(problem: _Problem, theta, modes):
    """(start, its wide robust cost) of unlabelled peaks, the frequency scale searched: with μ (or
    else ρ_s) free, every model frequency is multiplied by a factor k on a log grid of
    :data:`SCALE_FACTORS` points (μ k² or ρ_s/k² inside its bounds; f ∝ sqrt(μ/ρ_s), exactly at
    V = 0), the peaks are matched at each (:func:`assign_modes`, wide), and the start moves to the
    best k, where its cost is evaluated anew (V̂ ∝ 1/sqrt(μ) moves too). A grid of starts spaced
    in μ alone puts the modes a whole mode spacing apart (0.5 ln 5 = 0.8 in ln f across bounds
    (2e4, 1e5) Pa), so that the best start of a coarse grid may match every peak to its
    neighbour's mode; the search finds the scale that the spectrum of peaks sets."""
    table = _mode_table(problem, theta, modes)
    wide = _match(problem, table, modes[2], True)[1]
    names = problem.free
    which = next((name for name in ("shear_modulus", "density") if name in names), None)
    if which is None:
        return theta, wide
    k = names.index(which)
    power = 2.0 if which == "shear_modulus" else -2.0  # the parameter moves as k^power
    low, high = sorted((problem.lower[k] / theta[k], problem.upper[k] / theta[k]))
    factors = np.exp(np.linspace(math.log(low), math.log(high), SCALE_FACTORS) / power)
    costs = [_match(problem, table, modes[2], True, factor)[1] for factor in factors]
    best = int(np.argmin(costs))
    if costs[best] >= wide:
        return theta, wide
    moved = theta.copy()
    span = problem.upper[k] - problem.lower[k]
    moved[k] = np.clip(theta[k] * factors[best] ** power, problem.lower[k] + 1e-3 * span,
                       problem.upper[k] - 1e-3 * span)
    cost = assign_modes(problem, moved, modes, wide=True)[1]
    return (moved, cost) if cost <= wide else (theta, wide)


def _best_starts(problem, starts, labels, n_starts, modes):
    """``initial`` (first, if given) and the ``n_starts`` candidates of lowest initial cost (the
    wide robust cost of :func:`assign_modes` for unlabelled peaks, each start moved to its best
    frequency scale first (:func:`_scaled_start`); Σ r² of the seeded branches otherwise)."""
    initial, starts = starts
    if n_starts == 0:
        return initial
    costs, starts = [], list(starts)
    for i, theta in enumerate(starts):
        if labels is None:
            starts[i], cost = _scaled_start(problem, theta, modes)
            costs.append(cost)
        elif _damped(problem):
            seed = _seed(problem, theta, labels)
            r = _residual(problem, _evaluate(problem, theta, labels, seed)[1], labels[:, 0] >= 0)
            costs.append(float(r @ r) if np.all(np.isfinite(r)) else np.inf)
        else:
            seed = _seed(problem, theta, labels)
            scale = float(hz_per_omega(_values(problem, theta)))
            r = (seed * scale - problem.frequency) / problem.sigma
            costs.append(float(r @ r) if np.all(np.isfinite(r)) else np.inf)
    costs = np.array(costs)
    order = np.argsort(costs, kind="stable")
    chosen = [starts[i] for i in order[:n_starts] if np.isfinite(costs[i])]
    return initial + (chosen if chosen or initial else [starts[order[0]]])


def fitted_frequencies(result: FitResult, voltage_V, m, n, branch=0, *, torsional=False,
                       lambda_i=None, lambda_z=None, pressure_Pa=None) -> np.ndarray:
    """Frequencies in Hz of the fitted model: f = Ω_k(m; V̂, α̂_n) c_s/(2π R_i) at the parameters
    of ``result`` (``result.parameters``, ``result.settings``), per point.

    Ω_k is the k-th lowest positive root (k = ``branch``) of the global root scan (the definition
    of a branch in :func:`fit`); NaN where that root does not exist. A damped fit's (``damping=``):
    Re Ω of the complex root continued from it (:func:`_seed`). The arguments broadcast.
    ``torsional``: the torsional family (m = 0). ``lambda_i``, ``lambda_z``, ``pressure_Pa``: the
    loading of each point where the fit had them as data columns (or to evaluate the fitted tube
    at another loading); ``pressure_Pa`` only for a tube held by pressure, ``lambda_i`` only for
    one held by stretch (``result.settings["loading"]``).

    Examples:
        >>> voltage = np.linspace(0.0, 5e3, 21)
        >>> f_01 = fitted_frequencies(result, voltage, m=0, n=1)        # (21,) Hz
        >>> f_11 = fitted_frequencies(result, voltage, m=1, n=1, branch=1)
    """
    require_x64()
    settings = result.settings
    by_pressure = settings.get("loading", "stretch") == "pressure"
    loads = []
    for name, values, needed in (("lambda_i", lambda_i, "lambda_i"),
                                 ("lambda_z", lambda_z, "lambda_z"),
                                 ("pressure_Pa", pressure_Pa, "pressure")):
        if values is None:
            if needed not in result.parameters and not (
                    (name == "lambda_i" and by_pressure) or (name == "pressure_Pa"
                                                             and not by_pressure)):
                raise ValueError(f"{name} is needed: the fit had it as a data column")
            values = np.nan
        else:
            if (name == "lambda_i" and by_pressure) or (name == "pressure_Pa" and not by_pressure):
                raise ValueError(f"{name} does not apply to a tube held by "
                                 f"{settings.get('loading', 'stretch')}")
            values = np.asarray(values, dtype=np.float64)
            if not np.all(np.isfinite(values)) or (name != "pressure_Pa" and np.any(values <= 0)):
                raise ValueError(f"{name} must be finite" + (" and > 0" if name != "pressure_Pa"
                                                             else ""))
        loads.append(values)
    voltage, m, n, branch, torsional, *loads = np.broadcast_arrays(
        np.asarray(voltage_V, dtype=np.float64), np.asarray(m), np.asarray(n), np.asarray(branch),
        np.asarray(torsional), *loads)
    shape = voltage.shape
    voltage, m, n, branch, torsional = (x.ravel() for x in (voltage, m, n, branch, torsional))
    load = np.stack([np.ravel(x) for x in loads], axis=1).astype(np.float64)
    if not np.all(np.isfinite(voltage)):
        raise ValueError("voltage_V must be finite")
    for name, values, low in (("m", m, 0), ("n", n, 1), ("branch", branch, 0)):
        if np.any(values != np.round(values)) or np.any(values < low):
            raise ValueError(f"{name} must hold integers >= {low}")
    m, n, branch, torsional = m.astype(int), n.astype(int), branch.astype(int), torsional.astype(bool)
    if np.any(torsional & (m != 0)):
        raise ValueError("torsional modes are m = 0")
    layers = settings["n_layers"]
    if settings.get("scheme", "midpoint") != "midpoint" or settings.get("graded", False):
        layers = Layers(int(layers), settings["scheme"], bool(settings.get("graded", False)))
    base = np.array([result.parameters.get(k, 1.0) for k in NAMES], dtype=np.float64)
    base[NAMES.index("gent")] = result.parameters.get("gent", Tube.gent)  # as fit's, without one
    problem = _Problem(voltage, np.ones_like(voltage), np.ones_like(voltage), False, (),
                       np.zeros(0), np.zeros(0), base, np.zeros(0, int), layers,
                       settings["coupling"], settings["bessel_order"], by_pressure=by_pressure,
                       outer=_outer_si(settings.get("outer")), wall=wall_from_settings(settings))
    out = np.full(voltage.size, np.nan)
    if voltage.size:
        n_roots = int(branch.max()) + 1
        scale = float(hz_per_omega(base))
        for start in range(0, voltage.size, CURVE_CHUNK):  # one compiled batch size
            part = slice(start, start + CURVE_CHUNK)
            roots = _roots(problem, np.zeros(0), voltage[part], n[part], m[part], n_roots,
                           load[part], torsional[part])
            root = roots[np.arange(roots.shape[0]), branch[part]]
            if _damped(problem):  # Re Ω of the complex root continued from the elastic one
                sub = problem._replace(voltage=voltage[part], load=load[part])
                labels = np.stack([m[part], n[part], branch[part], torsional[part]], axis=1)
                root = root.astype(complex)
                for step in range(1, HOMOTOPY_STEPS + 1):
                    root = _evaluate_damped(sub, np.zeros(0), labels, root,
                                            step / HOMOTOPY_STEPS)[0]
                root = root.real
            out[part] = root * scale
    return out.reshape(shape)
