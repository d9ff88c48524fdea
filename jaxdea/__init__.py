"""jaxdea: differentiable dispersion (every circumferential order m) of pre-stretched,
voltage-driven soft dielectric elastomer tubes, empty or filled with an inviscid compressible fluid
(see docs/theory/axisymmetric.md).

64-bit floats are required: ``jax.config.update("jax_enable_x64", True)`` before use.
Importing jaxdea changes nothing in the process; :func:`configure` opts in to the on-disk program
cache and XLA's loop threshold (:mod:`jaxdea.compiled`).
"""

from importlib import metadata as _metadata

from . import compiled, units  # noqa: F401 - jaxdea.compiled and jaxdea.units as attributes
from .apps.explore import explore  # ipywidgets is imported on the first call only
from .compiled import Configuration, configure
from .io.fit_io import plot_fit, write_fit
from .materials import (
    Energy,
    FractionalKelvinVoigt,
    Gent,
    GentGent,
    Hysteretic,
    KelvinVoigt,
    MooneyRivlin,
    NeoHookean,
    Ogden,
    Prony,
)
from .numerics.scalar import Status
from .params import Fluid, Layer, Tube, axial_wavenumber
from .physics.base_state import (
    inner_stretch,
    pressure_difference,
    pull_in,
    thickness_ratio,
    with_thickness_ratio,
)
from .physics.dispersion import characteristic
from .solve.accuracy import Estimate, frequencies_with_error
from .solve.complex_curves import (
    ComplexCurve,
    WavenumberCurve,
    complex_dispersion_curve,
    wavenumber_curve,
)
from .solve.complex_frequencies import ComplexRoots, complex_frequencies, solve_complex_frequency
from .solve.counting import CountStatus, RootCount, count_roots
from .solve.curves import Curve, dispersion_curve
from .solve.energy import energy_velocity
from .solve.instability import first_instability
from .solve.modes import ModeShape, fluid_pressure, mode_shape, outer_pressure
from .solve.roots import (
    Instability,
    Roots,
    critical_voltage,
    critical_voltages,
    frequencies,
    frequency,
    group_velocity,
    growth_rates,
    phase_velocity,
    solve_critical_voltage,
    solve_critical_voltages,
    solve_frequencies,
    solve_frequency,
)
from .solve.stability import Stability, stability
from .solve.trace import Branch, BranchEnd, trace_branch
from .solve.wavenumbers import SearchStatus, Wavenumbers, wavenumbers
from .studies.design import DesignResult, DesignStatus, design_for_frequency, maximise_tunability, tunability
from .studies.fit import FitResult, FitStatus, IdentifiabilityWarning, fit, fitted_frequencies
from .studies.peaks import read_peaks, write_peaks
from .studies.sweeps import SweepResult, sweep

__all__ = [
    "Branch",
    "ComplexCurve",
    "ComplexRoots",
    "BranchEnd",
    "Configuration",
    "CountStatus",
    "Curve",
    "DesignResult",
    "DesignStatus",
    "Energy",
    "Estimate",
    "FitResult",
    "FitStatus",
    "Fluid",
    "FractionalKelvinVoigt",
    "Gent",
    "GentGent",
    "Hysteretic",
    "IdentifiabilityWarning",
    "Instability",
    "KelvinVoigt",
    "Layer",
    "MooneyRivlin",
    "NeoHookean",
    "Ogden",
    "Prony",
    "RootCount",
    "Roots",
    "SearchStatus",
    "Stability",
    "Status",
    "SweepResult",
    "Tube",
    "WavenumberCurve",
    "Wavenumbers",
    "axial_wavenumber",
    "characteristic",
    "complex_dispersion_curve",
    "complex_frequencies",
    "configure",
    "count_roots",
    "critical_voltage",
    "critical_voltages",
    "design_for_frequency",
    "dispersion_curve",
    "energy_velocity",
    "explore",
    "first_instability",
    "fit",
    "fitted_frequencies",
    "fluid_pressure",
    "frequencies",
    "frequencies_with_error",
    "frequency",
    "group_velocity",
    "growth_rates",
    "inner_stretch",
    "maximise_tunability",
    "mode_shape",
    "ModeShape",
    "outer_pressure",
    "phase_velocity",
    "plot_fit",
    "pressure_difference",
    "pull_in",
    "read_peaks",
    "solve_complex_frequency",
    "solve_critical_voltage",
    "solve_critical_voltages",
    "solve_frequencies",
    "solve_frequency",
    "stability",
    "sweep",
    "thickness_ratio",
    "trace_branch",
    "tunability",
    "units",
    "wavenumber_curve",
    "wavenumbers",
    "with_thickness_ratio",
    "write_fit",
    "write_peaks",
]
try:
    __version__ = _metadata.version("jaxdea")
except _metadata.PackageNotFoundError:  # a source tree that is not installed
    __version__ = "0+unknown"

