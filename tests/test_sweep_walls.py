"""Sweeps over real walls (issue 44, "users' terms"): a tube of a material object, axes and
jacobians over the material's and the layers' parameters, each point against jaxdea.frequencies of
the tube built by hand; the active layer absorbs a passive layer's fraction."""

import dataclasses

import jax
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics.leaves import apply_parameters, wall_names
from jaxdea.studies import sweeps as sweep_module
from jaxdea.studies.sweeps import SweepResult, sweep

EQUAL = dict(n_layers=12, scheme="magnus6")  # one discretisation for the sweep and the single solves
MOONEY = jd.Tube(voltage=0.02, lambda_i=1.1, lambda_z=1.2, eta=0.8, material=jd.MooneyRivlin(0.2))
LINER = jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0)
SANDWICH = jd.Tube(voltage=0.02, lambda_i=1.1, lambda_z=1.2, eta=0.8,
                   layers=(LINER, jd.Layer(0.6, jd.Gent(97.2), active=True), LINER))


def _with_layer(tube, k, **changes):
    layers = list(tube.layers)
    layers[k] = dataclasses.replace(layers[k], **changes)
    return tube.replace(layers=tuple(layers))


def test_sweep_of_a_mooney_rivlin_tube_and_its_beta(tmp_path):
    """A MooneyRivlin tube sweeps (it was refused: material must be a str); the axis material_beta
    gives jaxdea.frequencies of MooneyRivlin(β) at each point to 1e-12, and dΩ/dβ that of jax.grad
    to 1e-9; the settings name the material."""
    res = sweep(MOONEY, alpha=0.8, material_beta=[0.1, 0.3], n_roots=2, jacobian=["material_beta"],
                progress=False, **EQUAL)
    tube = MOONEY.replace(material=jd.MooneyRivlin(0.3))
    np.testing.assert_allclose(res.omega[0, 1], jd.frequencies(tube, 0.8, n_roots=2, **EQUAL),
                               rtol=1e-12)
    grad = jax.grad(lambda b: jd.frequencies(MOONEY.replace(material=jd.MooneyRivlin(b)), 0.8,
                                             n_roots=1, **EQUAL)[0])(0.3)
    np.testing.assert_allclose(res.derivative("material_beta")[0, 1, 0], grad, rtol=1e-9)
    assert res.settings["material"] == {"kind": "mooney_rivlin", "beta": 0.2}
    res.to_npz(tmp_path / "walls.npz")
    assert SweepResult.from_npz(tmp_path / "walls.npz").settings == res.settings


def test_sweep_over_the_encapsulation_takes_its_fraction_from_the_active_layer():
    """Axes layer2_fraction and layer2_shear_ratio of the sandwich: the point (0.3, 10) equals
    jaxdea.frequencies of the wall built by hand (liner 0.2, active 0.5, encapsulation 0.3 of
    shear ratio 10) to 1e-12; the derivatives in both match central differences to 1e-6."""
    res = sweep(SANDWICH, alpha=0.8, layer2_fraction=[0.1, 0.3], layer2_shear_ratio=[3.0, 10.0],
                n_roots=2, jacobian=["layer2_fraction", "layer2_shear_ratio"], progress=False, **EQUAL)
    assert np.all(res.status == jd.Status.CONVERGED)
    by_hand = _with_layer(_with_layer(SANDWICH, 2, fraction=0.3, shear_ratio=10.0), 1, fraction=0.5)
    np.testing.assert_allclose(res.omega[0, 1, 1], jd.frequencies(by_hand, 0.8, n_roots=2, **EQUAL),
                               rtol=1e-12)
    h = 1e-5
    for name, value in (("layer2_fraction", 0.3), ("layer2_shear_ratio", 10.0)):
        moved = [apply_parameters(by_hand, 0.8, None, {name: value + s * h})[0] for s in (1, -1)]
        up, down = (jd.frequencies(t, 0.8, n_roots=1, **EQUAL)[0] for t in moved)
        np.testing.assert_allclose(res.derivative(name)[0, 1, 1, 0], (up - down) / (2 * h), rtol=1e-6)


def test_an_emptied_active_layer_is_an_invalid_point():
    """layer0_fraction = 0.8 with the encapsulation at 0.2 leaves the active layer nothing: that
    point is NaN, status INVALID, and the others are solved."""
    res = sweep(SANDWICH, alpha=0.8, layer0_fraction=[0.2, 0.8], n_roots=1, progress=False, **EQUAL)
    assert res.status[0, 0, 0] == jd.Status.CONVERGED
    assert res.status[0, 1, 0] == jd.Status.INVALID and np.isnan(res.omega[0, 1, 0])


def test_wall_names_and_their_errors():
    """The names a tube's wall offers, and a ValueError that says why for the others."""
    assert wall_names(MOONEY) == ("material_beta",)
    assert wall_names(SANDWICH) == ("layer0_fraction", "layer0_shear_ratio", "layer0_density_ratio",
                                    "layer1_material_gent", "layer2_fraction", "layer2_shear_ratio",
                                    "layer2_density_ratio")
    moved = apply_parameters(SANDWICH, 0.8, None, {"layer0_fraction": 0.1, "layer2_fraction": 0.3})[0]
    assert [float(layer.fraction) for layer in moved.layers] == [0.1, 0.6, 0.3]
    cases = [(SANDWICH, "layer1_fraction", "active layer's fraction follows the others"),
             (SANDWICH, "layer3_fraction", "the tube has 3 layers"),
             (SANDWICH, "layer1_shear_ratio", "its ratios are 1"),
             (jd.Tube(), "material_beta", "need a material object"),
             (MOONEY, "material_gent", "has no scalar parameter 'gent'")]
    for tube, name, message in cases:
        with pytest.raises(ValueError, match=message):
            sweep(tube, alpha=0.8, progress=False, **{name: [0.1]})
        with pytest.raises(ValueError, match=message):
            sweep(tube, alpha=0.8, progress=False, jacobian=[name])


def test_saved_attributes_name_each_layer():
    """The netCDF attributes of a layered sweep give each layer's fixed values as layer<k>_<field>,
    without the swept ones and without the active fraction that follows them."""
    settings = sweep_module._settings(SANDWICH, None, 2, None, 12)
    res = SweepResult(axes={"alpha": np.array([0.8]), "layer2_fraction": np.array([0.1, 0.3])},
                      omega=np.zeros((1, 2, 2)), status=np.zeros((1, 2, 2), np.int32),
                      alpha=np.full((1, 2), 0.8), settings=settings)
    attrs = res._attributes()
    assert attrs["layer0_fraction"] == 0.2 and attrs["layer0_material_kind"] == "neo_hookean"
    assert attrs["layer1_material_gent"] == 97.2 and attrs["layer1_active"] == 1
    assert attrs["layer2_shear_ratio"] == 3.0
    assert "layer2_fraction" not in attrs and "layer1_fraction" not in attrs


OGDEN = jd.Ogden(mu=(0.6, 0.4 / 3.0), alpha=(2.0, 6.0))  # shares 0.6 and 0.4 of μ (Σ μ_kα_k = 2)


def test_sweep_over_an_ogden_exponent_keeps_the_shear_modulus():
    """Ogden's exponents are axes (``material_alpha<k>``; its tuples were no names): α_0 = 1.5 keeps
    the term's share 0.6 of the unit shear modulus, μ_0 = 2·0.6/1.5, built by hand here and
    normalised (2(W_1 + W_2) = 1 at rest, to 1e-14); each point equals jaxdea.frequencies of that
    material to 1e-12, and dΩ/dα_0 a central difference of the hand-built family to 1e-6."""
    tube = MOONEY.replace(material=OGDEN)
    assert "material_alpha0" in wall_names(tube) and "material_alpha1" in wall_names(tube)
    res = sweep(tube, alpha=0.8, material_alpha0=[1.5, 2.0], n_roots=2,
                jacobian=["material_alpha0"], progress=False, **EQUAL)
    assert np.all(res.status == jd.Status.CONVERGED)

    def by_hand(a0):
        return tube.replace(material=jd.Ogden(mu=(2 * 0.6 / a0, 0.4 / 3.0), alpha=(a0, 6.0)))

    assert float(by_hand(1.5).material.shear_modulus()) == pytest.approx(1.0, abs=1e-14)
    for i, a0 in enumerate((1.5, 2.0)):
        np.testing.assert_allclose(res.omega[0, i], jd.frequencies(by_hand(a0), 0.8, n_roots=2,
                                                                   **EQUAL), rtol=1e-12)
    assert abs(res.omega[0, 0, 0] / res.omega[0, 1, 0] - 1) > 1e-3  # the exponent matters
    h = 1e-5
    up, down = (jd.frequencies(by_hand(1.5 + s * h), 0.8, n_roots=1, **EQUAL)[0] for s in (1, -1))
    np.testing.assert_allclose(res.derivative("material_alpha0")[0, 0, 0], (up - down) / (2 * h),
                               rtol=1e-6)


def test_trace_along_wall_names():
    """trace_branch follows a branch along a passive layer's shear ratio and along a layer's Ogden
    exponent (both were refused: unknown parameter); traced points equal jaxdea.frequencies of the
    walls built by hand to 1e-11."""
    tube = _with_layer(SANDWICH, 2, material=OGDEN)
    omega = float(jd.frequencies(tube, 0.8, n_roots=1, **EQUAL)[0])
    branch = jd.trace_branch(tube, 0.8, omega, along="layer2_shear_ratio", stop=8.0, **EQUAL)
    k = int(branch.n_points)
    assert branch.status == jd.BranchEnd.REACHED_STOP and k >= 3
    for j in (k // 2, k - 1):
        s = float(branch.parameter[j])
        built = _with_layer(tube, 2, shear_ratio=s)
        np.testing.assert_allclose(branch.omega[j], jd.frequencies(built, 0.8, n_roots=1, **EQUAL)[0],
                                   rtol=1e-11)
    branch = jd.trace_branch(tube, 0.8, omega, along="layer2_material_alpha1", stop=3.0, **EQUAL)
    k = int(branch.n_points)
    assert branch.status == jd.BranchEnd.REACHED_STOP
    a1 = float(branch.parameter[k - 1])
    built = _with_layer(tube, 2, material=jd.Ogden(mu=(0.6, 0.4 * 2 / a1), alpha=(2.0, a1)))
    np.testing.assert_allclose(branch.omega[k - 1], jd.frequencies(built, 0.8, n_roots=1, **EQUAL)[0],
                               rtol=1e-11)
