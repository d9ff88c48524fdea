"""The default dispersion curve at the promised accuracy (issue 42, item 11): a concrete
``dispersion_curve`` without accuracy arguments starting at 0.45 of the rule's N (its roots checked
on a wall of 2N, solved again where they ask), against the same call starting at the rule's N (the
default before: N = 16 on these walls, checked on N/2), interleaved in one process, warm; and the
error of each against an independent reference.

Cases: the peer's curve (the unstretched tube, η = 0.85, 200 α̂ in 0.01–5, K = 4; reference: the
exact incompressible cylinder, tests/exact_cylinder.py, at every 10th α̂) and the paper's tube
(V̂ = 0.1, λ_i = 0.9, λ_z = 1.2; reference: graded magnus6 on 192 sublayers at every 20th α̂).

    python3 benchmarks/checked_curve.py [--rounds 15]
    python3 benchmarks/checked_curve.py --survey [--rounds 5]

``--survey``: the start N, the counts solved and the warm time of the checked default curve
(100 α̂ in [0.05, 3], K = 4 and 8) on a table of walls, families and states, with the start below
the rule where the rule's count is 16 or m > 0 (``transfer.CHECKED_RULE_MAX``, today's policy)
against the start below the rule everywhere (the policy of the first checked curve), interleaved.

Writes nothing; its output is copied into benchmarks/README.md (section l).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxdea as jd  # noqa: E402
from jaxdea.physics import transfer  # noqa: E402
from jaxdea.physics.transfer import Layers, laminate  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
import exact_cylinder  # noqa: E402

jd.configure()
START = transfer.CHECKED_SHARE

PEER = jd.Tube(eta=0.85, lambda_i=1.0, lambda_z=1.0, voltage=0.0)
PAPER = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85)
GRID = np.linspace(0.01, 5.0, 200)


def peer_reference(alpha, omega):
    return np.array([exact_cylinder.roots(a, 1.0, 1 / 0.85, 4, 1.3 * w[-1] + 0.5, 2000)
                     for a, w in zip(alpha, omega, strict=True)])


def paper_reference(alpha, omega):
    fine = Layers(192, "magnus6", True)
    return np.array([np.asarray(jd.frequencies(PAPER, a, n_roots=4, n_layers=fine)) for a in alpha])


CASES = {"peer's curve (exact cylinder)": (PEER, 10, peer_reference),
         "paper's tube (N = 192)": (PAPER, 20, paper_reference)}


def call(tube, share):
    transfer.CHECKED_SHARE = share
    try:
        return jax.block_until_ready(jd.dispersion_curve(tube, GRID, n_roots=4))
    finally:
        transfer.CHECKED_SHARE = START


PAPER_TUBE = jd.Tube(lambda_z=1.2, eta=0.85, lambda_i=0.9)
SURVEY = {
    "paper's tube": (PAPER_TUBE, {}),
    "paper's tube, m = 2": (PAPER_TUBE, dict(m=2)),
    "paper's tube, torsional": (PAPER_TUBE, dict(torsional=True)),
    "paper's tube, acoustic fluid": (PAPER_TUBE, dict(fluid=jd.Fluid())),
    "unstretched": (jd.Tube(), {}),
    "thick, η = 0.5": (jd.Tube(eta=0.5, lambda_i=0.9, lambda_z=1.2), {}),
    "thick, η = 0.3": (jd.Tube(eta=0.3), {}),
    "thick, η = 0.5, m = 2": (jd.Tube(eta=0.5, lambda_i=0.9, lambda_z=1.2), dict(m=2)),
    "inflated, λ_i = 1.3, G = 10": (jd.Tube(eta=0.6, lambda_i=1.3, lambda_z=1.1, gent=10.0), {}),
    "near locking, G = 4": (jd.Tube(eta=0.7, lambda_i=1.3, lambda_z=1.2, gent=4.0), {}),
    "Mooney–Rivlin β = 0.2": (PAPER_TUBE.replace(material=jd.MooneyRivlin(0.2)), {}),
}


def survey(rounds):
    """Print, per case and K, the solves and warm ms of both policies (module docstring)."""
    from jaxdea.solve import curves

    checked, solved = curves._checked_curve, []

    def spy(solve, curve, layers, *rest):
        solved.append(layers.count)
        return checked(lambda finer: solved.append(finer.count) or solve(finer), curve, layers, *rest)

    curves._checked_curve = spy
    today = transfer.CHECKED_RULE_MAX
    policies = {"below the rule where it gives 16 or m > 0": today,
                "below the rule everywhere": transfer.LAYER_COUNTS[-1]}
    alpha = np.linspace(0.05, 3.0, 100)
    print(f"load {os.getloadavg()[0]:.2f}, {rounds} interleaved rounds, warm ms best")
    print("| case | K | " + " | ".join(f"{p}: N solved, ms" for p in policies) + " |")
    print("|---|---|" + "---|" * len(policies))
    for name, (tube, kw) in SURVEY.items():
        for k in (4, 8):
            counts, times = {}, {p: [] for p in policies}
            for _ in range(rounds + 1):
                for policy, limit in policies.items():
                    transfer.CHECKED_RULE_MAX = limit
                    solved.clear()
                    start = time.perf_counter()
                    jax.block_until_ready(jd.dispersion_curve(tube, alpha, n_roots=k, **kw).omega)
                    times[policy].append(1e3 * (time.perf_counter() - start))
                    counts[policy] = list(solved)
            transfer.CHECKED_RULE_MAX = today
            print(f"| {name} | {k} | " + " | ".join(
                f"{' → '.join(map(str, counts[p]))}, {min(times[p][1:]):.1f}" for p in policies) + " |",
                flush=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--survey", action="store_true")
    args = parser.parse_args()
    if args.survey:
        survey(args.rounds)
        return
    print(f"load {os.getloadavg()[0]:.2f}, {args.rounds} interleaved rounds, ms best / median")
    for name, (tube, every, reference) in CASES.items():
        times = {START: [], 1.0: []}
        curves = {share: call(tube, share) for share in times}
        for _ in range(args.rounds):
            for share in times:
                start = time.perf_counter()
                call(tube, share)
                times[share].append(1e3 * (time.perf_counter() - start))
        rows = slice(None, None, every)
        ref = reference(GRID[rows], np.asarray(curves[1.0].omega)[rows])
        for share, label in ((1.0, "start at the rule (before)"), (START, f"start at {START} of it")):
            omega = np.asarray(curves[share].omega)[rows]
            error = float(np.max(np.abs(omega / ref - 1.0)))
            transfer.CHECKED_SHARE = share
            n = laminate(None, None, tube, GRID, 4, checked=True).count
            transfer.CHECKED_SHARE = START
            print(f"{name}, {label}: start N = {n}, {min(times[share]):.2f} / "
                  f"{statistics.median(times[share]):.2f} ms, max error {error:.2g}, statuses "
                  f"{sorted(set(np.asarray(curves[share].status).ravel().tolist()))}")


if __name__ == "__main__":
    main()
