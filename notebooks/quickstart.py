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
# # jaxdea quickstart
#
# A pre-stretched dielectric elastomer tube (the paper's: η = R_i/R_o = 0.85, λ_z = 1.2, Gent G = 97.2)
# under a radial voltage V̂: its axisymmetric dispersion curve, phase and group velocity, an exact
# gradient dΩ/dV̂, the critical voltage and a mode shape. Everything is dimensionless
# (Ω = ωR_i/c_s, α̂ = αR_i, V̂ = V√(ε/μ)/R_i). `JAXDEA_NOTEBOOK_FAST=1` runs it on coarse grids.
#
# The first call of each solver compiles it (a minute or two in all on a small machine, cell by
# cell); later calls reuse the compiled programs and take milliseconds.

# %%
import os

import jax
import matplotlib.pyplot as plt
import numpy as np

jax.config.update("jax_enable_x64", True)  # jaxdea refuses to compute in float32
import jaxdea as jd  # noqa: E402

jd.configure()  # opt in: compiled programs cached on disk, XLA's loop threshold

FAST = os.environ.get("JAXDEA_NOTEBOOK_FAST") == "1"
points = 12 if FAST else 60

# %% [markdown]
# ## One dispersion curve: the three lowest frequencies against α̂

# %%
tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85)
alphas = np.linspace(0.05, 3.0, points)
curve = jd.sweep(tube, alpha=alphas, n_roots=3, jacobian=["voltage"])
print(curve)

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
ax1.plot(alphas, curve.omega, marker=".")
ax1.set(xlabel="axial wavenumber α̂", ylabel="frequency Ω", title="dispersion curve (V̂ = 0.1)")
ax2.plot(alphas, curve.phase_velocity, marker=".")
ax2.set(xlabel="α̂", ylabel="phase velocity Ω/α̂", ylim=(0, 6))
fig.tight_layout()
plt.show()


# %% [markdown]
# ## A finer curve by continuation
# `jaxdea.dispersion_curve` predicts the roots at the next α̂ from the last three, corrects them by
# Newton and checks the step (ordering, distance, and the alternating signs of f(0), f'(Ω_k)); the
# guaranteed scan of `frequencies` runs only where a check fails. The same roots to the 1e-8 that
# every default call promises (a concrete curve chooses and checks its own sublayers, fewer than
# the points': docs/howto/accuracy.md; here 6.6e-10 apart), several times faster than scanning
# every α̂.

# %%
fine = np.linspace(0.05, 3.0, 4 * (points - 1) + 1)  # holds every α̂ of the sweep above
continued = jd.dispersion_curve(tube, fine, n_roots=3)
print(f"{fine.size} α̂, scanned at {int(continued.scanned.sum())} of them")
assert np.allclose(continued.omega[::4], curve.omega, rtol=1e-8, atol=0.0, equal_nan=True)
fig, ax = plt.subplots(figsize=(5, 4))
ax.plot(fine, continued.omega, lw=1)
ax.plot(alphas, curve.omega, ".", color="k")
ax.set(xlabel="α̂", ylabel="Ω", title="continuation (lines) and the sweep (dots)")
plt.show()


# %% [markdown]
# ## An exact gradient
# `jaxdea.frequency` refines one root by safeguarded Newton and carries implicit-function derivatives
# dΩ/dθ = −(∂f/∂θ)/(∂f/∂Ω). Check it against a central difference.

# %%
alpha = jd.axial_wavenumber(tube, 1)
omega0 = float(jd.frequencies(tube, alpha, n_roots=1)[0])


def lowest(v):
    return jd.frequency(tube.replace(voltage=v), alpha, omega0)


grad = float(jax.grad(lowest)(0.1))
h = 1e-5
fd = (float(lowest(0.1 + h)) - float(lowest(0.1 - h))) / (2 * h)
print(f"Ω = {omega0:.6f}, dΩ/dV̂ = {grad:.8f} (central difference {fd:.8f})")
assert abs(grad - fd) < 1e-6 * abs(grad)

# %% [markdown]
# The sweep above carried the same derivative at every point (`jacobian=["voltage"]`) and the group
# velocity dΩ/dα̂ by the implicit function theorem:

# %%
dw_dv = curve.derivative("voltage")
print("dΩ/dV̂ of the lowest branch at the first points:", np.round(dw_dv[:4, 0], 5))
print("group velocity of the lowest branch:", np.round(curve.group_velocity[:4, 0], 5))

# %% [markdown]
# ## Critical voltage and a mode shape
# The critical voltage is the smallest V̂ at which the lowest frequency of mode n reaches zero.

# %%
v_cr = float(jd.critical_voltage(tube, alpha))
print(f"V̂_cr(n = 1) = {v_cr:.5f}")
near = float(jd.frequencies(tube.replace(voltage=0.99 * v_cr), alpha, n_roots=1)[0])
print(f"lowest Ω at 0.99 V̂_cr: {near:.5f} (→ 0 at V̂_cr)")

r, fields = jd.mode_shape(tube, alpha, omega0)
fig, ax = plt.subplots(figsize=(5, 3.5))
ax.plot(r, fields[0], label="radial ū")
ax.plot(r, fields[1], label="axial w̄")
ax.set(xlabel="radius r̂", ylabel="displacement (max = 1)", title=f"mode shape at Ω = {omega0:.4f}")
ax.legend()
plt.show()
