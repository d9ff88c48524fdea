"""Benchmarks of jaxdea against a naive JAX variant and the SciPy baseline, side by side in one run.

    python3 benchmarks/run.py [--quick] [--out benchmarks/results.md] [--only order_m]

Every workload runs in its own subprocess (``--worker NAME``) so that its peak memory (ru_maxrss)
is its own; all of them use single-threaded BLAS (OPENBLAS_NUM_THREADS=1: 6×6 products gain nothing
from threads, and a threaded OpenBLAS is 100× slower on a loaded machine). Timings: one warm-up
call (compilation; jaxdea's persistent compile cache is left on, as for a user), then the best of k
repeats with ``jax.block_until_ready``. See benchmarks/README.md for what each row means.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SINGLE_THREAD = dict(OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
for _key, _value in SINGLE_THREAD.items():  # before numpy is imported (workers, direct use)
    os.environ.setdefault(_key, _value)

import numpy as np  # noqa: E402

FIG3 = dict(lambda_z=1.2, lambda_i=[0.9, 1.1], voltage=[0.0, 0.2], n=list(range(1, 21)), n_roots=3)
CURVE = dict(alpha_min=0.025, alpha_max=5.0, points=200, n_roots=4, rtol=1e-8)
FIG3_REFERENCE = 60  # Fig. 3 at the baseline's accuracy: against magnus6 at N = 60 (error ~1e-12)
REFERENCE_LAYERS = 240  # the reference curve: Richardson of N = 240 and 480 (on every 10th α̂)
FIRST_CALLS = ("characteristic", "frequencies", "critical_voltage")  # (d): first calls timed
ORDER_M = dict(orders=[0, 1, 2], batch=4096, n_layers=30, n_max=3, m_max=8)  # (g)
PAPER_TUBE = dict(lambda_i=0.9, lambda_z=1.2, eta=0.85)  # (g): first_instability
EXPLORE = dict(voltages=[0.02, 0.04], lambda_i=[0.9, 0.92])  # (i): the explorer's slider moves
FIT = dict(voltages=[0.0, 2.5e3, 5e3], orders=[0, 1], modes=[1, 2, 3, 4, 5], n_layers=30,
           start=dict(shear_modulus=1.1, lambda_i=0.95, lambda_z=1.05, eta=0.95),
           noise=0.005)  # (h): 30 peaks; the free parameters and their start / truth


def settings(quick: bool) -> dict:
    """Sizes and repeat counts of a full or a --quick run."""
    return dict(
        quick=quick,
        repeats=3 if quick else 5,
        solve_repeats=5 if quick else 7,
        min_time=0.2 if quick else 0.5,
        batches=[1, 64, 4096] if quick else [1, 4, 16, 64, 256, 1024, 4096],
        layers=[10, 30, 100, 300],
        layer_batch=64 if quick else 256,
        scipy_max_evals=128 if quick else 1024,
        scipy_budget_s=20.0 if quick else 60.0,
        curve_levels=[8, 10, 12, 16, 20, 30, 60],
        magnus_levels=[4, 5, 6, 8, 10],
        fig3_magnus_levels=[2, 3, 4, 5, 6],
    )


# ----------------------------------------------------------------------------------------- timing
def peak_rss_mb() -> float:
    """Peak resident set size of this process so far, MiB (ru_maxrss is KiB on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def best_time(fn, repeats: int, min_time: float):
    """(seconds per call: best of ``repeats``, first-call seconds, the last output).

    A first call warms up (compiles); each repeat loops over enough calls to last ``min_time``. The
    first repeat also calibrates that count; with ``min_time`` = 0 (long workloads) every repeat is
    one call."""
    import jax

    start = time.perf_counter()
    out = jax.block_until_ready(fn())
    first = time.perf_counter() - start
    best, inner = math.inf, 1
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(inner):
            out = jax.block_until_ready(fn())
        sec = (time.perf_counter() - start) / inner
        best = min(best, sec)
        inner = max(1, int(math.ceil(min_time / max(sec, 1e-9))))
    return best, first, out


def _jax():
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxdea

    jaxdea.configure()  # the disk cache (JAXDEA_CACHE_DIR; 'off' for none) and XLA's loop threshold
    return jax, jaxdea


def _baseline():
    sys.path.insert(0, HERE)
    import scipy_baseline

    return scipy_baseline


def _omegas(batch):
    return np.linspace(0.05, 20.0, batch)


# ---------------------------------------------------------------------------------------- workers
def naive_characteristic(tube, n_layers, alpha):
    """vmap-able det(B A S) with A from ``jax.scipy.linalg.expm`` per sublayer (no normalisation):
    ``jaxdea.physics.transfer.transfer_matrix(..., method="expm")`` and the fluid-free initial basis."""
    import jax.numpy as jnp

    from jaxdea.physics import transfer

    def f(om):
        wall = transfer.discretize(tube, n_layers)
        a = transfer.transfer_matrix(wall, om, alpha, method="expm")
        p, ri = wall.pressure_inner, wall.r_inner
        zero, one = jnp.zeros_like(p), jnp.ones_like(p)
        s = jnp.array([[one, zero, zero], [zero, one, zero], [zero, zero, zero],
                       [-p / ri, -alpha * p, zero], [-alpha * p, zero, zero], [zero, zero, one]])
        return jnp.linalg.det(a[2:5] @ s)

    return f


def work_characteristic(impl: str, layers: list, batches: list, cfg: dict) -> dict:
    """Evaluations per second of the characteristic function over Ω for each (N, batch)."""
    tube_kw = dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
    out = []
    if impl == "scipy":
        sb = _baseline()
        tube = sb.Tube(**tube_kw)
        alpha = sb.axial_wavenumber(tube, 2)
        for n_layers in layers:
            wall = sb.discretize(tube, n_layers)
            for batch in batches:
                count = min(batch, max(1, int(cfg["scipy_max_evals"] * 30 / n_layers)))
                oms = _omegas(batch)[:count]
                sec, _, _ = best_time(lambda oms=oms, wall=wall: [sb.characteristic_on_wall(
                    wall, om, alpha, normalise=True) for om in oms], cfg["repeats"], cfg["min_time"])
                out.append(dict(n_layers=n_layers, batch=batch, evaluated=count,
                                evals_per_s=count / sec, first_call_s=None))
        return dict(rows=out)
    jax, jaxdea = _jax()
    tube = jaxdea.Tube(**tube_kw)
    alpha = jaxdea.axial_wavenumber(tube, 2)
    for n_layers in layers:
        if impl == "jaxdea":
            one = lambda om, n_layers=n_layers: jaxdea.characteristic(tube, om, alpha,  # noqa: E731
                                                                      n_layers=n_layers)
        else:
            one = naive_characteristic(tube, n_layers, alpha)
        fn = jax.jit(jax.vmap(one))
        for batch in batches:
            oms = jax.numpy.asarray(_omegas(batch))
            sec, first, _ = best_time(lambda fn=fn, oms=oms: fn(oms), cfg["repeats"], cfg["min_time"])
            out.append(dict(n_layers=n_layers, batch=batch, evaluated=batch, evals_per_s=batch / sec,
                            first_call_s=first))
    return dict(rows=out)


def work_order_m(cfg: dict) -> dict:
    """(g) Characteristic evaluations per second at each order m (batch 4096, N = 30; the public
    ``characteristic``: m = 0 the 6×6 longitudinal path, m ≥ 1 the 8×8 one) timed side by side
    (round-robin, best per order), the same with m traced (one program for every order), and
    ``first_instability`` (n ≤ 3, m ≤ 8) on the paper's tube, warm."""
    jax, jaxdea = _jax()
    tube = jaxdea.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
    alpha = jaxdea.axial_wavenumber(tube, 2)
    batch, n_layers = ORDER_M["batch"], ORDER_M["n_layers"]
    oms = jax.numpy.asarray(_omegas(batch))
    fns = {}
    for m in ORDER_M["orders"]:
        fns[f"m{m}"] = (jax.jit(jax.vmap(lambda om, m=m: jaxdea.characteristic(
            tube, om, alpha, n_layers=n_layers, m=m))), (oms,))
    traced = jax.jit(jax.vmap(lambda om, m: jaxdea.characteristic(tube, om, alpha, n_layers=n_layers,
                                                                  m=m), (0, None)))
    for m in ORDER_M["orders"][1:]:
        fns[f"m{m}_traced"] = (traced, (oms, jax.numpy.float64(m)))
    fluid = jaxdea.Fluid()  # the acoustic coupling (the default), the paper's fluid
    for m in ORDER_M["orders"]:
        fns[f"m{m}_acoustic"] = (jax.jit(jax.vmap(lambda om, m=m: jaxdea.characteristic(
            tube, om, alpha, fluid, n_layers=n_layers, m=m))), (oms,))
    first = {}
    for key, (fn, args) in fns.items():
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        first[key] = time.perf_counter() - start
    best = {key: math.inf for key in fns}
    cpu = {key: math.inf for key in fns}
    for _ in range(cfg["repeats"] * 4):  # round-robin: every order sees the same machine load
        for key, (fn, args) in fns.items():
            start, start_cpu = time.perf_counter(), time.process_time()
            jax.block_until_ready(fn(*args))
            best[key] = min(best[key], time.perf_counter() - start)
            cpu[key] = min(cpu[key], time.process_time() - start_cpu)
    rows = [dict(key=key, evals_per_s=batch / best[key], first_call_s=first[key],
                 ratio_to_m0=best[key] / best["m0"], cpu_ratio_to_m0=cpu[key] / cpu["m0"],
                 **(dict(ratio_to_empty=best[key] / best[key.split("_")[0]],
                         cpu_ratio_to_empty=cpu[key] / cpu[key.split("_")[0]])
                    if key.endswith("_acoustic") else {}))
            for key in fns]
    paper = jaxdea.Tube(**PAPER_TUBE)
    sec, first_s, inst = best_time(lambda: jaxdea.first_instability(
        paper, n_max=ORDER_M["n_max"], m_max=ORDER_M["m_max"], n_layers=n_layers),
        cfg["solve_repeats"], 0.0)
    return dict(batch=batch, n_layers=n_layers, rows=rows, instability_seconds=sec,
                instability_first_call_s=first_s, instability_voltage=float(inst.voltage),
                instability_m=int(inst.m), instability_n=int(inst.n))


def work_fit(cfg: dict) -> dict:
    """(h) ``fit``: 4 free parameters to 30 labelled peaks (V = 0, 2.5, 5 kV × m = 0, 1 × n = 1…5
    of a VHB-like tube, N = 30, 0.5 % noise, σ given) from ``initial`` 5–10 % off alone
    (``n_starts=0``).
    The first fit compiles; the rows are the best of the later fits (other noise draws), after
    compilation."""
    jax, jaxdea = _jax()
    from jaxdea.units import VACUUM_PERMITTIVITY, Scales, tube_from_si

    truth = dict(shear_modulus=1e5, density=1000.0, permittivity=4.7 * VACUUM_PERMITTIVITY,
                 inner_radius=5e-3, length=50e-3, eta=0.85, lambda_i=1.0, lambda_z=1.2, gent=97.0)
    scales = Scales(truth["shear_modulus"], truth["density"], truth["permittivity"],
                    truth["inner_radius"])
    rows = []
    for voltage in FIT["voltages"]:
        tube = tube_from_si(scales, outer_radius=truth["inner_radius"] / truth["eta"],
                            length=truth["length"], voltage=voltage, lambda_i=truth["lambda_i"],
                            lambda_z=truth["lambda_z"], gent=truth["gent"])
        for m in FIT["orders"]:
            for n in FIT["modes"]:
                omega = jaxdea.frequencies(tube, jaxdea.axial_wavenumber(tube, n), n_roots=1, m=m,
                                           n_layers=FIT["n_layers"])[0]
                rows.append((voltage, float(scales.omega_to_hz(omega)), m, n))
    table = np.array(rows)
    free = {k: (0.5 * truth[k], 1.5 * truth[k]) for k in FIT["start"]}
    free["eta"] = (0.6, 0.95)
    fixed = {k: v for k, v in truth.items() if k not in free}
    initial = {k: truth[k] * factor for k, factor in FIT["start"].items()}
    sigma = FIT["noise"] * table[:, 1]
    times, results = [], []
    for seed in range(1 + cfg["repeats"]):
        noise = np.random.default_rng(seed).standard_normal(len(rows))
        data = dict(voltage_V=table[:, 0], frequency_Hz=table[:, 1] + sigma * noise,
                    sigma_Hz=sigma, m=table[:, 2].astype(int), n=table[:, 3].astype(int))
        start = time.perf_counter()
        result = jaxdea.fit(data, free, fixed, initial=initial, n_layers=FIT["n_layers"],
                            n_starts=0)
        times.append(time.perf_counter() - start)
        results.append(result)
    best = int(np.argmin(times[1:])) + 1
    return dict(peaks=len(rows), parameters=len(free), first_call_s=times[0],
                seconds=times[best], iterations=int(results[best].iterations),
                status=results[best].status.name,
                max_rel_error=max(abs(results[best].estimate[k] / truth[k] - 1) for k in free))


def work_explore(cfg: dict) -> dict:
    """(i) One update of the ``jaxdea.explore`` app after a slider move, warm (the programs compiled
    by a first move): recomputing the curves (``explorer_data``), the whole update (curves, the
    stability status and rendering the figure) for V̂ on the empty tube at m = 0, the filled tube
    (acoustic) and m = 2, and a λ_i move, which solves ``first_instability`` again (m ≤ 4, n ≤ 3).
    Best of the repeats; the paper's tube, 45 α̂ × 3 branches, the default discretisation."""
    jax, jaxdea = _jax()
    from jaxdea.apps.explore import explorer_data

    tube = jaxdea.Tube(voltage=0.1, **PAPER_TUBE)
    app = jaxdea.explore(tube)

    def best_move(control, values):
        """Best time of one move (the update the user waits for); the background first-instability
        solve of a new wall is waited for after the timing, and its best time returned too."""
        app.controls[control].value = values[-1]  # compiles what this setting needs
        app.wait()
        best, background = math.inf, math.inf
        for i in range(cfg["repeats"] * len(values)):
            start = time.perf_counter()
            app.controls[control].value = values[i % len(values)]
            moved = time.perf_counter()
            app.wait()
            best = min(best, moved - start)
            background = min(background, time.perf_counter() - start)
        assert app.error is None, app.error
        return best, background

    rows = []
    cases = [("empty tube, m = 0", {}), ("filled tube (acoustic), m = 0", dict(filled="filled")),
             ("empty tube, m = 2", dict(filled="empty", m=2))]
    for label, settings in cases:
        app.set(**settings)
        parameters = app.parameters()
        data_s, _, _ = best_time(lambda p=parameters: explorer_data(*p).omega, cfg["repeats"],
                                 cfg["min_time"])
        rows.append(dict(label=label, data_s=data_s,
                         update_s=best_move("voltage", EXPLORE["voltages"])[0]))
    app.set(m=0)
    geometry, status = best_move("lambda_i", EXPLORE["lambda_i"])
    return dict(rows=rows, geometry_update_s=geometry, geometry_status_s=status,
                points=int(app.data.alpha.size),
                load_average=list(os.getloadavg()))


def _fig3_points():
    return [(li, v, n) for li in FIG3["lambda_i"] for v in FIG3["voltage"] for n in FIG3["n"]]


def work_fig3(impl: str, cfg: dict) -> dict:
    """Roots of the Fig.-3 sweep (λ_z = 1.2; λ_i × V̂ × n, 3 lowest roots each)."""
    points = _fig3_points()
    if impl == "scipy":
        sb = _baseline()
        done, roots, evals = [], {}, 0
        start = time.perf_counter()
        order = list(range(0, len(points), 7)) + [i for i in range(len(points)) if i % 7]
        for i in order:  # an even spread first; stop when the time budget is spent
            li, v, n = points[i]
            tube = sb.Tube(voltage=v, lambda_i=li, lambda_z=FIG3["lambda_z"])
            r, calls = sb.frequencies(tube, sb.axial_wavenumber(tube, n), n_roots=FIG3["n_roots"])
            roots[i], evals = r.tolist(), evals + calls
            done.append(i)
            if time.perf_counter() - start > cfg["scipy_budget_s"]:
                break
        sec = time.perf_counter() - start
        return dict(points=len(points), solved=len(done), seconds_solved=sec,
                    seconds_extrapolated=sec * len(points) / len(done), evaluations=evals,
                    roots={str(k): v for k, v in roots.items()})
    jax, jaxdea = _jax()

    def run_curves(n_layers=30, scheme="midpoint"):
        """The same roots by continuation along n: one dispersion_curve per (λ_i, V̂)."""
        out = []
        for li in FIG3["lambda_i"]:
            for v in FIG3["voltage"]:
                tube = jaxdea.Tube(lambda_z=FIG3["lambda_z"], lambda_i=li, voltage=v)
                alphas = jaxdea.axial_wavenumber(tube, np.array(FIG3["n"]))
                out.append(jaxdea.dispersion_curve(tube, alphas, n_roots=FIG3["n_roots"],
                                                   n_layers=n_layers, scheme=scheme).omega)
        return jax.numpy.stack(out)

    def run(n_layers=30, scheme="midpoint"):
        """The sweep: the guaranteed scan at every point."""
        return jaxdea.sweep(jaxdea.Tube(lambda_z=FIG3["lambda_z"]), n_roots=FIG3["n_roots"],
                            lambda_i=np.array(FIG3["lambda_i"]), voltage=np.array(FIG3["voltage"]),
                            n=np.array(FIG3["n"]), progress=False, n_layers=n_layers,
                            scheme=scheme).omega

    def flat(x):
        return np.asarray(x).reshape(len(points), FIG3["n_roots"])

    sec, first, omega = best_time(run, cfg["solve_repeats"], cfg["min_time"])
    omega = flat(omega)
    sec_c, first_c, omega_c = best_time(run_curves, cfg["solve_repeats"], cfg["min_time"])
    omega_c = flat(omega_c)
    # at the baseline's accuracy: the error of N = 30 (SciPy's laminate; its roots equal jaxdea's to
    # ~1e-13) against the sixth-order scheme at N = FIG3_REFERENCE, and the fewest magnus6 sublayers
    # that do as well
    reference = flat(run(FIG3_REFERENCE, "magnus6"))

    def error(x):
        same = np.array_equal(np.isnan(x), np.isnan(reference))
        return float(np.nanmax(np.abs(x / reference - 1.0))) if same else float("inf")

    laminate_error = error(omega)
    checks, chosen = [], None
    for n_layers in cfg["fig3_magnus_levels"]:
        err = error(flat(run(n_layers, "magnus6")))
        checks.append(dict(n_layers=n_layers, rel_error=err))
        if err <= laminate_error:
            chosen = n_layers
            break
    extra = dict(laminate_rel_error=laminate_error, magnus_checks=checks, magnus_chosen=chosen)
    if chosen is not None:
        repeats, min_time = cfg["solve_repeats"], cfg["min_time"]
        sec_m, _, omega_m = best_time(lambda: run(chosen, "magnus6"), repeats, min_time)
        sec_mc, _, omega_mc = best_time(lambda: run_curves(chosen, "magnus6"), repeats, min_time)
        extra.update(magnus_seconds=sec_m, magnus_seconds_curve=sec_mc,
                     magnus_rel_error=error(flat(omega_m)),
                     magnus_curve_vs_sweep=float(np.nanmax(np.abs(flat(omega_mc) / flat(omega_m) - 1.0))))
    return dict(points=len(points), seconds=sec, first_call_s=first, roots=omega.tolist(),
                seconds_curve=sec_c, first_call_curve_s=first_c,
                curve_vs_sweep=float(np.nanmax(np.abs(omega_c / omega - 1.0))),
                curve_nan_match=bool(np.array_equal(np.isnan(omega_c), np.isnan(omega))), **extra)


def _curve_alphas():
    return np.linspace(CURVE["alpha_min"], CURVE["alpha_max"], CURVE["points"])


def _richardson(coarse, fine):
    return (4.0 * np.asarray(fine) - np.asarray(coarse)) / 3.0


def work_curve_jaxdea(cfg: dict) -> dict:
    """The unstretched-tube curve (200 α̂ × 4 roots) at 1e-8 relative accuracy.

    Roots are isolated by ``jaxdea.sweep`` on the laminate of N sublayers (every root of that
    laminate is found), then followed by ``jaxdea.frequency`` (safeguarded Newton, vmapped over all
    roots) on the laminate 2N, and combined by Richardson (4Ω(2N) − Ω(N))/3 (error O(N⁻⁴)). N is the
    smallest of ``curve_levels`` whose result on every 10th α̂ meets 1e-8 against the reference
    Richardson(240, 480) (followed the same way, from the N = 30 roots); the timing is that of the
    whole chain at that N."""
    jax, jaxdea = _jax()
    alphas = _curve_alphas()
    tube = jaxdea.Tube()

    def roots_at(alpha, n_layers, scheme="midpoint"):
        return np.asarray(jaxdea.sweep(tube, n_roots=CURVE["n_roots"], n_layers=n_layers,
                                       scheme=scheme, alpha=alpha, progress=False).omega)

    follow_fns = {}

    def follow(alpha, seeds, n_layers):
        """Newton from the seeds on the laminate of ``n_layers`` (NaN seeds stay NaN)."""
        if n_layers not in follow_fns:
            one = lambda a, g: jaxdea.frequency(tube, a, g, n_layers=n_layers)  # noqa: E731
            follow_fns[n_layers] = jax.jit(jax.vmap(one))
        a = np.broadcast_to(np.asarray(alpha)[:, None], seeds.shape).ravel()
        g = seeds.ravel()
        ok = np.isfinite(g)
        out = np.asarray(follow_fns[n_layers](a, np.where(ok, g, 1.0)))
        return np.where(ok, out, np.nan).reshape(seeds.shape)

    def curve(alpha, n_layers):
        coarse = roots_at(alpha, n_layers)
        return _richardson(coarse, follow(alpha, coarse, 2 * n_layers))

    subset = alphas[::10]
    seeds = roots_at(subset, 30)
    reference = _richardson(follow(subset, seeds, REFERENCE_LAYERS),
                            follow(subset, seeds, 2 * REFERENCE_LAYERS))
    checks, chosen = [], None
    for n_layers in cfg["curve_levels"]:
        coarse = roots_at(subset, n_layers)
        fine = follow(subset, coarse, 2 * n_layers)
        plain = np.max(np.abs(fine / reference - 1.0))
        extrapolated = np.max(np.abs(_richardson(coarse, fine) / reference - 1.0))
        checks.append(dict(n_layers=n_layers, plain_rel_error=float(plain),
                           richardson_rel_error=float(extrapolated)))
        if extrapolated <= CURVE["rtol"]:  # NaN (a root lost) never passes
            chosen = n_layers
            break
    if chosen is None:
        return dict(checks=checks, chosen=None, n_subset=len(subset))

    def continued(alpha, n_layers):
        """The same chain by continuation in α̂ (dispersion_curve) on both laminates."""
        coarse, fine = (jaxdea.dispersion_curve(tube, alpha, n_roots=CURVE["n_roots"], n_layers=n)
                        for n in (n_layers, 2 * n_layers))
        return _richardson(coarse.omega, fine.omega), int(coarse.scanned.sum() + fine.scanned.sum())

    sec, first, omega = best_time(lambda: curve(alphas, chosen), cfg["solve_repeats"], cfg["min_time"])
    sec_c, first_c, (omega_c, scans) = best_time(lambda: continued(alphas, chosen),
                                                 cfg["solve_repeats"], cfg["min_time"])
    sub, sub_c = omega[::10], omega_c[::10]

    # one laminate of the sixth-order Magnus scheme instead of two midpoint laminates and Richardson
    magnus_checks, magnus = [], None
    for n_layers in cfg["magnus_levels"]:
        err = float(np.max(np.abs(roots_at(subset, n_layers, "magnus6") / reference - 1.0)))
        magnus_checks.append(dict(n_layers=n_layers, rel_error=err))
        if err <= CURVE["rtol"]:
            magnus = n_layers
            break
    extra = dict(magnus_checks=magnus_checks, magnus_chosen=magnus)
    if magnus is not None:
        sec_m, first_m, omega_m = best_time(lambda: roots_at(alphas, magnus, "magnus6"),
                                            cfg["solve_repeats"], cfg["min_time"])
        sec_mc, first_mc, curve_m = best_time(
            lambda: jaxdea.dispersion_curve(tube, alphas, n_roots=CURVE["n_roots"], n_layers=magnus,
                                            scheme="magnus6"), cfg["solve_repeats"], cfg["min_time"])
        omega_mc = np.asarray(curve_m.omega)
        extra.update(magnus_seconds=sec_m, magnus_first_call_s=first_m,
                     magnus_rel_error=float(np.nanmax(np.abs(omega_m[::10] / reference - 1.0))),
                     magnus_seconds_curve=sec_mc, magnus_first_call_curve_s=first_mc,
                     magnus_curve_scans=int(np.sum(curve_m.scanned)),
                     magnus_curve_rel_error=float(np.nanmax(np.abs(omega_mc[::10] / reference - 1.0))),
                     magnus_curve_vs_sweep=float(np.nanmax(np.abs(omega_mc / omega_m - 1.0))))
    return dict(checks=checks, chosen=chosen, seconds=sec, first_call_s=first, **extra,
                finite=int(np.sum(np.isfinite(omega))), roots=sub.tolist(),
                measured_rel_error=float(np.nanmax(np.abs(sub / reference - 1.0))),
                reference=reference.tolist(), n_subset=len(subset),
                seconds_curve=sec_c, first_call_curve_s=first_c, curve_scans=scans,
                curve_rel_error=float(np.nanmax(np.abs(sub_c / reference - 1.0))),
                curve_vs_sweep=float(np.nanmax(np.abs(omega_c / omega - 1.0))),
                curve_nan_match=bool(np.array_equal(np.isnan(omega_c), np.isnan(omega))))


def work_curve_scipy(cfg: dict, n_layers: int) -> dict:
    """The same curve with the SciPy baseline: roots isolated on the laminate N (grid + brentq),
    then brentq on the laminate 2N in a bracket of ±1e-3 Ω around each (the full scan again where
    that bracket holds no sign change), Richardson. Every 10th α̂ is timed until the budget is spent;
    the time is extrapolated to the 200 α̂."""
    import scipy.optimize

    sb = _baseline()
    tube = sb.Tube()
    alphas = _curve_alphas()
    roots, start = {}, time.perf_counter()

    def follow(alpha, seeds, layers):
        wall = sb.discretize(tube, layers)
        f = lambda om: sb.characteristic_on_wall(wall, om, alpha)  # noqa: E731
        out = []
        for r in seeds:
            lo, hi = r * (1 - 1e-3), r * (1 + 1e-3)
            if np.isfinite(r) and f(lo) * f(hi) < 0:
                out.append(scipy.optimize.brentq(f, lo, hi, xtol=1e-14, rtol=4 * np.finfo(float).eps))
            else:
                return sb.frequencies(tube, alpha, n_roots=len(seeds), n_layers=layers, wall=wall)[0]
        return np.array(out)

    for i in range(0, len(alphas), 10):  # the reference subset: every 10th α̂
        seeds, _ = sb.frequencies(tube, alphas[i], n_roots=CURVE["n_roots"], n_layers=n_layers)
        roots[i // 10] = _richardson(seeds, follow(alphas[i], seeds, 2 * n_layers)).tolist()
        if time.perf_counter() - start > cfg["scipy_budget_s"]:
            break
    sec = time.perf_counter() - start
    return dict(solved=len(roots), seconds_solved=sec,
                seconds_extrapolated=sec * len(alphas) / len(roots),
                roots={str(k): v for k, v in roots.items()})


def work_compile(what: str, cache: bool = False) -> dict:
    """First-call time in a fresh process; compile ≈ first call − second call.

    ``cache=False``: without the persistent compile cache (JAXDEA_CACHE_DIR=off set by the parent).
    ``cache=True``: with the cache directory the parent chose and filled by an earlier run of the
    same call, so the first call loads the compiled program (:mod:`jaxdea.compiled`)."""
    start = time.perf_counter()
    jax, jaxdea = _jax()
    imported = time.perf_counter() - start
    enabled = jax.config.jax_compilation_cache_dir is not None
    assert enabled == cache, f"persistent compile cache {'off' if cache else 'still enabled'}"
    tube = jaxdea.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
    if what == "frequencies":
        call = lambda a: jaxdea.frequencies(tube, a)  # noqa: E731
    elif what == "critical_voltage":
        call = lambda a: jaxdea.critical_voltage(tube, a)  # noqa: E731
    else:
        call = lambda a: jaxdea.characteristic(tube, 1.0, a)  # noqa: E731
    start = time.perf_counter()
    jax.block_until_ready(call(0.445))
    first = time.perf_counter() - start
    start = time.perf_counter()
    jax.block_until_ready(call(0.89))
    second = time.perf_counter() - start
    return dict(import_s=imported, first_call_s=first, second_call_s=second, compile_s=first - second)


def work_defaults(cfg: dict) -> dict:
    """(j) The default, accurate discretisation (``n_layers=None``: graded magnus6, N from the case)
    against the paper's laminate (``scheme="midpoint", n_layers=30``, the default before) on
    the cases where the paper's laminate was inaccurate: time (warm, best of the repeats) and the
    relative error of each against a converged reference (the same scheme on a graded wall 4× finer
    than the accurate one's, error 4⁶ times smaller)."""
    jax, jaxdea = _jax()
    import numpy as np

    from jaxdea.physics.problem import describe
    from jaxdea.physics.transfer import Layers, laminate
    from jaxdea.solve import roots as R

    paper = jaxdea.Tube(voltage=0.0, **PAPER_TUBE)
    alpha1 = float(jaxdea.axial_wavenumber(paper, 1))
    locking = jaxdea.Tube(voltage=0.05, lambda_i=0.35890249, lambda_z=1.2, eta=0.75, gent=4.0)
    alpha_lock = float(jaxdea.axial_wavenumber(locking, 2))
    unstretched = jaxdea.Tube(eta=0.85)

    def fine_roots(tube, alpha, fluid=None, n_roots=3):
        layers = laminate(None, None, tube, alpha, n_roots)
        order = describe(tube, alpha, fluid, None, None).order
        t, a, f, om = R.canonical(tube, alpha, fluid, None)
        return np.asarray(R._solve_frequencies(t, a, f, om, n_roots, Layers(4 * layers.count,
                                                                            "magnus6", True),
                                               order).omega)

    v_ref = float(jaxdea.critical_voltage(paper, alpha1, n_layers=4 * laminate(
        None, None, paper, alpha1).count, scheme="magnus6"))
    near = paper.replace(voltage=0.9999 * v_ref)
    curve_alphas = np.linspace(0.01, 5.0, 40)
    cases = [
        ("V̂_cr of the paper's tube (λ_i 0.9, n = 1)",
         lambda **kw: np.asarray(jaxdea.critical_voltage(paper, alpha1, **kw)), np.asarray(v_ref)),
        ("lowest root at V̂ = 0.9999 V̂_cr",
         lambda **kw: np.asarray(jaxdea.frequencies(near, alpha1, n_roots=1, **kw)),
         fine_roots(near, alpha1, n_roots=1)),
        ("unstretched tube, 40 α̂ in 0.01–5 × 3 roots (`frequencies` per point)",
         lambda **kw: np.stack([np.asarray(jaxdea.frequencies(unstretched, a, **kw))
                                for a in curve_alphas]),
         np.stack([fine_roots(unstretched, a) for a in curve_alphas])),
        ("99 % of Gent locking (G = 4), acoustic fluid, n = 2, 3 roots",
         lambda **kw: np.asarray(jaxdea.frequencies(locking, alpha_lock, jaxdea.Fluid(), **kw)),
         fine_roots(locking, alpha_lock, jaxdea.Fluid())),
        ("paper's tube at V̂ = 0.1, α̂ = 0.445, 3 roots",
         lambda **kw: np.asarray(jaxdea.frequencies(paper.replace(voltage=0.1), 0.445, **kw)),
         fine_roots(paper.replace(voltage=0.1), 0.445)),
    ]
    rows = []
    for label, run, ref in cases:
        row = dict(label=label)
        for key, kw in (("paper", dict(scheme="midpoint", n_layers=30)), ("default", dict(n_layers=None))):
            got = run(**kw)
            row[f"{key}_error"] = float(np.nanmax(np.abs(got - ref) / np.abs(ref)))
            row[f"{key}_s"] = best_time(lambda kw=kw, run=run: run(**kw), cfg["solve_repeats"],
                                        cfg["min_time"])[0]
        rows.append(row)
    first = {}
    for key, kw in (("paper", dict(scheme="midpoint", n_layers=30)), ("default", dict(n_layers=None))):
        jaxdea.first_instability(paper, n_max=3, m_max=8, **kw).voltage.block_until_ready()
        first[key] = best_time(lambda kw=kw: jaxdea.first_instability(
            paper, n_max=3, m_max=8, **kw).voltage.block_until_ready(), cfg["solve_repeats"],
            cfg["min_time"])[0]
    return dict(rows=rows, first_instability_s=first, load_average=list(os.getloadavg()))


def _fixed_quintic(hist_alpha, hist_omega, n_hist, alpha, slope=None):
    """The continuation's predictor before the adaptive order (section k): the Lagrange polynomial
    through the newest min(n, 6) rows, the tangent line after a scan."""
    import jax.numpy as jnp

    if slope is not None:
        tangent = jnp.isfinite(slope) & (n_hist <= 1)
        line = hist_omega[-1] + jnp.where(tangent, slope, 0.0) * (alpha - hist_alpha[-1])
        return jnp.where(tangent, line, _fixed_quintic(hist_alpha, hist_omega, n_hist, alpha))
    size = hist_alpha.shape[0]
    row = jnp.arange(size)
    used = row >= size - jnp.clip(n_hist, 1, 6)
    w = jnp.where(used, 1.0, 0.0)
    for j in range(size):
        w = jnp.where(used & used[j] & (row != j),
                      w * (alpha - hist_alpha[j]) / (hist_alpha - hist_alpha[j]), w)
    return w @ jnp.where(jnp.isfinite(hist_omega), hist_omega, 0.0)


def work_gewtool(cfg: dict) -> dict:
    """(k) The GEWtool-shaped curve: the unstretched tube (η = 0.85, G = 97.2), 200 α̂ in 0.01–5,
    the 4 lowest roots, ``jaxdea.dispersion_curve`` at the default discretisation (no accuracy
    arguments). Timed warm: the public call, and its compiled program side by side (alternating
    repeats, best of each) with the continuation before the adaptive predictor and the shared
    curvature refresh, with the adaptive predictor alone, and the current one on the magnus6
    N = 5 wall; the derivative attachment the public call skips on concrete inputs is timed
    alone. Accuracy: every root against the exact incompressible cylinder
    (``tests/exact_cylinder.py``; every 4th α̂ with --quick)."""
    jax, jaxdea = _jax()
    import numpy as np

    sys.path.insert(0, os.path.join(ROOT, "tests"))
    import exact_cylinder

    from jaxdea.compiled import compiler_options
    from jaxdea.params import canonical
    from jaxdea.physics.transfer import Layers, laminate
    from jaxdea.solve import curves
    from jaxdea.solve.roots import Roots, attach_derivatives

    tube = jaxdea.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
    alpha = np.linspace(0.01, 5.0, 200)
    n_roots = 4
    public = best_time(lambda: jaxdea.dispersion_curve(tube, alpha, n_roots=n_roots),
                       cfg["solve_repeats"], cfg["min_time"])
    curve = public[2]
    omega = np.asarray(curve.omega)
    t, a, m = canonical(tube, alpha, 0.0)
    layers = laminate(None, None, t, a, n_roots, m)
    statics = ("n_roots", "n_layers", "order", "family")
    saved = curves._extrapolate, curves._refresh
    programs = {}
    for key, patch in (("before", (_fixed_quintic, lambda k, age: jax.numpy.array(False))),
                       ("adaptive_predictor", (curves._extrapolate,
                                               lambda k, age: jax.numpy.array(False))),
                       ("current", saved)):
        curves._extrapolate, curves._refresh = patch

        def variant(tube, alpha, fluid, n_roots, n_layers, order):  # its own trace cache
            return curves.curve_unchecked(tube, alpha, fluid, n_roots, n_layers, order)

        program = jax.jit(variant, static_argnames=statics[:3], compiler_options=compiler_options())
        jax.block_until_ready(program(t, a, None, n_roots, layers, 0))  # traced with the patch
        programs[key] = (program, layers)
    curves._extrapolate, curves._refresh = saved
    programs["current_magnus6_n5"] = (programs["current"][0], Layers(5, "magnus6"))
    outputs = {k: jax.block_until_ready(p(t, a, None, n_roots, lay, 0))
               for k, (p, lay) in programs.items()}
    calls = {k: (lambda p=p, lay=lay: p(t, a, None, n_roots, lay, 0))
             for k, (p, lay) in programs.items()}
    calls["public"] = lambda: jaxdea.dispersion_curve(tube, alpha, n_roots=n_roots)
    best = dict.fromkeys(calls, math.inf)
    for _ in range(3 * cfg["solve_repeats"]):
        for k, call in calls.items():
            start = time.perf_counter()
            jax.block_until_ready(call())
            best[k] = min(best[k], time.perf_counter() - start)
    attach = jax.vmap(lambda w, s, x: attach_derivatives(Roots(w, s), (t, x, None, m), layers, 0,
                                                        "omega").omega)
    attach_s = best_time(lambda: attach(curve.omega, curve.status, a), cfg["solve_repeats"],
                         cfg["min_time"])[0]
    rows = range(0, 200, 4 if cfg["quick"] else 1)
    exact = np.array([exact_cylinder.roots(alpha[i], 1.0, 1 / 0.85, n_roots,
                                           1.3 * omega[i, -1] + 0.5, 2000) for i in rows])
    return dict(
        n_layers=layers.count, scheme=layers.scheme, seconds=min(public[0], best["public"]),
        first_call_s=public[1],
        scanned=int(np.sum(np.asarray(curve.scanned))),
        converged=bool(np.all(np.asarray(curve.status) == jaxdea.Status.CONVERGED)),
        exact_rel_error=float(np.max(np.abs(omega[list(rows)] / exact - 1.0))),
        exact_points=len(rows),
        program_s={k: v for k, v in best.items() if k != "public"},
        vs_current={k: float(np.nanmax(np.abs(np.asarray(o.omega) / omega - 1.0)))
                    for k, o in outputs.items() if k != "current_magnus6_n5"},
        magnus6_n5_exact_rel_error=float(np.max(np.abs(
            np.asarray(outputs["current_magnus6_n5"].omega)[list(rows)] / exact - 1.0))),
        attach_s=attach_s, load_average=list(os.getloadavg()))


def worker(name: str, params: dict) -> None:
    """Run one workload and print its result as JSON (last line of stdout)."""
    cfg = params["cfg"]
    rss0 = peak_rss_mb()
    if name == "characteristic":
        result = work_characteristic(params["impl"], params["layers"], params["batches"], cfg)
    elif name == "fig3":
        result = work_fig3(params["impl"], cfg)
    elif name == "curve_jaxdea":
        result = work_curve_jaxdea(cfg)
    elif name == "curve_scipy":
        result = work_curve_scipy(cfg, params["n_layers"])
    elif name == "compile":
        result = work_compile(params["what"], params.get("cache", False))
    elif name == "order_m":
        result = work_order_m(cfg)
    elif name == "explore":
        result = work_explore(cfg)
    elif name == "fit":
        result = work_fit(cfg)
    elif name == "defaults":
        result = work_defaults(cfg)
    elif name == "gewtool":
        result = work_gewtool(cfg)
    else:
        raise ValueError(f"unknown worker {name!r}")
    result.update(rss_start_mb=rss0, rss_peak_mb=peak_rss_mb())
    print(json.dumps(result))


def spawn_worker(name: str, params: dict, env_extra=None, timeout=3600) -> dict:
    """Run a worker in a fresh Python process; its JSON result with the wall time."""
    env = dict(os.environ, **SINGLE_THREAD, **(env_extra or {}))
    start = time.perf_counter()
    done = subprocess.run([sys.executable, os.path.abspath(__file__), "--worker", name,
                           "--params", json.dumps(params)], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=timeout)
    if done.returncode != 0:
        raise RuntimeError(f"worker {name} {params.get('impl', '')} failed:\n{done.stderr[-4000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    result["wall_s"] = time.perf_counter() - start
    print(f"  {name} {params.get('impl', params.get('what', ''))}: {result['wall_s']:.1f} s",
          flush=True)
    return result


# ------------------------------------------------------------------------------------ the report
def machine_info() -> dict:
    import jax
    import jaxlib
    import scipy

    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return dict(cpu=cpu, cores=os.cpu_count(), python=platform.python_version(),
                jax=jax.__version__, jaxlib=jaxlib.__version__, numpy=np.__version__,
                scipy=scipy.__version__, device=str(jax.devices()[0]),
                backend=jax.default_backend(), load_average=list(os.getloadavg()),
                date=time.strftime("%Y-%m-%d %H:%M:%S"))


def compare(points_a, points_b, rtol=1e-6):
    """Roots of two solvers point by point, matched by value (rtol): (max relative difference of
    the matched roots, roots only in a, roots only in b)."""
    diff, only_a, only_b = 0.0, 0, 0
    for ra, rb in zip(points_a, points_b, strict=True):
        ra = np.asarray(ra, float)[np.isfinite(ra)]
        rb = np.asarray(rb, float)[np.isfinite(rb)]
        top = min(ra.max(initial=-np.inf), rb.max(initial=-np.inf))  # compare below both ends
        ra, rb = ra[ra <= top * (1 + rtol)], rb[rb <= top * (1 + rtol)]
        for x in ra:
            j = np.argmin(np.abs(rb / x - 1.0)) if rb.size else None
            if j is not None and abs(rb[j] / x - 1.0) <= rtol:
                diff = max(diff, float(abs(rb[j] / x - 1.0)))
            else:
                only_a += 1
        only_b += int(sum(not np.any(np.abs(ra / y - 1.0) <= rtol) for y in rb))
    return diff, only_a, only_b


def run_all(cfg: dict, partial: str, reuse: bool) -> dict:
    """Every workload, each result saved to ``partial`` as it comes (``reuse``: skip those there)."""
    res = dict(settings=cfg)
    done = {}
    if reuse and os.path.exists(partial):
        with open(partial) as f:
            done = json.load(f)

    def spawn(key, name, params, env_extra=None):
        if key in done and done[key].get("settings") == cfg:
            print(f"  {key}: reused from {partial}", flush=True)
            res[key] = done[key]["result"]
            return res[key]
        res[key] = spawn_worker(name, params, env_extra)
        done[key] = dict(settings=cfg, result=res[key])
        with open(partial, "w") as f:
            json.dump(done, f)
        return res[key]

    print("characteristic (a, f) ...", flush=True)
    layers_extra = [n for n in cfg["layers"] if n != 30]
    for impl in ("jaxdea", "naive", "scipy"):
        spawn(f"char_{impl}", "characteristic", dict(impl=impl, layers=[30], batches=cfg["batches"],
                                                     cfg=cfg))
        spawn(f"layers_{impl}", "characteristic", dict(impl=impl, layers=layers_extra,
                                                       batches=[cfg["layer_batch"]], cfg=cfg))
    print("Fig.-3 sweep (b, c) ...", flush=True)
    spawn("fig3_jaxdea", "fig3", dict(impl="jaxdea", cfg=cfg))
    spawn("fig3_scipy", "fig3", dict(impl="scipy", cfg=cfg))
    print("200 x 4 curve at 1e-8 (b, c) ...", flush=True)
    chosen = spawn("curve_jaxdea", "curve_jaxdea", dict(cfg=cfg)).get("chosen") or cfg["curve_levels"][-1]
    spawn("curve_scipy", "curve_scipy", dict(cfg=cfg, n_layers=chosen))
    print("order m (g) ...", flush=True)
    spawn("order_m", "order_m", dict(cfg=cfg))
    print("interactive explorer (i) ...", flush=True)
    spawn("explore", "explore", dict(cfg=cfg))
    print("fit (h) ...", flush=True)
    spawn("fit", "fit", dict(cfg=cfg))
    print("GEWtool-shaped curve at the default discretisation (k) ...", flush=True)
    spawn("gewtool", "gewtool", dict(cfg=cfg))
    print("first-call compile, no persistent cache (d) ...", flush=True)
    for what in FIRST_CALLS:
        spawn(f"compile_{what}", "compile", dict(what=what, cfg=cfg),
              env_extra=dict(JAXDEA_CACHE_DIR="off"))
    print("first call with a warm persistent cache (d) ...", flush=True)
    with tempfile.TemporaryDirectory() as cache_dir:
        for what in FIRST_CALLS:
            for key in (f"cache_fill_{what}", f"cache_warm_{what}"):  # the first run fills it
                done.pop(key, None)  # a reused entry would not have filled this directory
                spawn(key, "compile", dict(what=what, cache=True, cfg=cfg),
                      env_extra=dict(JAXDEA_CACHE_DIR=cache_dir))
    res["machine"] = machine_info()
    return res


def _rate(rows, n_layers, batch):
    for r in rows:
        if r["n_layers"] == n_layers and r["batch"] == batch:
            return r["evals_per_s"]
    return math.nan


def fmt(x, digits=3):
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if abs(x) >= 100:
        return f"{x:,.0f}"
    return f"{x:.{digits}g}"


def render(res: dict, provisional: bool) -> str:
    cfg, m = res["settings"], res["machine"]
    lines = ["# jaxdea benchmarks", ""]
    if provisional:
        lines += ["**PROVISIONAL** (`--quick` run while the core is being optimised and the 2-core "
                  "machine is shared with other jobs: absolute numbers are noisy and low; only the "
                  "ratios measured in the same run mean something; the final table is regenerated "
                  "at the end).", ""]
    load = ", ".join(f"{x:.1f}" for x in m["load_average"])
    lines += [f"Machine: {m['cpu']}, {m['cores']} cores, backend `{m['backend']}` ({m['device']}); "
              f"Python {m['python']}, jax {m['jax']}, jaxlib {m['jaxlib']}, NumPy {m['numpy']}, "
              f"SciPy {m['scipy']}; load average at the end {load}; "
              f"{m['date']}. Mode: {'--quick' if cfg['quick'] else 'full'}; best of {cfg['repeats']} "
              f"repeats (root solves: {cfg['solve_repeats']}) after a warm-up; single-threaded BLAS "
              "everywhere.", ""]
    # (a) characteristic
    cj, cn, cs = (res[f"char_{k}"]["rows"] for k in ("jaxdea", "naive", "scipy"))
    lines += ["## (a) Characteristic evaluations per second, N = 30", "",
              "| batch | jaxdea | naive vmap(expm) | SciPy loop | jaxdea / naive | jaxdea / SciPy |",
              "|---:|---:|---:|---:|---:|---:|"]
    for b in cfg["batches"]:
        j, n, s = _rate(cj, 30, b), _rate(cn, 30, b), _rate(cs, 30, b)
        lines.append(f"| {b} | {fmt(j)} | {fmt(n)} | {fmt(s)} | {fmt(j / n)}× | {fmt(j / s)}× |")
    lines += ["", "The SciPy loop evaluates at most "
              f"{cfg['scipy_max_evals']} Ω of a batch (its rate does not depend on the batch).", ""]
    # (f) scaling with N
    lj, ln, ls = (res[f"layers_{k}"]["rows"] + res[f"char_{k}"]["rows"]
                  for k in ("jaxdea", "naive", "scipy"))
    b = cfg["layer_batch"]
    lines += [f"## (f) Scaling with N (batch {b}), evaluations per second", "",
              "| N | jaxdea | naive | SciPy | jaxdea / naive | jaxdea / SciPy |",
              "|---:|---:|---:|---:|---:|---:|"]
    for n_layers in cfg["layers"]:
        bb = b if n_layers != 30 else min(cfg["batches"], key=lambda x: abs(x - b))
        j, n, s = _rate(lj, n_layers, bb), _rate(ln, n_layers, bb), _rate(ls, n_layers, bb)
        note = f" (batch {bb})" if bb != b else ""
        lines.append(f"| {n_layers}{note} | {fmt(j)} | {fmt(n)} | {fmt(s)} | {fmt(j / n)}× | {fmt(j / s)}× |")
    lines += ["", "Scaling with batch size: the rows of (a) (N = 30).", ""]
    # (b, c) sweeps
    fj, fs = res["fig3_jaxdea"], res["fig3_scipy"]
    fig_roots = fj["points"] * FIG3["n_roots"]
    diff, only_s, only_j = compare([fs["roots"][k] for k in fs["roots"]],
                                   [fj["roots"][int(k)] for k in fs["roots"]])
    note = f" (extrapolated from {fs['solved']} points)" if fs["solved"] < fs["points"] else ""
    cvj, cvs = res["curve_jaxdea"], res["curve_scipy"]
    lines += ["## (b, c) Root solves", "",
              "| workload | jaxdea | SciPy baseline | jaxdea / SciPy |", "|---|---:|---:|---:|",
              f"| Fig. 3 sweep: {fj['points']} points × {FIG3['n_roots']} roots, N = 30: seconds | "
              f"{fmt(fj['seconds'])} | {fmt(fs['seconds_extrapolated'])}"
              f"{note} | "
              f"{fmt(fs['seconds_extrapolated'] / fj['seconds'])}× |",
              f"| Fig. 3 sweep: root solves per second | {fmt(fig_roots / fj['seconds'])} | "
              f"{fmt(fig_roots / fs['seconds_extrapolated'])} | |"]
    if "seconds_curve" in fj:
        lines += [f"| Fig. 3 by continuation along n (`dispersion_curve`, 4 lines of 20 modes): "
                  f"seconds | {fmt(fj['seconds_curve'])} | {fmt(fs['seconds_extrapolated'])} | "
                  f"{fmt(fs['seconds_extrapolated'] / fj['seconds_curve'])}× |"]
    if fj.get("magnus_chosen"):
        m, scipy_s = fj["magnus_chosen"], fs["seconds_extrapolated"]
        what = (f"Fig. 3 at the baseline's accuracy, `scheme=\"magnus6\"` N = {m} (max rel. error "
                f"{fj['magnus_rel_error']:.1e}, N = 30 has {fj['laminate_rel_error']:.1e}; against "
                f"magnus6 N = {FIG3_REFERENCE})")
        lines += [f"| {what} by `sweep`: seconds | {fmt(fj['magnus_seconds'])} | {fmt(scipy_s)} | "
                  f"{fmt(scipy_s / fj['magnus_seconds'])}× |",
                  f"| {what} by `dispersion_curve` along n: seconds | "
                  f"{fmt(fj['magnus_seconds_curve'])} | {fmt(scipy_s)} | "
                  f"{fmt(scipy_s / fj['magnus_seconds_curve'])}× |"]
    if cvj.get("chosen"):
        n_curve = CURVE["points"] * CURVE["n_roots"]
        cdiff, conly_s, conly_j = compare([cvs["roots"][k] for k in cvs["roots"]],
                                          [cvj["roots"][int(k)] for k in cvs["roots"]])
        lines += [f"| curve {CURVE['points']} α̂ × {CURVE['n_roots']} roots at 1e-8 (isolated at "
                  f"N = {cvj['chosen']}, Richardson of N = {cvj['chosen']}, {2 * cvj['chosen']}; "
                  f"measured rel. error "
                  f"{cvj['measured_rel_error']:.1e}): seconds | {fmt(cvj['seconds'])} | "
                  f"{fmt(cvs['seconds_extrapolated'])} (extrapolated from {cvs['solved']} α̂) | "
                  f"{fmt(cvs['seconds_extrapolated'] / cvj['seconds'])}× |",
                  f"| curve: root solves per second | {fmt(n_curve / cvj['seconds'])} | "
                  f"{fmt(n_curve / cvs['seconds_extrapolated'])} | |"]
        if "seconds_curve" in cvj:
            lines += [f"| curve by continuation in α̂ (`dispersion_curve` at N = {cvj['chosen']} "
                      f"and {2 * cvj['chosen']}, Richardson; {cvj['curve_scans']} of "
                      f"{2 * CURVE['points']} steps scanned; measured rel. error "
                      f"{cvj['curve_rel_error']:.1e}): seconds | {fmt(cvj['seconds_curve'])} | "
                      f"{fmt(cvs['seconds_extrapolated'])} | "
                      f"{fmt(cvs['seconds_extrapolated'] / cvj['seconds_curve'])}× |",
                      f"| curve by continuation: root solves per second | "
                      f"{fmt(n_curve / cvj['seconds_curve'])} | | |"]
        if cvj.get("magnus_chosen"):
            m = cvj["magnus_chosen"]
            lines += [f"| curve by `sweep` with `scheme=\"magnus6\"` (one laminate, N = {m}; measured "
                      f"rel. error {cvj['magnus_rel_error']:.1e}): seconds | "
                      f"{fmt(cvj['magnus_seconds'])} | {fmt(cvs['seconds_extrapolated'])} | "
                      f"{fmt(cvs['seconds_extrapolated'] / cvj['magnus_seconds'])}× |",
                      f"| curve by `dispersion_curve` with `scheme=\"magnus6\"` (N = {m}; "
                      f"{cvj['magnus_curve_scans']} of {CURVE['points']} steps scanned; measured rel. "
                      f"error {cvj['magnus_curve_rel_error']:.1e}): seconds | "
                      f"{fmt(cvj['magnus_seconds_curve'])} | {fmt(cvs['seconds_extrapolated'])} | "
                      f"{fmt(cvs['seconds_extrapolated'] / cvj['magnus_seconds_curve'])}× |"]
    lines += ["", f"Agreement (roots matched by value, below the highest root of both): Fig. 3, the "
              f"{fs['solved']} points solved by both: max relative difference {diff:.1e}; "
              f"{only_j} roots found by jaxdea only (missed by the SciPy sign-change scan: two roots "
              f"inside one grid step), {only_s} by SciPy only."]
    if cvj.get("chosen"):
        lines += [f"Curve, {cvs['solved']} α̂: max relative difference {cdiff:.1e}; {conly_j} roots "
                  f"found by jaxdea only, {conly_s} by SciPy only."]
    for name, r in (("Fig. 3", fj), ("Curve", cvj)):
        if "curve_vs_sweep" in r:
            same = "the same" if r["curve_nan_match"] else "NOT the same"
            lines += [f"{name}: continuation against `sweep` (the scan at every point): max relative "
                      f"difference {r['curve_vs_sweep']:.1e}, {same} missing roots."]
    for name, r in (("Fig. 3", fj), ("Curve", cvj)):
        if "magnus_curve_vs_sweep" in r:
            lines += [f"{name}, magnus6: continuation against `sweep`: max relative difference "
                      f"{r['magnus_curve_vs_sweep']:.1e}."]
    if "magnus_checks" in fj:
        tried = ", ".join(f"N = {c['n_layers']}: {c['rel_error']:.1e}" for c in fj["magnus_checks"])
        lines += ["", f"Fig. 3 at the baseline's accuracy: the midpoint laminate N = 30 (the baseline's "
                  f"discretisation) is {fj['laminate_rel_error']:.1e} off magnus6 N = {FIG3_REFERENCE} "
                  f"(max rel. error over the 240 roots); magnus6 tried: {tried}; the first N that "
                  f"does as well is timed."]
    lines += ["", f"Accuracy of the curve (every 10th α̂, {cvj.get('n_subset', '?')} α̂ × {CURVE['n_roots']} "
              f"roots, against Richardson(N = {REFERENCE_LAYERS}, {2 * REFERENCE_LAYERS})):", "",
              "| N | Ω(2N): max rel. error | Richardson (4Ω(2N) − Ω(N))/3: max rel. error |",
              "|---:|---:|---:|"]
    for c in cvj["checks"]:
        lines.append(f"| {c['n_layers']} | {c['plain_rel_error']:.1e} | {c['richardson_rel_error']:.1e} |")
    lines += ["", f"The first N whose Richardson value meets {CURVE['rtol']:g} is timed "
              f"({cvj.get('chosen') or 'none met it'})."]
    if cvj.get("magnus_checks"):
        lines += ["", "The sixth-order Magnus scheme (`scheme=\"magnus6\"`, one laminate, no "
                  "Richardson), same reference:", "", "| N | max rel. error |", "|---:|---:|"]
        lines += [f"| {c['n_layers']} | {c['rel_error']:.1e} |" for c in cvj["magnus_checks"]]
        lines += ["", f"The first N that meets {CURVE['rtol']:g} is timed "
                  f"({cvj.get('magnus_chosen') or 'none met it'})."]
    lines += [""]
    # (d) compile, (e) memory
    lines += ["## (d) First call in a fresh process, persistent compile cache off", "",
              "| function | import jaxdea (s) | first call (s) | second call (s) "
              "| compile ≈ first − second (s) |",
              "|---|---:|---:|---:|---:|"]
    for what in FIRST_CALLS:
        c = res[f"compile_{what}"]
        lines.append(f"| `{what}` | {fmt(c['import_s'])} | {fmt(c['first_call_s'])} | "
                     f"{fmt(c['second_call_s'])} | {fmt(c['compile_s'])} |")
    if all(f"cache_warm_{what}" in res for what in FIRST_CALLS):
        lines += ["", "With the persistent caches on (a fresh directory; one process fills it, the "
                  "next one is timed): the first call then loads the compiled program from disk "
                  "without tracing it (`jaxdea.compiled`: keyed by the function, its static "
                  "arguments and argument types, the jaxdea sources and the versions).", "",
                  "| function | first call, filling the cache (s) | first call, warm cache (s) "
                  "| second call (s) |", "|---|---:|---:|---:|"]
        for what in FIRST_CALLS:
            fill, warm = res[f"cache_fill_{what}"], res[f"cache_warm_{what}"]
            lines.append(f"| `{what}` | {fmt(fill['first_call_s'])} | {fmt(warm['first_call_s'])} "
                         f"| {fmt(warm['second_call_s'])} |")
    if "order_m" in res:
        lines += render_order_m(res["order_m"])
    if "fit" in res:
        lines += render_fit(res["fit"])
    if "explore" in res:
        lines += render_explore(res["explore"])
    if "defaults" in res:
        lines += render_defaults(res["defaults"])
    if "gewtool" in res:
        lines += render_gewtool(res["gewtool"])
    lines += ["", "## (e) Peak memory (ru_maxrss of the worker process)", "",
              "| workload | after imports (MiB) | peak (MiB) |", "|---|---:|---:|"]
    names = [("char_jaxdea", f"jaxdea characteristic, N = 30, batches {cfg['batches']}"),
             ("char_naive", "naive vmap(expm), same"), ("char_scipy", "SciPy loop, same"),
             ("layers_jaxdea", f"jaxdea characteristic, N = {layers_label(cfg)}, batch {b}"),
             ("layers_naive", "naive, same"), ("layers_scipy", "SciPy, same"),
             ("fig3_jaxdea", "jaxdea Fig. 3 sweep"), ("fig3_scipy", "SciPy Fig. 3 sweep"),
             ("curve_jaxdea", "jaxdea curve (incl. the reference and the N search)"),
             ("curve_scipy", "SciPy curve"), ("compile_frequencies", "first `frequencies` call")]
    for key, label in names:
        lines.append(f"| {label} | {fmt(res[key]['rss_start_mb'])} | {fmt(res[key]['rss_peak_mb'])} |")
    lines.append("")
    return "\n".join(lines)


def render_order_m(r: dict) -> list:
    """Section (g): order-m characteristic rates against m = 0, and first_instability."""
    lines = ["", f"## (g) Circumferential order m: characteristic evaluations per second "
             f"(batch {r['batch']}, N = {r['n_layers']}, timed side by side)", "",
             "| order | evaluations per s | time / time at m = 0 | CPU time / CPU time at m = 0 "
             "| first call (s) |", "|---|---:|---:|---:|---:|"]
    filled = [row for row in r["rows"] if row["key"].endswith("_acoustic")]
    for row in r["rows"]:
        m, traced = row["key"][1:].split("_")[0], row["key"].endswith("_traced")
        if row in filled:
            continue
        label = f"m = {m}" + (" (traced m: one program for every order)" if traced else "")
        if m == "0":
            label += " (6×6 longitudinal path)"
        lines.append(f"| {label} | {fmt(row['evals_per_s'])} | {row['ratio_to_m0']:.2f} | "
                     f"{row['cpu_ratio_to_m0']:.2f} | {fmt(row['first_call_s'])} |")
    if filled:
        lines += ["", "With the acoustic fluid (ρ̂_f = 0.13, ĉ_f = 0.27, the same Ω batch, in the same "
                  "round-robin): its cost over the empty tube of the same order.", "",
                  "| order | evaluations per s | time / empty tube's | CPU time / empty tube's |",
                  "|---|---:|---:|---:|"]
        for row in filled:
            lines.append(f"| m = {row['key'][1:].split('_')[0]}, acoustic fluid | "
                         f"{fmt(row['evals_per_s'])} | {row['ratio_to_empty']:.2f} | "
                         f"{row['cpu_ratio_to_empty']:.2f} |")
    lines += ["", f"`first_instability` of the paper's tube (η = {PAPER_TUBE['eta']}, λ_i = "
              f"{PAPER_TUBE['lambda_i']}, λ_z = {PAPER_TUBE['lambda_z']}; n ≤ {ORDER_M['n_max']}, "
              f"m ≤ {ORDER_M['m_max']}, N = {r['n_layers']}): {fmt(r['instability_seconds'])} s warm "
              f"(first call {fmt(r['instability_first_call_s'])} s); V̂_cr = "
              f"{r['instability_voltage']:.5f} at m = {r['instability_m']}, n = {r['instability_n']}."]
    return lines


def render_fit(r: dict) -> list:
    """Section (h): the inverse characterisation."""
    free = ", ".join(FIT["start"])
    return ["", "## (h) Inverse characterisation (`fit`)", "",
            "| workload | seconds |", "|---|---:|",
            f"| fit: {r['parameters']} parameters to {r['peaks']} peaks, after compilation "
            f"({free}; N = {FIT['n_layers']}, 0.5 % noise, {r['iterations']} iterations, "
            f"{r['status'].lower()}, max rel. error of the estimates {r['max_rel_error']:.1e}) | "
            f"{fmt(r['seconds'])} |",
            f"| fit: the same, first call in the process (compilation, or loading it from the "
            f"persistent cache) | {fmt(r['first_call_s'])} |"]


def render_explore(r: dict) -> list:
    """Section (i): one update of the interactive explorer."""
    lines = ["", f"## (i) Interactive explorer (`jaxdea.explore`): one update after a slider move, "
             f"warm ({r['points']} α̂ × 3 branches, the default discretisation)", "",
             "| setting | curves (`explorer_data`), s | whole update of V̂ (curves, status, figure), s |",
             "|---|---:|---:|"]
    for row in r["rows"]:
        lines.append(f"| {row['label']} | {fmt(row['data_s'])} | {fmt(row['update_s'])} |")
    lines += ["", f"A λ_i move (empty tube, m = 0): the update {fmt(r['geometry_update_s'])} s; the "
              f"stability status follows from `first_instability` (m ≤ 4, n ≤ 3), solved in the "
              f"background, {fmt(r.get('geometry_status_s', math.nan))} s after the move."]
    if "load_average" in r:
        lines[-1] += (" Load average at the end of this workload: "
                      + ", ".join(f"{x:.1f}" for x in r["load_average"]) + ".")
    return lines


def render_defaults(r: dict) -> list:
    """Section (j): the default discretisation against the paper's laminate."""
    lines = ["", "## (j) Accurate by default: the default discretisation (`n_layers=None`) against "
             "the paper's laminate",
             "", "Accurate: graded sixth-order Magnus, N chosen from the case (16 for the paper's "
             "tube, 96 at 99 % of locking); paper's: `scheme=\"midpoint\", n_layers=30` (the "
             "default before). Errors relative to the same scheme on a graded wall 4× finer; "
             "times warm, best of the repeats.", "",
             "| case | paper's N = 30: error | accurate: error | paper's: s | accurate: s | "
             "accurate / paper's time |", "|---|---:|---:|---:|---:|---:|"]
    for row in r["rows"]:
        lines.append(f"| {row['label']} | {row['paper_error']:.1e} | {row['default_error']:.1e} | "
                     f"{fmt(row['paper_s'])} | {fmt(row['default_s'])} | "
                     f"{fmt(row['default_s'] / row['paper_s'])} |")
    f = r["first_instability_s"]
    lines += ["", f"`first_instability` of the paper's tube (n ≤ 3, m ≤ 8), warm: paper's laminate "
              f"{fmt(f['paper'])} s, accurate {fmt(f['default'])} s. Load average at the end: "
              + ", ".join(f"{x:.1f}" for x in r["load_average"]) + "."]
    return lines


def render_gewtool(r: dict) -> list:
    """Section (k): the GEWtool-shaped curve at the default discretisation."""
    p = r["program_s"]
    ms = lambda s: fmt(1e3 * s)  # noqa: E731
    lines = ["", "## (k) GEWtool-shaped curve: `dispersion_curve` at the default discretisation", "",
             f"The unstretched tube (η = 0.85, G = 97.2), 200 α̂ in 0.01–5, the 4 lowest roots, "
             f"`jaxdea.dispersion_curve(tube, alpha, n_roots=4)` with no accuracy arguments "
             f"(graded {r['scheme']}, N = {r['n_layers']}); {r['scanned']} of 200 α̂ scanned, "
             f"{'every root CONVERGED' if r['converged'] else 'NOT every root converged'}; max "
             f"relative error against the exact incompressible cylinder "
             f"{r['exact_rel_error']:.1e} ({r['exact_points']} α̂ × 4 roots).", "",
             "| variant (warm, best of the alternating repeats) | ms | max rel. difference from "
             "the public call's roots |", "|---|---:|---:|",
             f"| public call `dispersion_curve` | {ms(r['seconds'])} | 0 |"]
    labels = {"before": "program before: fixed quintic predictor, each branch's curvature "
                        "measured anew at its own step",
              "adaptive_predictor": "+ adaptive predictor order (12 rows)",
              "current": "+ shared curvature refresh (current program)"}
    for key, label in labels.items():
        lines.append(f"| {label} | {ms(p[key])} | {r['vs_current'][key]:.1e} |")
    lines += [f"| current program on the magnus6 N = 5 wall (max rel. error against the exact "
              f"cylinder {r['magnus6_n5_exact_rel_error']:.1e}) | {ms(p['current_magnus6_n5'])} | "
              f"– |", "",
              f"Attaching implicit derivatives to the 200 rows, which the public call now skips on "
              f"concrete inputs: {ms(r['attach_s'])} ms. First call {fmt(r['first_call_s'])} s. "
              "Load average at the end: " + ", ".join(f"{x:.1f}" for x in r["load_average"]) + "."]
    return lines


def run_only(what: str, cfg: dict, out: str, provisional: bool) -> dict:
    """Run one workload (``--only``) and merge it into the results.json next to ``out``; the
    markdown is rewritten from the merged results."""
    path = os.path.splitext(out)[0] + ".json"
    with open(path) as f:
        res = json.load(f)
    if what in ("order_m", "fit", "explore", "defaults", "gewtool"):
        res[what] = spawn_worker(what, dict(cfg=cfg))
        res[what]["settings"] = cfg
    else:
        raise ValueError(f"--only supports 'order_m', 'fit', 'explore', 'defaults' and 'gewtool', "
                         f"got {what!r}")
    with open(path, "w") as f:
        json.dump(res, f, indent=1)
    with open(out, "w") as f:
        f.write(render(res, provisional))
    return res


def layers_label(cfg):
    return ", ".join(str(n) for n in cfg["layers"] if n != 30)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes and fewer repeats")
    parser.add_argument("--out", default=os.path.join(HERE, "results.md"), help="markdown output")
    parser.add_argument("--provisional", action="store_true", help="label the table provisional")
    parser.add_argument("--reuse", action="store_true",
                        help="reuse the workloads already saved in OUT.partial.json by an interrupted "
                             "run with the same settings")
    parser.add_argument("--render", metavar="JSON",
                        help="only rewrite the markdown from the results.json of an earlier run")
    parser.add_argument("--only", choices=["order_m", "fit", "explore", "defaults", "gewtool"],
                        help="run only this workload, merge it into OUT's .json and rewrite OUT")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--params", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        worker(args.worker, json.loads(args.params))
        return
    if args.render:
        with open(args.render) as f:
            res = json.load(f)
        with open(args.out, "w") as f:
            f.write(render(res, args.provisional))
        return
    if args.only:
        run_only(args.only, settings(args.quick), args.out, args.provisional)
        print(f"written {args.out} and its .json ({args.only} only)")
        return
    start = time.perf_counter()
    res = run_all(settings(args.quick), os.path.splitext(args.out)[0] + ".partial.json", args.reuse)
    res["total_s"] = time.perf_counter() - start
    text = render(res, args.provisional)
    with open(args.out, "w") as f:
        f.write(text)
    with open(os.path.splitext(args.out)[0] + ".json", "w") as f:
        json.dump(res, f, indent=1)
    partial = os.path.splitext(args.out)[0] + ".partial.json"
    if os.path.exists(partial):
        os.remove(partial)
    print(text)
    print(f"written {args.out} and its .json ({res['total_s']:.0f} s)")


if __name__ == "__main__":
    main()
