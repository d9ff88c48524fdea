"""An interactive explorer: sliders for the tube, the fluid and the order m, live dispersion curves,
phase velocities, the axial modes n, the stability status and the mode shape of a chosen root.

The computation lives in pure functions (:func:`explorer_data`, :func:`stability_status`,
:func:`explorer_mode`); :func:`explore` wraps them in an ipywidgets app (``pip install
jaxdea[explore]``) that redraws a matplotlib figure whenever a control changes: an interactive
ipympl canvas widget where ipympl is installed (clicks on a curve select a mode; in JupyterLab,
Jupyter Notebook and voila), else a PNG image. The user's matplotlib backend is never changed.
Every slider value is a traced leaf of the compiled solvers, so moving a slider never recompiles;
the empty tube, the filled one, each coupling and m = 0 against m ≥ 1 are separate programs, each
compiled on first use (the app says "compiling (once)…" meanwhile).

A damping control (none, Kelvin–Voigt η_v, hysteretic ζ, with a slider for its size) adds the
complex roots of the damped tube at the axial modes n (:func:`damped_roots`): a few points only,
each Newton (:func:`jaxdea.solve_complex_frequency`) continued from the elastic root in the size.
"""

from __future__ import annotations

import concurrent.futures
import functools
import html
import io
import threading
from typing import NamedTuple

import numpy as np

from ..compiled import jit
from ..materials import Hysteretic, KelvinVoigt
from ..params import Fluid, Tube, axial_wavenumber
from ..solve.curves import dispersion_curve
from ..solve.modes import mode_shape
from ..solve.roots import first_instability, growth_rates, phase_velocity

ALPHAS = np.linspace(0.05, 3.0, 40)
"""The default α̂ grid of the explorer (the axial modes' α̂_n are added to it)."""
N_AXIAL = 5  # axial modes n = 1 … N_AXIAL marked on the curves
DEFAULT_TUBE = Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85)  # the paper's tube
UNSTABLE_FACE = "#fbe3e3"  # axes background of an unstable state


class ExplorerData(NamedTuple):
    """The arrays the explorer plots (NumPy).

    Attributes:
        alpha: the grid α̂, shape (M,): the requested grid and the α̂_n, sorted.
        omega: the ``n_modes`` lowest Ω at each α̂ (:func:`jaxdea.dispersion_curve`), (M, K).
        phase_velocity: Ω/α̂, (M, K).
        status: :class:`~jaxdea.Status` per root, (M, K).
        axial_n: the axial mode numbers n = 1 … n_axial.
        axial_alpha: their α̂_n (:func:`jaxdea.axial_wavenumber`).
        axial_index: the row of each α̂_n in ``alpha`` (its roots are ``omega[axial_index]``).
    """

    alpha: np.ndarray
    omega: np.ndarray
    phase_velocity: np.ndarray
    status: np.ndarray
    axial_n: np.ndarray
    axial_alpha: np.ndarray
    axial_index: np.ndarray


DAMPING_LAWS = {"none": None, "Kelvin–Voigt η_v": KelvinVoigt, "hysteretic ζ": Hysteretic}
"""The explorer's damping choices: the law, whose one parameter the size slider sets (η*(Ω) = iΩη_v
or iζ, :mod:`jaxdea.materials`)."""
DAMPING_STEPS = 4
"""Newton solves per damped root: the size reached in this many equal steps from the elastic root."""


class DampedRoots(NamedTuple):
    """The complex roots of the damped tube at the axial modes (:func:`damped_roots`).

    Attributes:
        omega: Ω of each axial mode n (rows) and branch (columns), (n_axial, K), complex (NaN where
            the elastic root is missing or Newton failed); decaying modes have Im Ω > 0.
        quality_factor: Q = Re Ω/(2 Im Ω), (n_axial, K).
        status: :class:`~jaxdea.Status` of the last Newton solve, (n_axial, K).
    """

    omega: np.ndarray
    quality_factor: np.ndarray
    status: np.ndarray


@functools.partial(jit, static_argnames=("kind", "m", "n_layers"))
def _damped(tube, alphas, guesses, size, fluid, kind, m, n_layers):
    """Ω (N, K) and the last status: :func:`jaxdea.solve_complex_frequency` at each (α̂_n, branch)
    from the elastic root, the law's size raised in :data:`DAMPING_STEPS` steps (each Newton from
    the last root)."""
    import jax
    import jax.numpy as jnp

    from ..solve.complex_frequencies import solve_complex_frequency

    law = DAMPING_LAWS[kind]

    def one(alpha, guess):
        def step(omega, fraction):
            root, status = solve_complex_frequency(tube.replace(damping=law(size * fraction)), alpha,
                                                   omega, fluid, m=m, n_layers=n_layers)
            return root, status

        fractions = jnp.arange(1, DAMPING_STEPS + 1, dtype=jnp.float64) / DAMPING_STEPS
        root, statuses = jax.lax.scan(step, guess.astype(jnp.complex128), fractions)
        return root, statuses[-1]

    return jax.vmap(jax.vmap(one, (None, 0)), (0, 0))(alphas, guesses)


def damped_roots(tube: Tube, data: ExplorerData, kind: str, size: float, fluid: Fluid | None = None,
                 m: int = 0, n_layers: int | None = None) -> DampedRoots | None:
    """The complex roots Ω of the tube with the damping ``kind`` (a key of :data:`DAMPING_LAWS`) of
    ``size`` (η_v or ζ) at the axial modes of ``data``: Newton from each elastic root Ω(α̂_n) with
    the size raised in :data:`DAMPING_STEPS` steps; the quality factor Q = Re Ω/(2 Im Ω) (light
    damping: Q ≈ 1/ζ for the hysteretic law at V̂ = 0). None for ``"none"``.

    Raises:
        ValueError: for the paper's coupling (complex roots are solved with the acoustic one) and
            invalid inputs (as :func:`jaxdea.solve_complex_frequency`).
    """
    if DAMPING_LAWS[kind] is None:
        return None
    if fluid is not None and fluid.coupling != "acoustic":
        raise ValueError("damping: complex roots need the acoustic coupling (or an empty tube)")
    from ..numerics.scalar import Status

    alphas = np.asarray(data.axial_alpha, np.float64)
    guesses = np.asarray(data.omega[data.axial_index], np.complex128)
    omega, status = _damped(tube, alphas, guesses, float(size), fluid, kind, int(m), n_layers)
    omega, status = np.asarray(omega), np.asarray(status)
    omega = np.where(status == Status.CONVERGED, omega, complex(np.nan, np.nan))
    with np.errstate(invalid="ignore", divide="ignore"):
        quality = np.where(omega.imag != 0, omega.real / (2.0 * omega.imag), np.inf)
    return DampedRoots(omega, np.where(np.isnan(omega.real), np.nan, quality), status)


class StabilityStatus(NamedTuple):
    """The stability of a state against the first instability (:func:`jaxdea.first_instability`).

    Attributes:
        voltage: V̂_first, the smallest critical voltage over the (m, n) searched (NaN: none below
            pull-in; 0: unstable already at V̂ = 0).
        m, n: its order and axial mode (−1, 0 where none).
        unstable: True where the tube's V̂ ≥ V̂_first.
        text: a one-line summary.
    """

    voltage: float
    m: int
    n: int
    unstable: bool
    text: str


def explorer_grid(tube: Tube, alphas=ALPHAS, n_axial: int = N_AXIAL):
    """(grid, n, α̂_n, rows): ``alphas`` with the α̂_n of n = 1 … ``n_axial`` inserted, sorted (a
    fixed size, so the compiled curve is reused for every tube), and the row of each α̂_n."""
    n = np.arange(1, n_axial + 1)
    axial = np.asarray(axial_wavenumber(tube, n), dtype=np.float64)
    grid = np.sort(np.concatenate([np.asarray(alphas, dtype=np.float64), axial]))
    return grid, n, axial, np.searchsorted(grid, axial)


def explorer_data(tube: Tube, fluid: Fluid | None = None, m: int = 0, n_modes: int = 3,
                  alphas=ALPHAS, n_axial: int = N_AXIAL, n_layers: int | None = None) -> ExplorerData:
    """The dispersion curves Ω(α̂) of the ``n_modes`` lowest modes of order ``m`` by continuation
    (:func:`jaxdea.dispersion_curve` on :func:`explorer_grid`), their phase velocities and the
    axial modes n on them.

    Raises:
        ValueError: for invalid inputs (as :func:`jaxdea.dispersion_curve`, e.g. a wall past Gent
            locking or the ``"paper"`` coupling at m ≥ 1).
    """
    grid, n, axial, rows = explorer_grid(tube, alphas, n_axial)
    curve = dispersion_curve(tube, grid, fluid, n_roots=n_modes, n_layers=n_layers, m=m)
    omega = np.asarray(curve.omega)
    return ExplorerData(grid, omega, np.asarray(phase_velocity(omega, grid[:, None])),
                        np.asarray(curve.status), n, axial, rows)


def stability_status(tube: Tube, n_max: int = 3, m_max: int = 4,
                     n_layers: int | None = None) -> StabilityStatus:
    """Whether the tube's V̂ has reached its first instability over 0 ≤ m ≤ ``m_max``,
    1 ≤ n ≤ ``n_max`` (:func:`jaxdea.first_instability`; independent of V̂ and of a fluid)."""
    first = first_instability(tube, n_max=n_max, m_max=m_max, n_layers=n_layers)
    return judge_stability(float(first.voltage), int(first.m), int(first.n), float(tube.voltage),
                           n_max, m_max)


def judge_stability(v_first: float, m: int, n: int, voltage: float, n_max: int = 3,
                    m_max: int = 4) -> StabilityStatus:
    """The :class:`StabilityStatus` of V̂ = ``voltage`` against a first instability V̂_first at
    (m, n) (NaN: none found for m ≤ ``m_max``, n ≤ ``n_max``)."""
    if not np.isfinite(v_first):
        return StabilityStatus(v_first, m, n, False, f"stable: no instability for m ≤ {m_max}, "
                               f"n ≤ {n_max} below pull-in")
    unstable = voltage >= v_first
    where = f"(m = {m}, n = {n})"
    if v_first == 0.0:
        text = f"UNSTABLE at every V̂: {where} buckles already at V̂ = 0"
    elif unstable:
        text = f"UNSTABLE: V̂ = {voltage:.4g} ≥ V̂_first = {v_first:.4g} {where}"
    else:
        text = f"stable: V̂ = {voltage:.4g} < V̂_first = {v_first:.4g} {where}"
    return StabilityStatus(v_first, m, n, bool(unstable), text)


def explorer_mode(tube: Tube, data: ExplorerData, alpha, branch: int, fluid: Fluid | None = None,
                  m: int = 0, n_layers: int | None = None):
    """(α̂, Ω, r, fields) of the root of ``branch`` (0: the lowest) at the grid α̂ nearest to
    ``alpha``: :func:`jaxdea.mode_shape` there.

    Raises:
        ValueError: where that branch has no root at that α̂ (or as ``mode_shape``).
    """
    row = int(np.argmin(np.abs(data.alpha - float(alpha))))
    a, omega = float(data.alpha[row]), float(data.omega[row, branch])
    if not np.isfinite(omega):
        raise ValueError(f"branch {branch + 1} has no root at α̂ = {a:.4g}")
    r, fields = mode_shape(tube, a, omega, fluid, n_layers=n_layers, m=m)
    return a, omega, np.asarray(r), np.asarray(fields)


def explore(tube: Tube | None = None, fluid: Fluid | None = None, *, n_modes: int = 3,
            alphas=ALPHAS, n_axial: int = N_AXIAL, n_layers: int | None = None, n_max: int = 3,
            m_max: int = 4, stability: bool = True):
    """An ipywidgets app to explore the dispersion and stability of a tube interactively.

    Sliders set V̂, λ_i, λ_z, η, G, ρ̂_f, ĉ_f and the order m; toggles choose the empty or filled
    tube and the coupling (``"paper"`` with its Bessel order ν, valid at m = 0 only). The plots
    show the ``n_modes`` lowest Ω(α̂) (:func:`explorer_data`), the phase velocity Ω/α̂, the axial
    modes n = 1 … ``n_axial`` marked on both, the stability status of :func:`stability_status`
    (shaded when V̂ ≥ V̂_first) and, shaded red, the α̂ where the lowest root of order m is
    imaginary (:func:`unstable_alphas`: the curve there is the next root). Both solves run in the
    background (the curves are drawn at once, the status and marks when they end; ``app.wait()``
    blocks until then), so no update waits for them. A click on a curve (the ipympl canvas), the
    α̂ and branch controls, or ``app.select(alpha, branch)`` shows that root's mode shape in the
    side panel. The fluid controls are disabled for the empty tube. Invalid combinations (e.g. a
    wall past Gent locking) show the error message instead of raising. The damping control (none,
    Kelvin–Voigt η_v, hysteretic ζ) and its size slider add the damped roots at the axial modes
    (:func:`damped_roots`): their Re Ω marked on the curves, their quality factors listed beside.

    Args:
        tube: the initial :class:`~jaxdea.Tube` (default: the paper's, V̂ = 0.1); its
            ``length_ratio``, ``material`` and ``layers`` are kept (the G slider acts on the
            Gent energy only: disabled for another material or a layered wall).
        fluid: the initial :class:`~jaxdea.Fluid`, or None for an empty tube.
        n_modes: K, the number of branches (static).
        alphas: the α̂ grid (its size is fixed for the life of the app: no recompilation).
        n_axial: axial modes marked.
        n_layers: sublayers N of every solve (None: the default, accurate discretisation).
        n_max, m_max: the (m, n) searched for the first instability.
        stability: False leaves the stability status out (no ``first_instability`` solves).

    Returns:
        The app, an ``ipywidgets.VBox``: ``controls`` (the widgets by parameter name), ``set``
        (several controls, one redraw), ``select``, ``on_click`` and ``png`` (the figure as PNG
        bytes); ``data`` (:class:`ExplorerData`), ``status`` (:class:`StabilityStatus`, None while
        its solve runs: ``wait``), ``unstable`` (the α̂ flags of :func:`unstable_alphas`),
        ``mode`` ((α̂, Ω, r, fields)), ``damped`` (:class:`DampedRoots` or None) and ``error``
        (the message, or None) hold what is shown.

    Raises:
        ImportError: without ipywidgets (``pip install jaxdea[explore]``).

    Examples:
        >>> app = jaxdea.explore(jaxdea.Tube(voltage=0.05, lambda_i=0.9, lambda_z=1.2))
        >>> app.controls["voltage"].value = 0.02   # redraws; app.data holds the curves
        >>> app.set(filled="filled", m=2)          # several controls, one redraw
        >>> app.select(0.445, 0)                   # mode shape of the lowest root at α̂ ≈ 0.445
        >>> app                                    # shows the app in a notebook
    """
    try:
        import ipywidgets  # noqa: F401
    except ImportError as exc:
        raise ImportError("jaxdea.explore needs ipywidgets: pip install jaxdea[explore]") from exc
    return _app_class()(tube if tube is not None else DEFAULT_TUBE, fluid, n_modes=n_modes,
                        alphas=np.asarray(alphas, dtype=np.float64), n_axial=n_axial,
                        n_layers=n_layers, n_max=n_max, m_max=m_max, stability=stability)


def unstable_alphas(tube: Tube, alpha, fluid: Fluid | None = None, m: int = 0,
                    n_layers: int | None = None) -> np.ndarray:
    """Where the lowest root of order ``m`` is imaginary (Ω² < 0: the mode grows, at the rate s of
    :func:`jaxdea.growth_rates`), at each α̂ of ``alpha``: there :func:`jaxdea.dispersion_curve`
    gives the next, real root, and the plotted branch drops. A bool array like ``alpha``; False where
    the growth-rate scan fails (e.g. the paper's coupling, which has none)."""
    out = np.zeros(np.shape(alpha), bool)
    for k, a in enumerate(np.asarray(alpha, np.float64)):
        try:
            s = float(growth_rates(tube, float(a), fluid, n_roots=1, n_layers=n_layers, m=m)[0])
        except ValueError:
            return np.zeros(np.shape(alpha), bool)
        out[k] = np.isfinite(s) and s > 0.0
    return out


def _png(figure, dpi=100) -> bytes:
    """The figure as PNG bytes (whatever its canvas)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi, pil_kwargs=dict(compress_level=1))  # fast encoding
    return buffer.getvalue()


def _interactive_canvas(figure):
    """An ipympl canvas widget showing ``figure`` (clicks reach its ``mpl_connect`` handlers), or None
    without ipympl. The user's matplotlib backend is left as it is: importing the ``ipympl``
    package would switch it (its ``__init__`` calls ``matplotlib.use`` when matplotlib is loaded), so
    the package is imported with matplotlib hidden for that moment, and only its canvas is used."""
    import sys

    if "ipympl" not in sys.modules:
        loaded = sys.modules.pop("matplotlib", None)
        try:
            import ipympl  # noqa: F401
        except ImportError:
            return None
        finally:
            if loaded is not None:
                sys.modules["matplotlib"] = loaded
    try:
        from ipympl.backend_nbagg import Canvas, FigureManager
    except ImportError:
        return None
    import warnings

    with warnings.catch_warnings():  # ipympl's toolbar passes traitlets an argument it deprecates
        warnings.simplefilter("ignore", DeprecationWarning)
        canvas = Canvas(figure)
        FigureManager(canvas, 0)  # the manager wires the canvas to its front end
    canvas.header_visible = canvas.footer_visible = canvas.resizable = False
    canvas.toolbar_visible = False
    canvas.layout.width = "100%"
    return canvas


def _slider(widgets, description, value, low, high, step, log=False):
    """A float slider that updates on release, its range widened to hold ``value``."""
    value = float(value)
    if log:
        value = value if np.isfinite(value) and value > 0 else 10.0**high
        exponent = np.log10(value)
        return widgets.FloatLogSlider(value=value, base=10, min=min(low, np.floor(exponent)),
                                      max=max(high, np.ceil(exponent)), step=step,
                                      description=description, continuous_update=False)
    return widgets.FloatSlider(value=value, min=min(low, value), max=max(high, value), step=step,
                               description=description, continuous_update=False, readout_format=".3f")


FLUID_CONTROLS = ("density_ratio", "speed_ratio", "coupling", "bessel_order")


def outside_fluids(given: Fluid | None = None) -> dict:
    """The choices of the explorer's "outside" control: vacuum, air and water around a VHB-like
    wall (μ = 20 kPa, ρ_s = 960 kg/m³; :data:`jaxdea.units.AIR`, :data:`jaxdea.units.WATER`), led by
    the tube's own surrounding fluid ("as given") where it has one."""
    from ..physics.units import AIR, WATER, Scales, fluid_from_si

    scales = Scales(shear_modulus=20e3, density=960.0, permittivity=4.2e-11, inner_radius=5e-3)
    choices = {"vacuum": None, "air": fluid_from_si(scales, AIR), "water": fluid_from_si(scales, WATER)}
    return choices if given is None else {"as given": given, **choices}


@functools.cache
def _app_class():
    """The app's class (a ``VBox``), defined on first use so that ipywidgets stays optional."""
    import ipywidgets as widgets
    from matplotlib.figure import Figure

    from .plotstyle import LABELS, SHORT_LABELS, style

    class Explorer(widgets.VBox):
        """The explorer app (see :func:`explore`)."""

        def __init__(self, tube, fluid, *, n_modes, alphas, n_axial, n_layers, n_max, m_max,
                     stability):
            self.base_tube, self.n_modes, self.alphas = tube, int(n_modes), alphas
            self.n_axial, self.n_layers, self.n_max, self.m_max = n_axial, n_layers, n_max, m_max
            self.stability = stability
            self.data = self.status = self.mode = self.error = None
            self.damped = None  # :class:`DampedRoots` at the axial modes, or None (no damping)
            self.unstable = None  # where the lowest root is imaginary (:func:`unstable_alphas`), or None
            self.selection = None  # (α̂, branch) of the mode shown
            self._first = {}  # (V̂_first, m, n) of the last wall
            self._growth = {}  # {state key: unstable α̂ flags}
            self._compiled = set()  # the kinds of problem solved once (their programs compiled)
            self._holding = False  # True while set() changes several controls
            self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=1)
            self._pending = None  # (wall key, future) of the background first-instability solve
            self._pending_growth = None  # (state key, future) of the background growth-rate scan
            self._lock = threading.RLock()  # one recomputation or redraw at a time
            shown = fluid if fluid is not None else Fluid()
            self.outside = outside_fluids(tube.outer)
            wide = dict(description_width="initial")
            c = self.controls = dict(
                voltage=_slider(widgets, "V̂", tube.voltage, 0.0, 0.3, 0.002),
                lambda_i=_slider(widgets, "λ_i", tube.lambda_i, 0.7, 1.6, 0.01),
                lambda_z=_slider(widgets, "λ_z", tube.lambda_z, 0.8, 2.0, 0.01),
                eta=_slider(widgets, "η", tube.eta, 0.5, 0.95, 0.01),
                gent=_slider(widgets, "G", tube.gent, -1.0, 3.0, 0.05, log=True),
                density_ratio=_slider(widgets, "ρ̂_f", shown.density_ratio, 0.01, 2.0, 0.01),
                speed_ratio=_slider(widgets, "ĉ_f", shown.speed_ratio, 0.05, 2.0, 0.01),
                m=widgets.IntSlider(value=0, min=0, max=8, description="order m",
                                    continuous_update=False),
                filled=widgets.ToggleButtons(options=["empty", "filled"], description="tube",
                                             value="filled" if fluid is not None else "empty", style=wide),
                coupling=widgets.ToggleButtons(options=["acoustic", "paper"], value=shown.coupling,
                                               description="fluid model", style=wide),
                bessel_order=widgets.BoundedIntText(value=shown.bessel_order or 1, min=0, max=20,
                                                    description="ν (paper)"),
                outside=widgets.ToggleButtons(options=list(self.outside), value=next(iter(self.outside)),
                                              description="outside", style=wide),
                damping=widgets.ToggleButtons(options=list(DAMPING_LAWS), value="none",
                                              description="damping", style=wide),
                damping_size=_slider(widgets, "η_v or ζ", 0.05, 0.0, 0.5, 0.005),
            )
            if tube.layers is not None or tube.material != "gent":  # G is the Gent energy's alone
                c["gent"].disabled = True
                c["gent"].description = "G (layers)" if tube.layers is not None else "G (material)"
            self.pick = dict(
                alpha=widgets.FloatSlider(value=float(alphas[0]), min=float(alphas.min()),
                                          max=float(alphas.max()), step=0.01, description="α̂",
                                          continuous_update=False, readout_format=".3f"),
                branch=widgets.Dropdown(options=[(str(k + 1), k) for k in range(self.n_modes)],
                                        value=0, description="branch"),
                show=widgets.Button(description="show mode shape"),
            )
            self.message = widgets.HTML()
            self.status_label = widgets.HTML()
            self.busy = widgets.HTML()  # "compiling (once)…" while a new kind of problem compiles
            self.mode_label = widgets.HTML("mode shape: click a curve, or pick α̂ and branch")
            self.damping_label = widgets.HTML()  # Q of the damped roots at the axial modes
            with style():
                self.figure = Figure(figsize=(12.0, 3.8), layout="constrained")
                *self.axes, self.mode_axes = self.figure.subplots(1, 3, width_ratios=[1.0, 1.0, 0.8])
            self.canvas = _interactive_canvas(self.figure)
            if self.canvas is None:  # a PNG image: no clicks, the α̂ and branch controls select
                from matplotlib.backends.backend_agg import FigureCanvasAgg

                FigureCanvasAgg(self.figure)
                self.image = widgets.Image(format="png", layout=widgets.Layout(width="100%"))
                self.plot = self.image
            else:
                self.image, self.plot = None, self.canvas
            self._setup_axes(LABELS, SHORT_LABELS)
            self.figure.canvas.mpl_connect("button_press_event", self.on_click)
            super().__init__([
                widgets.HBox([widgets.VBox(list(c.values())),
                              widgets.VBox([self.status_label, self.busy, self.message, self.mode_label,
                                            widgets.HBox(list(self.pick.values())),
                                            self.damping_label])]),
                self.plot,
            ])
            for control in c.values():
                control.observe(self.refresh, names="value")
            self.pick["show"].on_click(lambda _: self.select(self.pick["alpha"].value,
                                                             self.pick["branch"].value))
            self.refresh()

        # --------------------------------------------------------------------------- state
        def parameters(self):
            """(tube, fluid, m) of the controls (the fluid None for the empty tube)."""
            c = self.controls
            tube = self.base_tube.replace(outer=self.outside[c["outside"].value],
                                          **{k: float(c[k].value) for k in
                                             ("voltage", "lambda_i", "lambda_z", "eta", "gent")})
            fluid = None
            if c["filled"].value == "filled":
                paper = c["coupling"].value == "paper"
                fluid = Fluid(float(c["density_ratio"].value), float(c["speed_ratio"].value),
                              coupling=c["coupling"].value,
                              bessel_order=int(c["bessel_order"].value) if paper else None)
            return tube, fluid, int(c["m"].value)

        def png(self) -> bytes:
            """The figure as shown, as PNG bytes."""
            return _png(self.figure)

        @staticmethod
        def _wall_key(tube):
            return (tube.lambda_i, tube.lambda_z, tube.eta, tube.gent, tube.length_ratio,
                    tube.material)

        def _kind(self, fluid, m):
            """The kind of problem (one set of compiled programs): the fluid model, a surrounding
            fluid or none, and m = 0 or m ≥ 1."""
            return ("empty" if fluid is None else fluid.coupling,
                    self.outside[self.controls["outside"].value] is not None, m > 0)

        def _compiling(self, what, kind):
            """Say "compiling (once)…" while a kind of problem is solved for the first time."""
            if (what, kind) not in self._compiled:
                self.busy.value = (f"<i>compiling (once)… the first {what} of this kind of problem "
                                   "(fluid model, m = 0 or m ≥ 1) takes tens of seconds</i>")

        def _compiled_now(self, what, kind):
            self._compiled.add((what, kind))
            self.busy.value = ""

        def _sync_controls(self):
            """The fluid controls act only on a filled tube, ν only with the paper's coupling."""
            c = self.controls
            empty = c["filled"].value == "empty"
            for key in FLUID_CONTROLS:
                c[key].disabled = empty
            c["bessel_order"].disabled = empty or c["coupling"].value != "paper"
            c["damping_size"].disabled = DAMPING_LAWS[c["damping"].value] is None

        def _stability(self, tube):
            """:func:`stability_status` when the first instability of this wall is known (it does
            not depend on V̂ or the fluid); else None, and its ``first_instability`` solve starts
            in the background (the status and shading follow when it ends; :meth:`wait`)."""
            key = self._wall_key(tube)
            if key in self._first:
                return judge_stability(*self._first[key], float(tube.voltage), self.n_max,
                                       self.m_max)
            if self._pending is None or self._pending[0] != key:
                self._pending = (key, self._pool.submit(self._solve_first, key, tube))
            return None

        def _solve_first(self, key, tube):
            """The background solve: store (V̂_first, m, n) and, if the controls still show this
            wall, put its status on the app."""
            try:
                first = first_instability(tube, n_max=self.n_max, m_max=self.m_max,
                                          n_layers=self.n_layers)
            except ValueError as exc:  # shown, like every other error; never a status left pending
                with self._lock:
                    self.status_label.value = ""
                    self._show_error(str(exc))
                return
            with self._lock:
                self._first = {key: (float(first.voltage), int(first.m), int(first.n))}
                try:
                    tube_now, _, _ = self.parameters()
                except ValueError:
                    return
                if self.data is not None and self._wall_key(tube_now) == key:
                    self.status = self._stability(tube_now)
                    self._show_status()
                    self._draw()

        def _state_key(self, tube, fluid, m):
            return (tuple(float(getattr(tube, k)) for k in ("voltage", "lambda_i", "lambda_z", "eta", "gent")),
                    fluid, tube.outer, m)

        def _unstable_alphas(self, tube, fluid, m):
            """The α̂ flags of :func:`unstable_alphas` when known for this state; else None, and
            the scan starts in the background (the marks follow when it ends; :meth:`wait`)."""
            key = self._state_key(tube, fluid, m)
            if key in self._growth:
                return self._growth[key]
            if self._pending_growth is None or self._pending_growth[0] != key:
                self._pending_growth = (key, self._pool.submit(self._solve_growth, key, tube, fluid, m,
                                                               self.data.alpha))
            return None

        def _solve_growth(self, key, tube, fluid, m, alpha):
            """The background growth-rate scan of a state (skipped if the controls moved on)."""
            with self._lock:
                try:
                    current = self._state_key(*self.parameters())
                except ValueError:
                    return
                if current != key:
                    return
                self._compiling("check of unstable α̂", self._kind(fluid, m))
            flags = unstable_alphas(tube, alpha, fluid, m, self.n_layers)
            with self._lock:
                self._compiled_now("check of unstable α̂", self._kind(fluid, m))
                self._growth = {key: flags}
                try:
                    current = self._state_key(*self.parameters())
                except ValueError:
                    return
                if self.data is not None and current == key:
                    self.unstable = flags
                    self._draw()

        def wait(self):
            """Block until the background solves (first instability, unstable α̂) have ended and
            what they give is shown."""
            for pending in (self._pending, self._pending_growth):
                if pending is not None:
                    pending[1].result()

        def _show_status(self):
            status = self.status
            if not self.stability:
                self.status_label.value = ""
            elif status is None:
                self.status_label.value = "<i>stability: solving the first instability…</i>"
            else:
                self.status_label.value = (
                    f'<b style="color:{"#b00020" if status.unstable else "#1b5e20"}">'
                    f"{html.escape(status.text)}</b>")

        def _show_error(self, text):
            self.message.value = f'<span style="color:#b00020">{html.escape(text)}</span>'

        def set(self, **values):
            """Set several controls (by their key in ``controls``) with one recomputation."""
            self._holding = True
            try:
                for key, value in values.items():
                    self.controls[key].value = value
            finally:
                self._holding = False
            self.refresh()

        def refresh(self, change=None):
            """Recompute for the controls' values and redraw; a ValueError is shown, not raised."""
            if self._holding:
                return
            with self._lock:
                self._refresh()

        def _refresh(self):
            self.message.value = ""
            self._sync_controls()
            try:
                tube, fluid, m = self.parameters()
                self._compiling("curve", self._kind(fluid, m))
                data = explorer_data(tube, fluid, m, self.n_modes, self.alphas, self.n_axial,
                                     self.n_layers)
                self._compiled_now("curve", self._kind(fluid, m))
            except ValueError as exc:
                self.busy.value = ""
                self.data, self.status, self.mode, self.error = None, None, None, str(exc)
                self.unstable = None
                self._show_error(str(exc))
                self.status_label.value = ""
            else:
                self.data, self.error = data, None
                self.status = self._stability(tube) if self.stability else None
                self.unstable = self._unstable_alphas(tube, fluid, m) if self.stability else None
                self._show_status()
                slider, low, high = self.pick["alpha"], float(data.alpha[0]), float(data.alpha[-1])
                if low > slider.max:
                    slider.max, slider.min = high, low
                else:
                    slider.min, slider.max = low, high
                self.mode = self._mode(*self.selection) if self.selection is not None else None
                self.damped = self._damped(tube, fluid, m)
            if self.data is None:
                self.damped = None
            self._show_damping()
            self._draw()

        def _damped(self, tube, fluid, m):
            """:func:`damped_roots` for the damping controls, or None (no damping, or its error
            shown beside the elastic curves)."""
            kind = self.controls["damping"].value
            if DAMPING_LAWS[kind] is None:
                return None
            what = f"damped roots ({kind})"
            try:
                self._compiling(what, self._kind(fluid, m))
                damped = damped_roots(tube, self.data, kind, float(self.controls["damping_size"].value),
                                      fluid, m, self.n_layers)
            except ValueError as exc:
                self.busy.value = ""
                self._show_error(str(exc))
                return None
            self._compiled_now(what, self._kind(fluid, m))
            return damped

        def _show_damping(self):
            """The quality factors of the damped roots at the axial modes, one line per branch."""
            if self.damped is None:
                self.damping_label.value = ""
                return
            rows = []
            for k in range(self.n_modes):
                values = ", ".join("–" if not np.isfinite(q) else f"{q:.3g}"
                                   for q in self.damped.quality_factor[:, k])
                rows.append(f"branch {k + 1}: {values}")
            n = self.data.axial_n
            self.damping_label.value = (f"<b>damped: Q = Re Ω/(2 Im Ω)</b> at n = {n[0]}…{n[-1]}<br>"
                                        + "<br>".join(rows))

        def _mode(self, alpha, branch):
            """:func:`explorer_mode` for the controls' values, or None (the error shown)."""
            tube, fluid, m = self.parameters()
            try:
                self._compiling("mode shape", self._kind(fluid, m))
                mode = explorer_mode(tube, self.data, alpha, branch, fluid, m, self.n_layers)
            except ValueError as exc:
                self.busy.value = ""
                self._show_error(str(exc))
                return None
            self._compiled_now("mode shape", self._kind(fluid, m))
            return mode

        def select(self, alpha, branch):
            """Show the mode shape of ``branch`` (0: the lowest) at the grid α̂ nearest to
            ``alpha`` (:func:`explorer_mode`) and return it as (α̂, Ω, r, fields); a ValueError is
            shown, not raised (None returned)."""
            with self._lock:
                self.selection = (float(alpha), int(branch))
                self.mode = self._mode(*self.selection) if self.data is not None else None
                if self.mode is not None:  # the α̂ and branch controls show what is selected
                    self.pick["alpha"].value = self.mode[0]
                    self.pick["branch"].value = int(branch)
                self._draw()
                return self.mode

        def on_click(self, event):
            """Matplotlib click handler: the root nearest to the click (in axes units) on either
            plot is selected."""
            if self.data is None or event.inaxes not in self.axes or event.xdata is None:
                return
            ax = event.inaxes
            y = self.data.omega if ax is self.axes[0] else self.data.phase_velocity
            x0, x1 = ax.get_xlim()
            y0, y1 = ax.get_ylim()
            dx = (self.data.alpha[:, None] - event.xdata) / (x1 - x0)
            dy = (y - event.ydata) / (y1 - y0)
            distance = np.where(np.isfinite(dy), np.hypot(dx, dy), np.inf)
            row, branch = np.unravel_index(np.argmin(distance), distance.shape)
            if np.isfinite(distance[row, branch]):
                self.select(self.data.alpha[row], branch)

        # ------------------------------------------------------------------------ drawing
        def _setup_axes(self, labels, short):
            ax, axv = self.axes
            with style():
                self.lines = [ax.plot([], [], lw=1.5, label=f"branch {k + 1}")[0]
                              for k in range(self.n_modes)]
                self.speed_lines = [axv.plot([], [], lw=1.5, color=line.get_color())[0]
                                    for line in self.lines]
                self.markers = ax.plot([], [], "o", ms=4, color="k", label="axial modes $n$")[0]
                self.speed_markers = axv.plot([], [], "o", ms=4, color="k")[0]
                self.picked = ax.plot([], [], "*", ms=12, color="crimson", label="mode shown")[0]
                self.damped_markers = ax.plot([], [], "D", ms=5, mfc="none", mec="tab:purple", mew=1.2,
                                              label=r"damped: Re $\Omega$ at the modes $n$")[0]
                self.mode_lines = [self.mode_axes.plot([], [], label=name)[0]
                                   for name in (r"$\bar u$ (radial)", r"$\bar v$ (hoop)", r"$\bar w$ (axial)")]
                self.labels, self.spans = [], []
                ax.set(xlabel=labels["alpha"], ylabel=short["omega"])
                axv.set(xlabel=labels["alpha"], ylabel=short["phase_velocity"])
                self.mode_axes.set(xlabel=r"radius $\hat r = r/R_i$", ylabel="displacement (max = 1)")
                from matplotlib.patches import Patch

                self.unstable_patch = Patch(facecolor="#f4b6b6", alpha=0.6,
                                            label=r"$\Omega^2 < 0$: lowest root imaginary (unstable)")
                for axis in (*self.axes, self.mode_axes):  # fewer tick labels: text dominates drawing
                    axis.locator_params(nbins=5)

        def _draw(self):
            """Put the data, the status and the mode shape on the figure and render it."""
            with style():
                self._draw_curves()
                self._draw_mode()
            if self.canvas is not None:
                self.canvas.draw_idle()
            else:
                self.image.value = _png(self.figure)

        def _draw_curves(self):
            ax, axv = self.axes
            for artist in self.labels + self.spans:
                artist.remove()
            self.labels, self.spans = [], []
            d = self.data
            unstable = self.status is not None and self.status.unstable
            for axis in self.axes:
                axis.set_facecolor(UNSTABLE_FACE if unstable else "white")
            if d is None:
                for line in self.lines + self.speed_lines + [self.markers, self.speed_markers,
                                                             self.damped_markers]:
                    line.set_data([], [])
                ax.set_title("invalid parameters (see the message)")
                axv.set_title("")
                if ax.get_legend() is not None:
                    ax.get_legend().remove()
                return
            for k in range(self.n_modes):
                self.lines[k].set_data(d.alpha, d.omega[:, k])
                self.speed_lines[k].set_data(d.alpha, d.phase_velocity[:, k])
            rows = np.repeat(d.axial_index, self.n_modes)
            ks = np.tile(np.arange(self.n_modes), len(d.axial_index))
            self.markers.set_data(d.alpha[rows], d.omega[rows, ks])
            self.speed_markers.set_data(d.alpha[rows], d.phase_velocity[rows, ks])
            for n, a in zip(d.axial_n, d.axial_alpha, strict=True):
                self.labels.append(ax.annotate(f"$n$={n}", (a, 1.0), xycoords=("data", "axes fraction"),
                                               xytext=(0, 2), textcoords="offset points",
                                               ha="center", va="bottom", fontsize=7))
            handles = [*self.lines, self.markers]
            if self.unstable is not None and np.any(self.unstable):
                edges = np.concatenate([[d.alpha[0]], 0.5 * (d.alpha[1:] + d.alpha[:-1]), [d.alpha[-1]]])
                for k in np.flatnonzero(self.unstable):
                    for axis in self.axes:
                        self.spans.append(axis.axvspan(edges[k], edges[k + 1], facecolor="#f4b6b6",
                                                       alpha=0.6, lw=0, zorder=0))
                handles.append(self.unstable_patch)
            if self.mode is not None:
                handles.append(self.picked)
            if self.damped is not None:
                rows = np.repeat(np.arange(len(d.axial_alpha)), self.n_modes)
                ks = np.tile(np.arange(self.n_modes), len(d.axial_alpha))
                self.damped_markers.set_data(d.axial_alpha[rows], self.damped.omega.real[rows, ks])
                low = self.damped.quality_factor[:, 0]
                self.damped_markers.set_label(r"damped Re $\Omega$ (branch 1 $Q$: "
                                              + ", ".join("–" if not np.isfinite(q) else f"{q:.3g}"
                                                          for q in low) + ")")
                handles.append(self.damped_markers)
            else:
                self.damped_markers.set_data([], [])
            ax.legend(handles=handles, loc="upper left", fontsize=7)
            tube, fluid, m = self.parameters()
            filled = "empty" if fluid is None else f"filled ({fluid.coupling})"
            outside = self.controls["outside"].value
            filled += "" if tube.outer is None else f", in {outside}"
            ax.set_title(f"order $m$ = {m}, {filled}, $\\hat V$ = {float(tube.voltage):.3g}", pad=12)
            axv.set_title(self.status.text if self.status is not None else "", fontsize=8,
                          color="#b00020" if unstable else "black")
            for axis in self.axes:
                axis.set_xlim(d.alpha[0], d.alpha[-1])
            # the default view: every branch unless the highest squeezes the others (a thickness
            # branch far above them), then the lower ones with room
            finite = d.omega[np.isfinite(d.omega)]
            top, shown = (float(np.max(finite)) if finite.size else 1.0), self.n_modes
            if self.n_modes > 2:
                lower = d.omega[:, : self.n_modes - 1]
                lower = lower[np.isfinite(lower)]
                if lower.size and top > 2.0 * np.max(lower):
                    top, shown = 1.5 * float(np.max(lower)), self.n_modes - 1
            ax.set_ylim(0.0, 1.05 * top)
            speeds = d.phase_velocity[d.alpha >= 0.2 * d.alpha[-1], :shown]
            speed_top = np.nanmax(speeds, initial=0.0) if speeds.size else 0.0
            axv.set_ylim(0.0, 1.1 * speed_top if np.isfinite(speed_top) and speed_top > 0 else 1.0)

        def _draw_mode(self):
            axes = self.mode_axes
            if self.mode is None:
                self.picked.set_data([], [])
                for line in self.mode_lines:
                    line.set_data([], [])
                axes.set_axis_off()  # no empty frame, ticks or legend
                if axes.get_legend() is not None:
                    axes.get_legend().remove()
                axes.set_title("")
                if not getattr(self, "_hint", None):
                    self._hint = axes.text(0.5, 0.5, "mode shape:\nclick a curve,\nor pick α̂ and branch",
                                           transform=axes.transAxes, ha="center", va="center",
                                           color="0.4")
                self._hint.set_visible(True)
                self.mode_label.value = "mode shape: click a curve, or pick α̂ and branch"
                return
            a, omega, r, fields = self.mode
            axes.set_axis_on()
            if getattr(self, "_hint", None):
                self._hint.set_visible(False)
            rows = (0, None, 1) if fields.shape[0] == 6 else (0, 1, 2)  # ū, v̄ (order m), w̄
            for line, row in zip(self.mode_lines, rows, strict=True):
                line.set_data(([], []) if row is None else (r, fields[row]))
            axes.relim()
            axes.autoscale_view()
            axes.legend(handles=[line for line, row in zip(self.mode_lines, rows, strict=True)
                                 if row is not None], loc="best", fontsize=7)
            branch = self.selection[1] + 1 if self.selection is not None else 1
            axes.set_title(rf"branch {branch}: $\hat\alpha$ = {a:.3f}, $\Omega$ = {omega:.4f}")
            self.picked.set_data([a], [omega])
            self.mode_label.value = (f"mode shape: branch {branch} at α̂ = {a:.4f}, "
                                     f"Ω = {omega:.5f}")

    return Explorer
