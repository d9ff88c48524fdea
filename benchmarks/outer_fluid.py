"""The cost of a surrounding fluid, side by side with the tube in vacuum (issue "a tube in water").

    python3 benchmarks/outer_fluid.py [--points 200] [--repeats 7]

Rows (best and median of ``repeats`` rounds; in each round the calls run one after another, so a
changing load hits them alike):

* ``dispersion_curve``: ``points`` α̂ in [0.15, 5] of Tube(voltage=0, lambda_i=1, lambda_z=1,
  eta=0.85), 4 roots each (the peer's curve of benchmarks/vmap_idiom.py, from α̂ = 0.15 instead of
  0.01: the goal is for subsonic curves, and below α̂ ≈ 0.11 its fourth root, Ω ≈ 35.6, lies above
  water's sound line ĉ_oα̂ and leaks; at 0.15 it is 27 % below it), in vacuum and in water (ρ̂_o = 1.04, ĉ_o = 324.7: the VHB-like wall of :mod:`jaxdea.units`'
  example; every root subsonic);
* ``frequencies``: one call of that tube at α̂ = 0.445, m = 0 and m = 2, in vacuum and in water;
* ``f and f' at 1000 Ω``: the characteristic function's value and slope (the corrector lanes'
  evaluation, :func:`jaxdea.physics.characteristic.value_and_slope`) at 1000 Ω in [0.1, 5], α̂ = 0.445,
  vmapped: the cost of one evaluation, whatever the roots.

The solvers' counts of evaluations follow the roots: in water at α̂ = 0.445 the scan evaluates f 100
times against 44 in vacuum (its lowest roots, 0.49 and 1.02, crowd where the vacuum's are 0.74 and
1.91), at α̂ = 1.5 44 times in both (counted with a callback).

The goal is ≤ 1.2× the vacuum curve. The result is printed as a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxdea as jd  # noqa: E402

jd.configure()

TUBE = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
WATER = jd.Fluid(density_ratio=998.2 / 960.0, speed_ratio=1482.0 / np.sqrt(20e3 / 960.0))


def block(x):
    return jax.block_until_ready(x)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    alpha = np.linspace(0.15, 5.0, args.points)
    calls = {}
    for label, outer in (("vacuum", None), ("water", WATER)):
        calls[("dispersion_curve", label)] = (
            lambda outer=outer: jd.dispersion_curve(TUBE, alpha, n_roots=4, outer=outer).omega)
        for m in (0, 2):
            calls[(f"frequencies m = {m}", label)] = (
                lambda outer=outer, m=m: jd.frequencies(TUBE, 0.445, m=m, outer=outer))
    from jaxdea.physics import characteristic
    from jaxdea.physics.families import Family
    from jaxdea.physics.transfer import discretize

    omegas = np.linspace(0.1, 5.0, 1000)
    for label, outer in (("vacuum", None), ("water", WATER)):
        wall = discretize(TUBE.replace(outer=outer), 16)
        lanes = jax.jit(jax.vmap(lambda om, wall=wall: characteristic.value_and_slope(
            Family.LONGITUDINAL, wall, om, 0.445)))
        calls[("f and f' at 1000 Ω", label)] = lambda lanes=lanes: lanes(omegas)
    for call in calls.values():  # compile
        block(call())
    times = {key: [] for key in calls}
    for _ in range(args.repeats):
        for key, call in calls.items():
            start = time.perf_counter()
            block(call())
            times[key].append(time.perf_counter() - start)
    curve = jd.dispersion_curve(TUBE, alpha, n_roots=4, outer=WATER)
    vacuum = jd.dispersion_curve(TUBE, alpha, n_roots=4)
    status = np.asarray(curve.status)
    print(f"{args.points} α̂, {args.repeats} rounds; load {os.getloadavg()[0]:.2f}; in water "
          f"{int(np.sum(status == 0))} roots converged, {int(np.sum(status == 1))} above the sound line "
          f"(NO_ROOT), {int(np.sum(status > 1))} other; lowest root at α̂ = 1: "
          f"{float(np.interp(1.0, alpha, vacuum.omega[:, 0])):.5f} (vacuum), "
          f"{float(np.interp(1.0, alpha, curve.omega[:, 0])):.5f} (water)\n")
    print("| row | vacuum best (ms) | water best (ms) | ratio best | ratio median |")
    print("|---|---|---|---|---|")
    for row in ("f and f' at 1000 Ω", "dispersion_curve", "frequencies m = 0", "frequencies m = 2"):
        vac, wat = times[(row, "vacuum")], times[(row, "water")]
        print(f"| {row} | {1e3 * min(vac):.2f} | {1e3 * min(wat):.2f} | {min(wat) / min(vac):.2f} | "
              f"{statistics.median(wat) / statistics.median(vac):.2f} |")


if __name__ == "__main__":
    main()
