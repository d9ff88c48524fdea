"""The cost of complex roots, side by side with the elastic paths they generalise (issue "damping
and complex roots", performance goals).

    python3 benchmarks/complex_curves.py [--points 200] [--repeats 5]

Rows (best and median of ``repeats`` rounds; in each round the calls run one after another, so a
changing load hits them alike), on the unstretched tube Tube(voltage=0, lambda_i=1, lambda_z=1,
eta=0.85), m = 0, 4 roots:

* the elastic ``dispersion_curve`` at ``points`` α̂ in [0.15, 3] (the reference of every goal);
* ``wavenumber_curve`` of the tube with Hysteretic(0.05) at ``points`` Ω in [0.5, 3]: the whole call
  (the certified search at the first Ω, then the continuation) and the continuation alone
  (``complex_curves._curves`` from those roots);
* ``complex_dispersion_curve`` of the tube with KelvinVoigt(0.05) on the α̂ grid: the whole call and
  the continuation alone;
* ``complex_frequencies`` (KelvinVoigt(0.05)) against ``frequencies`` (elastic) at α̂ = 0.445.

The goals are ≤ 3× the elastic curve (wavenumbers at 200 frequencies, a complex curve) and ≤ 3×
``frequencies``. The result is printed as a Markdown table.
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
from jaxdea.physics.characteristic import Unknown  # noqa: E402
from jaxdea.physics.problem import NO_ALPHA, describe  # noqa: E402
from jaxdea.physics.transfer import laminate  # noqa: E402
from jaxdea.solve import complex_curves  # noqa: E402
from jaxdea.solve.wavenumbers import default_alpha_max  # noqa: E402

jd.configure()


def _continuation(tube, grid, starts, unknown, reach, n_roots):
    """The continuation of complex_curves alone, from given roots: its checked default
    discretisation (started where the library starts it, refined where its check asks) without
    the first point's search."""
    problem = describe(tube, NO_ALPHA if unknown is Unknown.ALPHA else float(grid[0]), None, None, None,
                       0, False, damped=True)
    layers = laminate(None, None, tube, reach, n_roots, 0, checked=True)
    return lambda: jax.block_until_ready(complex_curves._checked(
        problem, tube, layers, None, 0, np.asarray(grid), starts, unknown, True))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    elastic = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
    hysteretic = elastic.replace(damping=jd.Hysteretic(0.05))
    kelvin = elastic.replace(damping=jd.KelvinVoigt(0.05))
    alphas = np.linspace(0.15, 3.0, args.points)
    omegas = np.linspace(0.5, 3.0, args.points)
    first_alpha = jd.wavenumbers(hysteretic, float(omegas[0]), n_roots=4).alpha
    first_omega = jd.complex_frequencies(kelvin, float(alphas[0]), n_roots=4).omega
    problem = describe(hysteretic, NO_ALPHA, None, None, None, 0, False, damped=True)
    reach = max(default_alpha_max(problem, hysteretic, float(omegas[-1]), None),
                float(np.max(np.abs(np.asarray(first_alpha)))))  # as wavenumber_curve
    block = jax.block_until_ready
    calls = {
        "dispersion_curve (elastic, reference)":
            lambda: block(jd.dispersion_curve(elastic, alphas, n_roots=4)),
        "wavenumber_curve, whole call":
            lambda: block(jd.wavenumber_curve(hysteretic, omegas, n_roots=4)),
        "wavenumber_curve, continuation alone":
            _continuation(hysteretic, omegas, first_alpha, Unknown.ALPHA, reach, 4),
        "complex_dispersion_curve, whole call":
            lambda: block(jd.complex_dispersion_curve(kelvin, alphas, n_roots=4)),
        "complex_dispersion_curve, continuation alone":
            _continuation(kelvin, alphas, first_omega, Unknown.OMEGA, float(alphas[-1]), 4),
        "frequencies (elastic, α̂ = 0.445)": lambda: block(jd.frequencies(elastic, 0.445, n_roots=4)),
        "complex_frequencies (α̂ = 0.445)":
            lambda: block(jd.complex_frequencies(kelvin, 0.445, n_roots=4)),
    }
    for call in calls.values():  # compile
        call()
    times = {name: [] for name in calls}
    for _ in range(args.repeats):
        for name, call in calls.items():
            start = time.perf_counter()
            call()
            times[name].append(time.perf_counter() - start)
    reference = {"curve": min(times["dispersion_curve (elastic, reference)"]),
                 "frequencies": min(times["frequencies (elastic, α̂ = 0.445)"])}
    print(f"load average {os.getloadavg()[0]:.1f}; {args.points} points, 4 roots, "
          f"{args.repeats} rounds\n")
    print("| call | best (ms) | median (ms) | best / elastic reference |")
    print("|---|---|---|---|")
    for name, values in times.items():
        ref = reference["frequencies" if "frequencies (" in name else "curve"]
        print(f"| {name} | {1e3 * min(values):.1f} | {1e3 * statistics.median(values):.1f} | "
              f"{min(values) / ref:.1f}× |")


if __name__ == "__main__":
    main()
