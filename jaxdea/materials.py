"""Elastic energies of incompressible isotropic materials, in units of the small-strain shear modulus.

Two forms live here:

* the W(I_1) functions of the historical static names (``ENERGIES``: ``"gent"``, ``"neo_hookean"``),
  whose moduli :mod:`jaxdea.physics.moduli` writes in closed form (docs/theory/axisymmetric.md §0, §3);
* material objects (:class:`Material`): ``Gent``, ``NeoHookean``, ``MooneyRivlin``, ``GentGent``,
  ``Ogden`` and a user's :class:`Energy`. Each is a pytree whose parameters are differentiable
  leaves, and gives its energy as a function of the principal stretches, W(λ_1, λ_2, λ_3), the
  unconstrained extension of docs/theory/real_tubes.md §1. Their moduli come from that energy by
  automatic differentiation (:meth:`Material.derivatives`).

The electro-elastic energy adds I_5/2 (ideal dielectric, paper Eq. 9) in the active layer.
"""

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np


def gent(i1, gent_constant):
    """Gent energy W = −(G/2) ln[1 − (I_1 − 3)/G]; G = inf gives neo-Hookean (docs/theory/axisymmetric.md
    §0)."""
    limited = jnp.isinf(gent_constant)
    g = jnp.where(limited, 1.0, gent_constant)  # double-where: finite gradients at G = inf
    x = jnp.where(limited, 0.0, (i1 - 3.0) / g)
    return jnp.where(limited, 0.5 * (i1 - 3.0), -0.5 * g * jnp.log1p(-x))


def neo_hookean(i1, gent_constant=None):
    """Neo-Hookean energy W = (I_1 − 3)/2."""
    del gent_constant
    return 0.5 * (i1 - 3.0)


ENERGIES = {"gent": gent, "neo_hookean": neo_hookean}
"""The W(I_1) of the static material names a :class:`jaxdea.Tube` accepts (``material="gent"``)."""


def invariants(stretches):
    """(I_1, I_2) = (Σ λ_i², Σ_{i<j} λ_i² λ_j²) of principal stretches (last axis of length 3)."""
    sq = stretches * stretches
    return jnp.sum(sq, -1), sq[..., 0] * sq[..., 1] + sq[..., 1] * sq[..., 2] + sq[..., 0] * sq[..., 2]


REST = (1.0, 1.0, 1.0)


class Material:
    """An incompressible isotropic elastic energy, normalised to unit small-strain shear modulus.

    Subclasses give :meth:`energy` W(λ_1, λ_2, λ_3) (principal stretches, unconstrained) and
    :meth:`shear_pair` Q_ij = (λ_iW_i − λ_jW_j)/(λ_i² − λ_j²) in a form without 0/0 where two
    stretches coalesce (docs/theory/real_tubes.md §1)."""

    def energy(self, stretches):
        raise NotImplementedError

    def shear_pair(self, stretches, first_derivatives):
        raise NotImplementedError

    def derivatives(self, stretches):
        """(W_i, W_ij, Q_ij): the gradient (3,) and Hessian (3, 3) of W in the principal stretches
        (automatic differentiation) and the (3, 3) matrix of Q_ij (diagonal unused)."""
        stretches = jnp.asarray(stretches, jnp.result_type(stretches, jnp.float64))
        grad = jax.grad(self.energy)(stretches)
        hess = jax.hessian(self.energy)(stretches)
        return grad, hess, self.shear_pair(stretches, grad)

    def shear_modulus(self):
        """2(W_1 + W_2) at rest, i.e. Q_ij at λ = (1, 1, 1): 1 for a normalised material."""
        return self.derivatives(jnp.asarray(REST))[2][0, 1]

    def parameter_names(self) -> tuple:
        """The names of the scalar parameters that sweeps, traces and fits may set
        (:meth:`with_parameters`): the dataclass fields holding one real number."""
        return tuple(f.name for f in dataclasses.fields(self) if not f.metadata.get("static")
                     and np.ndim(getattr(self, f.name)) == 0
                     and np.isrealobj(getattr(self, f.name))
                     and not isinstance(getattr(self, f.name), (str, bool, type(None))))

    def parameter(self, name: str):
        """The value of a parameter of :meth:`parameter_names`."""
        return getattr(self, name)

    def with_parameters(self, **values):
        """A copy with parameters of :meth:`parameter_names` set."""
        return dataclasses.replace(self, **values)


class InvariantMaterial(Material):
    """A material given as W(I_1, I_2) (:meth:`invariant_energy`); Q_ij = 2(W_1 + W_2 λ_k²), k the
    third index, exact at coalescent stretches (docs/theory/real_tubes.md §1)."""

    def invariant_energy(self, i1, i2):
        raise NotImplementedError

    def energy(self, stretches):
        return self.invariant_energy(*invariants(stretches))

    def shear_pair(self, stretches, first_derivatives):
        del first_derivatives
        w1, w2 = jax.grad(self.invariant_energy, argnums=(0, 1))(*invariants(stretches))
        sq = stretches * stretches
        third = jnp.array([[0, 2, 1], [2, 0, 0], [1, 0, 0]])  # k ≠ i, j (diagonal unused)
        return 2.0 * (w1 + w2 * sq[third])


def _dataclass(cls):
    cls = dataclasses.dataclass(frozen=True)(cls)
    return jax.tree_util.register_dataclass(cls)


@_dataclass
class Gent(InvariantMaterial):
    """Gent: W = −(G/2) ln(1 − (I_1 − 3)/G), G = ``gent`` the locking constant (API.md)."""

    gent: float = 97.2

    def invariant_energy(self, i1, i2):
        del i2
        return gent(i1, jnp.asarray(self.gent, jnp.float64))


@_dataclass
class NeoHookean(InvariantMaterial):
    """Neo-Hookean: W = (I_1 − 3)/2."""

    def invariant_energy(self, i1, i2):
        del i2
        return neo_hookean(i1)


@_dataclass
class MooneyRivlin(InvariantMaterial):
    """Mooney–Rivlin: W = (1 − β)(I_1 − 3)/2 + β(I_2 − 3)/2, β = ``beta`` (API.md)."""

    beta: float = 0.2

    def invariant_energy(self, i1, i2):
        beta = self.beta
        return 0.5 * (1.0 - beta) * (i1 - 3.0) + 0.5 * beta * (i2 - 3.0)


@_dataclass
class GentGent(InvariantMaterial):
    """Gent–Gent (Pucci–Saccomandi): W = −(1 − β)(G/2) ln(1 − (I_1 − 3)/G) + (3β/2) ln(I_2/3)
    (API.md)."""

    gent: float = 97.2
    beta: float = 0.2

    def invariant_energy(self, i1, i2):
        beta = self.beta
        return (1.0 - beta) * gent(i1, jnp.asarray(self.gent, jnp.float64)) + 1.5 * beta * jnp.log(i2 / 3.0)


@_dataclass
class Ogden(Material):
    """Ogden: W = Σ_k μ_k/α_k (λ_1^α_k + λ_2^α_k + λ_3^α_k − 3), normalised by Σ μ_kα_k = 2 (API.md).

    Q_ij = Σ_k μ_k λ_j^{α_k−2} expm1(α_k t)/expm1(2t), t = ln(λ_i/λ_j), → Σ μ_kα_k λ^{α_k−2}/2 at
    t = 0 (docs/theory/real_tubes.md §1, pitfall 3)."""

    mu: tuple = (1.0,)
    alpha: tuple = (2.0,)

    def parameter_names(self) -> tuple:
        """The exponents ``alpha0``, ``alpha1``, …: setting α_k keeps the term's share
        μ_kα_k/2 of the unit shear modulus (μ_k ← μ_kα_k/α_k,new), so the material stays
        normalised (Σ μ_kα_k = 2) along a sweep, a trace or a fit."""
        return tuple(f"alpha{k}" for k in range(len(self.alpha)))

    def parameter(self, name: str):
        return self.alpha[_term(self, name)]

    def with_parameters(self, **values):
        mu, alpha = list(self.mu), list(self.alpha)
        for name, value in values.items():
            k = _term(self, name)
            mu[k] = mu[k] * alpha[k] / value
            alpha[k] = value
        return dataclasses.replace(self, mu=tuple(mu), alpha=tuple(alpha))

    def energy(self, stretches):
        total = 0.0
        for mu, alpha in zip(self.mu, self.alpha, strict=True):
            total = total + mu / alpha * (jnp.sum(stretches ** alpha) - 3.0)
        return total

    def shear_pair(self, stretches, first_derivatives):
        del first_derivatives
        li, lj = stretches[:, None], stretches[None, :]
        t = jnp.log(li / lj)
        small = jnp.abs(t) < 1e-8
        t_safe = jnp.where(small, 1.0, t)
        total = 0.0
        for mu, alpha in zip(self.mu, self.alpha, strict=True):
            ratio = jnp.where(small, 0.5 * alpha * (1.0 + 0.5 * (alpha - 2.0) * t),
                              jnp.expm1(alpha * t_safe) / jnp.expm1(2.0 * t_safe))
            total = total + mu * lj ** (alpha - 2.0) * ratio
        return total


def _term(material, name: str) -> int:
    """k of an Ogden parameter name ``alpha<k>``; ValueError otherwise."""
    names = material.parameter_names()
    if name not in names:
        raise ValueError(f"{type(material).__name__} has no parameter {name!r}: allowed are "
                         f"{', '.join(names)}")
    return int(name.removeprefix("alpha"))


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Energy(InvariantMaterial):
    """A user's energy W(I_1, I_2, params) written in JAX: ``fn`` static, ``params`` a pytree of
    differentiable leaves; the moduli come by automatic differentiation (API.md)."""

    fn: Callable = dataclasses.field(metadata=dict(static=True))
    params: object = ()

    def invariant_energy(self, i1, i2):
        return self.fn(i1, i2, self.params)


MATERIAL_TYPES = (Gent, NeoHookean, MooneyRivlin, GentGent, Ogden, Energy)
"""The material classes of the public API."""
KINDS = {"gent": Gent, "neo_hookean": NeoHookean, "mooney_rivlin": MooneyRivlin,
         "gent_gent": GentGent, "ogden": Ogden}
"""The material classes by the ``kind`` that configuration files and sweep settings name them
(``Energy``, a user's JAX function, has none)."""


class Damping:
    """A viscoelastic law of the increments on a relaxed base state (docs/theory/real_tubes.md §4):
    the incremental stress gains η*(Ω) f_pi (L_pi + L_ip), η* in units of μ (:meth:`viscous_modulus`), f the
    stretch coupling (1 unless :class:`FractionalKelvinVoigt` has ``stretch_coupling`` ≠ 0)."""

    stretch_coupling = 0.0

    def viscous_modulus(self, omega):
        """η*(Ω) at a (complex) frequency Ω, time factor e^{iΩt}."""
        raise NotImplementedError


@_dataclass
class Prony(Damping):
    """Generalised Maxwell branches: η*(Ω) = Σ_k g_k iΩτ_k/(1 + iΩτ_k), ``moduli`` g_k (units of μ),
    ``times`` τ_k (units of R_i/c_s). Poles at Ω = i/τ_k, on the imaginary axis."""

    moduli: tuple = (1.0,)
    times: tuple = (1.0,)

    def viscous_modulus(self, omega):
        total = 0.0
        for g, tau in zip(self.moduli, self.times, strict=True):
            x = 1j * omega * tau
            total = total + g * x / (1.0 + x)
        return total


@_dataclass
class FractionalKelvinVoigt(Damping):
    """Fractional Kelvin–Voigt: η*(Ω) = g (iΩτ)^n (principal power, branch cut on the positive
    imaginary Ω axis), with POnG's optional stretch coupling f_ij = 1 + β'(λ_i² + λ_j² − 2)/2
    (``stretch_coupling`` β')."""

    modulus: float = 1.0
    time: float = 1.0
    order: float = 0.5
    stretch_coupling: float = 0.0

    def viscous_modulus(self, omega):
        return self.modulus * (1j * omega * self.time) ** self.order


@_dataclass
class KelvinVoigt(Damping):
    """Kelvin–Voigt: η*(Ω) = iΩη_v, ``viscosity`` η_v in units of μR_i/c_s."""

    viscosity: float = 0.1

    def viscous_modulus(self, omega):
        return 1j * omega * self.viscosity


@_dataclass
class Hysteretic(Damping):
    """Frequency-independent (structural) loss: η*(Ω) = iζ, ``loss`` ζ."""

    loss: float = 0.1

    def viscous_modulus(self, omega):
        return 1j * self.loss * jnp.ones_like(omega)


DAMPING_TYPES = (Prony, FractionalKelvinVoigt, KelvinVoigt, Hysteretic)
"""The damping laws of the public API."""
DAMPING_KINDS = {"prony": Prony, "fractional_kelvin_voigt": FractionalKelvinVoigt,
                 "kelvin_voigt": KelvinVoigt, "hysteretic": Hysteretic}
"""The damping laws by the ``kind`` that configuration files (``[damping]``) and settings name them."""
