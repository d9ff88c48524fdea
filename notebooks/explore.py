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
# # Interactive explorer
#
# `jaxdea.explore()` opens an ipywidgets app (`pip install "jaxdea[explore]"`): sliders for the
# voltage V̂, the stretches λ_i and λ_z, the radius ratio η, the Gent constant G, the fluid's ρ̂_f and
# ĉ_f and the circumferential order m; toggles for the empty or filled tube and the coupling. It
# draws the dispersion curves Ω(α̂) of the three lowest branches (by continuation,
# `jaxdea.dispersion_curve`), their phase velocities Ω/α̂, the axial modes n of the tube's length on
# both, and the stability status against `jaxdea.first_instability` (the plots are shaded once V̂
# reaches the first critical voltage). A click on a curve (or the α̂ and branch controls) shows that
# root's mode shape in the right-hand panel. Moving a slider reuses the compiled solvers; the first
# use of each kind of problem (empty or filled, each coupling, m = 0 or m ≥ 1) compiles it.

# %%
import os

import jax
import numpy as np
from IPython.display import Image, display

jax.config.update("jax_enable_x64", True)  # jaxdea refuses to compute in float32
import jaxdea as jd  # noqa: E402

jd.configure()  # opt in: compiled programs cached on disk, XLA's loop threshold
from jaxdea.apps.explore import explorer_data  # noqa: E402

FAST = os.environ.get("JAXDEA_NOTEBOOK_FAST") == "1"
tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85)  # the paper's tube
app = jd.explore(tube, m_max=2 if FAST else 4)
app

# %% [markdown]
# ## What the app shows
# The paper's tube at V̂ = 0.1 is past its first instability: ring buckling (m = 2, n = 1) sets in at
# V̂ ≈ 0.0293, a tenth of the axisymmetric critical voltage, so the plots are shaded. The arrays
# drawn come from the pure function `jaxdea.apps.explore.explorer_data`, the same curve as
# `dispersion_curve` on the app's grid (the α̂ grid with the axial modes' α̂_n inserted).

# %%
app.wait()  # the first-instability solve of a new wall runs in the background
print(app.status.text)
assert app.status.unstable and (app.status.m, app.status.n) == (2, 1)
curve = jd.dispersion_curve(tube, app.data.alpha, n_roots=3)
assert np.allclose(app.data.omega, curve.omega, rtol=1e-12)
display(Image(app.png(), width=900))  # a still of the figure (the page is static)

# %% [markdown]
# ## Moving the sliders
# Setting a control's value redraws at once (in a notebook the sliders do it); `app.set` changes
# several controls with one redraw. Below the first critical voltage the state is stable.

# %%
app.controls["voltage"].value = 0.02
print(app.status.text)
assert not app.status.unstable
assert np.allclose(app.data.omega, explorer_data(tube.replace(voltage=0.02)).omega, rtol=1e-12)

# %% [markdown]
# ## A mode shape
# `app.select(alpha, branch)` is what a click on a curve does: the root of that branch (0 = the
# lowest) at the grid α̂ nearest to `alpha`, and its `jaxdea.mode_shape` in the side panel.

# %%
alpha_1 = float(jd.axial_wavenumber(tube, 1))
alpha, omega, r, fields = app.select(alpha_1, 0)
print(f"α̂ = {alpha:.4f}, Ω = {omega:.5f}")
assert np.allclose(fields, jd.mode_shape(tube.replace(voltage=0.02), alpha, omega)[1], atol=1e-10)
display(Image(app.png(), width=900))  # a still of the figure (the page is static)

# %% [markdown]
# ## Invalid values
# A wall stretched past Gent locking (here G = 0.1) cannot be solved: the app shows the message
# instead of raising, and recovers when the value is valid again.

# %%
app.controls["gent"].value = 0.1
print(app.error)
assert app.data is None and "Gent locking" in app.error
app.controls["gent"].value = 97.2
assert app.error is None
