"""Command line: ``jaxdea table`` prints the lowest frequencies of the paper's tube."""

import argparse
import sys
import time

import jax

TABLE_HELP = """Lowest three frequencies Ω of the paper's tube (η = 0.85, λ_z = 1.2, G = 97.2) for
λ_i = 0.9 and 1.1, V̂ = 0 and 0.2, axial modes n = 1..3: empty, filled with the consistent
acoustic fluid (ρ̂_f = 0.13, ĉ_f = 0.27) and with the paper's coupling (Bessel order ν = n)."""


def paper_table(n_layers=30, n_modes=3, n_roots=3):
    """Rows (lambda_i, voltage, n, alpha, model, roots) of the paper's-tube table."""
    import jaxdea as jd

    rows = []
    for model in ("empty", "acoustic", "paper"):
        for lambda_i in (0.9, 1.1):
            for voltage in (0.0, 0.2):
                tube = jd.Tube(voltage=voltage, lambda_i=lambda_i, lambda_z=1.2, eta=0.85)
                for n in range(1, n_modes + 1):
                    alpha = jd.axial_wavenumber(tube, n)
                    fluid = None if model == "empty" else jd.Fluid(coupling=model)
                    roots = jd.solve_frequencies(tube, alpha, fluid, n_roots=n_roots,
                                                 n_layers=n_layers)
                    rows.append((lambda_i, voltage, n, float(alpha), model, roots))
    return rows


def _table(args):
    jax.config.update("jax_enable_x64", True)
    t0 = time.perf_counter()
    rows = paper_table(n_layers=args.n_layers)
    header = f"{'model':>8} {'λ_i':>5} {'V̂':>5} {'n':>2} {'α̂':>8}   Ω_1 … Ω_3"
    print(TABLE_HELP.replace("\n", " "))
    print(header)
    print("-" * len(header))
    for lambda_i, voltage, n, alpha, model, roots in rows:
        values = "  ".join(f"{float(w):12.8f}" for w in roots.omega)
        flags = "" if int(roots.status.max()) == 0 else f"  status {roots.status.tolist()}"
        print(f"{model:>8} {lambda_i:5.2f} {voltage:5.2f} {n:2d} {alpha:8.5f}   {values}{flags}")
    print(f"({len(rows)} cases, N = {args.n_layers} sublayers, {time.perf_counter() - t0:.1f} s)")
    return 0


def build_parser():
    parser = argparse.ArgumentParser(
        prog="jaxdea",
        description="Axisymmetric dispersion of pre-stretched, voltage-driven (fluid-filled) "
        "dielectric elastomer tubes, with exact gradients (JAX).",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    table = sub.add_parser("table", help="print the lowest frequencies of the paper's tube",
                           description=TABLE_HELP)
    table.add_argument("--n-layers", type=int, default=30,
                       help="number of sublayers N of the laminate (default 30; error ~ N^-2)")
    table.set_defaults(run=_table)
    return parser


def main(argv=None):
    """Entry point of the ``jaxdea`` command."""
    args = build_parser().parse_args(argv)
    if getattr(args, "n_layers", 1) < 1:
        print("jaxdea: error: --n-layers must be >= 1", file=sys.stderr)
        return 2
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
