"""``jax.vmap`` of the solvers against the other ways of solving the same batch, side by side.

    python3 benchmarks/vmap_idiom.py [--points 200] [--repeats 5]

Batch: ``points`` α̂ in [0.01, 5] of the tube Tube(voltage=0, lambda_i=1, lambda_z=1, eta=0.85),
4 roots each. For each solver the row gives, in seconds, the best and the median of ``repeats``
(the calls of one round run one after another, so that a changing load hits them alike):

* **vmap**: ``jax.jit(jax.vmap(...))`` of the public function, what a user writes (a batch over
  α̂ alone is continued along α̂ by :func:`jaxdea.solve.curves.frequencies_along` and
  :func:`jaxdea.solve.curves.critical_voltages_along`);
* **vectorised**: ``jax.jit(jax.vmap(...))`` of the solver's program itself, every while loop
  vectorised lane by lane;
* **lax.map**: ``jax.jit`` of ``jax.lax.map`` of the public function, one point after another;
* **sweep** (``frequencies``): ``jaxdea.sweep`` of the same points;
* **continuation**: the fastest way the library has to the same answer: ``jaxdea.dispersion_curve``
  along the points for ``frequencies`` and ``frequency`` (its 4 roots against the one root of
  ``frequency``), the critical-voltage path of the figures (``jaxdea.solve.curves.critical_path_unchecked``,
  compiled by ``solve_critical_path``) for ``critical_voltage``.

``frequency`` starts Newton at 1.02 times the lowest root of each point. The last columns are the
ratios of vmap to the continuation (best and median) and to the best of lax.map and sweep, and of
the vectorised program to vmap; the heading gives the load averages at the end of the run.
"""

from __future__ import annotations

import argparse
import os
import time

import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxdea as jd  # noqa: E402
from jaxdea.params import canonical  # noqa: E402
from jaxdea.physics.state_matrix import LONGITUDINAL  # noqa: E402
from jaxdea.physics.transfer import laminate  # noqa: E402
from jaxdea.solve import curves, roots  # noqa: E402

jd.configure()  # the disk cache and XLA's loop threshold, as the CLI runs

TUBE = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
N_ROOTS = 4


def workloads(alpha):
    """{solver: {path: call}}: the calls of each row (each returns arrays to block on)."""
    tube = canonical(TUBE)
    a = jnp.asarray(alpha)
    guess = jnp.asarray(jd.sweep(TUBE, alpha=alpha, n_roots=1, progress=False).omega[:, 0] * 1.02)

    def vectorised_frequencies(x):  # the public call's program and laminate (N of a traced α̂)
        layers = laminate(None, None, tube, x, N_ROOTS)
        return roots._solve_frequencies(tube, x, None, None, N_ROOTS, layers, 0).omega

    def vectorised_critical_voltage(x):
        layers = laminate(None, None, tube, x, at_rest=True)
        return roots._solve_critical_voltage(tube, x, None, layers, 0)[0]

    def frequencies(x):
        return jd.frequencies(TUBE, x, n_roots=N_ROOTS)

    def frequency(x, g):
        return jd.frequency(TUBE, x, g)

    def critical_voltage(x):
        return jd.critical_voltage(TUBE, x)

    def critical_path():  # the figures' path along α̂ (the public call's laminate)
        layers = laminate(None, None, tube, a, at_rest=True)
        tubes = jax.tree_util.tree_map(lambda v: jnp.full(a.shape, v), tube)
        return curves.solve_critical_path(tubes, a, a, jnp.zeros(a.shape, bool), jnp.zeros(a.shape),
                                           layers, LONGITUDINAL)[0]

    def curve():
        return jd.dispersion_curve(TUBE, alpha, n_roots=N_ROOTS).omega

    def vmapped(fun, *args):
        compiled = jax.jit(jax.vmap(fun))
        return lambda: compiled(*args)

    def mapped(fun, *args):
        compiled = jax.jit(lambda *xs: jax.lax.map(lambda p: fun(*p), xs))
        return lambda: compiled(*args)

    return {
        "frequencies": {
            "vmap": vmapped(frequencies, a),
            "vectorised": vmapped(vectorised_frequencies, a),
            "lax.map": mapped(frequencies, a),
            "sweep": lambda: jd.sweep(TUBE, alpha=alpha, n_roots=N_ROOTS, progress=False).omega,
            "continuation": curve,
        },
        "frequency": {
            "vmap": vmapped(frequency, a, guess),
            "lax.map": mapped(frequency, a, guess),
            "continuation": curve,
        },
        "critical_voltage": {
            "vmap": vmapped(critical_voltage, a),
            "vectorised": vmapped(vectorised_critical_voltage, a),
            "lax.map": mapped(critical_voltage, a),
            "continuation": critical_path,
        },
    }


def timed(call):
    start = time.perf_counter()
    jax.block_until_ready(call())
    return time.perf_counter() - start


def measure(calls, repeats):
    """{path: (first call s, best s, median s of ``repeats``)}, the paths alternating within each
    round."""
    first = {name: timed(call) for name, call in calls.items()}
    times = {name: [] for name in calls}
    for _ in range(repeats):
        for name, call in calls.items():
            times[name].append(timed(call))
    return {name: (first[name], min(times[name]), float(np.median(times[name]))) for name in calls}


def table(results, points, load):
    paths = ["vmap", "vectorised", "lax.map", "sweep", "continuation"]
    lines = [f"vmap idiom, {points} α̂ × {N_ROOTS} roots (seconds: best / median of the repeats, first "
             f"call with compilation in parentheses); load average "
             f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f}",
             "",
             "| solver | batch | " + " | ".join(paths) + " | vmap / continuation (best, median) "
             "| vmap / best other | vectorised / vmap |",
             "|" + "---|" * (len(paths) + 5)]
    for solver, res in results.items():
        best = {k: v[1] for k, v in res.items()}
        median = {k: v[2] for k, v in res.items()}
        others = [t for k, t in best.items() if k in ("lax.map", "sweep")]
        row = [solver, str(points)]
        row += [("–" if k not in res else f"{res[k][1]:.4f} / {res[k][2]:.4f} ({res[k][0]:.1f})")
                for k in paths]
        row.append(f"{best['vmap'] / best['continuation']:.2f}, "
                   f"{median['vmap'] / median['continuation']:.2f}")
        row.append(f"{best['vmap'] / min(others):.3f}")
        row.append(f"{best['vectorised'] / best['vmap']:.1f}" if "vectorised" in best else "–")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--only", choices=["frequencies", "frequency", "critical_voltage"],
                        action="append", help="measure only these solvers (repeatable)")
    args = parser.parse_args()
    alpha = np.linspace(0.01, 5.0, args.points)
    results = {}
    for solver, calls in workloads(alpha).items():
        if args.only and solver not in args.only:
            continue
        print(f"{solver} ...", flush=True)
        results[solver] = measure(calls, args.repeats)
    print(table(results, args.points, os.getloadavg()))


if __name__ == "__main__":
    main()
