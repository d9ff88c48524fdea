"""Design optimisation with optax: thickness and voltage for a target frequency, and tunability.

Two example problems on the fluid-free tube, both for the lowest frequency Ω of one axial mode n
(α̂ = 2nπη/(L/R_o · λ_z), :func:`jaxdea.axial_wavenumber`, so α̂ follows the thickness through η),
both under the safety constraint V̂ ≤ m V̂_cr (m = ``voltage_margin`` = 0.8; V̂_cr from
:func:`jaxdea.critical_voltage`, the smallest voltage at which Ω of the mode reaches zero):

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
* Each step solves for values only: V̂_cr by :func:`jaxdea.solve_critical_voltage` and Ω by
  :func:`jaxdea.solve_frequency` (the safeguarded Newton of :func:`jaxdea.frequency`) started at the
  previous iterate's root; a failed solve stops the run (status NOT_FINITE). :func:`jaxdea.frequencies`
  seeds the first guess and verifies the optimum (the tracked root must be the lowest).
* The loss and its gradient come from one small compiled program that attaches implicit-function
  derivatives to those roots, dx/dθ = −(∂g/∂θ)/(∂g/∂x) for g(Ω) = f(Ω; θ) and g(V̂) = f(0; V̂, θ)
  (``jax.lax.custom_root``; never derivatives of the iterations), and differentiates in forward
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
from .dispersion import characteristic
from .params import Fluid, Tube, as_float, canonical, mode_wavenumber, require_x64, validate_layers
from .roots import frequencies, solve_critical_voltage, solve_frequency
from .scalar import Status, implicit_root
from .transfer import validate_scheme

DECAY = 0.97  # learning-rate factor per step
FLOOR = 1e-9  # the rate never falls below FLOOR x its initial value
NEWTON_START = 1e-3  # frequency design: |Ω/Ω_t − 1| below which a stalled adam is finished by Newton
NEWTON_STEPS = 8
PLATEAU = 10  # steps over which maximise_tunability's loss must have settled


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
        critical_voltage: V̂_cr of the optimised tube and mode.
        thickness: undeformed H/R_i = 1/η − 1.
        voltage: V̂.
        voltage_fraction: s = V̂ / (m V̂_cr), in [0, 1].
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


def tunability(tube: Tube, alpha, omega, fluid: Fluid | None = None, n_layers: int = 30,
               scheme: str = "midpoint"):
    """dΩ/dV̂ on the branch through the root ``omega``: T = −(∂f/∂V̂)/(∂f/∂Ω) (implicit function theorem).

    ``omega`` should be a root (from :func:`jaxdea.frequency` or :func:`jaxdea.frequencies`). When it
    carries its implicit derivatives, as those functions' roots do, ``jax.jacfwd``/``jax.grad`` of T
    with respect to any leaf is the exact second derivative d²Ω/dV̂dθ of the discretisation.

    Args:
        tube: the :class:`~jaxdea.Tube` (its ``voltage`` is the operating point).
        alpha: α̂ = α R_i.
        omega: a root Ω at that α̂.
        fluid: a :class:`~jaxdea.Fluid` or None.
        n_layers: sublayers N (static).
        scheme: the propagation scheme (static; :func:`jaxdea.frequencies`), that of the root.

    Example:
        >>> t = Tube(voltage=0.1, lambda_i=1.1, lambda_z=1.2)
        >>> a = axial_wavenumber(t, 1)
        >>> tunability(t, a, frequencies(t, a)[0])  # ≈ −1.217
    """
    require_x64()
    tube, alpha, omega = canonical(tube, alpha, omega)
    voltage = as_float(tube.voltage)

    def f(om, v):
        return characteristic(tube.replace(voltage=v), om, alpha, fluid, n_layers, scheme)

    f_omega = jax.jvp(lambda om: f(om, voltage), (omega,), (jnp.ones_like(omega),))[1]
    f_voltage = jax.jvp(lambda v: f(omega, v), (voltage,), (jnp.ones_like(voltage),))[1]
    return -f_voltage / f_omega


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


def _objective(x, omega_root, v_cr_root, setting, kind, n_layers, scheme):
    """(loss, aux) at x, given the roots solved there (values); differentiable through them."""
    tube, alpha, fraction = _point(x, setting, kind)
    v_cr = _with_implicit_derivatives(
        lambda v: characteristic(tube.replace(voltage=v), jnp.zeros_like(v), alpha, n_layers=n_layers,
                                 scheme=scheme),
        v_cr_root)
    biased = tube.replace(voltage=fraction * setting["margin"] * v_cr)
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
    aux = dict(loss=loss, omega=omega, alpha=alpha, critical_voltage=v_cr, tube=biased,
               tunability=slope, fraction=fraction, miss=miss)
    return loss, aux


@cached_jit(static_argnames=("kind", "n_layers", "scheme"))
def _loss_and_gradient(x, omega_root, v_cr_root, setting, kind, n_layers, scheme):
    """(aux, dloss/dx) by forward mode (at most two design variables)."""
    grad, aux = jax.jacfwd(_objective, has_aux=True)(x, omega_root, v_cr_root, setting, kind, n_layers,
                                                     scheme)
    return jax.lax.stop_gradient(aux), grad


def _evaluate(x, guess, setting, kind, n_layers, scheme):
    """Solve the roots at x (values) and return (aux, gradient), or None where a solve failed."""
    tube, alpha, fraction = _point(x, setting, kind)
    v_cr, status = solve_critical_voltage(tube, alpha, n_layers=n_layers, scheme=scheme)
    if int(status) != Status.CONVERGED:
        return None
    biased = tube.replace(voltage=fraction * setting["margin"] * v_cr)
    omega, status = solve_frequency(biased, alpha, guess, n_layers=n_layers, scheme=scheme)
    if int(status) != Status.CONVERGED:
        return None
    aux, grad = _loss_and_gradient(x, omega, v_cr, setting, kind, n_layers, scheme)
    if not (math.isfinite(float(aux["loss"])) and bool(jnp.all(jnp.isfinite(grad)))):
        return None
    return aux, grad


def _run(x0, guess, setting, kind, n_layers, scheme, learning_rate, max_steps, done):
    """adam with a geometrically decaying rate, each step from the previous root."""
    schedule = optax.exponential_decay(learning_rate, transition_steps=1, decay_rate=DECAY,
                                       end_value=FLOOR * learning_rate)
    optimiser = optax.adam(schedule)
    x = jnp.asarray(x0, jnp.float64)
    state = optimiser.init(x)
    history, last, status = [], None, DesignStatus.MAX_STEPS
    for _ in range(max_steps):
        out = _evaluate(x, guess, setting, kind, n_layers, scheme)
        if out is None:
            status = DesignStatus.NOT_FINITE
            break
        aux, grad = out
        history.append(float(aux["loss"]))
        last = aux
        guess = aux["omega"]
        if done(aux, grad):
            status = DesignStatus.CONVERGED
            break
        updates, state = optimiser.update(grad, state, x)
        x = optax.apply_updates(x, updates)
    if last is None:
        raise ValueError("the first design step failed (no root at the starting point): check the "
                         "tube and the starting values")
    return last, history, status, x


def _newton_finish(x, guess, setting, n_layers, scheme, history, done):
    """Newton on the thickness variable at s = s_op exactly, from adam's last iterate.

    adam's decaying rate can freeze the iterate just short of the tolerance (measured: a miss of
    1.3e-6 against rtol 1e-6 after 500 steps). At s = s_op the loss is miss², its gradient
    2·miss·∂miss/∂x_H, so the Newton step for miss = 0 is −2 miss²/∂L/∂x_H, with the exact
    (implicit) gradient of the adam steps: quadratic convergence, no new program to compile.

    Returns (aux, status) of a converged finish, or None (then adam's result stands).
    """
    x = jnp.asarray([x[0], _sigmoid_inverse(float(setting["s_op"]), 0.0, 1.0)], jnp.float64)
    for _ in range(NEWTON_STEPS):
        out = _evaluate(x, guess, setting, "frequency", n_layers, scheme)
        if out is None:
            return None
        aux, grad = out
        history.append(float(aux["loss"]))
        if done(aux, grad):
            return aux, DesignStatus.CONVERGED
        guess = aux["omega"]
        slope = float(grad[0])
        if slope == 0.0:
            return None
        x = x.at[0].add(-2.0 * float(aux["miss"]) ** 2 / slope)
    return None


def _finish(aux, history, status, margin, material, n_layers, scheme):
    """Verify the tracked root with :func:`jaxdea.frequencies` and build the result."""
    leaves = {k: float(getattr(aux["tube"], k)) for k in ("voltage", "lambda_i", "lambda_z", "eta",
                                                          "gent", "length_ratio")}
    tube = Tube(**leaves, material=material)
    alpha = float(aux["alpha"])
    lowest = float(frequencies(tube, alpha, n_roots=1, n_layers=n_layers, scheme=scheme)[0])
    tracked = float(aux["omega"])
    if status == DesignStatus.CONVERGED and not abs(lowest - tracked) <= 1e-9 * abs(tracked):
        status = DesignStatus.WRONG_BRANCH
    v_cr = float(aux["critical_voltage"])
    slope = float(aux["tunability"])
    if not math.isfinite(slope):
        slope = float(jit(tunability, static_argnames=("n_layers", "scheme"))(
            tube, alpha, lowest, n_layers=n_layers, scheme=scheme))
    return DesignResult(
        tube=tube, alpha=alpha, omega=lowest, critical_voltage=v_cr, thickness=1.0 / tube.eta - 1.0,
        voltage=tube.voltage, voltage_fraction=float(aux["fraction"]),
        tunability=slope, loss=float(aux["loss"]), history=history,
        n_steps=len(history), converged=status == DesignStatus.CONVERGED, status=status)


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


def _check_common(tube, n, margin, learning_rate, max_steps, rtol, n_layers, scheme):
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


def _seed(tube, alpha, fraction, margin, n_layers, scheme, what):
    """V̂_cr at the start and the lowest root there (the first Newton guess)."""
    v_cr = float(solve_critical_voltage(tube, alpha, n_layers=n_layers, scheme=scheme)[0])
    if not math.isfinite(v_cr):
        raise ValueError(f"the tube has no critical voltage at the starting {what} (no zero "
                         "frequency below pull-in): the constraint V̂ <= voltage_margin * V̂_cr is "
                         "undefined there")
    biased = tube.replace(voltage=fraction * margin * v_cr)
    guess = float(frequencies(biased, alpha, n_roots=1, n_layers=n_layers, scheme=scheme)[0])
    if not math.isfinite(guess):
        raise ValueError(f"no frequency found at the starting {what}")
    return guess


# ----------------------------------------------------------------------------- problem 1


def design_for_frequency(tube: Tube, target, n: int = 1, *, operating_fraction=0.5, thickness=None,
                         voltage_fraction=None, thickness_bounds=(0.05, 1.0), voltage_margin=0.8,
                         learning_rate=0.2, max_steps=500, rtol=1e-6,
                         n_layers: int = 30, scheme: str = "midpoint") -> DesignResult:
    """Undeformed thickness H/R_i and voltage V̂ that put the lowest frequency of mode n at ``target``.

    Fluid-free tube; λ_i, λ_z, G, L/R_o are kept. Design variables, mapped onto their ranges:
    H/R_i = H_lo + (H_hi − H_lo) σ(x_H) (η = 1/(1 + H/R_i), α̂ = 2nπη/(L/R_o · λ_z)) and
    V̂ = s · m V̂_cr(η) with s = σ(x_s) ∈ (0, 1), so every iterate satisfies V̂ < m V̂_cr. Loss (adam)::

        L = (Ω(H, V̂)/Ω_t − 1)² + (s − s_op)².

    The target alone leaves a one-parameter family of designs (a curve in the (H/R_i, V̂) plane). The
    second term picks the member that reaches Ω_t at the operating fraction s_op of the admissible
    voltage (default 0.5: the target sits mid-way in the voltage range, so the frequency can be tuned
    both ways from it). Where Ω_t is reachable at s_op within the thickness bounds both terms vanish
    at the optimum: the target is met exactly (no penalty bias), and the optimum is unique when Ω
    is monotone in H along s = s_op (as on the paper's tube, where thicker walls are stiffer).
    Otherwise the loss finds the best compromise (status MAX_STEPS or a loss that stays > 0).

    Convergence: |Ω/Ω_t − 1| ≤ rtol and |s − s_op| ≤ rtol at the tracked root. If adam's decayed
    rate stalls short of that within ``max_steps`` but |Ω/Ω_t − 1| ≤ 1e-3, up to 8 Newton steps on
    H/R_i at s = s_op finish the solve (the steps count in ``n_steps``). The optimum is then
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
        voltage_margin: m in (0, 1) of V̂ ≤ m V̂_cr.
        learning_rate: initial adam rate (decays by 0.97 a step).
        max_steps: step limit (>= 1).
        rtol: tolerance of the convergence test, in (0, 1).
        n_layers: sublayers N (static).
        scheme: the propagation scheme (:func:`jaxdea.frequencies`) of every solve; ``"magnus6"``
            with ``n_layers=6`` resolves the wall to about 1e-9 (the default N = 30: 1e-5).

    Returns:
        :class:`DesignResult`.

    Raises:
        ValueError: a bad input, naming the parameter and its allowed range.

    Example:
        >>> res = design_for_frequency(Tube(lambda_i=1.1, lambda_z=1.2), target=0.72)
        >>> res.thickness, res.voltage, res.omega  # Ω = 0.72 at V̂ = 0.4 V̂_cr
    """
    _check_common(tube, n, voltage_margin, learning_rate, max_steps, rtol, n_layers, scheme)
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
    start, alpha, _ = _point(jnp.asarray(x0), setting, "frequency")
    guess = _seed(start, alpha, s0, voltage_margin, n_layers, scheme, "thickness")

    def done(aux, grad):
        del grad
        return abs(float(aux["miss"])) <= rtol and abs(float(aux["fraction"]) - s_op) <= rtol

    aux, history, status, x = _run(x0, guess, setting, "frequency", int(n_layers), scheme,
                                   learning_rate, max_steps, done)
    if status == DesignStatus.MAX_STEPS and abs(float(aux["miss"])) <= NEWTON_START:
        finished = _newton_finish(x, aux["omega"], setting, int(n_layers), scheme, history, done)
        if finished is not None:
            aux, status = finished
    return _finish(aux, np.asarray(history), status, voltage_margin, tube.material, int(n_layers),
                   scheme)


# ----------------------------------------------------------------------------- problem 2


def maximise_tunability(tube: Tube, n: int = 1, *, lambda_i_bounds=None, voltage_fraction=0.5,
                        lambda_i=None, voltage_margin=0.8, learning_rate=0.3, max_steps=300,
                        rtol=1e-9, n_layers: int = 30, scheme: str = "midpoint") -> DesignResult:
    """Voltage (and optionally λ_i) that maximise the tunability |dΩ/dV̂| of the lowest frequency.

    Fixed thickness (η), λ_z, G; fluid-free. Loss −|T| with T = dΩ/dV̂ = −(∂f/∂V̂)/(∂f/∂Ω) at the
    tracked root (:func:`tunability`; its gradient is an exact second derivative). Variables:
    V̂ = s · m V̂_cr(λ_i) with s = (1 − cos x_s)/2 ∈ [0, 1], and, with ``lambda_i_bounds``,
    λ_i = λ_lo + (λ_hi − λ_lo)(1 − cos x_λ)/2.

    Near V̂_cr the lowest frequency falls like sqrt(V̂_cr − V̂), so |T| grows without bound towards
    V̂_cr: on the tubes we measured |T| increases monotonically with s (and with λ_i), and the
    optimum lies on the constraint V̂ = m V̂_cr (and on a λ_i bound). The cosine maps reach a bound at
    the finite x = π with zero slope, so the active constraint is met to rounding (an x error δ
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
        voltage_margin, learning_rate, max_steps, n_layers, scheme: as in
            :func:`design_for_frequency`.

    Returns:
        :class:`DesignResult` (``tunability`` is T at the optimum, negative where Ω falls with V̂).

    Raises:
        ValueError: a bad input, naming the parameter and its allowed range.

    Example:
        >>> res = maximise_tunability(Tube(lambda_i=1.1, lambda_z=1.2))
        >>> res.voltage_fraction, res.tunability  # 1.0 (V̂ = 0.8 V̂_cr), T ≈ −5.30
    """
    _check_common(tube, n, voltage_margin, learning_rate, max_steps, rtol, n_layers, scheme)
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
    start, alpha, _ = _point(jnp.asarray(x0), setting, kind)
    guess = _seed(start, alpha, s0, voltage_margin, n_layers, scheme, "lambda_i")

    recent = []

    def done(aux, grad):
        del grad
        recent.append(float(aux["loss"]))
        return len(recent) > PLATEAU and abs(recent[-1] - recent[-1 - PLATEAU]) <= rtol * abs(recent[-1])

    aux, history, status, _ = _run(x0, guess, setting, kind, int(n_layers), scheme, learning_rate,
                                   max_steps, done)
    return _finish(aux, np.asarray(history), status, voltage_margin, tube.material, int(n_layers),
                   scheme)
