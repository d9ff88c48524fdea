"""First calls of the public entry points with the caches off, split into trace / lower / compile,
and their warm times, each entry point in a fresh process (issue 42, item 9: "every public entry
point's first call takes <= 3 s with the caches off").

    python benchmarks/first_calls.py [--only NAME ...] [--trees DIR ...] [--out FILE]

With ``--trees`` (source trees of jaxdea, e.g. a worktree of main and this branch) each entry point
runs once per tree, the trees alternating, so that before and after share the machine's load.

Each entry point runs in its own subprocess (``--worker NAME``) that calls ``jaxdea.configure(
cache=False)`` (XLA's loop threshold on, no disk cache), times the first call (the sum of JAX's
trace, lowering and backend-compile durations from ``jax.monitoring``, and the wall time), then
the warm call (median of 7 after two warm-ups). ``uptime`` is recorded: the machine is shared."""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

ROOT, ROOT_M2 = 0.7686111431540606, 1.9399417824719305  # frequencies(tube, 0.445)[0], m = 0 and 2


def _calls():
    import jax.numpy as jnp

    import jaxdea as jd

    tube = jd.Tube(lambda_z=1.2, eta=0.85, gent=97.2, length_ratio=10.0, lambda_i=0.9, voltage=0.1)
    paper = jd.Tube(lambda_z=1.2, eta=0.85, lambda_i=0.9)
    fluid = jd.Fluid()
    liner = jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0)
    sandwich = tube.replace(layers=(liner, jd.Layer(0.6, jd.Gent(97.2), active=True), liner))
    curve = jnp.linspace(0.2, 1.2, 200)
    unstretched = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)  # as complex_curves.py
    kelvin = unstretched.replace(damping=jd.KelvinVoigt(0.05))
    hysteretic = unstretched.replace(damping=jd.Hysteretic(0.05))
    block = lambda x: __import__("jax").block_until_ready(x)  # noqa: E731
    return {
        "characteristic": lambda: jd.characteristic(tube, 1.3, 0.445),
        "frequencies": lambda: jd.frequencies(tube, 0.445),
        "frequencies_acoustic": lambda: jd.frequencies(tube, 0.445, fluid),
        "frequencies_m2": lambda: jd.frequencies(tube, 0.445, m=2),
        "frequencies_layered": lambda: jd.frequencies(sandwich, 0.445),
        "dispersion_curve_layered": lambda: jd.dispersion_curve(sandwich, curve, n_roots=4),
        "frequency": lambda: jd.frequency(tube, 0.445, 0.77),
        "growth_rates_m2": lambda: jd.growth_rates(tube, 0.445, m=2),
        "group_velocity": lambda: jd.group_velocity(tube, 0.445, ROOT),
        "critical_voltage": lambda: jd.critical_voltage(paper, 0.445),
        "critical_voltage_m2": lambda: jd.critical_voltage(paper, 0.445, m=2),
        "critical_voltages": lambda: jd.critical_voltages(paper, 3),
        "first_instability": lambda: jd.first_instability(paper, n_max=3, m_max=8),
        "dispersion_curve": lambda: jd.dispersion_curve(tube, curve, n_roots=4),
        "dispersion_curve_m2": lambda: jd.dispersion_curve(tube, curve, n_roots=4, m=2),
        "trace_branch": lambda: jd.trace_branch(tube, 0.445, 0.77, stop=0.6, max_points=8),
        "count_roots": lambda: jd.count_roots(tube, 0.445, 0.1, 2.0),
        "frequencies_with_error": lambda: jd.frequencies_with_error(tube, 0.445),
        "mode_shape": lambda: jd.mode_shape(tube, 0.445, ROOT),
        "mode_shape_m2": lambda: jd.mode_shape(tube, 0.445, ROOT_M2, m=2),
        "sweep": lambda: jd.sweep(tube, voltage=jnp.linspace(0.0, 0.1, 8), alpha=0.445),
        "design_for_frequency": lambda: jd.design_for_frequency(paper, 0.8, n=1),
        "complex_frequencies": lambda: jd.complex_frequencies(kelvin, 0.445, n_roots=4),
        "wavenumbers": lambda: jd.wavenumbers(hysteretic, 1.0, n_roots=4),
        "complex_dispersion_curve": lambda: jd.complex_dispersion_curve(
            kelvin, jnp.linspace(0.15, 3.0, 200), n_roots=4),
        "wavenumber_curve": lambda: jd.wavenumber_curve(hysteretic, jnp.linspace(0.5, 3.0, 200),
                                                        n_roots=4),
    }, block


def worker(name: str) -> dict:
    import jaxdea as jd

    jd.configure(cache=False)
    import jax

    jax.config.update("jax_enable_x64", True)
    from jax import monitoring

    durations: dict[str, float] = {}

    def listen(event, seconds, **_):
        for key, short in (("jaxpr_trace", "trace"), ("to_mlir", "lower"), ("backend_compile", "compile")):
            if key in event:
                durations[short] = durations.get(short, 0.0) + seconds

    monitoring.register_event_duration_secs_listener(listen)
    calls, block = _calls()
    fn = calls[name]
    start = time.perf_counter()
    block(fn())
    first = time.perf_counter() - start
    split = dict(durations)
    for _ in range(2):
        block(fn())
    warm = []
    for _ in range(7):
        start = time.perf_counter()
        block(fn())
        warm.append(time.perf_counter() - start)
    return dict(name=name, first_s=first, **{f"{k}_s": v for k, v in split.items()},
                warm_s=statistics.median(warm), jax=jax.__version__)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--worker")
    parser.add_argument("--only", nargs="*")
    parser.add_argument("--trees", nargs="*", default=[None])
    parser.add_argument("--out")
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker)))
        return
    names = args.only or list(_calls_names())
    env = dict(os.environ, JAXDEA_CACHE_DIR="off")
    rows = []
    for name in names:
        for tree in args.trees:
            load = os.getloadavg()[0]
            run_env = dict(env, PYTHONPATH=tree) if tree else env
            out = subprocess.run([sys.executable, __file__, "--worker", name], env=run_env,
                                 capture_output=True, text=True, check=False)
            try:
                row = json.loads(out.stdout.strip().splitlines()[-1])
            except (IndexError, json.JSONDecodeError):
                row = dict(name=name, error=out.stderr[-800:])
            row.update(load=load, tree=tree)
            rows.append(row)
            print(json.dumps(row), flush=True)
    if args.out:
        with open(args.out, "w") as f:
            json.dump(rows, f, indent=1)


def _calls_names():
    return ("characteristic", "frequencies", "frequencies_acoustic", "frequencies_m2",
            "frequencies_layered", "dispersion_curve_layered", "frequency",
            "growth_rates_m2", "group_velocity", "critical_voltage", "critical_voltage_m2",
            "critical_voltages", "first_instability", "dispersion_curve", "dispersion_curve_m2",
            "trace_branch", "count_roots", "frequencies_with_error", "mode_shape", "mode_shape_m2",
            "sweep", "design_for_frequency")


if __name__ == "__main__":
    main()
