"""The golden file of public calls: about sixty calls of jaxdea's public API whose every number is
kept bit for bit in ``tests/golden/public_calls.json`` (float hex), the guardrail of refactors.

``python tests/golden.py`` (from the repository root) records the file anew: do that only in a
commit that says which numbers change and why. ``tests/test_golden.py`` recomputes every call and
compares the bits (slow tier: ``python -m pytest -m slow tests/test_golden.py``).

Bits hold for one build of XLA on one instruction set: the file records the versions of jax and
jaxlib and the CPU's vector extensions it was made with, and where those differ the test compares
to :data:`OTHER_MACHINE_RTOL` instead (XLA:CPU compiles for the host's extensions, so FMA
contraction and vector widths can move the last bits).

The calls cover the empty tube and both fluid couplings; the families m = 0, 1, 2 and torsion;
V̂ = 0 and 0.1; thin (η = 0.85) and thick (η = 0.5) walls; roots, curves, critical voltages,
growth rates, the first instability, mode shapes, sweeps, the group velocity, gradients, a fit.
"""

import dataclasses
import json
import os
import platform
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxdea as jd  # noqa: E402

if __name__ == "__main__":
    # exactly as the tests run (tests/conftest.py): the disk cache under .jax_cache and XLA's loop
    # threshold, set before anything below starts JAX's backend (GRID does): XLA reads its flags
    # once, and a recording made after it had started rounded 12 calls differently from the tests.
    # Programs called through the cache are exported ones, compiled from StableHLO, and can round
    # differently from a direct jit (7 entries did by up to 1.2e-14): record as checked.
    os.environ.setdefault("JAXDEA_CACHE_DIR", str(Path(__file__).resolve().parents[1] / ".jax_cache"))
    jd.configure()

GOLDEN = Path(__file__).parent / "golden" / "public_calls.json"
OTHER_MACHINE_RTOL = 1e-12
"""Relative agreement required where the machine or the JAX build differs from the recording."""

THIN = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85)
THIN_RELAXED = THIN.replace(voltage=0.0)
THICK = jd.Tube(voltage=0.1, lambda_i=1.05, lambda_z=1.1, eta=0.5)
UNSTRETCHED = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
ACOUSTIC = jd.Fluid()
PAPER = jd.Fluid(coupling="paper", bessel_order=1)
ALPHA = 0.445
OMEGA = 0.7686116251533485  # the lowest root of THIN at ALPHA (N = 30)
GRID = jnp.linspace(0.2, 1.2, 6)


def _fit():
    """Labelled synthetic peaks of a VHB-like tube (tests/test_fit.py's), μ and G free."""
    from jaxdea.units import VACUUM_PERMITTIVITY, Scales, tube_from_si

    truth = dict(shear_modulus=1e5, density=1000.0, permittivity=4.7 * VACUUM_PERMITTIVITY,
                 inner_radius=5e-3, length=50e-3, eta=0.85, lambda_i=1.0, lambda_z=1.2, gent=97.0)
    scales = Scales(truth["shear_modulus"], truth["density"], truth["permittivity"],
                    truth["inner_radius"])
    rows = []
    for voltage in (2e3, 5e3):
        for m, n in ((0, 1), (0, 2), (1, 1)):
            tube = tube_from_si(scales, outer_radius=truth["inner_radius"] / truth["eta"],
                                length=truth["length"], voltage=voltage, lambda_i=1.0,
                                lambda_z=1.2, gent=97.0)
            omega = jd.frequencies(tube, jd.axial_wavenumber(tube, n), n_roots=1, m=m, n_layers=12)[0]
            rows.append((voltage, float(scales.omega_to_hz(omega)) * 1.001, m, n))
    table = np.array(rows)
    data = dict(voltage_V=table[:, 0], frequency_Hz=table[:, 1], m=table[:, 2].astype(int),
                n=table[:, 3].astype(int))
    free = {"shear_modulus": (5e4, 2e5), "gent": (40.0, 200.0)}
    fixed = {k: v for k, v in truth.items() if k not in free}
    result = jd.fit(data, free, fixed, n_layers=12)
    return {"estimate": result.estimate, "interval": result.interval}


def _roots(result):
    return {"omega": result.omega, "status": result.status} if hasattr(result, "status") else result


CALLS = {
    # the characteristic function
    "characteristic_empty": lambda: jd.characteristic(THIN, 1.3, ALPHA),
    "characteristic_acoustic": lambda: jd.characteristic(THIN, 1.3, ALPHA, ACOUSTIC),
    "characteristic_paper": lambda: jd.characteristic(THIN, 1.3, ALPHA, PAPER),
    "characteristic_m1": lambda: jd.characteristic(THIN, 1.3, ALPHA, m=1),
    "characteristic_m2_acoustic": lambda: jd.characteristic(THIN, 1.3, ALPHA, ACOUSTIC, m=2),
    "characteristic_torsional": lambda: jd.characteristic(THIN, 1.3, ALPHA, torsional=True),
    "characteristic_thick": lambda: jd.characteristic(THICK, 1.3, ALPHA),
    # roots
    "frequencies_empty": lambda: jd.frequencies(THIN, ALPHA),
    "frequencies_empty_v0": lambda: jd.frequencies(THIN_RELAXED, ALPHA),
    "frequencies_acoustic": lambda: jd.frequencies(THIN, ALPHA, ACOUSTIC),
    "frequencies_paper": lambda: jd.frequencies(THIN, ALPHA, PAPER, omega_max=3.0),
    "frequencies_m1": lambda: jd.frequencies(THIN, ALPHA, m=1),
    "frequencies_m2": lambda: jd.frequencies(THIN_RELAXED, ALPHA, m=2),
    "frequencies_m2_acoustic": lambda: jd.frequencies(THIN_RELAXED, ALPHA, ACOUSTIC, m=2),
    "frequencies_torsional": lambda: jd.frequencies(THIN, ALPHA, torsional=True),
    "frequencies_thick": lambda: jd.frequencies(THICK, ALPHA),
    "frequencies_thick_m1": lambda: jd.frequencies(THICK, ALPHA, m=1),
    "frequencies_unstretched_n30": lambda: jd.frequencies(UNSTRETCHED, 0.89, n_layers=30),
    "solve_frequencies_acoustic": lambda: _roots(jd.solve_frequencies(THIN, ALPHA, ACOUSTIC)),
    "frequency": lambda: jd.frequency(THIN, ALPHA, 0.77),
    "frequency_acoustic": lambda: jd.frequency(THIN, ALPHA, 0.3, ACOUSTIC),
    "frequency_m2": lambda: jd.frequency(THIN_RELAXED, ALPHA, 0.2, m=2),
    "frequencies_with_error": lambda: jd.frequencies_with_error(THIN, ALPHA, n_roots=2),
    "count_roots": lambda: jd.count_roots(THIN, ALPHA, 0.1, 2.0),
    "count_roots_m1": lambda: jd.count_roots(THIN, ALPHA, 0.1, 2.0, m=1),
    # derivatives
    "grad_frequency_voltage": lambda: jax.grad(
        lambda v: jd.frequency(THIN.replace(voltage=v), ALPHA, 0.77))(0.1),
    "grad_frequency_eta": lambda: jax.grad(
        lambda e: jd.frequency(THIN.replace(eta=e), ALPHA, 0.77))(0.85),
    "grad_frequency_acoustic_density": lambda: jax.grad(
        lambda r: jd.frequency(THIN, ALPHA, 0.3, ACOUSTIC.replace(density_ratio=r)))(0.13),
    "grad_frequency_m2_lambda_i": lambda: jax.grad(
        lambda li: jd.frequency(THIN_RELAXED.replace(lambda_i=li), ALPHA, 0.2, m=2))(0.9),
    "jacfwd_frequencies": lambda: jax.jacfwd(
        lambda v: jd.frequencies(THIN.replace(voltage=v), ALPHA, n_roots=2))(0.1),
    "group_velocity": lambda: jd.group_velocity(THIN, ALPHA, OMEGA),
    "group_velocity_m1": lambda: jd.group_velocity(
        THIN, ALPHA, float(jd.frequencies(THIN, ALPHA, m=1, n_roots=1)[0]), m=1),
    "tunability": lambda: jd.tunability(THIN, ALPHA, OMEGA),
    "grad_critical_voltage_eta": lambda: jax.grad(
        lambda e: jd.critical_voltage(THIN.replace(eta=e), ALPHA))(0.85),
    # stability
    "critical_voltage": lambda: jd.critical_voltage(THIN, ALPHA),
    "critical_voltage_acoustic": lambda: jd.critical_voltage(THIN, ALPHA, ACOUSTIC),
    "critical_voltage_m2": lambda: jd.critical_voltage(THIN, ALPHA, m=2),
    "critical_voltage_thick": lambda: jd.critical_voltage(THICK, ALPHA),
    "critical_voltages": lambda: jd.critical_voltages(THIN, 3),
    "critical_voltages_m1": lambda: jd.critical_voltages(THIN, 2, m=1),
    "growth_rates_m2": lambda: jd.growth_rates(THIN, ALPHA, m=2),
    "growth_rates_m0": lambda: jd.growth_rates(THIN.replace(voltage=0.35), ALPHA),
    "first_instability": lambda: jd.first_instability(THIN, n_max=2, m_max=3),
    "first_instability_acoustic": lambda: jd.first_instability(THIN, n_max=1, m_max=2, fluid=ACOUSTIC),
    "stability": lambda: jd.stability(THIN, n_max=1, m_max=2),
    # curves and tracing
    "dispersion_curve": lambda: jd.dispersion_curve(THIN, GRID, n_roots=3),
    "dispersion_curve_v0": lambda: jd.dispersion_curve(THIN_RELAXED, GRID, n_roots=3),
    "dispersion_curve_acoustic": lambda: jd.dispersion_curve(THIN, GRID, ACOUSTIC, n_roots=2),
    "dispersion_curve_m2": lambda: jd.dispersion_curve(THIN_RELAXED, GRID, n_roots=2, m=2),
    "dispersion_curve_torsional": lambda: jd.dispersion_curve(THIN, GRID, n_roots=2, torsional=True),
    "dispersion_curve_thick": lambda: jd.dispersion_curve(THICK, GRID, n_roots=2),
    "trace_branch_alpha": lambda: jd.trace_branch(THIN, ALPHA, OMEGA, stop=0.6, max_points=8),
    "trace_branch_voltage": lambda: jd.trace_branch(THIN, ALPHA, OMEGA, along="voltage", stop=0.2,
                                                    max_points=8),
    # sweeps
    "sweep_alpha": lambda: jd.sweep(THIN, alpha=jnp.linspace(0.3, 0.6, 3), n_roots=2, progress=False),
    "sweep_voltage_acoustic": lambda: jd.sweep(THIN, ACOUSTIC, voltage=[0.0, 0.05, 0.1], alpha=[ALPHA],
                                               n_roots=2, progress=False),
    "sweep_m_axis": lambda: jd.sweep(THIN_RELAXED, m=[0, 1, 2], alpha=[ALPHA], n_roots=2,
                                     progress=False),
    "sweep_jacobian": lambda: jd.sweep(THIN, voltage=[0.05, 0.1], alpha=[ALPHA], n_roots=2,
                                       jacobian=("voltage", "eta"), progress=False),
    # static state and mode shapes
    "pressure_difference": lambda: jd.pressure_difference(THIN),
    "inner_stretch": lambda: jd.inner_stretch(THIN, 0.5),
    "pull_in": lambda: jd.pull_in(THICK),
    "thickness_ratio": lambda: jd.thickness_ratio(THICK),
    "with_thickness_ratio": lambda: jd.with_thickness_ratio(THIN, 0.2),
    "mode_shape": lambda: jd.mode_shape(THIN, ALPHA, OMEGA),
    "mode_shape_m2": lambda: jd.mode_shape(
        THIN_RELAXED, ALPHA, float(jd.frequencies(THIN_RELAXED, ALPHA, m=2)[0]), m=2),
    "fluid_pressure": lambda: jd.fluid_pressure(
        THIN, ALPHA, float(jd.frequencies(THIN, ALPHA, ACOUSTIC, n_roots=1)[0]), ACOUSTIC),
    # studies
    "fit": _fit,
}


def bits(result) -> list[str]:
    """The exact bits of every number in a result (pytrees, dataclasses, dicts), as float hex and
    integers, leaves in pytree order."""
    if dataclasses.is_dataclass(result) and jax.tree_util.treedef_is_leaf(
            jax.tree_util.tree_structure(result)):  # a plain dataclass (SweepResult): its fields
        result = {f.name: getattr(result, f.name) for f in dataclasses.fields(result)
                  if not isinstance(getattr(result, f.name), str | tuple | dict) or f.name == "axes"}
    out = []
    for leaf in jax.tree_util.tree_leaves(result):
        if isinstance(leaf, str):
            continue
        values = np.asarray(leaf)
        if values.dtype.kind in "fc":
            out += [float(x).hex() for x in np.ravel(values.real)]
            if values.dtype.kind == "c":
                out += [float(x).hex() for x in np.ravel(values.imag)]
        elif values.dtype.kind in "iub":
            out += [str(int(x)) for x in np.ravel(values)]
    return out


def machine() -> dict:
    """What the bits depend on besides jaxdea: the JAX build and the CPU's vector extensions."""
    flags = set()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                flags = set(line.split(":", 1)[1].split())
                break
    except OSError:
        pass
    vector = sorted(f for f in flags if f.startswith(("avx", "fma", "sse4")))
    return {"jax": jax.__version__, "jaxlib": jax.lib.__version__ if hasattr(jax.lib, "__version__")
            else __import__("jaxlib").__version__, "machine": platform.machine(), "vector": vector}


def record(path: Path = GOLDEN) -> None:
    """Compute every call and write the golden file (atomically)."""
    entries = {}
    for name, call in CALLS.items():
        entries[name] = bits(call())
        print(f"{name}: {len(entries[name])} numbers", flush=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"machine": machine(), "calls": entries}, indent=1) + "\n")
    os.replace(tmp, path)


if __name__ == "__main__":
    record()
