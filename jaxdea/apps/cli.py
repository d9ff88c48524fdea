"""Command line: ``jaxdea sweep CONFIG`` (user-defined sweeps to CSV/NPZ and a plot), ``jaxdea figures``
(the paper's figures), ``jaxdea table`` (the lowest frequencies of the paper's tube) and ``jaxdea fit
DATA.csv --config fit.toml`` (material and geometry from measured resonances: a summary, JSON and a
plot; :mod:`jaxdea.io.fit_io`).

:func:`main` takes the arguments as a list and returns the exit status (0: done, 2: any error,
reported in one line on stderr without a traceback; 130: Ctrl-C, 143: SIGTERM, also one line).
Outputs are written through :mod:`jaxdea.files`: whole or not at all.
"""

import argparse
import contextlib
import importlib.util
import itertools
import os
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

import jax
import numpy as np

from ..files import save_figure, write_together
from .plotstyle import LABELS, OMEGA_LABEL, SYMBOLS  # axis labels: the style of every figure

TABLE_HELP = """Lowest three frequencies Ω of the paper's tube (η = 0.85, λ_z = 1.2, G = 97.2) for
λ_i = 0.9 and 1.1, V̂ = 0 and 0.2, axial modes n = 1..3: empty, filled with the consistent
acoustic fluid (ρ̂_f = 0.13, ĉ_f = 0.27) and with the paper's coupling (Bessel order ν = n).
A row past the tube's first instability (V̂ ≥ V̂_first over m ≤ 4, n ≤ 3) is marked; where V̂ ≥ V̂_cr
of the axisymmetric mode n its lowest root is imaginary and Ω_1 is the next branch (said so)."""


def paper_table(n_layers=30, n_modes=3, n_roots=3, log=None):
    """Rows (lambda_i, voltage, n, alpha, model, roots) of the paper's-tube table; ``log(message)``
    reports the progress, model by model."""
    import jaxdea as jd

    rows = []
    for model in ("empty", "acoustic", "paper"):
        if log is not None:
            log(f"  {model}: {2 * 2 * n_modes} cases")
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


def table_stability(rows, n_layers=30, m_max=4, n_max=3):
    """({λ_i: (V̂_first, m, n)} of :func:`jaxdea.first_instability` over m ≤ ``m_max``, n ≤ ``n_max``,
    {(λ_i, n): V̂_cr of the axisymmetric mode n}) of the tubes of :func:`paper_table`'s ``rows``;
    both independent of V̂ and of the fluid."""
    import jaxdea as jd

    first, critical = {}, {}
    for lambda_i, _, n, alpha, _, _ in rows:
        tube = jd.Tube(lambda_i=lambda_i, lambda_z=1.2, eta=0.85)
        if lambda_i not in first:
            found = jd.first_instability(tube, n_max=n_max, m_max=m_max, n_layers=n_layers)
            first[lambda_i] = (float(found.voltage), int(found.m), int(found.n))
        if (lambda_i, n) not in critical:
            critical[lambda_i, n] = float(jd.critical_voltage(tube, alpha, n_layers=n_layers))
    return first, critical


def row_notes(voltage, first, v_cr) -> str:
    """What a table row must say about its state: past the first instability (the rule of
    :func:`jaxdea.apps.plotstyle.past_first_instability`), and whether its lowest root has gone imaginary."""
    from .plotstyle import past_first_instability

    notes = []
    v_first, m, n = first
    if past_first_instability(voltage, v_first):
        notes.append(f"UNSTABLE: past the first instability (m, n) = ({m}, {n}) at V̂_first = {v_first:.4f}")
    if np.isfinite(v_cr) and voltage >= v_cr:
        notes.append(f"lowest root imaginary (V̂ ≥ V̂_cr = {v_cr:.4f}): Ω_1 is the next branch")
    return "; ".join(notes)


def _table(args):
    if args.n_layers < 1:
        return _error("table", "--n-layers must be >= 1")
    t0 = time.perf_counter()
    log = None if args.quiet else (lambda message: print(message, file=sys.stderr, flush=True))
    if log:
        log("solving 36 cases of the paper's tube (a first run is compiling the solvers, once…)")
    rows = paper_table(n_layers=args.n_layers, log=log)
    if log:
        log("  the first instability and the critical voltages…")
    first, critical = table_stability(rows, n_layers=args.n_layers)
    header = f"{'model':>8} {'λ_i':>5} {'V̂':>5} {'n':>2} {'α̂':>8}   Ω_1 … Ω_3"
    print(TABLE_HELP.replace("\n", " "))
    print(header)
    print("-" * len(header))
    for lambda_i, voltage, n, alpha, model, roots in rows:
        values = "  ".join(f"{float(w):12.8f}" for w in roots.omega)
        flags = "" if int(roots.status.max()) == 0 else f"  status {roots.status.tolist()}"
        notes = row_notes(voltage, first[lambda_i], critical[lambda_i, n])
        print(f"{model:>8} {lambda_i:5.2f} {voltage:5.2f} {n:2d} {alpha:8.5f}   {values}{flags}"
              + (f"  [{notes}]" if notes else ""))
    print(f"({len(rows)} cases, N = {args.n_layers} sublayers, {time.perf_counter() - t0:.1f} s)")
    return 0


INTEGER_AXES = ("n", "m")  # axes of integers: integer ticks
LINE_STYLES = ("-", "--", ":", "-.")


def plot_sweep(result, x_name, path, title=None):
    """Ω of a :class:`jaxdea.SweepResult` against the axis ``x_name``, one line per root and per
    combination of the other axes' values (colour: the combination, line style: the root), as PNG.

    Returns:
        The matplotlib Figure (not shown; no pyplot state is touched).
    """
    from .plotstyle import style

    with style():
        return _draw_sweep(result, x_name, path, title)


def _draw_sweep(result, x_name, path, title):
    """:func:`plot_sweep`'s drawing, in the figures' style."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.ticker import MaxNLocator

    from .plotstyle import SAVE_DPI

    names = list(result.axes)
    x = np.asarray(result.axes[x_name])
    others = [k for k in names if k != x_name]
    k_roots = result.omega.shape[-1]
    omega = np.moveaxis(result.omega, names.index(x_name), 0).reshape(len(x), -1, k_roots)
    combos = list(itertools.product(*(range(len(result.axes[k])) for k in others)))
    varying = [k for k in others if len(result.axes[k]) > 1]
    cmap = colormaps["tab10" if len(combos) <= 10 else "viridis"]
    color = (lambda c: cmap(c)) if len(combos) <= 10 else (lambda c: cmap(c / (len(combos) - 1)))

    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.add_subplot()
    handles = []
    for c, combo in enumerate(combos):
        values = dict(zip(others, combo, strict=True))
        for j in range(k_roots):
            ax.plot(x, omega[:, c, j], color=color(c), linestyle=LINE_STYLES[j % len(LINE_STYLES)],
                    marker="o", markersize=3 if len(x) > 1 else 5)
        if varying:
            label = ", ".join(f"{SYMBOLS[k]} = {result.axes[k][values[k]]:g}" for k in varying)
            handles.append(Line2D([], [], color=color(c), label=label))
    handles += [Line2D([], [], color="k", linestyle=LINE_STYLES[j % len(LINE_STYLES)],
                       label=rf"$\Omega_{{{j + 1}}}$") for j in range(k_roots)]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small",
              frameon=False)
    ax.set_xlabel(LABELS[x_name])
    if x_name in INTEGER_AXES:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel(OMEGA_LABEL)
    _si_axes(ax, result, x_name)
    ax.set_title(title or _auto_title(result, others), fontsize="medium")
    ax.grid(alpha=0.3)
    save_figure(fig, path, dpi=SAVE_DPI)
    return fig


def _si_axes(ax, result, x_name):
    """With units (``result.scales``): f in Hz on the right and, for an axis with a linear SI
    counterpart (V, m, kg/m³, m/s), its SI values on top."""
    from ..studies.sweeps import SI_QUANTITIES

    scales = result.scales
    if scales is None:
        return
    hz = float(scales.omega_to_hz(1.0))
    right = ax.secondary_yaxis("right", functions=(lambda w: w * hz, lambda f: f / hz))
    right.set_ylabel("frequency $f$ (Hz)")
    if x_name in SI_QUANTITIES and x_name != "alpha":  # α̂ ↔ wavelength is no linear map
        si_name, unit, to_si, _ = SI_QUANTITIES[x_name]
        factor = float(to_si(scales, 1.0))
        top = ax.secondary_xaxis("top", functions=(lambda x: x * factor, lambda x: x / factor))
        top.set_xlabel(f"{si_name} ({unit})")


def _auto_title(result, others):
    """Two lines: the fluid (or none), then the fixed parameters (not swept, or axes of one value)."""
    settings = result.settings
    fluid = settings.get("fluid")
    case = "empty tube" if fluid is None else (
        f"filled, {settings['coupling']} coupling, {SYMBOLS['density_ratio']} = "
        f"{fluid['density_ratio']:g}, {SYMBOLS['speed_ratio']} = {fluid['speed_ratio']:g}")
    hidden = {*result.axes, "length_ratio", *(("eta",) if "thickness_ratio" in result.axes else ())}
    fixed = {k: v for k, v in settings["tube"].items() if k not in hidden and np.isfinite(v)}
    fixed.update({k: float(result.axes[k][0]) for k in others if len(result.axes[k]) == 1})
    values = ", ".join(f"{SYMBOLS[k]} = {v:g}" for k, v in fixed.items())
    return f"{result.omega.shape[-1]} lowest frequencies, {case}\n{values}"


INTERRUPTED = ("every output file is whole: written completely, or left as it was before the "
               "command")


def _error(command, message):
    """Report an error in one line on stderr; the exit status 2."""
    print(f"jaxdea {command}: error: {' '.join(str(message).split())}", file=sys.stderr)
    return 2


def _writable_folder(out):
    """Create the folder ``out`` (with its parents) and check that a file can be written there;
    None, or what is wrong."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        return f"{out} is a file, not a folder"
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        return f"cannot write into {out}: {exc.strerror or exc}"
    return None


def _sweep(args):
    from .. import Fluid, Status, Tube, sweep
    from ..io.config import SUFFIXES, load_config
    from ..studies.sweeps import SweepInterrupted

    try:
        cfg = load_config(args.config)
    except ValueError as exc:
        return _error("sweep", exc)
    if "netcdf" in cfg.formats and not all(importlib.util.find_spec(m) for m in ("xarray", "netCDF4")):
        return _error("sweep", "output format netcdf needs xarray and netCDF4: "
                      "pip install 'jaxdea[xarray]'")
    if args.out is not None:
        out = Path(args.out)
    else:
        out = Path(args.config).parent / cfg.out_dir if cfg.out_dir else Path()
    problem = _writable_folder(out)
    if problem:
        return _error("sweep", problem)
    t0 = time.perf_counter()
    try:
        tube = Tube(**cfg.tube, outer=None if cfg.outer is None else Fluid(**cfg.outer))
        fluid = None if cfg.fluid is None else Fluid(**cfg.fluid)
        result = sweep(tube, fluid, progress=False if args.quiet else None, **cfg.sweep_arguments())
    except ValueError as exc:
        return _error("sweep", exc)
    except SweepInterrupted as stop:  # the points solved so far, as NAME.partial.*
        if stop.result is None:
            raise _Interrupted(f"0 of {stop.total} points solved; no file was written") from None
        paths = _write_sweep(stop.result, cfg, out, f"{cfg.name}.partial")
        for path in paths:
            print(path)
        raise _Interrupted(f"{stop.solved} of {stop.total} points solved, written to "
                           f"{out / cfg.name}.partial.* (the others NaN, status "
                           f"{Status.NOT_SOLVED.value} not solved)") from None
    seconds = time.perf_counter() - t0
    paths = _write_sweep(result, cfg, out, cfg.name)
    for path in (out / f"{cfg.name}.partial.{suffix}" for suffix in (*SUFFIXES.values(), "png")):
        path.unlink(missing_ok=True)  # superseded by the complete result
    if not args.quiet:
        converged = int(np.sum(result.status == Status.CONVERGED))
        grid = " x ".join(f"{k}[{len(v)}]" for k, v in result.axes.items())
        unstable = "" if result.unstable is None else \
            f", {int(np.sum(result.unstable))}/{result.unstable.size} points unstable"
        print(f"sweep {grid}: {result.omega.shape[-1]} roots per point, {converged}/{result.status.size} "
              f"converged{unstable} ({seconds:.1f} s)")
    for path in paths:
        print(path)
    return 0


def _write_sweep(result, cfg, out, name):
    """Write the outputs of a sweep (the formats of ``cfg`` and the plot) as NAME.* into ``out``,
    all of them or none (:func:`jaxdea.files.write_together`); their paths."""
    from ..io.config import SUFFIXES

    if cfg.scales is not None:
        result = result.with_units(cfg.scales)
    writers = {"csv": result.to_csv, "npz": result.to_npz, "netcdf": result.to_netcdf}
    files = [(out / f"{name}.{SUFFIXES[f]}", writers[f]) for f in cfg.formats]
    if cfg.plot:
        files.append((out / f"{name}.png",
                      lambda path: plot_sweep(result, cfg.plot_axis, path, cfg.title)))
    try:
        return write_together(files)
    except (OSError, RuntimeError) as exc:  # RuntimeError: the netCDF library's "HDF error"
        raise ValueError(f"cannot write into {out}: {getattr(exc, 'strerror', None) or exc} (the "
                         "previous files are unchanged)") from None


def _fit(args):
    from ..io.fit_io import run_fit

    try:
        _, report, paths = run_fit(args.data, args.config, args.out)
    except ValueError as exc:
        return _error("fit", " ".join(str(exc).split()))
    print(report)  # the result itself: --quiet leaves it
    for path in paths:
        print(path)
    return 0


def _figures(args):
    from jaxdea.apps.figures import make_figures

    problem = _writable_folder(args.out)
    if problem:
        return _error("figures", problem)
    for path in make_figures(out=Path(args.out), quick=args.quick, progress=not args.quiet):
        print(path)
    return 0


DESCRIPTION = """Dispersion and stability of pre-stretched, voltage-driven dielectric elastomer tubes,
empty or filled with a compressible fluid, for every circumferential order m (axisymmetric and
torsional m = 0, bending m = 1, ovalisation and ring modes m >= 2): frequencies, dispersion curves,
critical voltages, the first instability, growth rates and mode shapes, with exact gradients (JAX).
All quantities are dimensionless: lengths / R_i, the frequency Ω = ω R_i/c_s with
c_s = sqrt(μ/ρ_s), the voltage V̂ = V sqrt(ε/μ)/R_i. Negative voltages are accepted: only V²
enters the physics, so -V gives the results of V."""
EXAMPLES = """examples:
  jaxdea sweep examples/sweep.toml            Ω over a grid of V̂ and n: CSV, NPZ and a plot
  jaxdea figures --out figures                the paper's figures, PNG plus CSV
  jaxdea table --n-layers 30                  the lowest frequencies of the paper's tube
  jaxdea fit peaks.csv --config fit.toml      parameters from measured resonance peaks
  jaxdea COMMAND --help                       the options of a command"""
SWEEP_HELP = """Solve the lowest frequencies Ω over a grid of parameters described by CONFIG, a TOML or
JSON file, and write NAME.csv (one row per grid point: axes, α̂, Ω_k, status_k and, with the
jacobian, dΩ_k/dα̂ and dΩ_k/dθ), NAME.npz (jaxdea.SweepResult.from_npz reads it back), NAME.nc
(netCDF, with output.formats = [..., "netcdf"]) and NAME.png (Ω against the first axis that has more
than one value). With a [units] table parameters may be given in SI units and the outputs add f in
Hz, the wavelength in m and the SI value of each axis. An error in CONFIG is reported with the
offending key and what is allowed there (exit status 2). The files are written together or not at
all: a failure (a full disk, Ctrl-C) leaves the previous ones as they were. Ctrl-C or SIGTERM during
the solve writes the points solved so far as NAME.partial.* (the others NaN, status 7 "not solved";
exit status 130, 143 for SIGTERM); a complete run removes them."""
FIGURES_HELP = """Regenerate the analogues of the paper's Figs. 2-10 (dispersion against V̂, the axial mode
number, ĉ_f, ρ̂_f and h/R_i, empty and fluid-filled, consistent acoustic model beside the paper's
coupling) and the static response, each as a PNG plus the CSV behind it (written together: a
failure or Ctrl-C leaves every file whole, new or as it was; exit status 130 for Ctrl-C)."""


CACHE_HELP = """Compiled programs are kept under JAXDEA_CACHE_DIR (default ~/.cache/jaxdea, also when
it is set but empty; 'off' for none): JAX's compilations in xla/, jaxdea's exported programs in
programs/, next to the CACHEDIR.TAG that marks the folder as jaxdea's. Only the first call of a
solver in a process pays for tracing and compiling once they are there. 'clear' deletes only
those (a folder without the tag is left alone); deleting them is always safe: the next run
compiles anew."""


def _cache(args):
    from .. import compiled

    if os.environ.get("JAXDEA_CACHE_DIR", "").lower() == "off":
        print("the cache is off (JAXDEA_CACHE_DIR=off)")
        return 0
    root = compiled.configured_root()
    if args.action == "clear":
        existed = root.exists()
        compiled.clear_cache(root)
        print(f"removed jaxdea's cache at {root}" if existed else f"nothing to remove at {root}")
        return 0
    files = [p for name in compiled.SUBFOLDERS for p in (root / name).rglob("*") if p.is_file()]
    size = sum(p.stat().st_size for p in files)
    print(f"{root}: {len(files)} files, {size / 1e6:.1f} MB")
    return 0


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr (exit status 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def build_parser():
    formatter = argparse.RawDescriptionHelpFormatter
    parser = _Parser(prog="jaxdea", description=DESCRIPTION, epilog=EXAMPLES,
                                     formatter_class=formatter)
    parser.add_argument("--quiet", action="store_true",
                        help="no progress bars or status lines (results and written paths are still "
                        "printed)")
    # --quiet is accepted after the command too; SUPPRESS keeps a global --quiet from being reset
    quiet = argparse.ArgumentParser(add_help=False)
    quiet.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS,
                       help="no progress bars or status lines (results and written paths are still "
                       "printed)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    from ..io.config import FORMAT

    sweep = sub.add_parser(
        "sweep", parents=[quiet], formatter_class=formatter, description=SWEEP_HELP,
        help="a user-defined sweep from a TOML/JSON config: CSV, NPZ and a plot",
        epilog=f"config format (keys; all optional except [axes]):\n{FORMAT}\nexamples:\n"
        "  jaxdea sweep examples/sweep.toml\n"
        "  jaxdea sweep --out results --quiet my_sweep.json")
    sweep.add_argument("config", metavar="CONFIG", help="the sweep configuration (.toml or .json)")
    sweep.add_argument("--out", metavar="DIR", default=None,
                       help="output folder (default: output.dir of CONFIG, relative to CONFIG's "
                       "folder, else the current folder)")
    sweep.set_defaults(run=_sweep)

    figures = sub.add_parser(
        "figures", parents=[quiet], formatter_class=formatter, description=FIGURES_HELP,
        help="regenerate the paper's figures (PNG plus CSV)",
        epilog="examples:\n  jaxdea figures\n  jaxdea figures --out /tmp/figs --quick")
    figures.add_argument("--out", metavar="DIR", default="figures",
                         help="output folder (default: figures)")
    figures.add_argument("--quick", action="store_true",
                         help="coarse grids and few sublayers: a fast preview, not for publication")
    figures.set_defaults(run=_figures)

    table = sub.add_parser("table", parents=[quiet], formatter_class=formatter,
                           help="print the lowest frequencies of the paper's tube",
                           description=TABLE_HELP,
                           epilog="example:\n  jaxdea table --n-layers 60")
    table.add_argument("--n-layers", type=int, default=30,
                       help="number of sublayers N of the laminate (default 30; error ~ N^-2)")
    table.set_defaults(run=_table)

    cache = sub.add_parser("cache", formatter_class=formatter, description=CACHE_HELP,
                           help="show or clear the on-disk cache of compiled programs",
                           epilog="examples:\n  jaxdea cache info\n  jaxdea cache clear")
    cache.add_argument("action", choices=("info", "clear"),
                       help="info: where the cache is and its size; clear: delete it")
    cache.set_defaults(run=_cache)

    from ..io.fit_io import FORMAT as FIT_FORMAT

    fit = sub.add_parser(
        "fit", parents=[quiet], formatter_class=formatter,
        help="material and geometry parameters from measured resonances (CSV + TOML)",
        description="Fit the free parameters of CONFIG to the peaks of DATA (CSV: voltage_V, "
        "frequency_Hz, optional sigma_Hz and labels m, n, branch), print the estimates with 95 % "
        "intervals and the mode of every peak, and write DATA_fit.json and DATA_fit.png (both or "
        "neither). An error is reported in one line naming the file, column or key (exit status "
        "2); Ctrl-C stops without writing (exit status 130).",
        epilog=f"config format (TOML):\n{FIT_FORMAT}\nexample:\n"
        "  jaxdea fit peaks.csv --config fit.toml --out results")
    fit.add_argument("data", metavar="DATA", help="the measured peaks (.csv)")
    fit.add_argument("--config", metavar="CONFIG", required=True,
                     help="free parameters, fixed values, fluid and options (.toml)")
    fit.add_argument("--out", metavar="DIR", default=None,
                     help="output folder (default: the current folder)")
    fit.set_defaults(run=_fit)
    return parser


class _Interrupted(KeyboardInterrupt):
    """An interrupt after which a command saved something: the message says what."""


@contextlib.contextmanager
def _terminate_as_interrupt(received: list):
    """SIGTERM (a batch system's time limit, ``kill``) raises KeyboardInterrupt, as Ctrl-C does,
    and is recorded in ``received`` (main thread only; the previous handler is restored)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        received.append(signum)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def main(argv=None):
    """Entry point of the ``jaxdea`` command: the exit status (0 done, 2 an error, 130 Ctrl-C,
    143 SIGTERM). Every error and interrupt is one line on stderr, never a traceback."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, message already printed)
        return 0 if exc.code is None else int(exc.code)
    jax.config.update("jax_enable_x64", True)
    if args.command != "cache":
        from .. import compiled

        compiled.configure()  # the on-disk program cache and XLA's loop threshold
    received = []
    try:
        with _terminate_as_interrupt(received):
            return args.run(args)
    except KeyboardInterrupt as exc:
        number = received[0] if received else signal.SIGINT
        what = str(exc) if isinstance(exc, _Interrupted) else INTERRUPTED
        print(f"jaxdea {args.command}: interrupted by {signal.Signals(number).name}: {what}",
              file=sys.stderr)
        return 128 + number
    except OSError as exc:  # one line, never a traceback
        where = f"{exc.filename}: " if exc.filename else ""
        return _error(args.command, f"{where}{exc.strerror or exc}")
    except (ValueError, ImportError) as exc:
        return _error(args.command, exc)
    except Exception as exc:  # anything else (MemoryError, a runtime error): still one line
        message = " ".join(str(exc).split())
        return _error(args.command, f"unexpected {type(exc).__name__}: "
                      f"{message[:300]}{' ...' if len(message) > 300 else ''}")


if __name__ == "__main__":
    sys.exit(main())
