"""How many graded sixth-order Magnus sublayers each case needs for roots to 1e-8 (the calibration
data an error estimate for the default N needs; issue 42 item 11).

    python3 benchmarks/layer_errors.py [--out records.json | --load records.json] [WALL ...]

For nine walls (the GEWtool-shaped tube, the paper's, η = 0.95 … 0.3, 99 % of Gent locking at
G = 4, λ_i = 0.8, a G = 10 wall), α̂ = 0.01 … 20, m = 0, 2, 8, 16 (and the acoustic fluid at
m = 0, 2 on three walls): the 8 lowest roots at N = 4, 6, 8, 12 against N = 192 (graded
magnus6), per root. The table gives, for the K lowest roots, N* (the N at which the largest
relative error crosses 1e-8: interpolated in log error between the measured N, extrapolated as
N^-6 beyond 12; "–" where a coarse N missed a root) and the N of today's rule
(:func:`jaxdea.physics.transfer.required_layers` before rounding up). A run takes 10–20 min on the
2-core machine, most of it compiling the 5 N × 3 families.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxdea as jd  # noqa: E402
from jaxdea.physics.transfer import Layers, point_lengths, required_layers  # noqa: E402

jd.configure()

N_ROOTS = 8
COUNTS = (4, 6, 8, 12)
REFERENCE = 192
TARGET = 1e-8
WALLS = {
    "peer": dict(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85),
    "paper": dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85),
    "eta95": dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.95),
    "eta6": dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.6),
    "eta5": dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.5),
    "eta3": dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.3),
    "lock4": dict(voltage=0.05, lambda_i=0.35890249, lambda_z=1.2, eta=0.75, gent=4.0),
    "li08": dict(voltage=0.0, lambda_i=0.8, lambda_z=1.2, eta=0.85),
    "g10": dict(voltage=0.0, lambda_i=1.3, lambda_z=1.1, eta=0.4, gent=10.0),
}
ALPHAS = (0.01, 0.445, 2.0, 5.0, 20.0)
ORDERS = (0, 2, 8, 16)
WITH_FLUID = ("peer", "paper", "lock4")


def measure(names):
    records = []
    for name in names:
        tube = jd.Tube(**WALLS[name])
        h, r, ell = (float(x) for x in point_lengths(tube))
        fluids = [None] + ([jd.Fluid()] if name in WITH_FLUID else [])
        for fluid, a, m in itertools.product(fluids, ALPHAS, ORDERS):
            if fluid is not None and m not in (0, 2):
                continue

            def roots(n, tube=tube, a=a, fluid=fluid, m=m):
                return np.asarray(jd.frequencies(tube, a, fluid, n_roots=N_ROOTS, m=m,
                                                 n_layers=Layers(n, "magnus6", True)))

            ref = roots(REFERENCE)
            errors = {n: (np.abs(roots(n) - ref) / ref).tolist() for n in COUNTS}
            records.append(dict(wall=name, fluid=None if fluid is None else "acoustic", alpha=a,
                                m=m, lengths=(h, r, ell), reference=ref.tolist(), errors=errors))
            print(name, records[-1]["fluid"], a, m, flush=True)
    return records


def needed(errors):
    """N* of the module docstring from the errors at COUNTS (None where a root was missed)."""
    e = np.asarray(errors, float)
    if np.any(np.isnan(e)):
        return None
    if e[-1] > TARGET:
        return COUNTS[-1] * (e[-1] / TARGET) ** (1 / 6)
    if e[0] <= TARGET:
        return COUNTS[0] * (e[0] / TARGET) ** (1 / 6)
    i = int(np.argmax(e <= TARGET))
    t = math.log(e[i - 1] / TARGET) / math.log(e[i - 1] / e[i])
    return COUNTS[i - 1] + t * (COUNTS[i] - COUNTS[i - 1])


def table(records, k_values=(4, 8)):
    lines = ["| wall | fluid | α̂ | m | " + " | ".join(f"N* (K = {k}) | rule (K = {k})" for k in k_values)
             + " |", "|" + "---|" * (4 + 2 * len(k_values))]
    for rec in records:
        row = [rec["wall"], rec["fluid"] or "–", f"{rec['alpha']:g}", str(rec["m"])]
        for k in k_values:
            star = needed([max(rec["errors"][n][:k]) for n in COUNTS])
            rule = float(required_layers(*rec["lengths"], rec["alpha"], k, rec["m"]))
            row += ["–" if star is None else f"{star:.1f}", f"{rule:.1f}"]
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("walls", nargs="*", help=f"walls to measure (default all: {', '.join(WALLS)})")
    parser.add_argument("--out", default=None, help="also write the records as JSON here")
    parser.add_argument("--load", default=None, help="tabulate the records of an earlier --out")
    args = parser.parse_args()
    if args.load:
        with open(args.load) as f:
            records = json.load(f)
        for rec in records:  # JSON keys are strings
            rec["errors"] = {int(n): v for n, v in rec["errors"].items()}
    else:
        unknown = set(args.walls) - set(WALLS)
        if unknown:
            parser.error(f"unknown walls {sorted(unknown)}; choose from {list(WALLS)}")
        records = measure(args.walls or list(WALLS))
    if args.out:
        with open(args.out, "w") as f:
            json.dump(records, f)
    print(table(records))


if __name__ == "__main__":
    main()
