"""Cost of the default discretisation's a-posteriori check (issue 42 item 11): each public call
with the check (one Newton step per root on the wall of N/2 sublayers, in the same program; a
curve at 9 of its points) against the same call with the rule alone, interleaved in one process,
warm. Also asserts that the roots are bit-identical where the rule sufficed.

    python3 benchmarks/default_check.py [--rounds 11]
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxdea as jd  # noqa: E402
from jaxdea.solve import curves, roots  # noqa: E402

jd.configure()
CHECKED = roots._concrete  # the library's test: a concrete call is checked

PAPER = jd.Tube(eta=0.85)
PEER = jd.Tube(eta=0.85, lambda_i=1.0, lambda_z=1.0, voltage=0.0)
CASES = {
    "frequencies, empty": lambda: jd.frequencies(PAPER, 0.445),
    "frequencies, acoustic": lambda: jd.frequencies(PAPER, 0.445, jd.Fluid()),
    "frequencies, m = 2": lambda: jd.frequencies(PAPER, 0.445, m=2),
    "frequencies, torsional": lambda: jd.frequencies(PAPER, 0.445, torsional=True),
    "dispersion_curve, peer's 200 α̂, K = 4":
        lambda: jd.dispersion_curve(PEER, np.linspace(0.01, 5.0, 200), n_roots=4).omega,
}


def switch(on: bool):
    """The check on (the library's own test) or off (the rule alone) in both solvers."""
    test = CHECKED if on else (lambda *args: False)
    roots._concrete = curves._concrete = test


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=11)
    args = parser.parse_args()
    print("| call | rule alone (ms) | checked (ms) | ratio of medians | bit-identical |")
    print("|---|---|---|---|---|")
    for name, call in CASES.items():
        values, times = {}, {True: [], False: []}
        for on in (False, True):
            switch(on)
            values[on] = np.asarray(call())
        for _ in range(args.rounds):
            for on in (False, True):
                switch(on)
                start = time.perf_counter()
                jax.block_until_ready(call())
                times[on].append(time.perf_counter() - start)
        off, on = np.median(times[False]), np.median(times[True])
        same = np.array_equal(values[False], values[True], equal_nan=True)
        print(f"| {name} | {1e3 * off:.2f} | {1e3 * on:.2f} | {on / off:.3f} | {same} |", flush=True)
    switch(True)


if __name__ == "__main__":
    main()
