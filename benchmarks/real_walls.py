"""The cost of real walls, side by side with the single Gent wall (issue "real walls").

    python3 benchmarks/real_walls.py [--points 200] [--repeats 7]

Rows (best and median of ``repeats`` rounds; in each round the calls run one after another, so a
changing load hits them alike), each against the single closed-form Gent wall (G = 97.2, λ_i = 0.9,
λ_z = 1.2, η = 0.85; V̂ = 0 and 0.05):

* ``dispersion_curve``: ``points`` α̂ in [0.1, 5], 4 roots, default accuracy;
* ``frequencies``: one call at α̂ = 0.445, 4 roots.

The walls:

* ``3 layers``: the §7(d) sandwich of docs/theory/real_tubes.md (liner and encapsulation of 0.2 of
  the wall, neo-Hookean, 3× as stiff, densities 1.2 and 0.8; the Gent DE layer active between);
* ``3 identical layers``: Gent, 0.3 | 0.4 (active) | 0.3, the single wall's roots at V̂ = 0;
* ``autodiff energy``: ``jd.Energy`` of the Gent W(I₁) written by the user, its moduli by automatic
  differentiation (the single wall's roots to rounding).

Goals: a three-layer wall ≤ 1.5×, an autodiff energy ≤ 1.2× the single wall on the same curve. The
result is printed as a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxdea as jd  # noqa: E402

jd.configure()

GENT = jd.Gent(97.2)
BASE = dict(lambda_i=0.9, lambda_z=1.2, eta=0.85)
SANDWICH = (jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=1.2),
            jd.Layer(0.6, GENT, active=True),
            jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=0.8))
IDENTICAL = (jd.Layer(0.3, GENT), jd.Layer(0.4, GENT, active=True), jd.Layer(0.3, GENT))


def gent_energy(i1, i2, params):
    """W = −(G/2) ln(1 − (I₁ − 3)/G), the Gent energy as a user writes it."""
    return -0.5 * params["G"] * jnp.log1p(-(i1 - 3.0) / params["G"])


def walls(voltage):
    single = jd.Tube(voltage=voltage, **BASE)
    return {"single Gent wall": single,
            "3 layers": single.replace(layers=SANDWICH),
            "3 identical layers": single.replace(layers=IDENTICAL),
            "autodiff energy": single.replace(material=jd.Energy(gent_energy, {"G": 97.2}))}


def block(x):
    return jax.block_until_ready(x)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    alpha = np.linspace(0.1, 5.0, args.points)
    calls, curves = {}, {}
    for voltage in (0.0, 0.05):
        for label, tube in walls(voltage).items():
            calls[("dispersion_curve", voltage, label)] = (
                lambda tube=tube: jd.dispersion_curve(tube, alpha, n_roots=4))
            calls[("frequencies", voltage, label)] = (
                lambda tube=tube: jd.frequencies(tube, 0.445, n_roots=4))
    for key, call in calls.items():  # compile, and keep the curves for the checks
        out = call()
        block(out.omega if key[0] == "dispersion_curve" else out)
        if key[0] == "dispersion_curve":
            curves[key[1:]] = out
    times = {key: [] for key in calls}
    for _ in range(args.repeats):
        for key, call in calls.items():
            start = time.perf_counter()
            out = call()
            block(out.omega if key[0] == "dispersion_curve" else out)
            times[key].append(time.perf_counter() - start)
    print(f"{args.points} α̂, {args.repeats} rounds; load {os.getloadavg()[0]:.2f}\n")
    for (voltage, label), curve in curves.items():
        single = np.asarray(curves[(voltage, "single Gent wall")].omega)
        status = np.asarray(curve.status)
        same = "" if label in ("3 layers",) or (label == "3 identical layers" and voltage) else (
            f", max |Ω/Ω_single − 1| = {np.max(np.abs(np.asarray(curve.omega) / single - 1)):.1e}")
        print(f"- V̂ = {voltage}, {label}: {int(np.sum(status == 0))}/{status.size} roots converged{same}")
    print("\n| row | V̂ | wall | best (ms) | ratio best | ratio median |")
    print("|---|---|---|---|---|---|")
    for (row, voltage, label), t in times.items():
        ref = times[(row, voltage, "single Gent wall")]
        print(f"| {row} | {voltage} | {label} | {1e3 * min(t):.2f} | {min(t) / min(ref):.2f} | "
              f"{statistics.median(t) / statistics.median(ref):.2f} |")


if __name__ == "__main__":
    main()
