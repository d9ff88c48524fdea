"""Material objects (API.md "Real tubes", docs/theory/real_tubes.md §1–§2): moduli by automatic
differentiation against the closed forms and against the push-forward of the full Hessian of W(F),
the general 8×8 state matrix against the W(I_1) one and reciprocity, the base state against closed
forms, the exact limits of §7(a), equalities between materials, gradients in material parameters
and the errors of bad materials."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea import materials as mt
from jaxdea.physics import base_state as bs
from jaxdea.physics import moduli as md
from jaxdea.physics import state_matrix as sm
from jaxdea.physics import transfer as tr

R, T, Z = 0, 1, 2
LOADED = dict(voltage=0.12, lambda_i=1.15, lambda_z=1.2, eta=0.7)
"""A stretched, voltage-loaded wall: every modulus differs from its value at rest."""
GENERAL = {
    "MooneyRivlin(0.2)": mt.MooneyRivlin(0.2),
    "GentGent(30, 0.3)": mt.GentGent(30.0, 0.3),
    "Ogden, 3 terms": mt.Ogden((1.0, 0.6, -0.05), (1.5, 0.5, -4.0)),
}


def gent_energy(i1, i2, g):
    """The Gent energy as a user's W(I_1, I_2): the general (autodiff) route for a known W."""
    del i2
    return mt.gent(i1, g)


GENT_AS_ENERGY = mt.Energy(gent_energy, 97.2)


def tensor_moduli(material, stretches):
    """A_piqj = λ_pλ_q ∂²W/∂F_ip∂F_jq at F = diag λ from the Hessian of W(F) (Ogden 1984): W of
    the invariants of C = FᵀF, or of the eigenvalues of C for Ogden (distinct stretches)."""

    def energy(f):
        c = f.T @ f
        if isinstance(material, mt.Ogden):
            return material.energy(jnp.sqrt(jnp.linalg.eigvalsh(c)))
        i1 = jnp.trace(c)
        return material.invariant_energy(i1, 0.5 * (i1 * i1 - jnp.trace(c @ c)))

    f = jnp.diag(stretches)
    return jnp.einsum("p,q,ipjq->piqj", stretches, stretches, jax.hessian(energy)(f))


def test_autodiff_moduli_equal_the_closed_form_gent():
    """The general route (principal-stretch derivatives of a user's Gent energy, the table of
    docs/theory/real_tubes.md §1) equals the closed-form W(I_1) coefficients to 1e-13, and its
    shear moduli equal their W(I_1) partners (c_θ = c, e_z = e, a_θ = a, p_θ = p_z = p_θz = p)."""
    for lam, lam_z, d, p in ((1.13, 1.2, 0.3, 0.7), (0.8, 1.6, 0.0, -0.2), (1.0, 1.0, 0.1, 1.0)):
        general = jax.jit(md.material_coefficients)(GENT_AS_ENERGY, lam, lam_z, d, p)
        closed = md.closed_form_coefficients(jnp.asarray(lam), lam_z, d, p, 97.2)
        for name in ("a", "b", "c", "d", "g", "q", "eps", "p", "e"):
            np.testing.assert_allclose(getattr(general, name), getattr(closed, name), rtol=1e-13,
                                       atol=1e-14, err_msg=name)
        for name, partner in (("c_t", "c"), ("e_z", "e"), ("a_t", "a"), ("p_t", "p"),
                              ("p_z", "p"), ("p_tz", "p")):
            np.testing.assert_allclose(getattr(general.shear, name), getattr(closed, partner),
                                       rtol=1e-13, atol=1e-14, err_msg=name)


@pytest.mark.parametrize("name", list(GENERAL))
def test_table_moduli_equal_the_hessian_of_w_of_f(name):
    """Every symbol of the state matrix from the principal-stretch table equals the push-forward
    of the full Hessian of W(F) (an independent route: no Q_ij, no coalescence formulas), at
    distinct stretches, to 1e-12."""
    material = GENERAL[name]
    lam, lam_z, d, p = 1.13, 1.2, 0.25, 0.4
    lam_r = 1.0 / (lam * lam_z)
    a = tensor_moduli(material, jnp.array([lam_r, lam, lam_z]))
    got = md.material_coefficients(material, lam, lam_z, d, p)
    dd = d * d
    a_rrrr = a[R, R, R, R] + dd
    expected = dict(
        a=a[Z, R, Z, R], c=a[R, Z, R, Z] + dd, e=a[T, R, T, R],
        b=0.5 * (a_rrrr + a[Z, Z, Z, Z] - 2 * a[R, R, Z, Z]),
        g=2 * a[R, R, Z, Z] - 2 * a[T, T, Z, Z] + a[T, T, T, T] - a_rrrr,
        q=a_rrrr - a[R, R, Z, Z] + a[T, T, Z, Z] - a[R, R, T, T],
    )
    shear = dict(c_t=a[R, T, R, T] + dd, e_z=a[T, Z, T, Z], a_t=a[Z, T, Z, T],
                 p_t=p + a[R, T, T, R], p_z=p + a[R, Z, Z, R], p_tz=p + a[T, Z, Z, T])
    for key, value in expected.items():
        np.testing.assert_allclose(getattr(got, key), value, rtol=1e-12, atol=1e-13, err_msg=key)
    for key, value in shear.items():
        np.testing.assert_allclose(getattr(got.shear, key), value, rtol=1e-12, atol=1e-13,
                                   err_msg=key)


def test_the_published_mooney_rivlin_moduli():
    """docs/theory/real_tubes.md §1: λ = 1.13, λ_z = 1.2, MooneyRivlin(0.2): A_rθrθ = 0.591711,
    A_rzrz = 0.573970, A_rθθr = −0.138889 (6 digits), and the I_2 term makes them differ."""
    got = md.material_coefficients(mt.MooneyRivlin(0.2), 1.13, 1.2, 0.0, 0.0)
    np.testing.assert_allclose(got.shear.c_t, 0.591711, atol=6e-7)
    np.testing.assert_allclose(got.c, 0.573970, atol=6e-7)
    np.testing.assert_allclose(got.shear.p_t - got.p, -0.138889, atol=6e-7)


def test_ogden_coalescent_stretches_are_the_limit():
    """Ogden's Q_ij by expm1 at coalescent stretches (λ_i = λ_j) is the limit of the quotient
    (λ_iW_i − λ_jW_j)/(λ_i² − λ_j²) at nearby distinct ones (pitfall 3: no 0/0)."""
    material = GENERAL["Ogden, 3 terms"]
    at = jnp.array([1.1, 1.1, 1.0 / 1.21])
    _, _, pair = material.derivatives(at)
    for eps in (1e-5, -1e-5):
        near = at.at[1].add(eps)
        w = jax.grad(material.energy)(near)
        quotient = (near[0] * w[0] - near[1] * w[1]) / (near[0] ** 2 - near[1] ** 2)
        np.testing.assert_allclose(pair[0, 1], quotient, rtol=1e-4)
    assert np.isfinite(np.asarray(pair)).all()


# ------------------------------------------------------------------ the 8×8 state matrix (§2)


def _general_twin(coef):
    """The W(I_1) coefficients with their shear moduli set equal to their partners (general
    route)."""
    return coef._replace(shear=md.Shear(coef.c, coef.e, coef.a, coef.p, coef.p, coef.p))


@pytest.mark.parametrize("m", [0.0, 1.0, 3.0])
def test_general_matrix_is_the_w_of_i1_matrix_for_equal_pairs(m):
    """With c_θ = c_z, e_z = e_r, a_θ = a_r, p_θ = p_z = p_θz = p the general 8×8 matrix equals
    docs/theory/order_m.md's entry by entry (1e-15 of the largest entry), and its m = 0 blocks
    are the 6×6 and torsion matrices."""
    wall = jax.jit(tr.discretize, static_argnums=1)(jd.Tube(**LOADED), 6)
    coef = jax.tree_util.tree_map(lambda x: x[2], wall.coef)
    r = wall.radii[2]
    for w in (0.0, 2.3, -0.4):
        old = np.asarray(sm.state_matrix_m(coef, r, w, 0.89, m))
        new = np.asarray(sm.state_matrix_m(_general_twin(coef), r, w, 0.89, m))
        np.testing.assert_allclose(new, old, rtol=0, atol=1e-15 * np.max(np.abs(old)))
    twin = _general_twin(coef)
    six = np.asarray(sm.state_matrix(twin, r, 0.7, 0.89))
    np.testing.assert_allclose(six, np.asarray(sm.state_matrix(coef, r, 0.7, 0.89)), rtol=0,
                               atol=1e-15 * np.max(np.abs(six)))
    np.testing.assert_allclose(np.asarray(sm.torsion_matrix(twin, r, 0.49, 0.89)),
                               np.asarray(sm.torsion_matrix(coef, r, 0.49, 0.89)), rtol=0,
                               atol=1e-15)


@pytest.mark.parametrize("name", list(GENERAL))
@pytest.mark.parametrize("m", [0.0, 1.0, 3.0])
def test_general_matrix_is_reciprocal(name, m):
    """Mᵀ J + J M + J/r̂ = 0 (docs/theory/real_tubes.md §2) for a loaded wall of a general material,
    where c_θ ≠ c_z, e_z ≠ e_r, a_θ ≠ a_r and the three p's differ: every entry of the two shear
    sets enters."""
    wall = jax.jit(tr.discretize, static_argnums=1)(jd.Tube(**LOADED, material=GENERAL[name]), 6)
    coef = jax.tree_util.tree_map(lambda x: x[2], wall.coef)
    r = float(wall.radii[2])
    assert abs(float(coef.shear.c_t - coef.c)) > 1e-3 and abs(float(coef.shear.p_tz - coef.p)) > 1e-3
    j = np.block([[np.zeros((4, 4)), np.eye(4)], [-np.eye(4), np.zeros((4, 4))]])
    for w in (0.0, 2.3, -0.4):
        mat = np.asarray(sm.state_matrix_m(coef, r, w, 0.89, m))
        residual = mat.T @ j + j @ mat + j / r
        assert np.max(np.abs(residual)) <= 1e-14 * np.max(np.abs(mat))


# ------------------------------------------------------------------ base state (§3)


def test_mooney_rivlin_pressure_is_a_scaled_neo_hookean_one():
    """σ_θ − σ_r = (λ² − λ_r²)(1 − β + βλ_z²) for MooneyRivlin(β) (docs/theory/real_tubes.md §1), so
    its elastic ΔP̂ is (1 − β + βλ_z²) times the neo-Hookean closed form, and the homogeneous state
    λ_i = λ_z^{-1/2} needs none, for every material."""
    beta = 0.3
    tube = jd.Tube(lambda_i=1.3, lambda_z=1.4, eta=0.6, voltage=0.0)
    mr = jax.jit(bs.pressure_difference_unchecked)(tube.replace(material=mt.MooneyRivlin(beta)))
    neo = jax.jit(bs.pressure_difference_unchecked)(tube.replace(material="neo_hookean"))
    np.testing.assert_allclose(mr, (1 - beta + beta * 1.4**2) * neo, rtol=1e-13)
    for material in GENERAL.values():
        homogeneous = jd.Tube(lambda_i=1.2**-0.5, lambda_z=1.2, material=material)
        assert abs(float(jax.jit(bs.pressure_difference_unchecked)(homogeneous))) < 1e-14


def test_general_base_state_equals_the_closed_form():
    """The quadrature base state of a user's Gent energy (p = λ_rW_r + d² − τ_rr) equals the closed
    form Gent one: ΔP̂ and p̂ across a loaded wall to 1e-12."""
    tube = jd.Tube(**LOADED)
    r = jnp.linspace(1.15, 1.5, 7)
    closed = jax.jit(bs.base_state)(tube, r)
    general = jax.jit(bs.base_state)(tube.replace(material=GENT_AS_ENERGY), r)
    np.testing.assert_allclose(general.pressure, closed.pressure, rtol=1e-12)


# ------------------------------------------------------------------ frequencies


def test_every_material_at_rest_is_the_linear_cylinder():
    """docs/theory/real_tubes.md §7(a): at λ_i = λ_z = 1, V̂ = 0 every normalised material gives the
    exact linear cylinder, m = 1, α̂ = 0.534: Ω = 0.27304509, 1.22366123, 2.72102485."""
    exact = [0.27304509, 1.22366123, 2.72102485]
    for material in (*GENERAL.values(), mt.MooneyRivlin(1.0)):
        tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85, material=material)
        got = jd.frequencies(tube, jnp.asarray(0.534), n_roots=3, omega_max=3.0, m=1)
        np.testing.assert_allclose(got, exact, rtol=1e-8)


@pytest.mark.parametrize("m, torsional", [(0, False), (2, False), (0, True)])
def test_equal_materials_give_equal_frequencies(m, torsional):
    """On a loaded wall: Ogden((1,), (2,)) = neo-Hookean, GentGent(G, 0) = Gent(G) and a user's
    Gent energy = Gent (general route against the closed forms), to 1e-10; MooneyRivlin(0.2)
    differs from neo-Hookean by far more (pitfall 1: the I_2 term is not a rescaling)."""
    alpha = jnp.asarray(0.8)
    kw = dict(n_roots=3, m=m, torsional=torsional)

    def roots(material):
        return np.asarray(jd.frequencies(jd.Tube(**LOADED, material=material), alpha, **kw))

    neo, gent = roots("neo_hookean"), roots("gent")
    np.testing.assert_allclose(roots(mt.Ogden((1.0,), (2.0,))), neo, rtol=1e-10)
    np.testing.assert_allclose(roots(mt.GentGent(97.2, 0.0)), gent, rtol=1e-10)
    np.testing.assert_allclose(roots(GENT_AS_ENERGY), gent, rtol=1e-10)
    assert np.max(np.abs(roots(mt.MooneyRivlin(0.2)) / neo - 1)) > 1e-3


def test_gradient_in_a_material_parameter():
    """dΩ/dβ of MooneyRivlin through jd.frequency's implicit derivative equals a central
    difference (the material parameter is a differentiable leaf)."""
    alpha = jnp.asarray(0.8)

    def lowest(beta):
        tube = jd.Tube(**LOADED, material=mt.MooneyRivlin(beta))
        return jd.frequencies(tube, alpha, n_roots=1, n_layers=24, scheme="magnus6")[0]

    grad = jax.grad(lowest)(0.2)
    h = 1e-5
    fd = (float(lowest(0.2 + h)) - float(lowest(0.2 - h))) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6)


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("material, message", [
    (mt.Ogden((1.0,), (1.0,)), r"not normalised to unit shear modulus: 2\(W_1 \+ W_2\) .* is 0.5"),
    (mt.Energy(lambda i1, i2, p: p * (i1 - 3.0), 1.0), r"is 2.0, it must be 1"),
    (mt.Energy(lambda i1, i2, p: jnp.log(i1 - 3.0), ()), "energy is not finite at rest"),
    (mt.MooneyRivlin(1.5), r"beta must be in \[0, 1\]"),
    (mt.GentGent(-1.0, 0.2), "gent must be > 0"),
    (mt.Ogden((1.0, 1.0), (2.0,)), "mu and alpha must be tuples of one length"),
    (mt.MooneyRivlin(float("nan")), "every parameter must be a finite real number"),
    ("rubber", "material must be one of"),
    (3, "material must be a name or a material object"),
])
def test_bad_materials_are_named(material, message):
    tube = jd.Tube(**LOADED, material=material)
    with pytest.raises(ValueError, match=message):
        jd.frequencies(tube, jnp.asarray(0.8), n_roots=1)


def test_a_material_closed_over_by_a_callers_jit_is_checked_there():
    """Concrete parameters inside a caller's jit: the check at rest is staged there, so it is
    evaluated op by op and still names an unnormalised material; a normalised one gives the roots
    of the call outside jit."""
    bad = jd.Tube(**LOADED, material=mt.Energy(lambda i1, i2, p: p * (i1 - 3.0), 1.0))
    with pytest.raises(ValueError, match=r"is 2.0, it must be 1"):
        jax.jit(lambda a: jd.frequencies(bad, a, n_roots=1))(0.8)
    good = jd.Tube(**LOADED, material=mt.MooneyRivlin(0.3))
    inside = jax.jit(lambda a: jd.frequencies(good, a, n_roots=2))(0.8)
    np.testing.assert_allclose(inside, jd.frequencies(good, 0.8, n_roots=2), rtol=1e-13)


def test_gent_gent_locking_is_checked():
    """A GentGent wall past its own locking constant is refused by name, and gives NaN under jit."""
    tube = jd.Tube(lambda_i=2.0, lambda_z=1.0, eta=0.85, material=mt.GentGent(1.0, 0.2))
    with pytest.raises(ValueError, match="beyond the Gent locking limit"):
        jd.frequencies(tube, jnp.asarray(0.8), n_roots=1)
    from jaxdea.params import admissible

    assert not bool(jax.jit(admissible)(tube))
    assert bool(jax.jit(admissible)(tube.replace(material=mt.GentGent(100.0, 0.2))))


def test_gent_and_neo_hookean_objects_are_the_named_energies():
    """Gent(G) means material="gent", gent=G; NeoHookean() means material="neo_hookean"."""
    tube = jd.Tube(material=mt.Gent(12.5))
    assert tube.material == "gent" and tube.gent == 12.5
    assert jd.Tube(material=mt.NeoHookean()).material == "neo_hookean"
    leaves = jax.tree_util.tree_leaves(jd.Tube(material=mt.Ogden((1.2, 0.4), (1.5, 0.5))))
    assert len(leaves) == 6 + 4
