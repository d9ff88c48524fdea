"""Energy velocity: the time-averaged axial power flux of a mode over its time-averaged energy
(docs/theory/real_tubes.md §9, Eqs. 9.1–9.12).

For a root (α̂, Ω) (real α̂ and Ω of :func:`jaxdea.frequencies`, or a complex α̂ at a real Ω of
:func:`jaxdea.wavenumbers` for a damped tube) the travelling wave ∝ e^{i(Ωt − α̂z)} is solved across
the wall on the tube's laminate:

1. the initial basis, sublayer exponentials and outer rows at (α̂, Ω) (the complex-α̂ pieces of
   :func:`jaxdea.physics.characteristic.pieces`, which add η*(Ω) of a damped wall) are carried
   across the wall by Householder QR, T_k Q_{k−1} = Q_k R_k; the null vector of the outer rows is
   carried back (c_{k−1} = R_k⁻¹c_k), giving the state Y_k at every sublayer interface;
2. the state at the Gauss–Legendre nodes of each (physical) layer follows from the nearest interface
   by one fourth-order Magnus step of the exact state matrix M(r̂) (its coefficients at the step's two
   Gauss nodes), and Y' = M Y there;
3. the flux and energy densities (Eqs. 9.4–9.6, 9.10) are integrated over the wall with those weights, the
   inner face adds the follower-pressure terms (Eq. 9.7), a filling its acoustic flux and energy
   (Eq. 9.8, Gauss–Legendre on [0, r̂_i]) and a surrounding fluid its own (Eq. 9.9, closed form).
"""

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import cached_jit
from ..numerics.bessel import coupling_log_factor, coupling_pair, scaled_k
from ..numerics.scalar import ROOT_RTOL
from ..params import (
    Fluid,
    Tube,
    as_float,
    canonical,
    traced,
    validate_count,
    validate_positive,
    with_outer,
)
from ..physics import characteristic
from ..physics.base_state import interface_radii, stretch
from ..physics.characteristic import Unknown
from ..physics.families import Face, Family
from ..physics.problem import NO_ALPHA, describe
from ..physics.state_matrix import family_matrix
from ..physics.transfer import (
    damped_wall,
    damping_pattern,
    discretize,
    expm_taylor,
    general_form,
    laminate,
    layer_coefficients,
)
from .modes import _midpoints

MAGNUS_NODES = (0.5 - np.sqrt(3.0) / 6.0, 0.5 + np.sqrt(3.0) / 6.0)
"""Gauss nodes of the fourth-order Magnus step from an interface to a quadrature node."""


def _complex(x):
    return jnp.asarray(x, dtype=jnp.complex128)


def _interface_states(basis, exponentials, out):
    """States Y_k (N+1, n) at the sublayer interfaces and the basis coefficients x (Y_0 = S x) of
    the null vector of ``out`` Q_N (module docstring, step 1; complex Householder QR)."""
    q0, r0 = jnp.linalg.qr(basis)

    def step(q, t):
        q_new, r_new = jnp.linalg.qr(t @ q)
        return q_new, (q_new, r_new)

    _, (qs, rs) = jax.lax.scan(step, q0, exponentials)
    qs = jnp.concatenate([q0[None], qs])
    rs = jnp.concatenate([r0[None], rs])
    _, _, vh = jnp.linalg.svd(out @ qs[-1])
    c_n = jnp.conj(vh[-1])

    def back(c, r):
        return jax.scipy.linalg.solve_triangular(r, c, lower=False), c

    c_0, cs = jax.lax.scan(back, c_n, rs[1:], reverse=True)
    states = jnp.einsum("kij,kj->ki", qs, jnp.concatenate([c_0[None], cs]))
    return states, jax.scipy.linalg.solve_triangular(rs[0], c_0, lower=False)


def _coefficients_at(tube: Tube, wall, r, omega):
    """The (general-form) coefficients at radii r̂ (any shape) at the real frequency Ω: those of
    :func:`jaxdea.physics.transfer.layer_coefficients` plus η*(Ω) times each damping law's pattern
    (docs/theory/real_tubes.md §4), as :func:`jaxdea.physics.transfer.damped_wall` adds them."""
    coef = general_form(layer_coefficients(tube, r))
    if wall.damping is None:
        return coef
    lam, lz = stretch(tube, r), as_float(tube.lambda_z)
    if tube.layers is None:
        patterns = (damping_pattern(tube.damping, lam, lz),)
    else:
        edges = interface_radii(tube)
        owner = jnp.clip(jnp.searchsorted(edges, r, side="right") - 1, 0, len(tube.layers) - 1)
        patterns = tuple(damping_pattern(layer.damping, lam, lz, (owner == k).astype(lam.dtype))
                         for k, layer in enumerate(tube.layers) if layer.damping is not None)
    return damped_wall(wall._replace(coef=coef, damping_pattern=patterns), omega).coef


def _take(coef, index):
    return jax.tree_util.tree_map(lambda x: x[index], coef)


def _densities(coef, r, y, dy, omega, alpha, m):
    """(flux, energy, dissipation, kinetic energy, axial work) densities per r̂ dr̂ at one radius
    (docs/theory/real_tubes.md Eqs. 9.4–9.6, 9.10, 9.12)
    from the 8 fields y = [U, V, W, Φ, T, Q, S, D] (standing-wave amplitudes of docs/theory/order_m.md
    §1), their radial derivatives dy and the general-form coefficients there."""
    u, v, w, phi, t, q, s, d_r = y
    du, dv, dw, dphi = dy[0], dy[1], dy[2], dy[3]
    sh = coef.shear
    d = coef.d
    active = 1.0 if coef.active is None else coef.active
    rho = 1.0 if coef.density is None else coef.density
    # displacement gradient L_ij = ∂u_i/∂x_j (Eq. 9.2)
    l_rr, l_rt, l_rz = du, -(m * u + v) / r, -alpha * u
    l_tr, l_tt, l_tz = dv, (u + m * v) / r, -alpha * v
    l_zr, l_zt, l_zz = dw, -m * w / r, alpha * w
    # electric field and displacement increments (Ė = −grad φ̇; ideal dielectric, Eq. 9.3)
    e_r, e_t, e_z = -dphi * active, m * phi / r * active, alpha * phi * active
    dd_r = d_r * active
    dd_t = (m * phi / r - d * (dv + l_rt)) * active
    dd_z = (alpha * phi - d * (dw + l_rz)) * active
    # the stress components that are not in the state (Eq. 9.3)
    t_tr = coef.e * l_rt + sh.p_t * dv + d * dd_t
    t_tt = t - (coef.g + 2.0 * coef.q) * l_rr - (coef.g + coef.q) * l_zz + coef.p * (l_tt - l_rr) \
        - 2.0 * d * dd_r
    t_tz = -(sh.e_z * m * w / r + sh.p_tz * alpha * v)
    t_zr = coef.a * l_rz + sh.p_z * dw + d * dd_z
    t_zt = -(sh.a_t * alpha * v + sh.p_tz * m * w / r)
    t_zz = t - coef.q * l_rr + (2.0 * coef.b - coef.q) * l_zz + coef.p * (l_zz - l_rr) \
        - 2.0 * d * dd_r
    flux = 0.5 * omega * jnp.real(t_zz * jnp.conj(w) - t_zr * jnp.conj(u) - t_zt * jnp.conj(v)
                                  - phi * active * jnp.conj(dd_z))
    work = (jnp.conj(l_rr) * t + jnp.conj(l_tt) * t_tt + jnp.conj(l_zz) * t_zz
            + jnp.conj(l_rt) * t_tr + jnp.conj(l_tr) * q + jnp.conj(l_rz) * t_zr
            + jnp.conj(l_zr) * s + jnp.conj(l_tz) * t_zt + jnp.conj(l_zt) * t_tz
            + jnp.conj(dd_r) * e_r + jnp.conj(dd_t) * e_t + jnp.conj(dd_z) * e_z)
    kinetic = rho * omega**2 * (jnp.abs(u) ** 2 + jnp.abs(v) ** 2 + jnp.abs(w) ** 2)
    axial = jnp.imag(jnp.conj(u) * t_zr + jnp.conj(v) * t_zt - jnp.conj(w) * t_zz)
    return (flux, 0.25 * (kinetic + jnp.real(work)), 0.5 * omega * jnp.imag(work), 0.25 * kinetic,
            axial)


def _wall_nodes(tube: Tube, wall, n_points: int):
    """Gauss–Legendre nodes and weights (× r̂) of every physical layer of the wall."""
    x, weight = np.polynomial.legendre.leggauss(n_points)
    edges = interface_radii(tube) if tube.layers is not None else jnp.stack(
        [wall.r_inner, wall.r_outer])
    lo, hi = edges[:-1, None], edges[1:, None]
    r = 0.5 * (lo + hi) + 0.5 * (hi - lo) * x
    return r.ravel(), (0.5 * (hi - lo) * weight * r).ravel()


def _wall_integrals(tube, wall, states, omega, alpha, m, family, n_points):
    """The integrals of :func:`_densities` over the wall by Gauss–Legendre per layer, the fields
    at the nodes by a Magnus step from the nearest sublayer interface (module docstring, step 2)."""
    edges = _midpoints(tube, wall)[0]
    r, weight = _wall_nodes(tube, wall, n_points)
    count = edges.shape[0] - 1
    k = jnp.clip(jnp.searchsorted(edges, r, side="right") - 1, 0, count - 1)
    near = jnp.where(r - edges[k] > edges[k + 1] - r, k + 1, k)
    start = edges[near]
    h = r - start
    radii = jnp.stack([start + c * h for c in MAGNUS_NODES] + [r], axis=-1)  # (P, 3)
    coef = _coefficients_at(tube, wall, radii, omega)
    w2 = omega * omega

    def matrix(c, rad):
        return family_matrix(family, c, rad, w2, alpha, m).astype(jnp.complex128)

    def node(c, rad, step, y0):
        a1, a2, a3 = (matrix(_take(c, j), rad[j]) for j in range(3))
        generator = 0.5 * step * (a1 + a2) + np.sqrt(3.0) / 12.0 * step**2 * (a2 @ a1 - a1 @ a2)
        y = expm_taylor(generator) @ y0
        return y, a3 @ y

    ys, dys = jax.vmap(node)(coef, radii, h, states[near])
    rows = jnp.asarray(family.order_m_rows)
    y8 = jnp.zeros((r.shape[0], 8), jnp.complex128).at[:, rows].set(ys)
    dy8 = jnp.zeros((r.shape[0], 8), jnp.complex128).at[:, rows].set(dys)
    densities = jax.vmap(_densities, (0, 0, 0, 0, None, None, None))(
        _take(coef, (slice(None), 2)), r, y8, dy8, omega, alpha, m)
    return tuple(jnp.sum(weight * x) for x in densities)


def _face_terms(wall, y_inner, omega, alpha, m):
    """(flux, energy) of the static follower pressure P̂_i on the inner face (Eq. 9.7)."""
    u, v, w = y_inner[0], y_inner[1], y_inner[2]
    pressure, ri = wall.pressure_inner, wall.r_inner
    flux = -0.5 * pressure * omega * jnp.real(w * jnp.conj(u)) * ri
    axial = -0.25 * pressure * jnp.real(w * jnp.conj(alpha * u) + u * jnp.conj(alpha * w)) * ri
    hoop = -0.25 * pressure * (jnp.abs(u) ** 2 + jnp.abs(v) ** 2 + 2.0 * m * jnp.real(u * jnp.conj(v)))
    return flux, axial + hoop


def _cavity_terms(wall, fluid, coefficient_u, y_inner, omega, alpha, m, n_points):
    """(flux, energy) of the acoustic filling (Eq. 9.8): p̂*(r̂) = Ω²ρ̂_f r̂_i c_u N_m(χ̂²r̂²) ×
    (r̂/r̂_i)^m (the pressure of :func:`jaxdea.solve.modes.fluid_pressure`) at Gauss–Legendre nodes
    on [0, r̂_i]; the gradient term by Green's identity, ∫(|p̂'|² + m²|p̂|²/r̂²) r̂ dr̂ =
    Re[r̂_i p̂*(r̂_i)^* p̂*'(r̂_i)] + Re χ̂² ∫|p̂*|² r̂ dr̂, with p̂*'(r̂_i) = Ω²ρ̂_f ū(r̂_i)."""
    rho, c_f = as_float(fluid.density_ratio), as_float(fluid.speed_ratio)
    ri = wall.r_inner
    x, weight = np.polynomial.legendre.leggauss(n_points)
    r = 0.5 * ri * (1.0 + x)
    weight = 0.5 * ri * weight * r
    chi2 = (omega / c_f) ** 2 - alpha**2
    s, s_i = chi2 * r**2, chi2 * ri**2
    if jnp.iscomplexobj(alpha):
        n = jax.vmap(lambda x: coupling_pair(x, m)[0])(s)
        n_i = coupling_pair(s_i, m)[0]
        # the series branch carries no factor; beyond it the factor is not known: NaN
        n = jnp.where(jnp.abs(s_i) <= 64.0, n, jnp.nan)
    else:
        n = coupling_pair(s, m)[0] * jnp.exp(coupling_log_factor(s_i) - coupling_log_factor(s))
        n_i = coupling_pair(s_i, m)[0]
    amplitude = omega**2 * rho * ri * coefficient_u
    p = amplitude * n * (r / ri) ** m
    p_i = amplitude * n_i
    squared = jnp.sum(weight * jnp.abs(p) ** 2)
    slope_i = omega**2 * rho * y_inner[0]
    gradient = (jnp.real(ri * jnp.conj(p_i) * slope_i) + jnp.real(chi2) * squared
                + jnp.abs(alpha) ** 2 * squared)
    flux = 0.5 * jnp.real(alpha) * squared / (omega * rho)
    energy = 0.25 * (gradient / (omega**2 * rho) + squared / (rho * c_f**2))
    return flux, energy


def _outer_terms(wall, fluid, y_outer, omega, alpha, m):
    """(flux, energy) of a surrounding fluid (Eq. 9.9) for a subsonic mode, in closed form:
    p̂*_o(r̂) = −T̄(r̂_o) K_m(γr̂)/K_m(γr̂_o), γ = sqrt(α̂² − Ω²/ĉ_o²), ∫_{r̂_o}^∞ K_m(γr̂)² r̂ dr̂ =
    (r̂_o²/2)(K_{m−1}K_{m+1} − K_m²)(γr̂_o) (checked against quadrature), and the
    gradient term by Green's identity, ∫(|p̂'|² + m²|p̂|²/r̂²) r̂ dr̂ = −r̂_o p̂ p̂'(r̂_o) − γ² ∫|p̂|² r̂ dr̂
    with p̂*_o'(r̂_o) = ρ̂_oΩ²ū(r̂_o)."""
    rho, c_o = as_float(fluid.density_ratio), as_float(fluid.speed_ratio)
    ro = wall.r_outer
    gamma_squared = alpha**2 - (omega / c_o) ** 2
    y = jnp.sqrt(gamma_squared) * ro
    k_m = scaled_k(y, m)
    ratio = scaled_k(y, jnp.abs(m - 1.0)) * scaled_k(y, m + 1.0) / (k_m * k_m)
    p_o = -y_outer[4]
    slope_o = rho * omega**2 * y_outer[0]
    squared = jnp.abs(p_o) ** 2 * 0.5 * ro**2 * (ratio - 1.0)  # ∫|p̂|² r̂ dr̂
    gradient = (-ro * jnp.real(jnp.conj(p_o) * slope_o) - gamma_squared * squared
                + alpha**2 * squared)  # ∫|∇p̂|² r̂ dr̂
    flux = 0.5 * alpha * squared / (omega * rho)
    energy = 0.25 * (gradient / (omega**2 * rho) + squared / (rho * c_o**2))
    return flux, energy


@cached_jit(static_argnames=("n_points", "n_layers", "order", "real", "family"))
def _energy_velocity(tube, alpha, omega, fluid, n_points, n_layers, order, real=True, m=0.0,
                     family=Family.LONGITUDINAL):
    """(v_e, flux P̄_z, energy Ē, dissipated power D̄ per unit length (Eq. 9.10), relative Newton
    distance of α̂ from a root of the same laminate, (the wall's kinetic energy, its axial work
    Im ∫[U*Ṫ_zr + V*Ṫ_zθ − W*Ṫ_zz] r̂ dr̂ of Eq. 9.12): the checks of the tests);
    ``real`` (static): α̂ is real (the cavity's Bessel functions in real arithmetic)."""
    wall = discretize(tube, n_layers)
    alpha = _complex(alpha)
    basis, exponentials, out = characteristic.pieces(family, wall, alpha, omega, fluid, order, m,
                                                     Unknown.ALPHA)
    f, log_slope = characteristic.value_and_log_slope(family, wall, alpha, omega, fluid, order, m,
                                                      Unknown.ALPHA, "taylor")  # any mode
    step = jnp.abs(1.0 / log_slope) / jnp.abs(alpha)  # Newton's relative step f/(f' α̂)
    # f exactly 0 (a root to the last bit) leaves 0/0 in the log-slope: a root
    distance = jnp.where(jnp.isfinite(step), step, jnp.where(jnp.abs(f) < 1e-13, 0.0, jnp.inf))
    states, coefficients = _interface_states(basis, exponentials, out)
    rows = jnp.asarray(family.order_m_rows)
    y_inner = jnp.zeros(8, jnp.complex128).at[rows].set(states[0])
    y_outer = jnp.zeros(8, jnp.complex128).at[rows].set(states[-1])
    flux, energy, dissipation, kinetic, axial = _wall_integrals(tube, wall, states, omega, alpha,
                                                                m, family, n_points)
    face = _face_terms(wall, y_inner, omega, alpha, m)
    flux, energy = flux + face[0], energy + face[1]
    if Face.of(fluid).has_pressure and family.moves_fluid:
        cavity = _cavity_terms(wall, fluid, coefficients[0], y_inner, omega,
                               jnp.real(alpha) if real else alpha, m, n_points)
        flux, energy = flux + cavity[0], energy + cavity[1]
    if tube.outer is not None and family.moves_fluid:
        outside = _outer_terms(wall, tube.outer, y_outer, omega, jnp.real(alpha), m)
        flux, energy = flux + outside[0], energy + outside[1]
    ok = (distance <= ROOT_RTOL) & jnp.isfinite(omega) & (omega > 0)
    velocity = jnp.where(ok, flux / energy, jnp.nan)
    return velocity, flux, energy, dissipation, distance, (kinetic, axial)


def _check_alpha(alpha) -> None:
    """α̂: a finite real or complex scalar with Re α̂ > 0 (the root with Re α̂ ≥ 0 of
    :func:`jaxdea.wavenumbers`, a wave travelling towards +z)."""
    try:
        value = np.asarray(alpha)
        ok = (value.ndim == 0 and np.issubdtype(value.dtype, np.number)
              and value.dtype != bool and np.isfinite(value) and np.real(value) > 0)
    except TypeError:
        ok = False
    if not ok:
        raise ValueError("alpha must be a finite real or complex scalar with Re(alpha) > 0 (a root "
                         f"of frequencies or wavenumbers), got {alpha!r}")


def energy_velocity(tube: Tube, alpha, omega, fluid: Fluid | None = None, n_points: int = 16,
                    n_layers: int | None = None, m=0, torsional: bool = False,
                    scheme: str | None = None, outer: Fluid | None = None):
    """The energy velocity v_e = P̄_z/Ē of the mode (α̂, Ω): its time-averaged axial power flux over
    its time-averaged energy per unit length (docs/theory/real_tubes.md §9, Eq. 9.1).

    P̄_z sums the wall's mechanical and electric (quasi-electrostatic φ̇ ∂Ḋ_z/∂t) flux (Eq. 9.4), the
    follower-pressure term of the inner face (Eq. 9.7) and the fluids' acoustic flux (Eqs. 9.8–9.9);
    Ē the kinetic and stored energy (Eq. 9.5; the real part of the moduli of a damped wall) and the
    fluids' ¼(ρ|v|² + |p|²/(ρc²)). For a lossless tube v_e equals :func:`jaxdea.group_velocity`
    (to the quadrature and the laminate's accuracy); for a damped one it is the speed at which the
    energy of the wave travels, the speed a measurement sees. The wave is e^{i(Ωt − α̂z)}: Re α̂ > 0
    travels towards +z (v_e > 0 unless the branch is backward).

    Args:
        tube: the :class:`~jaxdea.Tube` (damped or not).
        alpha: α̂: a real root (e.g. the α̂ at which :func:`jaxdea.frequencies` gives ``omega``) or,
            for a damped tube, a complex root at the real ``omega`` from :func:`jaxdea.wavenumbers`
            (Re α̂ > 0).
        omega: Ω > 0, real.
        fluid: None or an ``"acoustic"`` :class:`~jaxdea.Fluid` (the paper's coupling has no
            pressure field: ValueError).
        n_points: Gauss–Legendre nodes per layer of the wall (and in the cavity), static; the
            integrals converge spectrally in it.
        n_layers, scheme, m, torsional: the discretisation and family the root was found with, as for
            :func:`jaxdea.mode_shape`.
        outer: a surrounding :class:`~jaxdea.Fluid` or None (the tube's own ``tube.outer``); only a
            real, subsonic mode (Ω < ĉ_oα̂) has a finite energy in it.

    Returns:
        v_e (a float64 scalar), NaN where (α̂, Ω) is farther than ``ROOT_RTOL`` = 1e-4 from a root
        (relative Newton step in α̂) under a trace; a concrete non-root raises.

    Raises:
        ValueError: naming the parameter: a non-finite or non-positive Ω, an α̂ that is not finite
            or has Re α̂ ≤ 0, a non-root, the paper's coupling, a surrounding fluid with a complex
            or supersonic α̂, bad n_points, and the checks of :func:`jaxdea.mode_shape`.

    Examples:
        >>> import jaxdea as jd
        >>> tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
        >>> omega = jd.frequencies(tube, 0.445)[0]
        >>> jd.energy_velocity(tube, 0.445, omega)  # = jd.group_velocity(tube, 0.445, omega)
        >>> damped = tube.replace(damping=jd.KelvinVoigt(0.01))
        >>> alpha = jd.wavenumbers(damped, float(omega), n_roots=1).alpha[0]
        >>> jd.energy_velocity(damped, alpha, float(omega))
    """
    tube = with_outer(tube, outer)
    validate_positive("omega", omega)
    validate_count("n_points", n_points)
    if not traced(alpha):
        _check_alpha(alpha)
    complex_alpha = jnp.iscomplexobj(jnp.asarray(alpha))
    problem = describe(tube, NO_ALPHA if complex_alpha else alpha, fluid, n_layers, scheme, m,
                       torsional, damped=True)
    if Face.of(fluid).has_poles:
        raise ValueError("fluid: energy_velocity needs the 'acoustic' coupling (the paper's "
                         "coupling has no pressure field to carry a flux), got coupling='paper'")
    if tube.outer is not None and problem.family.moves_fluid:
        if complex_alpha:
            raise ValueError("outer: the energy in a surrounding fluid is computed for a real alpha "
                             "only (a subsonic, lossless mode), got a complex alpha")
        if not traced((alpha, omega, tube.outer)) and not (
                float(omega) < float(tube.outer.speed_ratio) * float(alpha)):
            raise ValueError("outer: the mode must be subsonic, omega < outer.speed_ratio * alpha "
                             "(a leaky mode radiates an infinite energy)")
    tube, omega, fluid = canonical(tube, omega, fluid)
    m_value = as_float(float(m) if not traced(m) else m)
    count = laminate(n_layers, scheme, tube, float(np.abs(alpha)) if not traced(alpha) else None,
                     m=m)
    velocity, _, _, _, distance, _ = _energy_velocity(
        tube, _complex(alpha), omega, fluid, int(n_points), count, problem.order, not complex_alpha,
        **problem.arguments(m_value))
    if not traced((alpha, omega, tube, fluid)) and not float(distance) <= ROOT_RTOL:
        raise ValueError(f"alpha = {complex(alpha)!r} is not a root at omega = {float(omega)!r} of "
                         f"this case (relative Newton step {float(distance):.3g} > {ROOT_RTOL}): "
                         "use a root of frequencies or wavenumbers with the same tube, fluid, order "
                         "and discretisation")
    return velocity
