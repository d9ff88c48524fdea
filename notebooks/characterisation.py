# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Inverse characterisation: material and geometry from measured resonances
#
# A VHB-like tube (μ = 100 kPa, ρ_s = 1000 kg/m³, ε = 4.7 ε_0, R_i = 5 mm, L = 50 mm, η = 0.85,
# λ_z = 1.2, λ_i = 1, G = 97) is "measured": the resonance peaks of the axisymmetric modes
# (m = 0, n = 1, 2), bending (m = 1, n = 1) and ovalisation (m = 2, n = 1) at a few voltages, with
# 0.5 % Gaussian noise and **no mode labels**. `fit` assigns each peak to a mode (minimum-cost
# matching of log-frequencies at each voltage, redone as the parameters move), estimates μ, λ_i and
# η by Levenberg–Marquardt with the exact Jacobian (implicit derivatives of the roots), and gives
# 95 % intervals from the covariance (JᵀJ)⁻¹ (σ known: normal quantile).
#
# f = Ω c_s/(2π R_i), c_s = sqrt(μ/ρ_s), V̂ = V sqrt(ε/μ)/R_i, α̂_n = 2nπ R_i/(λ_z L).
# `JAXDEA_NOTEBOOK_FAST=1` uses two voltages and a single start.

# %%
import os

import jax
import matplotlib.pyplot as plt
import numpy as np

jax.config.update("jax_enable_x64", True)  # jaxdea refuses to compute in float32
import jax.numpy as jnp  # noqa: E402

import jaxdea as jd  # noqa: E402

jd.configure()  # opt in: compiled programs cached on disk, XLA's loop threshold
from jaxdea.physics.families import Family  # noqa: E402
from jaxdea.studies.fit import NAMES, dimensionless, fit, mode_roots  # noqa: E402
from jaxdea.units import VACUUM_PERMITTIVITY, Scales, tube_from_si  # noqa: E402

FAST = os.environ.get("JAXDEA_NOTEBOOK_FAST") == "1"
N_LAYERS = 12  # the same N for the synthetic data and the model
truth = dict(shear_modulus=1e5, density=1000.0, permittivity=4.7 * VACUUM_PERMITTIVITY,
             inner_radius=5e-3, length=50e-3, eta=0.85, lambda_i=1.0, lambda_z=1.2, gent=97.0)
scales = Scales(truth["shear_modulus"], truth["density"], truth["permittivity"], truth["inner_radius"])


def tube_at(voltage):
    return tube_from_si(scales, outer_radius=truth["inner_radius"] / truth["eta"],
                        length=truth["length"], voltage=voltage, lambda_i=truth["lambda_i"],
                        lambda_z=truth["lambda_z"], gent=truth["gent"])


print(f"voltage unit R_i sqrt(μ/ε) = {float(scales.voltage_scale) / 1e3:.1f} kV, "
      f"Ω = 1 is {float(scales.omega_to_hz(1.0)):.2f} Hz")

# %% [markdown]
# ## Synthetic measurement
#
# The voltages stay below the tube's first instability (smallest critical voltage over m ≤ 3,
# n ≤ 3; checked in the full run).

# %%
voltages = (2e3, 5e3) if FAST else (1e3, 3e3, 5e3, 7e3)
if not FAST:
    first = jd.first_instability(tube_at(0.0), n_max=3, m_max=3, n_layers=N_LAYERS)
    v_first = float(scales.voltage_to_si(first.voltage))
    print(f"first instability (m, n) = ({int(first.m)}, {int(first.n)}) at {v_first / 1e3:.2f} kV")
    assert max(voltages) < 0.5 * v_first
modes = ((0, 1), (0, 2), (1, 1), (2, 1))
rng = np.random.default_rng(7)
rows = []
for v in voltages:
    tube = tube_at(v)
    for m, n in modes:
        omega = jd.frequencies(tube, jd.axial_wavenumber(tube, n), n_roots=1, m=m,
                               n_layers=N_LAYERS)[0]
        f_true = float(scales.omega_to_hz(omega))
        rows.append((v, f_true * (1 + 0.005 * rng.standard_normal()), 0.005 * f_true, m, n))
table = np.array(rows)
data = dict(voltage_V=table[:, 0], frequency_Hz=table[:, 1], sigma_Hz=table[:, 2])
true_labels = np.stack([table[:, 3], table[:, 4], 0 * table[:, 3]], axis=1).astype(int)
for row in rows:
    print(f"V = {row[0] / 1e3:.0f} kV: {row[1]:8.2f} Hz ± {row[2]:.2f}  (hidden label m={row[3]}, n={row[4]})")

# %% [markdown]
# ## Fit: μ, λ_i and η free, the peaks unlabelled
#
# The starts are a coarse grid inside the bounds (the best by initial assignment cost are fitted).

# %%
free = dict(shear_modulus=(5e4, 2e5), lambda_i=(0.8, 1.2), eta=(0.7, 0.95))
fixed = {k: v for k, v in truth.items() if k not in free}
result = fit(data, free, fixed, n_layers=N_LAYERS, m_max=2, n_max=2, n_branches=1,
                     n_starts=1 if FAST else 3, grid_points=3)
print(result.status.name, "after", result.iterations, "iterations")
for name in result.names:
    low, high = result.interval[name]
    i = result.names.index(name)
    std = np.sqrt(result.covariance[i, i])
    print(f"{name:14s} truth {truth[name]:.6g}  estimate {result.estimate[name]:.6g}  "
          f"95 % interval ({low:.6g}, {high:.6g})  {(result.estimate[name] - truth[name]) / std:+.2f} σ")
    assert abs(result.estimate[name] - truth[name]) < 4 * std
print("correlation\n", np.round(result.correlation, 3))
np.testing.assert_array_equal(result.assignment, true_labels)
chi2 = float(np.sum(result.residuals**2))
print(f"χ² = {chi2:.2f} for {len(rows) - len(free)} degrees of freedom")

# %% [markdown]
# ## Data against the fitted Hz(V)

# %%
values = jnp.array([result.estimate.get(k, truth.get(k, 1.0)) for k in NAMES[:9]] + [0.0, 1.0, 1.0])
grid = np.linspace(0.0, max(voltages) * 1.1, 8 if FAST else 32)  # batch sizes the fit compiled
hz = float(dimensionless(values, 0.0, 1.0)[3])
fig, ax = plt.subplots(figsize=(7, 4.5))
for (m, n), colour in zip(modes, ("C0", "C1", "C2", "C3"), strict=True):
    count = grid.size
    curve = mode_roots(values, jnp.asarray(grid), jnp.full(count, float(n)),
                               jnp.full(count, float(m)), 1, N_LAYERS, None, None,
                       Family.LONGITUDINAL if m == 0 else Family.ORDER_M)[:, 0]
    ax.plot(grid / 1e3, np.asarray(curve) * hz, color=colour, label=f"fit m={m}, n={n}")
    pick = (result.assignment[:, 0] == m) & (result.assignment[:, 1] == n)
    ax.errorbar(data["voltage_V"][pick] / 1e3, data["frequency_Hz"][pick],
                yerr=2 * data["sigma_Hz"][pick], fmt="o", color=colour)
ax.set_xlabel("voltage (kV)")
ax.set_ylabel("frequency (Hz)")
ax.legend(fontsize=8)
fig.tight_layout()
plt.show()
