"""Design optimisation with optax: thickness and voltage for a target frequency, and tunability.

Two example problems on the fluid-free tube, both for the lowest frequency Ω of one axial mode n
(α̂ = 2nπη/(L/R_o · λ_z), :func:`jaxdea.axial_wavenumber`, so α̂ follows the thickness through η),
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
  previous iterate's root; a failed solve stops the run (status NOT_FINITE). :func:`jaxdea.frequencies`
  seeds the first guess and verifies the optimum (the tracked root must be the lowest).
* The loss and its gradient come from one small compiled program that attaches implicit-function
  derivatives to those roots, dx/dθ = −(∂g/∂θ)/(∂g/∂x) for g(Ω) = f(Ω; θ) and g(V̂) = f(0; V̂, θ)
  (:func:`jaxdea.scalar.implicit_root`, the mechanism of every solver of the package; never
  derivatives of the iterations), and differentiates in forward
  mode (two or fewer variables). The solvers themselves are the library's compiled programs, shared
  with every other use, so a design run compiles only characteristic-function derivatives.
* The tunability T = dΩ/dV̂ = −(∂f/∂V̂)/(∂f/∂Ω) is evaluated at the root that carries its implicit
  derivatives (:func:`tunability`), so the gradient of T, a second derivative of Ω, is exact
  (nested ``jax.grad`` of :func:`jaxdea.frequency` gives the same second derivatives, tested).
* The learning rate decays geometrically (``optax.exponential_decay``): adam's steps have the size of
  the learning rate whatever the gradient, so a constant rate leaves the iterate oscillating at that
  size; the decay lets it settle to the tolerance.
"""

from __future__ import annotations

import enum
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

from .compiled import cached_jit, jit, serializable
from .dispersion import characteristic, check_inputs
from .modes import ROOT_RTOL, root_distance
from .params import Fluid, Tube, as_float, canonical, mode_wavenumber, require_x64, validate_layers
from .roots import first_instability, frequencies, solve_critical_voltage, solve_frequency
from .scalar import Status, implicit_root, refuse_non_root
from .transfer import laminate, validate_scheme

DECAY = 0.97  # learning-rate factor per step
FLOOR = 1e-9  # the rate never falls below FLOOR x its initial value
NEWTON_START = 1e-3  # frequency design: |Ω/Ω_t − 1| below which a stalled adam is finished by Newton
NEWTON_STEPS = 8
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
               scheme: str | None = None):
    """dΩ/dV̂ on the branch through the root ``omega``: T = −(∂f/∂V̂)/(∂f/∂Ω) (implicit function theorem).

    ``omega`` must be a root (from :func:`jaxdea.frequency` or :func:`jaxdea.frequencies`), to the
    relative Newton distance ``jaxdea.modes.ROOT_RTOL`` = 1e-4 of the same discretisation: a
    concrete non-root raises a ValueError (a traced one gives NaN), since −f_V̂/f_Ω off a root is a
    plausible number that means nothing. When ``omega`` carries its implicit derivatives, as those
    functions' roots do, ``jax.jacfwd``/``jax.grad`` of T with respect to any leaf is the exact
    second derivative d²Ω/dV̂dθ of the discretisation.

    Args:
        tube: the :class:`~jaxdea.Tube` (its ``voltage`` is the operating point).
        alpha: α̂ = α R_i.
        omega: a root Ω at that α̂.
        fluid: a :class:`~jaxdea.Fluid` or None.
        n_layers: sublayers N (static), or None: the accurate discretisation (:func:`jaxdea.frequencies`).
        scheme: the propagation scheme (static; :func:`jaxdea.frequencies`), that of the root.

    Examples:
        >>> t = Tube(voltage=0.1, lambda_i=1.1, lambda_z=1.2)
        >>> a = axial_wavenumber(t, 1)
        >>> tunability(t, a, frequencies(t, a)[0])  # ≈ −1.217
    """
    require_x64()
    order = check_inputs(tube, alpha, fluid, n_layers, scheme)
    tube, alpha, omega = canonical(tube, alpha, omega)
    voltage = as_float(tube.voltage)

    def f(om, v):
        return characteristic(tube.replace(voltage=v), om, alpha, fluid, n_layers, scheme)

    f_omega = jax.jvp(lambda om: f(om, voltage), (omega,), (jnp.ones_like(omega),))[1]
    f_voltage = jax.jvp(lambda v: f(omega, v), (voltage,), (jnp.ones_like(voltage),))[1]
    distance = root_distance(*jax.lax.stop_gradient((tube, alpha, omega, fluid)),
                             laminate(n_layers, scheme, tube, alpha), order)
    refuse_non_root(omega, distance)
    return jnp.where(distance <= ROOT_RTOL, -f_voltage / f_omega, jnp.nan)


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
        tube = tube.replace(eta=1.0 / (1.0 + thickness))
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


def _first_instability(tube, m_max, n_max, n_layers, scheme):
    """(V̂_first, (m, n), the full grid) of ``tube`` (values)."""
    first = first_instability(tube, n_max=n_max, m_max=m_max, n_layers=n_layers, scheme=scheme)
    found = int(first.status) == Status.CONVERGED
    return (float(first.voltage) if found else math.nan, (int(first.m), int(first.n)),
            np.asarray(first.critical))


def _solve_candidates(tube, candidates, n_layers, scheme):
    """V̂_cr of each candidate (values; NaN where it has none below pull-in), shape (K,)."""
    values, seen = [], {}
    for m, n in zip(np.asarray(candidates.m).tolist(), np.asarray(candidates.n).tolist()):
        if (m, n) not in seen:
            alpha = mode_wavenumber(tube, n)
            seen[m, n] = float(solve_critical_voltage(tube, alpha, n_layers=n_layers, scheme=scheme,
                                                      m=int(m))[0])
        values.append(seen[m, n])
    return jnp.asarray(values, jnp.float64)


def _bound(tube, v_roots, candidates, n_layers, scheme):
    """V̂_first = min over the candidates of V̂_cr(m, n), each root with implicit derivatives
    (g(V̂) = f(Ω = 0; V̂) of order m at α̂_n; order m as a traced value: one program for every
    candidate set, the longitudinal zeros at m = 0, docs/theory/order_m.md §3)."""
    def one(v_root, m, n):
        found = jnp.isfinite(v_root)
        alpha = mode_wavenumber(tube, n)
        v = _with_implicit_derivatives(
            lambda v: characteristic(tube.replace(voltage=v), jnp.zeros_like(v), alpha,
                                     n_layers=n_layers, scheme=scheme, m=m),
            jnp.where(found, v_root, 1.0))
        return jnp.where(found, v, jnp.inf)

    return jnp.min(jax.vmap(one)(v_roots, candidates.m, candidates.n))


def _objective(x, omega_root, v_roots, candidates, setting, kind, n_layers, scheme):
    """(loss, aux) at x, given the roots solved there (values); differentiable through them."""
    tube, alpha, fraction = _point(x, setting, kind)
    v_first = _bound(tube, v_roots, candidates, n_layers, scheme)
    biased = tube.replace(voltage=fraction * setting["margin"] * v_first)
    omega = _with_implicit_derivatives(
        lambda om: characteristic(biased, om, alpha, n_layers=n_layers, scheme=scheme), omega_root)
    if kind == "frequency":  # the tunability is left to _finish: a smaller program to compile
        slope = jnp.full_like(omega, jnp.nan)
        miss = omega / setting["target"] - 1.0
        loss = miss**2 + (fraction - setting["s_op"]) ** 2
    else:
        slope = tunability(biased, alpha, omega, n_layers=n_layers, scheme=scheme)
        miss = jnp.zeros_like(omega)
        loss = -jnp.abs(slope)
    aux = dict(loss=loss, omega=omega, alpha=alpha, critical_voltage=v_first, tube=biased,
               tunability=slope, fraction=fraction, miss=miss)
    return loss, aux


@cached_jit(static_argnames=("kind", "n_layers", "scheme"))
def _loss_and_gradient(x, omega_root, v_roots, candidates, setting, kind, n_layers, scheme):
    """(aux, dloss/dx) by forward mode (at most two design variables)."""
    grad, aux = jax.jacfwd(_objective, has_aux=True)(x, omega_root, v_roots, candidates, setting,
                                                     kind, n_layers, scheme)
    return jax.lax.stop_gradient(aux), grad


def _evaluate(x, guess, setting, kind, n_layers, scheme, candidates):
    """Solve the roots at x (values) and return (aux, gradient), or None where a solve failed."""
    tube, alpha, fraction = _point(x, setting, kind)
    v_roots = _solve_candidates(tube, candidates, n_layers, scheme)
    if not bool(jnp.any(jnp.isfinite(v_roots))):
        return None
    biased = tube.replace(voltage=fraction * setting["margin"] * jnp.nanmin(v_roots))
    omega, status = solve_frequency(biased, alpha, guess, n_layers=n_layers, scheme=scheme)
    if int(status) != Status.CONVERGED:
        return None
    aux, grad = _loss_and_gradient(x, omega, v_roots, candidates, setting, kind, n_layers, scheme)
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
                                                         self.n_layers, self.scheme)
        self.candidates = _candidates(grid)
        return self.candidates is not None and self.first > 0.0

    def confirmed(self, x, aux):
        """True if the full grid at x finds the bound of ``aux`` (to 1e-9); else refreshes."""
        tracked = float(aux["critical_voltage"])
        if not self.refresh(x):
            return False
        return abs(self.first - tracked) <= 1e-9 * abs(tracked)


def _run(x0, guess, bound, setting, kind, n_layers, scheme, learning_rate, max_steps, done,
         handoff=None):
    """adam with a geometrically decaying rate, each step from the previous root; converged only
    when the full (m, n) grid confirms the bound (:class:`_Bound`). Stops with status None where
    ``handoff(aux)`` holds (a local solver takes over)."""
    schedule = optax.exponential_decay(learning_rate, transition_steps=1, decay_rate=DECAY,
                                       end_value=FLOOR * learning_rate)
    optimiser = optax.adam(schedule)
    x = jnp.asarray(x0, jnp.float64)
    state = optimiser.init(x)
    history, last, status = [], None, DesignStatus.MAX_STEPS
    for step in range(max_steps):
        if step and step % REFRESH == 0 and not bound.refresh(x):
            status = DesignStatus.NOT_FINITE
            break
        out = _evaluate(x, guess, setting, kind, n_layers, scheme, bound.candidates)
        if out is None:
            status = DesignStatus.NOT_FINITE
            break
        aux, grad = out
        history.append(float(aux["loss"]))
        last = aux
        guess = aux["omega"]
        if done(aux, grad) and bound.confirmed(x, aux):
            status = DesignStatus.CONVERGED
            break
        if handoff is not None and handoff(aux):
            status = None
            break
        updates, state = optimiser.update(grad, state, x)
        x = optax.apply_updates(x, updates)
    if last is None:
        raise ValueError("the first design step failed (no root at the starting point): check the "
                         "tube and the starting values")
    return last, history, status, x


def _newton_finish(x, guess, bound, setting, n_layers, scheme, history, done):
    """Newton on the thickness variable at s = s_op exactly, from adam's iterate.

    adam's decaying rate freezes the iterate short of a tight tolerance (measured: a miss of
    1.3e-6 against rtol 1e-6 after 500 steps), and its last few hundred steps buy little. At
    s = s_op the loss is miss², its gradient 2·miss·∂miss/∂x_H, so the Newton step for miss = 0
    (Gauss–Newton on the residuals (miss, s − s_op), the second one zero) is −2 miss²/∂L/∂x_H,
    with the exact (implicit) gradient of the adam steps: quadratic convergence, no new program to
    compile.

    Returns (aux, status) of a converged finish, or None (then adam's result stands).
    """
    x = jnp.asarray([x[0], _sigmoid_inverse(float(setting["s_op"]), 0.0, 1.0)], jnp.float64)
    if not bound.refresh(x):
        return None
    for _ in range(NEWTON_STEPS):
        out = _evaluate(x, guess, setting, "frequency", n_layers, scheme, bound.candidates)
        if out is None:
            return None
        aux, grad = out
        history.append(float(aux["loss"]))
        if done(aux, grad) and bound.confirmed(x, aux):
            return aux, DesignStatus.CONVERGED
        guess = aux["omega"]
        slope = float(grad[0])
        if slope == 0.0:
            return None
        x = x.at[0].add(-2.0 * float(aux["miss"]) ** 2 / slope)
    return None


def _finish(aux, history, status, bound, material, n_layers, scheme):
    """Verify the tracked root with :func:`jaxdea.frequencies` and build the result."""
    leaves = {k: float(getattr(aux["tube"], k)) for k in ("voltage", "lambda_i", "lambda_z", "eta",
                                                          "gent", "length_ratio")}
    tube = Tube(**leaves, material=material)
    alpha = float(aux["alpha"])
    lowest = float(frequencies(tube, alpha, n_roots=1, n_layers=n_layers, scheme=scheme)[0])
    tracked = float(aux["omega"])
    if status == DesignStatus.CONVERGED and not abs(lowest - tracked) <= 1e-9 * abs(tracked):
        status = DesignStatus.WRONG_BRANCH
    v_first = float(aux["critical_voltage"])
    slope = float(aux["tunability"])
    if not math.isfinite(slope):
        slope = float(jit(tunability, static_argnames=("n_layers", "scheme"))(
            tube, alpha, lowest, n_layers=n_layers, scheme=scheme))
    return DesignResult(
        tube=tube, alpha=alpha, omega=lowest, critical_voltage=v_first, unstable_mode=bound.mode,
        thickness=1.0 / tube.eta - 1.0, voltage=tube.voltage,
        voltage_fraction=float(aux["fraction"]), tunability=slope, loss=float(aux["loss"]),
        history=history, n_steps=len(history), converged=status == DesignStatus.CONVERGED,
        status=status)


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


def _seed(x0, setting, kind, fraction, n_layers, scheme, m_max, n_max, what):
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
    biased = tube.replace(voltage=fraction * float(setting["margin"]) * bound.first)
    guess = float(frequencies(biased, alpha, n_roots=1, n_layers=n_layers, scheme=scheme)[0])
    if not math.isfinite(guess):
        raise ValueError(f"no frequency found at the starting {what}")
    return guess, bound


# ----------------------------------------------------------------------------- problem 1


def design_for_frequency(tube: Tube, target, n: int = 1, *, operating_fraction=0.5, thickness=None,
                         voltage_fraction=None, thickness_bounds=(0.05, 1.0), voltage_margin=0.8,
                         m_max: int = 8, n_max: int = 3, learning_rate=0.2, max_steps=500,
                         rtol=1e-6, n_layers: int | None = None, scheme: str | None = None) -> DesignResult:
    """Undeformed thickness H/R_i and voltage V̂ that put the lowest frequency of mode n at ``target``.

    Fluid-free tube; λ_i, λ_z, G, L/R_o are kept. Design variables, mapped onto their ranges:
    H/R_i = H_lo + (H_hi − H_lo) σ(x_H) (η = 1/(1 + H/R_i), α̂ = 2nπη/(L/R_o · λ_z)) and
    V̂ = s · m V̂_first(η) with s = σ(x_s) ∈ (0, 1), so every iterate satisfies V̂ < m V̂_first,
    V̂_first the first instability over the orders m ≤ ``m_max`` and axial modes n ≤ ``n_max``
    (module docstring). Loss (adam)::

        L = (Ω(H, V̂)/Ω_t − 1)² + (s − s_op)².

    The target alone leaves a one-parameter family of designs (a curve in the (H/R_i, V̂) plane). The
    second term picks the member that reaches Ω_t at the operating fraction s_op of the admissible
    voltage (default 0.5: the target sits mid-way in the voltage range, so the frequency can be tuned
    both ways from it). Where Ω_t is reachable at s_op within the thickness bounds both terms vanish
    at the optimum: the target is met exactly (no penalty bias), and the optimum is unique when Ω
    is monotone in H along s = s_op (as on the paper's tube, where thicker walls are stiffer).
    Otherwise the loss finds the best compromise (status MAX_STEPS or a loss that stays > 0).

    Convergence: |Ω/Ω_t − 1| ≤ rtol and |s − s_op| ≤ rtol at the tracked root. Once adam has
    brought both below 1e-3 (or used ``max_steps`` with |Ω/Ω_t − 1| ≤ 1e-3), up to 8 Newton steps
    on H/R_i at s = s_op finish the solve (they count in ``n_steps``; if they fail, adam goes on
    with the steps left). The optimum is then
    verified with :func:`jaxdea.frequencies` (the tracked root must be the lowest; else
    WRONG_BRANCH).

    Args:
        tube: the :class:`~jaxdea.Tube`; its ``voltage`` is ignored and its ``eta`` is the default
            start.
        target: Ω_t > 0.
        n: axial mode number (>= 1).
        operating_fraction: s_op in (0, 1).
        thickness: starting H/R_i inside the bounds (default 1/η − 1 of ``tube``, moved 5 % inside
            the bounds if outside).
        voltage_fraction: starting s in (0, 1) (default ``operating_fraction``).
        thickness_bounds: (H_lo, H_hi) with 0 < H_lo < H_hi <= 100.
        voltage_margin: m in (0, 1) of V̂ ≤ m V̂_first.
        m_max: the largest circumferential order of the stability constraint (>= 0; 0: the
            axisymmetric modes only, as in the paper).
        n_max: the largest axial mode number of the stability constraint (>= 1).
        learning_rate: initial adam rate (decays by 0.97 a step).
        max_steps: step limit (>= 1).
        rtol: tolerance of the convergence test, in (0, 1).
        n_layers: sublayers N (static), or None: the accurate discretisation (:func:`jaxdea.frequencies`).
        scheme: the propagation scheme (:func:`jaxdea.frequencies`) of every solve. The default
            discretisation is resolved once for the run (its N for the thickest wall allowed and
            the orders and modes of the bound): ≤ 1e-8; ``scheme="midpoint", n_layers=30`` is the
            paper's laminate (1e-5).

    Returns:
        An instance of :class:`DesignResult`.

    Raises:
        ValueError: a bad input, naming the parameter and its allowed range.

    Examples:
        >>> res = design_for_frequency(Tube(lambda_i=1.1, lambda_z=1.2), target=0.72)
        >>> res.thickness, res.voltage, res.omega  # Ω = 0.72 at V̂ = 0.4 V̂_first
        >>> res.unstable_mode  # (2, 1): ring buckling bounds the voltage
    """
    _check_common(tube, n, voltage_margin, learning_rate, max_steps, rtol, n_layers, scheme, m_max,
                  n_max)
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
                   margin=voltage_margin, h_lo=h_lo, h_hi=h_hi)
    setting = jax.tree_util.tree_map(as_float, setting)
    x0 = [_sigmoid_inverse(h0, h_lo, h_hi), _sigmoid_inverse(s0, 0.0, 1.0)]
    # one discretisation for the whole run: the default's N for its thickest wall and the orders
    # and modes of the bound (the run solves and differentiates on this one wall model)
    thickest = tube.replace(eta=1.0 / (1.0 + h_hi))
    layers = laminate(n_layers, scheme, thickest, mode_wavenumber(thickest, max(int(n), int(n_max))),
                      m=int(m_max), at_rest=True)  # at rest: the bound is a critical voltage
    guess, bound = _seed(x0, setting, "frequency", s0, layers, None, int(m_max), int(n_max),
                         "thickness")

    def done(aux, grad):
        del grad
        return abs(float(aux["miss"])) <= rtol and abs(float(aux["fraction"]) - s_op) <= rtol

    def near(aux):  # adam has brought the iterate into Newton's basin
        return abs(float(aux["miss"])) <= NEWTON_START and \
            abs(float(aux["fraction"]) - s_op) <= NEWTON_START

    steps_left, x, handoff = int(max_steps), x0, near
    history = []
    while True:
        aux, more, status, x = _run(x, guess, bound, setting, "frequency", layers, None,
                                    learning_rate, steps_left, done, handoff=handoff)
        history += more
        steps_left -= len(more)
        if status is None or (status == DesignStatus.MAX_STEPS
                              and abs(float(aux["miss"])) <= NEWTON_START):
            finished = _newton_finish(x, aux["omega"], bound, setting, layers, None,
                                      history, done)
            if finished is not None:
                aux, status = finished
                break
            if status is None and steps_left > 0:  # Newton failed: adam goes on, to the end
                guess, handoff = aux["omega"], None
                continue
            status = DesignStatus.MAX_STEPS if status is None else status
        break
    return _finish(aux, np.asarray(history), status, bound, tube.material, layers, None)


# ----------------------------------------------------------------------------- problem 2


def maximise_tunability(tube: Tube, n: int = 1, *, lambda_i_bounds=None, voltage_fraction=0.5,
                        lambda_i=None, voltage_margin=0.8, m_max: int = 8, n_max: int = 3,
                        learning_rate=0.3, max_steps=300, rtol=1e-9, n_layers: int | None = None,
                        scheme: str | None = None) -> DesignResult:
    """Voltage (and optionally λ_i) that maximise the tunability |dΩ/dV̂| of the lowest frequency.

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
        voltage_margin, m_max, n_max, learning_rate, max_steps, n_layers, scheme: as in
            :func:`design_for_frequency`.

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
    s0 = _check_open("voltage_fraction", voltage_fraction, 0.0, 1.0, "(0, 1)")
    free = lambda_i_bounds is not None
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
                   margin=voltage_margin, li_lo=li_lo, li_hi=li_hi)
    setting = jax.tree_util.tree_map(as_float, setting)
    kind = "tunability_lambda" if free else "tunability"
    x0 = [_cosine_inverse(s0, 0.0, 1.0)] + ([_cosine_inverse(li0, li_lo, li_hi)] if free else [])
    start = setting["tube"]
    layers = laminate(n_layers, scheme, start, mode_wavenumber(start, max(int(n), int(n_max))),
                      m=int(m_max), at_rest=True)  # one discretisation for the whole run, the bound's
    guess, bound = _seed(x0, setting, kind, s0, layers, None, int(m_max), int(n_max), "lambda_i")

    recent = []

    def done(aux, grad):
        del grad
        recent.append(float(aux["loss"]))
        return len(recent) > PLATEAU and abs(recent[-1] - recent[-1 - PLATEAU]) <= rtol * abs(recent[-1])

    aux, history, status, _ = _run(x0, guess, bound, setting, kind, layers, None,
                                   learning_rate, max_steps, done)
    return _finish(aux, np.asarray(history), status, bound, tube.material, layers, None)
