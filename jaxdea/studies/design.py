"""Design optimisation with optax: thickness and voltage for a target frequency, and tunability.

Two example problems on the fluid-free tube, both for the lowest frequency Ω of one mode (m, n):
any circumferential order m >= 0 (ring modes m >= 1, or the torsional family at m = 0) and axial
mode n (α̂ = 2nπ/(λ_z L/R_i), :func:`jaxdea.axial_wavenumber`; the frequency design holds the
undeformed length L/R_i by default, so α̂ does not change with the wall, or L/R_o on request),
both under the safety constraint V̂ ≤ m V̂_first (m = ``voltage_margin`` = 0.8), where V̂_first is the
tube's first instability: the smallest critical voltage over every circumferential order
0 ≤ m ≤ ``m_max`` and axial mode 1 ≤ n ≤ ``n_max`` (:func:`jaxdea.first_instability`). For the
paper's tube that is ring (m = 2) buckling at about half (λ_i = 1.1) or a tenth (λ_i = 0.9) of the
axisymmetric V̂_cr of the designed mode, which the paper's constraint used (``m_max=0, n_max=1``
restores it for n = 1):

* :func:`design_for_frequency`: the undeformed thickness H/R_i (η = R_i/R_o = 1/(1 + H/R_i)) and the
  voltage V̂ that put Ω at a target Ω_t;
* :func:`maximise_tunability`: the voltage (and optionally λ_i) that maximise the tunability
  |dΩ/dV̂| at fixed thickness.

How the problems are posed, and why (what converged robustly in our runs):

* Every design variable is mapped from an unconstrained variable x onto its admissible range, so
  adam never leaves it: V̂ = s · m V̂_cr(θ) with s ∈ (0, 1) meets the constraint at every iterate (no
  penalty weight to tune, no infeasible iterate, no bias at the optimum).
* An optimum inside a range is reached through a sigmoid, s = σ(x). An optimum *on* a bound (an
  active constraint) is reached through the map s = (1 − cos x)/2, which attains s = 1 at the
  finite x = π with ds/dx = 0: the constrained optimum becomes an ordinary stationary point,
  quadratic in x, instead of a point at x → ∞ that a sigmoid only approaches.
* V̂_first is the minimum of a few candidate critical voltages V̂_cr(m, n): those within
  ``CANDIDATE_BAND`` of the minimum of the full (m, n) grid of :func:`jaxdea.first_instability`,
  computed at the start, every ``REFRESH`` steps and at convergence. A run converges only when the
  full grid at the final iterate confirms that its first instability is among the candidates (else
  the candidates are replaced and the run goes on), so a mode that overtakes the others during the
  run is never missed; between refreshes each step solves only the candidates.
* Each step solves for values only: each candidate V̂_cr by :func:`jaxdea.solve_critical_voltage` and Ω by
  :func:`jaxdea.solve_frequency` (the safeguarded Newton of :func:`jaxdea.frequency`) started at the
  previous iterate's root; a failed solve stops the run (status NOT_FINITE). Between refreshes the
  candidates cannot see another mode's V̂_cr fall to 0: where a refresh finds the iterate buckling
  at V̂ = 0 (no admissible voltage: a target beyond the walls stable at rest), the run goes back,
  by bisection over its iterates, to the last one the full grid finds stable, and returns it with
  status UNSTABLE_AT_REST. :func:`jaxdea.frequencies`
  seeds the first guess and verifies the optimum (the tracked root must be the lowest).
* The loss and its gradient come from one small compiled program that attaches implicit-function
  derivatives to those roots, dx/dθ = −(∂g/∂θ)/(∂g/∂x) for g(Ω) = f(Ω; θ) and g(V̂) = f(0; V̂, θ)
  (:func:`jaxdea.numerics.scalar.implicit_root`, the mechanism of every solver of the package; never
  derivatives of the iterations), and differentiates in forward
  mode (two or fewer variables). The solvers themselves are the library's compiled programs, shared
  with every other use, so a design run compiles only characteristic-function derivatives.
* The tunability T = dΩ/dV̂ = −(∂f/∂V̂)/(∂f/∂Ω) is evaluated at the root that carries its implicit
  derivatives (:func:`tunability`), so the gradient of T, a second derivative of Ω, is exact
  (nested ``jax.grad`` of :func:`jaxdea.frequency` gives the same second derivatives, tested).
* The frequency design is a root of one scalar equation, g(H) = Ω(H, s_op m V̂_first(H))/Ω_t − 1,
  solved by safeguarded Newton with its exact derivative (quadratic convergence in a few steps);
  adam only seeks the compromise where the target is out of reach. (adam alone, with its
  decaying rate, froze 0.31 % short of a reachable 160 Hz target after 500 steps, issue 43.)
* adam's learning rate decays geometrically (``optax.exponential_decay``): adam's steps have the
  size of the learning rate whatever the gradient, so a constant rate leaves the iterate
  oscillating at that size; the decay lets it settle to the tolerance.
"""

from __future__ import annotations

import enum
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..compiled import cached_jit, jit, serializable
from ..numerics.scalar import ROOT_RTOL, Status, implicit_root, refuse_non_root
from ..params import (
    Fluid,
    Tube,
    as_float,
    canonical,
    mode_wavenumber,
    require_x64,
    validate_layers,
    validate_real,
    with_outer,
)
from ..physics.dispersion import characteristic
from ..physics.problem import describe, family_of
from ..physics.transfer import laminate, validate_scheme
from ..solve.instability import (
    branch_walls,
    first_instability,
    held_critical_stretch,
    held_critical_voltage,
    held_stretch,
    held_tube,
)
from ..solve.modes import root_distance
from ..solve.roots import frequencies, solve_critical_voltage, solve_frequency

DECAY = 0.97  # learning-rate factor per step
FLOOR = 1e-9  # the rate never falls below FLOOR x its initial value
NEWTON_MAX_STEP = 2.0  # frequency design: the longest Newton step in the thickness variable x_H
NEWTON_EDGE = 25.0  # |x_H| beyond which the thickness sits on a bound (σ(25) = 1 − 1.4e-11)
NEWTON_REFRESH = 0.25  # a Newton step longer than this (in x_H) refreshes the candidate modes
NEWTON_TURN = 1e-3  # frequency design: the width in x_H at which an extremum of g counts as found
NEWTON_STEPS = 40  # at most this many Newton steps before adam takes over
PLATEAU = 10  # steps over which maximise_tunability's loss must have settled
CANDIDATE_BAND = 0.05  # (m, n) with V̂_cr <= (1 + band) V̂_first are solved at every step
CANDIDATES = 4  # at most this many candidates (the lowest), padded by repeating the first
REFRESH = 20  # steps between two evaluations of the full (m, n) grid


class DesignStatus(enum.IntEnum):
    """Outcome of a design run."""

    CONVERGED = 0  # the convergence test was met
    MAX_STEPS = 1  # the step limit was reached first
    NOT_FINITE = 2  # a root solve failed or the loss became NaN: the last good iterate is returned
    WRONG_BRANCH = 3  # converged, but the tracked root is not the lowest one (verification failed)
    UNSTABLE_AT_REST = 4  # the run reached walls that buckle at V̂ = 0 (no admissible voltage): the
    # target lies beyond the walls stable at rest; the last iterate the full (m, n) grid confirms
    # stable is returned, with its bound


@serializable
class DesignResult(NamedTuple):
    """Result of a design run (Python floats; the history a NumPy array).

    Attributes:
        tube: the optimised :class:`~jaxdea.Tube` (``voltage``, ``eta``, ``lambda_i`` set).
        alpha: α̂ of the mode at the optimum.
        omega: lowest frequency Ω at the optimum (from :func:`jaxdea.frequencies`).
        critical_voltage: V̂_first of the optimised tube: its first instability over the orders
            and axial modes of the constraint (:func:`jaxdea.first_instability`).
        unstable_mode: (m, n) of that first instability.
        thickness: undeformed H/R_i = 1/η − 1.
        voltage: V̂.
        voltage_fraction: s = V̂ / (m V̂_first), in [0, 1].
        tunability: dΩ/dV̂ at the optimum.
        loss: loss at the returned iterate.
        history: loss at every step, shape (n_steps,).
        n_steps: number of loss evaluations (optimiser steps) taken.
        converged: True when ``status`` is CONVERGED.
        status: :class:`DesignStatus`.
    """

    tube: Tube
    alpha: float
    omega: float
    critical_voltage: float
    unstable_mode: tuple
    thickness: float
    voltage: float
    voltage_fraction: float
    tunability: float
    loss: float
    history: np.ndarray
    n_steps: int
    converged: bool
    status: DesignStatus


# ----------------------------------------------------------------------------- building blocks


def tunability(tube: Tube, alpha, omega, fluid: Fluid | None = None, n_layers: int | None = None,
               scheme: str | None = None, m=0, torsional: bool = False, delta_p=None,
               outer: Fluid | None = None):
    """dΩ/dV̂ on the branch through the root ``omega``: T = −(∂f/∂V̂)/(∂f/∂Ω) (implicit function theorem).

    A tube held by its pressure difference (``delta_p`` = ΔP̂) has λ_i = λ_i(V̂; ΔP̂)
    (:func:`jaxdea.inner_stretch`), and T is the total derivative −(∂f/∂V̂ + ∂f/∂λ_i dλ_i/dV̂)/(∂f/∂Ω):
    what a lab that holds the pressure measures.

    ``omega`` must be a root (from :func:`jaxdea.frequency` or :func:`jaxdea.frequencies`), to the
    relative Newton distance ``jaxdea.solve.modes.ROOT_RTOL`` = 1e-4 of the same discretisation: a
    concrete non-root raises a ValueError (a traced one gives NaN), since −f_V̂/f_Ω off a root is a
    plausible number that means nothing. When ``omega`` carries its implicit derivatives, as those
    functions' roots do, ``jax.jacfwd``/``jax.grad`` of T with respect to any leaf is the exact
    second derivative d²Ω/dV̂dθ of the discretisation.

    Args:
        tube: the :class:`~jaxdea.Tube` (its ``voltage`` is the operating point).
        alpha: α̂ = α R_i.
        omega: a root Ω at that α̂.
        fluid: a :class:`~jaxdea.Fluid` or None.
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_layers: sublayers N (static), or None: the accurate discretisation (:func:`jaxdea.frequencies`).
        scheme: the propagation scheme (static; :func:`jaxdea.frequencies`), that of the root.
        m: the circumferential order of the root (int >= 0, as :func:`jaxdea.frequencies`).
        torsional: the torsional family (m = 0 only), as :func:`jaxdea.frequencies`.
        delta_p: None (λ_i held) or ΔP̂ = (P_i − P_o)/μ, the pressure difference that holds the tube
            (``tube.lambda_i`` is then ignored: it is the λ_i that ΔP̂ holds at ``tube.voltage``).

    Examples:
        >>> t = Tube(voltage=0.1, lambda_i=1.1, lambda_z=1.2)
        >>> a = axial_wavenumber(t, 1)
        >>> tunability(t, a, frequencies(t, a)[0])  # ≈ −1.217
    """
    tube = with_outer(tube, outer)
    require_x64()
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    orders = dict(m=m, torsional=torsional) if problem.family.carries_m else {}
    tube, alpha, omega = canonical(tube, alpha, omega)
    if delta_p is not None:
        validate_real("delta_p", delta_p, "a finite real number (ΔP̂, the pressure difference)")
        delta_p = as_float(delta_p)
        tube = held_at(tube, tube.voltage, delta_p)
    voltage = as_float(tube.voltage)

    def f(om, v):
        return characteristic(held_at(tube, v, delta_p), om, alpha, fluid, n_layers, scheme,
                              **orders)

    f_omega = jax.jvp(lambda om: f(om, voltage), (omega,), (jnp.ones_like(omega),))[1]
    f_voltage = jax.jvp(lambda v: f(omega, v), (voltage,), (jnp.ones_like(voltage),))[1]
    layers = laminate(n_layers, scheme, tube, alpha, m=m)
    distance = root_distance(*jax.lax.stop_gradient((tube, alpha, omega, fluid)), layers,
                             problem.order, **problem.arguments(as_float(m)))
    refuse_non_root(omega, distance)
    return jnp.where(distance <= ROOT_RTOL, -f_voltage / f_omega, jnp.nan)


def held_at(tube: Tube, voltage, delta_p=None) -> Tube:
    """``tube`` at ``voltage``, held by its stretch (``delta_p`` None: λ_i kept) or by ΔP̂ (λ_i that
    ΔP̂ holds there, :func:`jaxdea.inner_stretch`, with implicit derivatives)."""
    tube = tube.replace(voltage=voltage)
    if delta_p is None:
        return tube
    return tube.replace(lambda_i=held_stretch(tube, delta_p))


def _with_implicit_derivatives(residual, root):
    """``root`` (a solved value of residual(x) = 0) with dx/dθ = −(∂g/∂θ)/(∂g/∂x) attached."""
    root = jax.lax.stop_gradient(root)
    return implicit_root(residual, lambda: (root, Status.CONVERGED), root)[0]


def _sigmoid_inverse(y, lo, hi):
    p = (y - lo) / (hi - lo)
    return math.log(p / (1.0 - p))


def _cosine(x):
    """(1 − cos x)/2: onto [0, 1], attaining both ends at finite x with zero slope."""
    return 0.5 * (1.0 - jnp.cos(x))


def _cosine_inverse(y, lo, hi):
    return math.acos(1.0 - 2.0 * (y - lo) / (hi - lo))


def _point(x, setting, kind):
    """(tube at V̂ = 0, α̂, s) of the design variables x; same code eagerly and under jit."""
    tube, n = setting["tube"], setting["n"]
    if kind == "frequency":
        thickness = setting["h_lo"] + (setting["h_hi"] - setting["h_lo"]) * jax.nn.sigmoid(x[0])
        eta = 1.0 / (1.0 + thickness)
        # hold = 1: L/R_i held (L/R_o = (L/R_i) η follows the wall); hold = 0: L/R_o held
        hold = setting["hold_length"]
        tube = tube.replace(eta=eta, length_ratio=hold * setting["length"] * eta
                            + (1.0 - hold) * tube.length_ratio)
        fraction = jax.nn.sigmoid(x[1])
    else:
        fraction = _cosine(x[0])
        if kind == "tunability_lambda":
            lam = setting["li_lo"] + (setting["li_hi"] - setting["li_lo"]) * _cosine(x[1])
            tube = tube.replace(lambda_i=lam)
    tube = tube.replace(voltage=jnp.zeros_like(fraction))
    alpha = mode_wavenumber(tube, n)
    return tube, alpha, fraction


class Candidates(NamedTuple):
    """The (m, n) whose V̂_cr bound the voltage between two refreshes (float arrays, shape (K,))."""

    m: jax.Array
    n: jax.Array


def _candidates(critical) -> Candidates | None:
    """The modes within CANDIDATE_BAND of the first instability of a (m_max + 1, n_max) grid of V̂_cr,
    at most CANDIDATES of them, padded to CANDIDATES by repeating the lowest; None if none is
    finite."""
    grid = np.where(np.isfinite(critical), critical, np.inf)
    order = np.argsort(grid, axis=None, kind="stable")
    lowest = grid.flat[order[0]]
    if not np.isfinite(lowest):
        return None
    keep = [k for k in order[:CANDIDATES] if grid.flat[k] <= (1.0 + CANDIDATE_BAND) * lowest]
    keep += [keep[0]] * (CANDIDATES - len(keep))
    m, n = np.unravel_index(np.asarray(keep), grid.shape)
    return Candidates(jnp.asarray(m, jnp.float64), jnp.asarray(n + 1, jnp.float64))


def _first_instability(tube, m_max, n_max, n_layers, scheme, delta_p=None):
    """(V̂_first, (m, n), the full grid) of ``tube`` (values), held by its stretch or by ΔP̂."""
    first = first_instability(tube, n_max=n_max, m_max=m_max, n_layers=n_layers, scheme=scheme,
                              delta_p=delta_p)
    found = int(first.status) == Status.CONVERGED
    return (float(first.voltage) if found else math.nan, (int(first.m), int(first.n)),
            np.asarray(first.critical))


def _solve_candidates(tube, candidates, n_layers, scheme, delta_p=None):
    """The critical root of each candidate (values; NaN where it has none below pull-in), shape
    (K,): V̂_cr of the tube held by its stretch, or λ_cr of the tube held by ΔP̂
    (:mod:`jaxdea.solve.instability`)."""
    values, seen = [], {}
    for m, n in zip(np.asarray(candidates.m).tolist(), np.asarray(candidates.n).tolist(), strict=True):
        if (m, n) not in seen:
            alpha = mode_wavenumber(tube, n)
            if delta_p is None:
                root = solve_critical_voltage(tube, alpha, n_layers=n_layers, scheme=scheme, m=int(m))
            else:
                root = held_critical_stretch(tube, delta_p, alpha, float(m),
                                             n_layers=laminate(n_layers, scheme))
            seen[m, n] = float(root[0])
        values.append(seen[m, n])
    return jnp.asarray(values, jnp.float64)


def _bound(tube, v_roots, candidates, n_layers, scheme, delta_p=None):
    """V̂_first = min over the candidates of V̂_cr(m, n), each root with implicit derivatives
    (g(V̂) = f(Ω = 0; V̂) of order m at α̂_n; order m as a traced value: one program for every
    candidate set, the longitudinal zeros at m = 0, docs/theory/order_m.md §3). Held by ΔP̂, the
    roots are λ_cr and V̂_cr = V̂(λ_cr) (:func:`jaxdea.solve.instability.held_critical_voltage`)."""
    def one(v_root, m, n):
        found = jnp.isfinite(v_root)
        alpha = mode_wavenumber(tube, n)
        root = jnp.where(found, v_root, 1.0)
        if delta_p is None:
            v = _with_implicit_derivatives(
                lambda v: characteristic(tube.replace(voltage=v), jnp.zeros_like(v), alpha,
                                         n_layers=n_layers, scheme=scheme, m=m), root)
        else:
            v = held_critical_voltage(tube, delta_p, alpha, m, laminate(n_layers, scheme), root)
        return jnp.where(found, v, jnp.inf)

    return jnp.min(jax.vmap(one)(v_roots, candidates.m, candidates.n))


def _orders(mode):
    """Keyword arguments of the solvers for the designed mode's (m, torsional) (none for the
    axisymmetric longitudinal family: its programs as before order m existed)."""
    m, torsional = mode
    return {} if (m, torsional) == (0, False) else dict(m=m, torsional=torsional)


def _objective(x, omega_root, v_roots, candidates, setting, kind, n_layers, scheme, mode=(0, False)):
    """(loss, aux) at x, given the roots solved there (values); differentiable through them."""
    tube, alpha, fraction = _point(x, setting, kind)
    delta_p = setting.get("delta_p")
    v_first = _bound(tube, v_roots, candidates, n_layers, scheme, delta_p)
    biased = held_at(tube, fraction * setting["margin"] * v_first, delta_p)
    omega = _with_implicit_derivatives(
        lambda om: characteristic(biased, om, alpha, n_layers=n_layers, scheme=scheme,
                                  **_orders(mode)), omega_root)
    if kind == "frequency":  # the tunability is left to _finish: a smaller program to compile
        slope = jnp.full_like(omega, jnp.nan)
        miss = omega / setting["target"] - 1.0
        loss = miss**2 + (fraction - setting["s_op"]) ** 2
    else:
        slope = tunability(biased, alpha, omega, n_layers=n_layers, scheme=scheme, delta_p=delta_p,
                           **_orders(mode))
        miss = jnp.zeros_like(omega)
        loss = -jnp.abs(slope)
    aux = dict(loss=loss, omega=omega, alpha=alpha, critical_voltage=v_first, tube=biased,
               tunability=slope, fraction=fraction, miss=miss)
    return loss, aux


@cached_jit(static_argnames=("kind", "n_layers", "scheme", "mode"))
def _loss_and_gradient(x, omega_root, v_roots, candidates, setting, kind, n_layers, scheme,
                       mode=(0, False)):
    """(aux, dloss/dx) by forward mode (at most two design variables)."""
    grad, aux = jax.jacfwd(_objective, has_aux=True)(x, omega_root, v_roots, candidates, setting,
                                                     kind, n_layers, scheme, mode)
    return jax.lax.stop_gradient(aux), grad


def _evaluate(x, guess, setting, kind, n_layers, scheme, candidates, mode=(0, False)):
    """Solve the roots at x (values) and return (aux, gradient), or None where a solve failed."""
    tube, alpha, fraction = _point(x, setting, kind)
    delta_p = setting.get("delta_p")
    v_roots = _solve_candidates(tube, candidates, n_layers, scheme, delta_p)
    if not bool(jnp.any(jnp.isfinite(v_roots))):
        return None
    v_first = jnp.nanmin(v_roots if delta_p is None else held_tube(tube, delta_p, v_roots).voltage)
    biased = held_at(tube, fraction * setting["margin"] * v_first, delta_p)
    omega, status = solve_frequency(biased, alpha, guess, n_layers=n_layers, scheme=scheme,
                                    **_orders(mode))
    if int(status) != Status.CONVERGED:
        return None
    aux, grad = _loss_and_gradient(x, omega, v_roots, candidates, setting, kind, n_layers, scheme,
                                   **({} if mode == (0, False) else dict(mode=mode)))
    if not (math.isfinite(float(aux["loss"])) and bool(jnp.all(jnp.isfinite(grad)))):
        return None
    return aux, grad


class _Bound:
    """The candidate modes of a run, refreshed from the full (m, n) grid (module docstring)."""

    def __init__(self, setting, kind, n_layers, scheme, m_max, n_max):
        self.setting, self.kind, self.n_layers, self.scheme = setting, kind, n_layers, scheme
        self.m_max, self.n_max = m_max, n_max
        self.candidates, self.first, self.mode = None, math.nan, (-1, 0)

    def refresh(self, x):
        """Candidates from the full grid at x; False if no (m, n) has a critical voltage, or if the
        tube is unstable already at V̂ = 0 (no admissible voltage)."""
        tube = _point(jnp.asarray(x, jnp.float64), self.setting, self.kind)[0]
        self.first, self.mode, grid = _first_instability(tube, self.m_max, self.n_max,
                                                         self.n_layers, self.scheme,
                                                         self.setting.get("delta_p"))
        self.candidates = _candidates(grid)
        return self.candidates is not None and self.first > 0.0

    def confirmed(self, x, aux):
        """True if the full grid at x finds the bound of ``aux`` (to 1e-9); else refreshes."""
        tracked = float(aux["critical_voltage"])
        if not self.refresh(x):
            return False
        return abs(self.first - tracked) <= 1e-9 * abs(tracked)


def _run(x0, guess, bound, setting, kind, n_layers, scheme, learning_rate, max_steps, done,
         mode=(0, False)):
    """adam with a geometrically decaying rate, each step from the previous root; converged only
    when the full (m, n) grid confirms the bound (:class:`_Bound`)."""
    schedule = optax.exponential_decay(learning_rate, transition_steps=1, decay_rate=DECAY,
                                       end_value=FLOOR * learning_rate)
    optimiser = optax.adam(schedule)
    x = jnp.asarray(x0, jnp.float64)
    state = optimiser.init(x)
    history, last, status = [], None, DesignStatus.MAX_STEPS
    iterates, confirmed = [], 0  # (x, root) of each step; the index of the last one refreshed
    for step in range(max_steps):
        if step and step % REFRESH == 0:
            if not bound.refresh(x):
                status = DesignStatus.NOT_FINITE
                if bound.first == 0.0:  # x buckles at V̂ = 0: back to the last stable iterate
                    status = DesignStatus.UNSTABLE_AT_REST
                    last = _last_stable(iterates + [(x, guess)], confirmed, bound, setting, kind,
                                        n_layers, scheme, mode) or last
                break
            confirmed = len(iterates)
        out = _evaluate(x, guess, setting, kind, n_layers, scheme, bound.candidates, mode)
        if out is None:
            status = DesignStatus.NOT_FINITE
            break
        aux, grad = out
        history.append(float(aux["loss"]))
        last = aux
        guess = aux["omega"]
        iterates.append((x, guess))
        if done(aux, grad) and bound.confirmed(x, aux):
            status = DesignStatus.CONVERGED
            break
        updates, state = optimiser.update(grad, state, x)
        x = optax.apply_updates(x, updates)
    if last is None:
        raise ValueError("the first design step failed (no root at the starting point): check the "
                         "tube and the starting values")
    return last, history, status, x


def _last_stable(iterates, stable, bound, setting, kind, n_layers, scheme, mode):
    """The aux of the last of ``iterates`` ((x, root) pairs) that the full (m, n) grid finds stable
    at V̂ = 0, by bisection between ``iterates[stable]`` (stable) and the last (not), with ``bound``
    refreshed there; None where its solve fails."""
    lo, hi = stable, len(iterates) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if bound.refresh(iterates[mid][0]):
            lo = mid
        else:
            hi = mid
    x, root = iterates[lo]
    if not bound.refresh(x):
        return None
    out = _evaluate(x, root, setting, kind, n_layers, scheme, bound.candidates, mode)
    return None if out is None else out[0]


def _newton(x_h, guess, bound, setting, n_layers, scheme, history, rtol, max_steps, mode):
    """Safeguarded Newton on the scalar constraint g(x_H) = Ω(H, s_op m V̂_first(H))/Ω_t − 1 = 0.

    At s = s_op the design is a root of one equation in one unknown, the thickness variable x_H
    (H/R_i = H_lo + (H_hi − H_lo) σ(x_H)), whose exact derivative dg/dx_H comes with the implicit
    derivatives of Ω and of V̂_first (the forward-mode gradient of the loss L = g² there is
    2 g dg/dx_H). Each step is a Newton step −g/g', at most ``NEWTON_MAX_STEP`` in x_H; once two
    iterates have residuals of opposite sign they bracket the root and a Newton step that leaves the
    bracket is replaced by bisection (convergence guaranteed, quadratic near the root). Ω(H) need
    not be monotone (a layered wall's is not): where two unbracketed iterates have slopes of
    opposite sign, g has an extremum between them, and Newton would cycle over it. The step is then
    a bisection on the sign of g' instead; it brackets the root if g reaches zero there, and gives
    up (out of reach) once the extremum is within ``NEWTON_TURN`` without a zero. The candidate
    modes of the bound are refreshed from the full (m, n) grid after every step longer than
    ``NEWTON_REFRESH`` and confirmed at convergence. (The earlier design finished adam's iterate
    by Newton only once adam had come within 1e-3 of the target; adam's geometrically decaying
    step froze first on a silicone tube in SI: 0.31 % off after 500 steps, issue 43.)

    Returns (aux, status, x) of a converged solve (status CONVERGED), or None where the root is not
    reached: the thickness runs onto a bound or onto an extremum of Ω(H) (target unreachable at
    s_op), a solve fails, or the
    step limit is used.
    """
    s_op = float(setting["s_op"])
    x = jnp.asarray([x_h, _sigmoid_inverse(s_op, 0.0, 1.0)], jnp.float64)
    bracket = {}  # sign of g -> (x_H, g) of the latest iterate on that side
    turn = {}  # sign of dg/dx_H -> x_H of the latest iterate on that side, while unbracketed
    last = None
    for _ in range(max_steps):
        out = _evaluate(x, guess, setting, "frequency", n_layers, scheme, bound.candidates, mode)
        if out is None:
            if last is None:
                return None
            x = x.at[0].set(0.5 * (float(x[0]) + last[0]))  # half the step back
            continue
        aux, grad = out
        history.append(float(aux["loss"]))
        miss, xh = float(aux["miss"]), float(x[0])
        if abs(miss) <= rtol and abs(float(aux["fraction"]) - s_op) <= rtol:
            if bound.confirmed(x, aux):
                return aux, DesignStatus.CONVERGED, x
            continue  # a new first instability: the refreshed candidates, same x
        guess = aux["omega"]
        bracket[miss > 0] = (xh, miss)
        slope = float(grad[0]) / (2.0 * miss)  # dg/dx_H
        step = -miss / slope if slope != 0.0 and math.isfinite(slope) else math.inf
        step = max(-NEWTON_MAX_STEP, min(NEWTON_MAX_STEP, step))
        new = xh + step
        turn[slope > 0] = xh
        if len(bracket) == 2:
            a, b = sorted((bracket[True][0], bracket[False][0]))
            if not a < new < b:
                new = 0.5 * (a + b)
        elif len(turn) == 2:  # g' changed sign on one side of the target: g has an extremum between
            a, b = sorted((turn[True], turn[False]))
            if b - a < NEWTON_TURN:  # the extremum found, and g has no zero there: out of reach
                return None
            new = 0.5 * (a + b)  # bisection towards the extremum: g = 0 there brackets the root
        elif abs(new) > NEWTON_EDGE:  # the thickness runs onto a bound: Ω_t out of reach at s_op
            return None
        last = (xh, miss)
        x = x.at[0].set(new)
        if abs(new - xh) > NEWTON_REFRESH and not bound.refresh(x):
            return None
    return None


def _finish(aux, history, status, bound, material, n_layers, scheme, mode=(0, False)):
    """Verify the tracked root with :func:`jaxdea.frequencies` and build the result."""
    leaves = {k: float(getattr(aux["tube"], k)) for k in ("voltage", "lambda_i", "lambda_z", "eta",
                                                          "gent", "length_ratio")}
    outer = aux["tube"].outer
    if outer is not None:  # the surrounding fluid, as plain floats
        outer = outer.replace(density_ratio=float(outer.density_ratio),
                              speed_ratio=float(outer.speed_ratio))
    layers = aux["tube"].layers
    if layers is not None:  # the layered wall (its thickness scaled by η), as plain floats
        layers = jax.tree_util.tree_map(float, layers)
    tube = Tube(**leaves, material=material, outer=outer, layers=layers)
    alpha = float(aux["alpha"])
    lowest = float(frequencies(tube, alpha, n_roots=1, n_layers=n_layers, scheme=scheme,
                               **_orders(mode))[0])
    tracked = float(aux["omega"])
    if status == DesignStatus.CONVERGED and not abs(lowest - tracked) <= 1e-9 * abs(tracked):
        status = DesignStatus.WRONG_BRANCH
    v_first = float(aux["critical_voltage"])
    slope = float(aux["tunability"])
    if not math.isfinite(slope):
        slope = float(_tunability(tube, alpha, lowest, n_layers=n_layers, scheme=scheme,
                                  delta_p=bound.setting.get("delta_p"), **_orders(mode)))
    return DesignResult(
        tube=tube, alpha=alpha, omega=lowest, critical_voltage=v_first, unstable_mode=bound.mode,
        thickness=1.0 / tube.eta - 1.0, voltage=tube.voltage,
        voltage_fraction=float(aux["fraction"]), tunability=slope, loss=float(aux["loss"]),
        history=history, n_steps=len(history), converged=status == DesignStatus.CONVERGED,
        status=status)


_tunability = jit(tunability, static_argnames=("n_layers", "scheme", "m", "torsional"))


def _check_open(name, value, lo, hi, allowed):
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a real number in {allowed}, got {value!r}") from exc
    if not (math.isfinite(v) and lo < v < hi):
        raise ValueError(f"{name} must be in {allowed}, got {value!r}")
    return v


def _check_bounds(name, bounds, lo, hi, allowed):
    try:
        a, b = (float(x) for x in bounds)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a pair (lower, upper) with {allowed}, got {bounds!r}") from exc
    if not (math.isfinite(a) and math.isfinite(b) and lo < a < b <= hi):
        raise ValueError(f"{name} must be a pair (lower, upper) with {allowed}, got {bounds!r}")
    return a, b


HOLDS = ("length", "length_ratio")


def _pressure(delta_p):
    """``{"delta_p": ΔP̂}`` of a tube held by its pressure difference, validated; {} for one held by
    its stretch."""
    if delta_p is None:
        return {}
    validate_real("delta_p", delta_p, "a finite real number (ΔP̂ = (P_i − P_o)/μ, the pressure "
                  "difference that holds the tube)")
    return dict(delta_p=float(delta_p))


def _branch(tube, setting):
    """``tube`` with λ_i = (λ_0, λ_end), the ends of the static branch held by ΔP̂ (its thickest and
    thinnest walls: the run's discretisation serves both), or as it is when held by its stretch."""
    if "delta_p" not in setting:
        return tube
    return branch_walls(canonical(tube), setting["delta_p"])


def _check_mode(m, torsional):
    """(m, torsional) of the designed mode as (int, bool), validated (ValueError naming m or
    torsional)."""
    family_of(m, torsional)  # m an integer >= 0, torsional a bool and only with m = 0
    return int(m), bool(torsional)


def _check_common(tube, n, margin, learning_rate, max_steps, rtol, n_layers, scheme, m_max, n_max):
    require_x64()
    validate_layers(n_layers)
    validate_scheme(scheme)
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
        raise ValueError(f"n (axial mode number) must be an integer >= 1, got {n!r}")
    _check_open("voltage_margin", margin, 0.0, 1.0, "(0, 1)")
    _check_open("learning_rate", learning_rate, 0.0, math.inf, "(0, inf)")
    if not isinstance(max_steps, (int, np.integer)) or isinstance(max_steps, bool) or max_steps < 1:
        raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")
    _check_open("rtol", rtol, 0.0, 1.0, "(0, 1)")
    for name, value, low in (("m_max", m_max, 0), ("n_max", n_max, 1)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")


def _seed(x0, setting, kind, fraction, n_layers, scheme, m_max, n_max, what, mode=(0, False)):
    """The candidate modes at the start and the lowest root there (the first Newton guess)."""
    bound = _Bound(setting, kind, n_layers, scheme, m_max, n_max)
    if not bound.refresh(x0):
        if bound.first == 0.0:
            raise ValueError(f"the tube is unstable already at V̂ = 0 at the starting {what} "
                             f"((m, n) = {bound.mode} grows): no voltage is admissible")
        raise ValueError(f"the tube has no critical voltage at the starting {what} (no order "
                         f"m <= {m_max} and axial mode n <= {n_max} loses "
                         "stability below pull-in): the constraint V̂ <= voltage_margin * V̂_first "
                         "is undefined there")
    tube, alpha, _ = _point(jnp.asarray(x0, jnp.float64), setting, kind)
    biased = held_at(tube, fraction * float(setting["margin"]) * bound.first, setting.get("delta_p"))
    guess = float(frequencies(biased, alpha, n_roots=1, n_layers=n_layers, scheme=scheme,
                              **_orders(mode))[0])
    if not math.isfinite(guess):
        raise ValueError(f"no frequency found at the starting {what}")
    return guess, bound


# ----------------------------------------------------------------------------- problem 1


def design_for_frequency(tube: Tube, target, n: int = 1, *, operating_fraction=0.5, thickness=None,
                         voltage_fraction=None, thickness_bounds=(0.05, 1.0), voltage_margin=0.8,
                         m_max: int = 8, n_max: int = 3, learning_rate=0.2, max_steps=500,
                         rtol=1e-6, n_layers: int | None = None, scheme: str | None = None,
                         hold: str = "length", m: int = 0, torsional: bool = False,
                         delta_p=None) -> DesignResult:
    """Undeformed thickness H/R_i and voltage V̂ that put the lowest frequency of mode (m, n) at ``target``.

    Fluid-free tube; λ_i (or the pressure difference ΔP̂ that holds the tube, ``delta_p``), λ_z, G
    and the undeformed length are kept (``hold``). Design variables,
    mapped onto their ranges: H/R_i = H_lo + (H_hi − H_lo) σ(x_H) (η = 1/(1 + H/R_i)) and
    V̂ = s · m V̂_first(η) with s = σ(x_s) ∈ (0, 1), so every iterate satisfies V̂ < m V̂_first,
    V̂_first the first instability over the orders m ≤ ``m_max`` and axial modes n ≤ ``n_max``
    (module docstring). The wavenumber of axial mode n is α̂ = 2nπ/(λ_z L/R_i): with
    ``hold="length"`` the undeformed length L/R_i = length_ratio/η of ``tube`` is held (in SI, L is
    the tube's length whatever the wall; L/R_o = (L/R_i) η follows the wall), with
    ``hold="length_ratio"`` L/R_o is held (a thinner wall then shortens the tube, the behaviour
    before 0.x).

    The target alone leaves a one-parameter family of designs (a curve in the (H/R_i, V̂) plane);
    the operating fraction picks the member with s = s_op (default 0.5: the target sits mid-way in
    the admissible voltage range, so the frequency can be tuned both ways from it). The design is
    then the root of the scalar constraint::

        g(H) = Ω(H, V̂ = s_op m V̂_first(H))/Ω_t − 1 = 0,

    solved by safeguarded Newton in x_H with the exact derivative dg/dx_H (implicit derivatives of
    Ω and of V̂_first; bisection once a sign change brackets the root): quadratic convergence, a
    handful of steps. Where Ω_t is out of reach at s_op within the thickness bounds (Newton runs
    onto a bound or onto an extremum of Ω(H)), adam minimises the compromise loss::

        L = (Ω(H, V̂)/Ω_t − 1)² + (s − s_op)²

    from the start (geometrically decaying rate; status MAX_STEPS or a loss that stays > 0).

    Convergence: |Ω/Ω_t − 1| ≤ rtol and |s − s_op| ≤ rtol at the tracked root, with the first
    instability confirmed on the full (m, n) grid. The optimum is then verified with
    :func:`jaxdea.frequencies` (the tracked root must be the lowest of order m; else
    WRONG_BRANCH).

    Args:
        tube: the :class:`~jaxdea.Tube`; its ``voltage`` is ignored and its ``eta`` is the default
            start (with ``hold="length"`` its ``length_ratio`` and ``eta`` give the held L/R_i).
        target: Ω_t > 0.
        n: axial mode number (>= 1).
        operating_fraction: s_op in (0, 1).
        thickness: starting H/R_i inside the bounds (default 1/η − 1 of ``tube``, moved 5 % inside
            the bounds if outside).
        voltage_fraction: starting s in (0, 1) of the adam fallback (default
            ``operating_fraction``; Newton works at s = s_op).
        thickness_bounds: (H_lo, H_hi) with 0 < H_lo < H_hi <= 100.
        voltage_margin: m in (0, 1) of V̂ ≤ m V̂_first.
        m_max: the largest circumferential order of the stability constraint (>= 0; 0: the
            axisymmetric modes only, as in the paper).
        n_max: the largest axial mode number of the stability constraint (>= 1).
        learning_rate: initial adam rate of the fallback (decays by 0.97 a step).
        max_steps: step limit (>= 1), Newton and adam steps together.
        rtol: tolerance of the convergence test, in (0, 1).
        n_layers: sublayers N (static), or None: the accurate discretisation (:func:`jaxdea.frequencies`).
        scheme: the propagation scheme (:func:`jaxdea.frequencies`) of every solve. The default
            discretisation is resolved once for the run (its N for the thickest wall allowed and
            the orders and modes of the bound): ≤ 1e-8; ``scheme="midpoint", n_layers=30`` is the
            paper's laminate (1e-5).
        hold: ``"length"`` (L/R_i held: the tube keeps its length in SI; default) or
            ``"length_ratio"`` (L/R_o held).
        m: circumferential order of the designed mode (int >= 0; ring modes m >= 1).
        torsional: design the torsional mode (m = 0 only).
        delta_p: None (the tube held by its stretch ``tube.lambda_i`` at every voltage) or ΔP̂ =
            (P_i − P_o)/μ, a finite real number: the tube held by that pressure difference, as in a
            lab. λ_i then follows the voltage and the wall (:func:`jaxdea.inner_stretch`), V̂_first is
            the first instability of the held tube (:func:`jaxdea.first_instability` with
            ``delta_p``), and the result's ``tube.lambda_i`` is the λ_i at the design point.
            ``jaxdea.pressure_difference(tube.replace(voltage=0))`` holds the tube's λ_i at V̂ = 0.

    Returns:
        An instance of :class:`DesignResult`.

    Raises:
        ValueError: a bad input, naming the parameter and its allowed range.

    Examples:
        >>> res = design_for_frequency(Tube(lambda_i=1.1, lambda_z=1.2), target=0.72)
        >>> res.thickness, res.voltage, res.omega  # Ω = 0.72 at V̂ = 0.4 V̂_first
        >>> res.unstable_mode  # (2, 1): ring buckling bounds the voltage
        >>> design_for_frequency(Tube(lambda_i=1.1, lambda_z=1.2), 0.4, m=2)  # a ring mode
    """
    _check_common(tube, n, voltage_margin, learning_rate, max_steps, rtol, n_layers, scheme, m_max,
                  n_max)
    mode = _check_mode(m, torsional)
    if hold not in HOLDS:
        raise ValueError(f"hold must be one of {HOLDS}, got {hold!r}")
    target = _check_open("target", target, 0.0, math.inf, "(0, inf)")
    s_op = _check_open("operating_fraction", operating_fraction, 0.0, 1.0, "(0, 1)")
    h_lo, h_hi = _check_bounds("thickness_bounds", thickness_bounds, 0.0, 100.0,
                               "0 < lower < upper <= 100")
    if thickness is None:
        inset = 0.05 * (h_hi - h_lo)
        thickness = min(max(1.0 / float(tube.eta) - 1.0, h_lo + inset), h_hi - inset)
    h0 = _check_open("thickness", thickness, h_lo, h_hi, f"({h_lo}, {h_hi}) (thickness_bounds)")
    s0 = _check_open("voltage_fraction", s_op if voltage_fraction is None else voltage_fraction,
                     0.0, 1.0, "(0, 1)")
    setting = dict(tube=canonical(tube.replace(voltage=0.0)), n=float(n), target=target, s_op=s_op,
                   margin=voltage_margin, h_lo=h_lo, h_hi=h_hi,
                   length=float(tube.length_ratio) / float(tube.eta),
                   hold_length=1.0 if hold == "length" else 0.0, **_pressure(delta_p))
    setting = jax.tree_util.tree_map(as_float, setting)
    x0 = [_sigmoid_inverse(h0, h_lo, h_hi), _sigmoid_inverse(s0, 0.0, 1.0)]
    # one discretisation for the whole run: the default's N for its thickest wall and the orders
    # and modes of the bound (the run solves and differentiates on this one wall model)
    eta = 1.0 / (1.0 + h_hi)
    thickest = _branch(tube.replace(eta=eta, length_ratio=float(setting["length"]) * eta
                                    if hold == "length" else tube.length_ratio), setting)
    layers = laminate(n_layers, scheme, thickest, mode_wavenumber(thickest, max(int(n), int(n_max))),
                      m=max(int(m_max), int(mode[0])), at_rest=True)  # at rest: V̂_cr is searched
    start = [x0[0], _sigmoid_inverse(s_op, 0.0, 1.0)]  # Newton works at s = s_op
    guess, bound = _seed(start, setting, "frequency", s_op, layers, None, int(m_max), int(n_max),
                         "thickness", mode)

    def done(aux, grad):
        del grad
        return abs(float(aux["miss"])) <= rtol and abs(float(aux["fraction"]) - s_op) <= rtol

    history = []
    solved = _newton(x0[0], guess, bound, setting, layers, None, history, rtol,
                     min(NEWTON_STEPS, int(max_steps)), mode)
    if solved is not None:
        aux, status, _ = solved
    else:  # out of reach at s_op (or Newton failed): adam's compromise from the start
        steps_left = int(max_steps) - len(history)
        if steps_left < 1:
            raise ValueError(f"max_steps = {max_steps} were used by Newton without reaching the "
                             "target: raise max_steps (>= 1) for the adam fallback")
        guess, bound = _seed(x0, setting, "frequency", s0, layers, None, int(m_max), int(n_max),
                             "thickness", mode)
        aux, more, status, _ = _run(x0, guess, bound, setting, "frequency", layers, None,
                                    learning_rate, steps_left, done, mode=mode)
        history += more
    return _finish(aux, np.asarray(history), status, bound, tube.material, layers, None, mode)


# ----------------------------------------------------------------------------- problem 2


def maximise_tunability(tube: Tube, n: int = 1, *, lambda_i_bounds=None, voltage_fraction=0.5,
                        lambda_i=None, voltage_margin=0.8, m_max: int = 8, n_max: int = 3,
                        learning_rate=0.3, max_steps=300, rtol=1e-9, n_layers: int | None = None,
                        scheme: str | None = None, m: int = 0, torsional: bool = False,
                        delta_p=None) -> DesignResult:
    """Voltage (and optionally λ_i) that maximise the tunability |dΩ/dV̂| of the lowest frequency of mode (m, n).

    Fixed thickness (η), λ_z, G; fluid-free. Loss −|T| with T = dΩ/dV̂ = −(∂f/∂V̂)/(∂f/∂Ω) at the
    tracked root (:func:`tunability`; its gradient is an exact second derivative). Variables:
    V̂ = s · m V̂_first(λ_i) with s = (1 − cos x_s)/2 ∈ [0, 1] (V̂_first: the first instability over
    m ≤ ``m_max``, n ≤ ``n_max``), and, with ``lambda_i_bounds``,
    λ_i = λ_lo + (λ_hi − λ_lo)(1 − cos x_λ)/2.

    Near the axisymmetric V̂_cr of the mode its frequency falls like sqrt(V̂_cr − V̂), so |T| grows
    towards it: on the tubes we measured |T| increases monotonically with s (and with λ_i), and the
    optimum lies on the constraint V̂ = m V̂_first (and on a λ_i bound). Where another (m, n)
    buckles first (ring buckling on the paper's tube), V̂_first is far below the mode's own V̂_cr
    and the attainable |T| is much smaller than the axisymmetric analysis promises. The cosine maps reach a
    bound at the finite x = π with zero slope, so the active constraint is met to rounding (an x error δ
    moves s by δ²/4), which neither a sigmoid (x → ∞) nor a penalty (a violation ∝ 1/weight) does.

    Convergence: the loss changed by at most rtol · |T| over the last ``PLATEAU`` steps (adam's
    steps shrink with the learning rate, so a stationary gradient test would wait for the rate to
    vanish; at the active bound an error δ in x costs only ~δ² in T). The optimum is then verified
    with :func:`jaxdea.frequencies`.

    Args:
        tube: the :class:`~jaxdea.Tube` (``eta`` fixed; ``lambda_i`` the fixed value, or the start
            with ``lambda_i_bounds``; ``voltage`` ignored).
        n: axial mode number (>= 1).
        lambda_i_bounds: None (λ_i fixed) or (λ_lo, λ_hi) with 0 < λ_lo < λ_hi <= 10.
        voltage_fraction: starting s in (0, 1).
        lambda_i: starting λ_i inside the bounds (default the tube's, moved 5 % inside if outside).
        rtol: tolerance of the plateau test, in (0, 1).
        voltage_margin, m_max, n_max, learning_rate, max_steps, n_layers, scheme, m, torsional:
            as in :func:`design_for_frequency` (m, torsional: the mode whose tunability is
            maximised; ring modes m >= 1 are often far more tunable than the axisymmetric one).
        delta_p: None (λ_i held) or ΔP̂, the pressure difference that holds the tube, as in
            :func:`design_for_frequency` (λ_i follows the voltage; T is then the total dΩ/dV̂ at
            fixed ΔP̂, :func:`tunability`); not with ``lambda_i_bounds``.

    Returns:
        An instance of :class:`DesignResult` (``tunability`` is T at the optimum, negative where Ω falls
        with V̂).

    Raises:
        ValueError: a bad input, naming the parameter and its allowed range.

    Examples:
        >>> res = maximise_tunability(Tube(lambda_i=1.1, lambda_z=1.2))
        >>> res.voltage_fraction, res.unstable_mode  # 1.0 (V̂ = 0.8 V̂_first), (2, 1)
    """
    _check_common(tube, n, voltage_margin, learning_rate, max_steps, rtol, n_layers, scheme, m_max,
                  n_max)
    mode = _check_mode(m, torsional)
    s0 = _check_open("voltage_fraction", voltage_fraction, 0.0, 1.0, "(0, 1)")
    free = lambda_i_bounds is not None
    if free and delta_p is not None:
        raise ValueError("lambda_i_bounds frees λ_i, while delta_p holds the tube by its pressure "
                         "difference (λ_i follows from it): give one of them")
    if free:
        li_lo, li_hi = _check_bounds("lambda_i_bounds", lambda_i_bounds, 0.0, 10.0,
                                     "0 < lower < upper <= 10")
        if lambda_i is None:
            inset = 0.05 * (li_hi - li_lo)
            lambda_i = min(max(float(tube.lambda_i), li_lo + inset), li_hi - inset)
        li0 = _check_open("lambda_i", lambda_i, li_lo, li_hi, f"({li_lo}, {li_hi}) (lambda_i_bounds)")
    elif lambda_i is not None:
        raise ValueError("lambda_i (a starting value) needs lambda_i_bounds; to fix λ_i, set "
                         "tube.lambda_i")
    else:
        li0, li_lo, li_hi = float(tube.lambda_i), 0.0, 1.0  # bounds unused
    setting = dict(tube=canonical(tube.replace(voltage=0.0, lambda_i=li0)), n=float(n),
                   margin=voltage_margin, li_lo=li_lo, li_hi=li_hi, **_pressure(delta_p))
    setting = jax.tree_util.tree_map(as_float, setting)
    kind = "tunability_lambda" if free else "tunability"
    x0 = [_cosine_inverse(s0, 0.0, 1.0)] + ([_cosine_inverse(li0, li_lo, li_hi)] if free else [])
    start = setting["tube"]
    layers = laminate(n_layers, scheme, _branch(start, setting),
                      mode_wavenumber(start, max(int(n), int(n_max))),
                      m=max(int(m_max), mode[0]), at_rest=True)  # one discretisation for the run
    guess, bound = _seed(x0, setting, kind, s0, layers, None, int(m_max), int(n_max), "lambda_i",
                         mode)

    recent = []

    def done(aux, grad):
        del grad
        recent.append(float(aux["loss"]))
        return len(recent) > PLATEAU and abs(recent[-1] - recent[-1 - PLATEAU]) <= rtol * abs(recent[-1])

    aux, history, status, _ = _run(x0, guess, bound, setting, kind, layers, None,
                                   learning_rate, max_steps, done, mode=mode)
    return _finish(aux, np.asarray(history), status, bound, tube.material, layers, None, mode)
