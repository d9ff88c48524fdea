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
# # Sensitivity maps
#
# `jaxdea.sweep(..., jacobian=True)` returns, at every grid point, the derivatives of each frequency
# with respect to the design parameters θ = (V̂, λ_i, λ_z, ρ̂_f, ĉ_f, h/R_i, G), from the implicit
# function theorem dΩ/dθ = −(∂f/∂θ)/(∂f/∂Ω) (no differentiation through the root iterations).
# Here: the lowest frequency of mode n = 1 of the paper's fluid-filled tube over a (V̂, λ_i) grid,
# its sensitivity maps, and one entry checked against a central difference.
# `JAXDEA_NOTEBOOK_FAST=1` uses a coarse grid.

# %%
import os

import jax
import matplotlib.pyplot as plt
import numpy as np

jax.config.update("jax_enable_x64", True)
import jaxdea as jd  # noqa: E402

jd.configure()  # opt in: compiled programs cached on disk, XLA's loop threshold

FAST = os.environ.get("JAXDEA_NOTEBOOK_FAST") == "1"
k = 4 if FAST else 16
tube = jd.Tube(lambda_z=1.2, eta=0.85)
fluid = jd.Fluid(density_ratio=0.13, speed_ratio=0.27)  # acoustic coupling
voltages = np.linspace(0.0, 0.12, k)
stretches = np.linspace(0.9, 1.1, k)

# %%
res = jd.sweep(tube, fluid, n_roots=1, jacobian=True, voltage=voltages, lambda_i=stretches, n=1)
print(res)
print("derivatives with respect to:", res.jacobian_names)

# %% [markdown]
# ## Maps of Ω and of its derivatives

# %%
names = ["voltage", "lambda_i", "density_ratio", "speed_ratio", "thickness_ratio"]
fig, axes = plt.subplots(2, 3, figsize=(13, 7))
extent = (stretches[0], stretches[-1], voltages[0], voltages[-1])
maps = [("Ω", res.omega[..., 0, 0])] + [(f"dΩ/d{n}", res.derivative(n)[..., 0, 0]) for n in names]
for ax, (title, values) in zip(axes.flat, maps, strict=True):
    im = ax.imshow(values, origin="lower", aspect="auto", extent=extent)
    ax.set(title=title, xlabel="λ_i", ylabel="V̂")
    fig.colorbar(im, ax=ax)
fig.tight_layout()
plt.show()


# %% [markdown]
# ## Check one entry against a central difference
# dΩ/dV̂ at one grid point, from two direct root solves (`jaxdea.frequency`) at V̂ ± h.

# %%
i, j = k // 2, k // 3
point = tube.replace(voltage=voltages[i], lambda_i=stretches[j])
alpha = jd.axial_wavenumber(point, 1)
omega = res.omega[i, j, 0, 0]
h = 1e-5
fd = (float(jd.frequency(point.replace(voltage=voltages[i] + h), alpha, omega, fluid))
      - float(jd.frequency(point.replace(voltage=voltages[i] - h), alpha, omega, fluid))) / (2 * h)
exact = res.derivative("voltage")[i, j, 0, 0]
print(f"dΩ/dV̂ at V̂ = {voltages[i]:.3f}, λ_i = {stretches[j]:.3f}: sweep {exact:.9f}, "
      f"central difference {fd:.9f}")
assert abs(exact - fd) <= 1e-6 * max(abs(exact), 1e-3)

# %% [markdown]
# The most effective knob per unit change, over the map: the largest |dΩ/dθ| of each parameter.

# %%
for name in names:
    d = res.derivative(name)[..., 0, 0]
    print(f"max |dΩ/d{name:15s}| = {np.nanmax(np.abs(d)):.4g}")
