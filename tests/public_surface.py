"""Every public entry point once, for the cross-process cache test (tests/test_compiled.py).

Run as a script in a fresh process: prints one line per entry point (its name and the exact bits
of every number it returned, as float hex) and a last line with the on-disk cache's counts of each
program (exported here, loaded from disk, stored). New public entry points join :data:`CALLS`.
"""

import dataclasses
import json
import sys

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxdea as jd  # noqa: E402

jd.configure()  # the disk cache under test (JAXDEA_CACHE_DIR) and XLA's loop threshold
from jaxdea import compiled  # noqa: E402

TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85)
FLUID = jd.Fluid()
ALPHA = 0.445
OMEGA = 0.7686116251533485  # the lowest root of TUBE at ALPHA (N = 30); a root at the default
# discretisation too (Newton distance 6e-7 <= ROOT_RTOL), as group_velocity, mode_shape and
# tunability require


def _design():
    return jd.design_for_frequency(TUBE, 1.0, max_steps=2)


def _tunability_design():
    return jd.maximise_tunability(TUBE, max_steps=2)


CALLS = {
    "characteristic": lambda: jd.characteristic(TUBE, 1.3, ALPHA),
    "frequencies": lambda: jd.frequencies(TUBE, ALPHA),
    "solve_frequencies": lambda: jd.solve_frequencies(TUBE, ALPHA, FLUID),
    "frequency": lambda: jd.frequency(TUBE, ALPHA, 0.77),
    "solve_frequency": lambda: jd.solve_frequency(TUBE, ALPHA, 0.77),
    "frequency_gradient": lambda: jax.grad(
        lambda v: jd.frequency(TUBE.replace(voltage=v), ALPHA, 0.77))(0.1),
    "group_velocity": lambda: jd.group_velocity(TUBE, ALPHA, OMEGA),
    "phase_velocity": lambda: jd.phase_velocity(OMEGA, ALPHA),
    "mode_shape": lambda: jd.mode_shape(TUBE, ALPHA, OMEGA),
    "energy_velocity": lambda: jd.energy_velocity(TUBE, ALPHA, OMEGA),
    "fluid_pressure": lambda: jd.fluid_pressure(
        TUBE, ALPHA, float(jd.frequencies(TUBE, ALPHA, FLUID, n_roots=1)[0]), FLUID),
    "critical_voltage": lambda: jd.critical_voltage(TUBE, ALPHA),
    "solve_critical_voltage": lambda: jd.solve_critical_voltage(TUBE, ALPHA),
    "critical_voltages": lambda: jd.critical_voltages(TUBE, 2),
    "solve_critical_voltages": lambda: jd.solve_critical_voltages(TUBE, 2),
    "pressure_difference": lambda: jd.pressure_difference(TUBE),
    "inner_stretch": lambda: jd.inner_stretch(TUBE, 0.5),
    "pull_in": lambda: jd.pull_in(TUBE),
    "thickness_ratio": lambda: jd.thickness_ratio(TUBE),
    "with_thickness_ratio": lambda: jd.with_thickness_ratio(TUBE, 0.2),
    "axial_wavenumber": lambda: jd.axial_wavenumber(TUBE, 2),
    "sweep": lambda: jd.sweep(TUBE, alpha=jnp.linspace(0.3, 0.6, 3), n_roots=2, progress=False),
    "dispersion_curve": lambda: jd.dispersion_curve(TUBE, jnp.linspace(0.3, 0.6, 4), n_roots=2),
    "trace_branch": lambda: jd.trace_branch(TUBE, ALPHA, OMEGA, stop=0.5, max_points=8),
    "count_roots": lambda: jd.count_roots(TUBE, ALPHA, 0.1, 2.0),
    "frequencies_with_error": lambda: jd.frequencies_with_error(TUBE, ALPHA, n_roots=2),
    "tunability": lambda: jd.tunability(TUBE, ALPHA, OMEGA),
    "frequencies_m2": lambda: jd.frequencies(TUBE, ALPHA, m=2),
    "growth_rates": lambda: jd.growth_rates(TUBE, ALPHA, m=2),
    "first_instability": lambda: jd.first_instability(TUBE, n_max=1, m_max=2),
    "stability": lambda: jd.stability(TUBE, n_max=1, m_max=2),
    "mode_shape_m2": lambda: jd.mode_shape(TUBE, ALPHA, float(jd.frequencies(TUBE, ALPHA, m=2)[0]), m=2),
    "characteristic_torsional": lambda: jd.characteristic(TUBE, 1.3, ALPHA, torsional=True),
    "design_for_frequency": _design,
    "maximise_tunability": _tunability_design,
}


def _bits(result):
    """The float hex of every number in a result (pytrees, dataclasses, dicts of arrays)."""
    if dataclasses.is_dataclass(result) and jax.tree_util.treedef_is_leaf(
            jax.tree_util.tree_structure(result)):  # a plain dataclass (SweepResult): its fields
        result = vars(result)
    out = []
    for leaf in jax.tree_util.tree_leaves(result):
        values = np.asarray(leaf)
        if values.dtype.kind in "fc":
            out += [float(x).hex() for x in np.ravel(values.real)]
        elif values.dtype.kind in "iub":
            out += [str(int(x)) for x in np.ravel(values)]
    return " ".join(out)


def main(names):
    for name in names or CALLS:
        print(name, _bits(CALLS[name]()), flush=True)
    counts = {p._name: p.counts for p in compiled.PROGRAMS if any(p.counts.values())}
    print(json.dumps(counts, sort_keys=True))


if __name__ == "__main__":
    main(sys.argv[1:])
