"""The paper's figures (Figs. 2–10 of the seed paper, §5), the model comparison and the static response.

``make_figures(out)`` (the main job, ``jaxdea figures``) writes, for each figure, a PNG and the CSV
behind it. The tube is the paper's: η = 0.85, L = 10 R_o, λ_z = 1.2, Gent G = 97.2; the fluid
ρ̂_f = 0.13, ĉ_f = 0.27. Every curve is the lowest frequency of the axial mode n (α̂ = 2nπη/(10λ_z)),
solved by certified continuation along the figure's own axis (V̂, n, ĉ_f, ρ̂_f, h/R_i:
:func:`solve_curves`, the roots of :func:`jaxdea.frequencies` at every point); the critical voltages
likewise along theirs (:func:`critical_curves`). The figures against n follow α̂ = n α̂_1 through
fractional n (the infinite tube's curve) and mark the tube's modes, the integers; the paper's
coupling, whose Bessel order is ν = n, exists at integer n only and is drawn there.

Styles are the same in every figure: one colour per axial mode n (:data:`MODE_COLORS`), per order m
(:data:`ORDER_COLORS`) or, against n, per V̂ (:data:`VOLTAGE_COLORS`); one line style per coupling and
λ_i (:func:`_style`: the empty tube and the acoustic coupling solid-based, the paper's dashed-based).
Legends sit below the axes. A curve breaks only where its root changes branch (:func:`solve_curves`),
the point after the break circled.

Past the critical voltage V̂_cr(n) the lowest frequency is imaginary (the tube buckles
axisymmetrically): the curves against V̂ run from V̂ = 0 to V̂_cr(n), where they end at Ω = 0 (the
points crowd there, V̂ = V̂_cr(1 − (1 − t)²) for t uniform: Ω falls like √(V̂_cr − V̂)); elsewhere such
points are left blank (NaN, ``status`` = ``"past critical"`` in the CSV). V̂_cr is solved directly
(:func:`jaxdea.critical_voltage`'s problem), so a blank point never hides a wrong branch.

The tube loses stability earlier in a non-axisymmetric order m (theory_m.md): for λ_i = 0.9 the
ring mode (m, n) = (2, 1) at V̂ ≈ 0.029, a tenth of the axisymmetric V̂_cr. The first instability
(the smallest V̂_cr over m ≤ 4, n ≤ max_mode, as :func:`jaxdea.first_instability`) is shaded on the
figures against V̂ (Figs. 2, 5) and stated on those against n (Figs. 3, 4, 6, 7; the curves past it
faded). Three figures of order m follow: the stability map (V̂_cr of m = 0 … 4 against λ_i and n),
the cross-sections of the lowest m = 1, 2, 3 modes, and the dispersion curves Ω(α̂) of m = 0, 1, 2.

Data layout of every CSV: one row per point and coupling, long format (``figure``, the swept
parameters, ``coupling``, ``alpha_hat``, ``omega``, ``phase_velocity`` = Ω/α̂, ``v_critical``,
``status``; Figs. 2–7 add ``v_first``, ``m_first``, ``n_first``, the first instability at the row's
λ_i).
"""

from __future__ import annotations

import concurrent.futures
import csv
import dataclasses
import math
import threading
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .base_state import _squared_voltage, pull_in
from .compiled import jit
from .curves import _solve_critical_path, _solve_path
from .files import atomic_write, save_figure, write_together
from .leaves import apply_parameters
from .modes import mode_shape
from .params import Fluid, Tube, mode_wavenumber
from .scalar import Status
from .state_matrix import ORDER_M

PAPER_TUBE = Tube(lambda_z=1.2, eta=0.85, gent=97.2, length_ratio=10.0)
PAPER_FLUID = dict(density_ratio=0.13, speed_ratio=0.27)
COUPLINGS = ("acoustic", "paper")
STRETCHES = (0.9, 1.1)  # subcritical and overcritical λ_i of the paper
MODES = (1, 2, 3)
MODE_COLORS = {1: "tab:blue", 2: "tab:orange", 3: "tab:green"}  # one colour per axial mode n
ORDER_COLORS = ("tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")  # m = 0 … 4
VOLTAGE_COLORS = {0.0: "black", 0.1: "tab:red", 0.15: "tab:purple", 0.2: "tab:brown"}  # against n
COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")  # other curves
SHAPE_STRETCH, SHAPE_VOLTAGE = 0.9, 0.01  # a stable state of the paper's tube (first instability 0.0293)
SHAPE_TUBE = PAPER_TUBE.replace(lambda_i=SHAPE_STRETCH, voltage=SHAPE_VOLTAGE)
ORDERS = (0, 1, 2, 3, 4)  # circumferential orders of the stability map and of the first instability
CRITICAL_STRETCH = 1.0 / math.sqrt(float(PAPER_TUBE.lambda_z))  # λ_i = λ_z^{-1/2} of Figs. 4 and 7
MAP_STRETCH_RANGE = (0.9, 1.4)  # below λ_i ≈ 0.9 the tube is unstable at V̂ = 0 (m = 2, n = 1: growth rate
# s = 0.35 at λ_i = 0.875, 0.96 at 0.8), where V̂_cr, the first zero of Ω² from V̂ = 0, means nothing
SHAPE_ORDERS = (1, 2, 3)
CURVE_ORDERS = (0, 1, 2)
CURVE_ROOTS = 3
SAVE_DPI = 130  # resolution of the PNGs
EMPTY_CURVE_ORDERS = tuple(sorted(set(CURVE_ORDERS) | set(SHAPE_ORDERS)))  # the empty tube's curves


@dataclasses.dataclass(frozen=True)
class Resolution:
    """Grid sizes: ``full`` for the figures, ``quick`` for tests and smoke runs."""

    voltages: int  # points of each curve against V̂, from 0 to its critical voltage
    max_mode: int
    mode_steps: int  # points per unit of n of the curves against the mode number (α̂ between modes)
    fluid_points: int
    static_points: int
    map_stretches: int  # λ_i of the stability map
    curve_steps: int  # α̂ steps of the order-m dispersion curves per mode spacing α̂_1
    outline_points: int  # angles θ of the cross-section outlines

    @classmethod
    def pick(cls, quick: bool) -> Resolution:
        if quick:
            return cls(voltages=8, max_mode=4, mode_steps=2, fluid_points=6, static_points=60,
                       map_stretches=5, curve_steps=2, outline_points=73)
        return cls(voltages=64, max_mode=15, mode_steps=5, fluid_points=40, static_points=240,
                   map_stretches=44, curve_steps=16, outline_points=361)

    def modes(self) -> np.ndarray:
        """The axial mode numbers n of the curves against n: ``mode_steps`` points per unit from 1
        to ``max_mode`` (fractional n: the wavenumber α̂ between the tube's modes)."""
        return np.round(np.linspace(1.0, self.max_mode, (self.max_mode - 1) * self.mode_steps + 1), 12)


class Table:
    """Rows of one figure's CSV (long format, module docstring)."""

    def __init__(self, name: str):
        self.name, self.rows = name, []

    def add(self, **row):
        self.rows.append({"figure": self.name, **row})

    def write(self, path: Path) -> None:
        names = list(dict.fromkeys(k for row in self.rows for k in row))
        with atomic_write(path) as tmp, open(tmp, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=names)
            writer.writeheader()
            for row in self.rows:
                writer.writerow({k: _fmt(v) for k, v in row.items()})


def _fmt(v):
    if isinstance(v, (float, np.floating)):
        return "nan" if not np.isfinite(v) else f"{float(v):.12g}"
    return v


# ----------------------------------------------------------------------------- computations


PATH_POINTS = 256  # points per compiled continuation call: curves are packed into padded paths


def _packed(curves: list):
    """Curves (values, abscissa) packed into paths of :data:`PATH_POINTS` points: yields (the
    indices of the curves of a path, {name: values (PATH_POINTS,)}, abscissa (NaN-padded), starts).
    ``values`` maps parameter names (the same for every curve) to scalars or arrays of the curve's
    points; padding repeats the last point."""
    paths, current, used = [], [], 0
    for k, (_, abscissa) in enumerate(curves):
        if len(abscissa) > PATH_POINTS:
            raise ValueError(f"a curve of {len(abscissa)} points exceeds PATH_POINTS = {PATH_POINTS}")
        if used + len(abscissa) > PATH_POINTS:
            paths.append(current)
            current, used = [], 0
        current.append(k)
        used += len(abscissa)
    paths.append(current)
    for members in paths:
        lengths = [len(curves[i][1]) for i in members]
        size = sum(lengths)
        values = {k: np.pad(np.concatenate([np.broadcast_to(np.asarray(curves[i][0][k], float), n)
                                            for i, n in zip(members, lengths, strict=True)]),
                            (0, PATH_POINTS - size), mode="edge") for k in curves[members[0]][0]}
        abscissa = np.full(PATH_POINTS, np.nan)
        abscissa[:size] = np.concatenate([np.asarray(curves[i][1], float) for i in members])
        starts = np.zeros(PATH_POINTS, bool)
        starts[np.cumsum([0] + lengths[:-1])] = True
        yield members, lengths, values, abscissa, starts


@jit
def _points(base: Tube, fluid: Fluid | None, values: dict):
    """(tubes, α̂, fluids) of the points of a path: ``base`` and ``fluid`` with ``values`` set
    (:func:`jaxdea.leaves.apply_parameters`, one point per entry of the arrays)."""
    return jax.vmap(lambda vals: apply_parameters(base, 1.0, fluid, vals))(values)


def _strong(tree):
    """Every leaf a strong float64 array of PATH_POINTS values (whichever parameters vary: one
    compiled program)."""
    return jax.tree_util.tree_map(
        lambda x: jnp.asarray(np.broadcast_to(np.asarray(x, float), PATH_POINTS)), tree)


def critical_curves(n_layers: int, curves: list, base: Tube = PAPER_TUBE) -> list[np.ndarray]:
    """V̂_cr along each curve (values, abscissa) of the tube ``base`` (``values``: names of
    :mod:`jaxdea.leaves` and ``m``, the circumferential order, 0 if absent), by continuation along
    the curve (:func:`jaxdea.curves.critical_path_unchecked`: the first zero of f(Ω = 0; V̂) in
    (0, V̂_lim], V̂_lim the pull-in limit; NaN where none); one compiled program for every curve."""
    out = [None] * len(curves)
    for members, lengths, values, abscissa, starts in _packed(curves):
        orders = values.pop("m", np.zeros(PATH_POINTS))
        tubes, alphas, _ = _points(base, None, {k: jnp.asarray(v) for k, v in values.items()})
        voltage, *_ = _solve_critical_path(*_strong((tubes, alphas)), jnp.asarray(abscissa),
                                           jnp.asarray(starts), jnp.asarray(orders), n_layers, ORDER_M)
        voltage = np.asarray(voltage)[:, 0]
        for i, first, size in zip(members, np.cumsum([0] + lengths[:-1]), lengths, strict=True):
            out[i] = voltage[first:first + size]
    return out


def critical_voltage_grid(tube: Tube, n_layers: int, **axes) -> np.ndarray:
    """V̂_cr over the grid of ``axes`` (tube leaves, ``thickness_ratio``, ``n`` and ``m``, the order:
    0 if absent), shape of the grid, by :func:`critical_curves` along the longest axis (the last of
    equals) for every combination of the others; NaN where the lowest frequency stays real up to
    the pull-in limit."""
    names = list(axes)
    values = [np.atleast_1d(np.asarray(v, float)) for v in axes.values()]
    along = max(reversed(range(len(names))), key=lambda k: len(values[k]))
    others = [k for k in range(len(names)) if k != along]
    combos = list(np.ndindex(*(len(values[k]) for k in others)))
    curves = [({**{names[k]: values[k][i] for k, i in zip(others, idx, strict=True)},
                names[along]: values[along]}, values[along]) for idx in combos]
    if "n" not in names:
        curves = [({**c, "n": 1.0}, a) for c, a in curves]
    solved = critical_curves(n_layers, curves, tube)
    grid = np.moveaxis(np.array(solved).reshape([len(values[k]) for k in others] + [len(values[along])]),
                       -1, along)
    return grid


@dataclasses.dataclass(frozen=True)
class Solved:
    """The lowest root (roots) along one curve: Ω, status and ``jumps`` (True where the root left
    the branch it followed: a branch change, see :func:`solve_curves`), each of shape (P,) (or
    (P, K)), and α̂ (P,)."""

    omega: np.ndarray
    status: np.ndarray
    alpha: np.ndarray
    jumps: np.ndarray


MASSLESS_FLUID = Fluid(density_ratio=1e-30, speed_ratio=1e6)
"""The empty tube's curves are solved as filled with this acoustic fluid, so that the empty tube and
the acoustic coupling share one compiled program per curve family (two programs fewer to compile
and to load: a cold ``jaxdea figures`` took 96 CPU s instead of 126, measured). It is the empty tube to
rounding: the coupling scales the basis column ū_i by D_0(s) > 0 (s = χ̂²r̂_i² < 0, no fluid
resonance) and adds Ω²ρ̂_f r̂_i N_0 e_T, 1e-25 of it here, and the orthonormalisation takes the scale
out; at ĉ_f = 1e6 the fluid's cutoff ĉ_fα̂ and step π ĉ_f/r̂_i lie far above the wall's, so the scan
has the empty tube's grid (tests/test_curves.py: the roots equal ``jaxdea.frequencies`` of the
empty tube)."""


def solve_curves(n_layers: int, fluid: Fluid | None, curves: list, base: Tube = PAPER_TUBE,
                 n_roots: int = 1, m=None) -> list[Solved]:
    """The lowest root (``n_roots`` lowest: Ω of shape (P, n_roots)) along each curve of the tube
    ``base``, by continuation along the curve (:func:`jaxdea.curves.path_unchecked`; of order m
    where ``m`` is not None, the order-m family with m traced).

    A curve is (values, abscissa): ``values`` maps parameter names of :mod:`jaxdea.leaves` (the same
    names for every curve; ``n`` sets α̂ from the mode number) to scalars or arrays of its P points,
    and the abscissa (P,) is the coordinate the predictor extrapolates in. Every point gets the
    roots of :func:`jaxdea.frequencies` (the scan where a step fails its checks, and at every point
    of the paper's coupling, ν = n). Curves are packed into paths of :data:`PATH_POINTS` points
    (:func:`_packed`), so one compiled program serves every figure of a coupling (the empty tube
    solved as :data:`MASSLESS_FLUID`: the acoustic coupling's program). A jump is a point
    solved by the scan whose root is more than a quarter of the gap to its neighbours (to Ω = 0 for
    the lowest) away from its prediction: the root changed branch there (a root that came down
    through Ω = 0 or went up through it past V̂_cr, or, with the paper's coupling, a pair born below
    it)."""
    fluid = MASSLESS_FLUID if fluid is None else fluid
    paper = fluid.coupling == "paper"
    solved = [None] * len(curves)
    for members, lengths, values, abscissa, starts in _packed(curves):
        tubes, alphas, fluids = _points(base, fluid, {k: jnp.asarray(v) for k, v in values.items()})
        orders = values["n"] if paper else np.zeros(PATH_POINTS)
        args = (*_strong((tubes, alphas, fluids)), jnp.asarray(abscissa), jnp.asarray(starts),
                jnp.asarray(orders), n_roots, n_layers, "n" if paper else 0)
        if m is None:
            omega, status, _, restarted = _solve_path(*args, decoupled=False)
        else:
            omega, status, _, restarted = _solve_path(*args, jnp.float64(m), ORDER_M)
        omega, status, restarted, alphas = (np.asarray(x) for x in (omega, status, restarted, alphas))
        if n_roots == 1:
            omega, status, restarted = omega[:, 0], status[:, 0], restarted[:, 0]
        for i, first, size in zip(members, np.cumsum([0] + lengths[:-1]), lengths, strict=True):
            rows = slice(first, first + size)
            jumps = restarted[rows].copy()
            jumps[0] = False  # the start of a curve
            solved[i] = Solved(omega[rows], status[rows], alphas[rows], jumps)
    return solved


@dataclasses.dataclass(frozen=True)
class Stability:
    """Critical voltages of the orders m = 0 … 4 (:data:`ORDERS`) of the paper's tube.

    Attributes:
        map_stretches: λ_i of the stability map, shape (L,).
        map_voltages: V̂_cr of (m, n = 1) at each of them, shape (L, len(ORDERS)).
        grids: {λ_i: V̂_cr of every (m, n), shape (len(ORDERS), max_mode)} at the λ_i of the figures.
        modes: fractional mode numbers n of the curves against n, shape (P,) (the integers among them).
        curves: {λ_i: V̂_cr of (m, n) along ``modes``, shape (len(ORDERS), P)} at λ_i = 0.9, 1.1.
    """

    map_stretches: np.ndarray
    map_voltages: np.ndarray
    grids: dict
    modes: np.ndarray
    curves: dict

    def first(self, lambda_i) -> tuple[float, int, int]:
        """(V̂, m, n) of the first instability at λ_i (:func:`lowest_critical` of its grid, as
        :func:`jaxdea.first_instability` with m_max = 4, n_max = max_mode)."""
        return lowest_critical(self.grids[float(lambda_i)])


def lowest_critical(grid) -> tuple[float, int, int]:
    """(V̂, m, n) of the smallest V̂_cr of a grid over (m = 0, 1, …) × (n = 1, 2, …), ties to the lowest
    m, then n; (NaN, −1, 0) if all are NaN."""
    flat = np.where(np.isnan(grid), np.inf, grid).ravel()
    first = int(np.argmin(flat))
    if not np.isfinite(flat[first]):
        return math.nan, -1, 0
    return float(flat[first]), first // grid.shape[1], first % grid.shape[1] + 1


def stability_of_paper_tube(n_layers: int, map_stretches, stretches, modes) -> Stability:
    """:class:`Stability`: V̂_cr of (λ_i, m, n = 1) along ``map_stretches``, of (m, n) along the
    fractional ``modes`` at λ_i = 0.9 and 1.1 (:data:`STRETCHES`) and along the whole modes up to
    ``modes[-1]`` at the other ``stretches``, by continuation (:func:`critical_voltage_grid`)."""
    orders = np.asarray(ORDERS, float)
    modes = np.asarray(modes, float)
    whole = np.arange(1.0, round(modes[-1]) + 1.0)
    along_map = critical_voltage_grid(PAPER_TUBE, n_layers, lambda_i=map_stretches, m=orders)
    on_mode = np.isclose(modes, np.round(modes))
    grids, curves = {}, {}
    for li in stretches:
        dense = li in STRETCHES
        grid = critical_voltage_grid(PAPER_TUBE, n_layers, lambda_i=li, m=orders,
                                     n=modes if dense else whole)[0]
        if dense:
            curves[float(li)] = grid
            grid = grid[:, on_mode]
        grids[float(li)] = grid
    return Stability(np.asarray(map_stretches, float), along_map, grids, modes, curves)


def _grid_key(axes: dict) -> tuple:
    """The key of a grid of critical voltages (:meth:`Context.critical_voltages`)."""
    return tuple((k, tuple(np.atleast_1d(np.asarray(v, float)).tolist())) for k, v in axes.items())


@dataclasses.dataclass
class Context:
    out: Path
    res: Resolution
    n_layers: int
    progress: bool
    written: list
    solved: dict = dataclasses.field(default_factory=dict)  # key: its Future (:meth:`once`)
    lock: threading.Lock = dataclasses.field(default_factory=threading.Lock)
    pool: concurrent.futures.Executor | None = None  # :meth:`curves_of`
    since: float = dataclasses.field(default_factory=time.perf_counter)  # when the last figure was saved

    def log(self, message: str) -> None:
        if self.progress:
            print(message, flush=True)

    def once(self, key, solve):
        """``solve()``, computed once per ``key`` by whichever thread asks first; the others wait
        for that result (:func:`make_figures` solves in several threads). A solve may ask for
        other keys, never for its own (none here waits in a cycle)."""
        with self.lock:
            future = self.solved.get(key)
            mine = future is None
            if mine:
                future = self.solved[key] = concurrent.futures.Future()
        if mine:
            try:
                future.set_result(solve())
            except BaseException as error:
                future.set_exception(error)
        return future.result()

    def critical_voltages(self, **axes) -> np.ndarray:
        """:func:`critical_voltage_grid` of the paper's tube, solved once per grid: V̂_cr does not
        depend on the fluid, so the empty-tube and fluid-filled figures share it. The axisymmetric
        V̂_cr along n at the λ_i of Figs. 3, 4, 6, 7 are those of :meth:`stability`."""
        key, grids = _grid_key(axes), self._stability_grids()
        if key in grids:
            return grids[key](self.stability())
        return self.once(("critical", key),
                         lambda: critical_voltage_grid(PAPER_TUBE, self.n_layers, **axes))

    def _stability_grids(self) -> dict:
        """{grid key: Stability ↦ the axisymmetric V̂_cr of that grid} of the grids along n that
        :meth:`stability` solves."""
        axisymmetric = ORDERS.index(0)
        whole = np.arange(1.0, self.res.max_mode + 1.0)
        grids = {}
        for stretches, modes, rows in ((STRETCHES, self.res.modes(), "curves"),
                                       (STRETCHES, whole, "grids"),
                                       ((CRITICAL_STRETCH,), whole, "grids")):
            grids[_grid_key(dict(lambda_i=stretches, n=modes))] = (
                lambda stab, stretches=stretches, rows=rows: np.stack(
                    [getattr(stab, rows)[float(li)][axisymmetric] for li in stretches]))
        return grids

    def stability(self) -> Stability:
        """:func:`stability_of_paper_tube` for the stability map (λ_i over :data:`MAP_STRETCH_RANGE`)
        and the λ_i of Figs. 2–7, solved once."""
        stretches = np.round(np.linspace(*MAP_STRETCH_RANGE, self.res.map_stretches), 12)
        return self.once("stability", lambda: stability_of_paper_tube(
            self.n_layers, stretches, STRETCHES + (CRITICAL_STRETCH,), self.res.modes()))

    def curves_of(self, cases: dict, curves) -> dict:
        """{coupling: :func:`solve_curves` of the paper's tube with this laminate, filled with
        ``cases[coupling]`` (a fluid or None), along ``curves(coupling)``}, the couplings solved
        side by side in the threads of ``pool`` (tasks that wait for no other)."""
        jobs = {c: (fluid, curves(c)) for c, fluid in cases.items()}
        if self.pool is None:
            return {c: solve_curves(self.n_layers, *job) for c, job in jobs.items()}
        futures = {c: self.pool.submit(solve_curves, self.n_layers, *job) for c, job in jobs.items()}
        return {c: future.result() for c, future in futures.items()}

    def save(self, name: str, fig, table: Table) -> None:
        import matplotlib
        import matplotlib.pyplot as plt

        png, csv_path = self.out / f"{name}.png", self.out / f"{name}.csv"
        # the tight bounding box (legends outside the axes) taken from the figure as laid out,
        # padded as bbox_inches="tight" pads it: the same pixels without the extra draw pass that
        # "tight" makes first (savefig 4.8-5.2 -> 4.2 CPU s over the figures, measured)
        fig.set_dpi(SAVE_DPI)
        bbox = fig.get_tightbbox(fig.canvas.get_renderer()).padded(
            matplotlib.rcParams["savefig.pad_inches"])
        for row in table.rows:  # the setting behind every number: the paper's laminate
            row["discretisation"] = f"midpoint, N = {self.n_layers}"
        try:  # the PNG and its CSV together, or neither
            write_together([(png, lambda tmp: save_figure(fig, tmp, dpi=SAVE_DPI, bbox_inches=bbox)),
                            (csv_path, table.write)])
        finally:
            plt.close(fig)
        self.written += [png, csv_path]
        now = time.perf_counter()
        self.log(f"  wrote {png} and {csv_path.name} ({now - self.since:.1f} s)")
        self.since = now


def _fluids():
    return {c: Fluid(**PAPER_FLUID, coupling=c) for c in COUPLINGS}


def _status_name(status, past):
    if past:
        return "past critical"
    return Status(int(status)).name.lower()


def _mask_past(omega, voltage, v_cr):
    """NaN where V̂ ≥ V̂_cr (the lowest root is imaginary there)."""
    past = np.asarray(voltage) >= np.asarray(v_cr)
    return np.where(past, np.nan, omega), past


# ----------------------------------------------------------------------------- plotting helpers


def _figure(ncols=2, title=None):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, ncols, figsize=(5.2 * ncols, 4.0), squeeze=False)
    if title:
        fig.suptitle(title)
    return fig, axes[0]


def _style(coupling, lambda_i):
    """The line style of a coupling and λ_i, the same in every figure: the empty tube and the
    acoustic coupling solid-based (λ_i = 0.9 solid, 1.1 dash-dot, λ_z^{-1/2} long dashes), the
    paper's coupling dashed-based (0.9 dashed, 1.1 dash-dot-dot, λ_z^{-1/2} dotted)."""
    k = min(range(3), key=lambda i: abs((STRETCHES + (CRITICAL_STRETCH,))[i] - float(lambda_i)))
    if coupling == "paper":
        return ("--", (0, (6, 2, 1, 2, 1, 2)), (0, (1, 1.5)))[k]
    return ("-", "-.", (0, (8, 2)))[k]


def _plot(ax, x, y, jumps=None, **kw):
    """A curve that breaks where the lowest root changes branch (``jumps``): the segments are drawn
    apart and the first point after a break is marked with an open circle."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    drawn = np.isfinite(y) & np.concatenate([[False], np.isfinite(y[:-1])])  # a start after a gap is none
    breaks = np.flatnonzero(np.asarray(jumps) & drawn) if jumps is not None else np.zeros(0, int)
    y_line = y.copy()
    if breaks.size:
        x, y_line = np.insert(x, breaks, np.nan), np.insert(y_line, breaks, np.nan)
    line, = ax.plot(x, y_line, **kw)
    if breaks.size:
        ax.plot(np.asarray(x)[breaks + np.arange(breaks.size) + 1], y[breaks], "o", mfc="none",
                color=line.get_color(), ms=5, alpha=kw.get("alpha", 1.0))
    return line


def _legend_styles(ax, entries):
    """Legend entries for colours and line styles drawn apart (``entries``: (label, plot kwargs))."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], **kw) for _, kw in entries]
    ax.legend(handles, [label for label, _ in entries], fontsize=7, loc="upper center",
              bbox_to_anchor=(0.5, -0.16), ncol=3, frameon=False)


def _finish(ax, xlabel, ylabel, legend=True):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    if legend:
        _legend_below(ax)


def _legend_below(ax):
    """The legend under the axes (outside them: it never covers a curve), two columns."""
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, frameon=False)


def _first_columns(stability: Stability, lambda_i) -> dict:
    """The CSV columns of the first instability at λ_i: ``v_first``, ``m_first``, ``n_first``."""
    v, m, n = stability.first(lambda_i)
    return dict(v_first=v, m_first=m, n_first=n)


def _shade_unstable(ax, stability: Stability, stretches) -> None:
    """Shade V̂ ≥ V̂_first of each λ_i (the tube has buckled in the order m, mode n that fails first),
    labelled "(m, n) unstable"."""
    right = ax.get_xlim()[1]
    for k, li in enumerate(stretches):
        v, m, n = stability.first(li)
        if not np.isfinite(v) or v >= right:
            continue
        ax.axvspan(v, right, color="0.5", alpha=0.12, lw=0, hatch="///" if k else None)
        ax.axvline(v, color="0.3", ls=":", lw=1)
        ax.annotate(f"λi={li}: ({m}, {n}) unstable", (v, 0.5), xycoords=("data", "axes fraction"),
                    xytext=(2, 0), textcoords="offset points", rotation=90, va="center", fontsize=7,
                    color="0.2", bbox=dict(fc="white", ec="none", alpha=0.7, pad=1))
    ax.set_xlim(right=right)


def _note_unstable(ax, stability: Stability, stretches) -> None:
    """State the first instability of each λ_i under the title of the figure of ``ax`` (the curves
    at V̂ ≥ V̂_first are faded; the legends are below the axes)."""
    lines = []
    for li in stretches:
        v, m, n = stability.first(li)
        lines.append(f"λi={li:.3g}: ({m}, {n}) unstable for V̂ ≥ {v:.4f}")
    ax.figure.text(0.5, 0.935, "first instability (curves past it faded): " + ";  ".join(lines),
                   ha="center", va="top", fontsize=8, color="0.2")


# ----------------------------------------------------------------------------- Figs. 2 and 5


def _style_entries(couplings, stretches):
    """Legend entries of the line styles of :func:`_style`."""
    return [(f"λi={li:.3g}" + (f" ({c})" if c else ""), dict(color="0.3", ls=_style(c, li)))
            for c in couplings for li in stretches]


def voltage_path(v_cr: float, v_top: float, points: int):
    """(V̂, abscissa t) of a curve against V̂: V̂ = V̂_cr (1 − (1 − t)²), t = k/points (k < points),
    where Ω ∝ √(V̂_cr − V̂) falls to zero: linear in t, and the points crowd where the curve is
    steep; V̂ = v_top·t where there is no V̂_cr below the pull-in limit."""
    t = np.arange(points) / points
    if not np.isfinite(v_cr):
        return v_top * t, t
    return v_cr * (1.0 - (1.0 - t) ** 2), t


def figure_voltage(ctx: Context, fluid_filled: bool) -> None:
    """Ω and c_p against V̂ for n = 1, 2, 3 at λ_i = 0.9, 1.1 (Fig. 2 fluid-free, Fig. 5 filled):
    continuation along V̂ up to V̂_cr(n), where the curve ends at Ω = 0."""
    name = "fig5_voltage_fluid" if fluid_filled else "fig2_voltage_empty"
    ctx.log(f"[{name}] Ω and phase velocity against V̂")
    v_cr = ctx.critical_voltages(lambda_i=STRETCHES, n=MODES)
    v_top = float(np.nanmax(v_cr))
    cases = _fluids() if fluid_filled else {None: None}
    keys = [(i, j) for i in range(len(STRETCHES)) for j in range(len(MODES))]
    grids = {key: voltage_path(v_cr[key], v_top, ctx.res.voltages) for key in keys}
    by_coupling = ctx.curves_of(cases, lambda _: [
        (dict(voltage=grids[i, j][0], lambda_i=STRETCHES[i], n=MODES[j]), grids[i, j][1])
        for i, j in keys])
    stability = ctx.stability()
    fig, (ax_w, ax_c) = _figure(title=("Fluid-filled" if fluid_filled else "Fluid-free")
                                + " tube: lowest frequency of modes n = 1, 2, 3 (λ_z = 1.2)")
    table = Table(name)
    for coupling, solved in by_coupling.items():
        for (i, j), sol in zip(keys, solved, strict=True):
            li, n, voltages = STRETCHES[i], MODES[j], grids[i, j][0]
            first = _first_columns(stability, li)
            for v, w, a, st in zip(voltages, sol.omega, sol.alpha, sol.status, strict=True):
                table.add(lambda_i=li, n=n, voltage=v, coupling=coupling or "none", alpha_hat=a,
                          omega=w, phase_velocity=w / a, v_critical=v_cr[i, j],
                          status=_status_name(st, False), **first)
            ends = np.isfinite(v_cr[i, j])
            x = np.append(voltages, v_cr[i, j]) if ends else voltages
            y = np.append(sol.omega, 0.0) if ends else sol.omega
            jumps = np.append(sol.jumps, False) if ends else sol.jumps
            kw = dict(color=MODE_COLORS[n], ls=_style(coupling, li), lw=1.3)
            _plot(ax_w, x, y, jumps, **kw)
            _plot(ax_c, x, y / sol.alpha[0], jumps, **kw)
    for ax in (ax_w, ax_c):
        _shade_unstable(ax, stability, STRETCHES)
    _finish(ax_w, "voltage V̂", "frequency Ω", legend=False)
    _legend_styles(ax_w, [(f"n={n}", dict(color=MODE_COLORS[n])) for n in MODES]
                   + _style_entries(cases, STRETCHES))
    _finish(ax_c, "voltage V̂", "phase velocity ĉ_p = Ω/α̂", legend=False)
    ctx.save(name, fig, table)


# ----------------------------------------------------------------------------- Figs. 3, 4, 6, 7


def figure_modes(ctx: Context, fluid_filled: bool, critical_stretch: bool) -> None:
    """Ω and c_p against the axial mode number n (Figs. 3/6: λ_i = 0.9, 1.1 and V̂ = 0, 0.2;
    Figs. 4/7: λ_i = λ_z^{-1/2} and V̂ = 0, 0.1, 0.15, 0.2): continuation along α̂ = α̂_1 n through
    fractional n (the curve Ω(α̂) of the infinite tube), the tube's modes (integer n) marked. The
    paper's coupling is defined at integer n only (its Bessel order is ν = n): drawn there, without
    jump marks (a grid of whole modes is too coarse to tell a branch change from the root's own
    variation).
    Past V̂_cr(n) the lowest root is imaginary and the point is blank."""
    if critical_stretch:
        name = "fig7_modes_critical_fluid" if fluid_filled else "fig4_modes_critical_empty"
        stretches, voltages = (CRITICAL_STRETCH,), (0.0, 0.1, 0.15, 0.2)
    else:
        name = "fig6_modes_fluid" if fluid_filled else "fig3_modes_empty"
        stretches, voltages = STRETCHES, (0.0, 0.2)
    ctx.log(f"[{name}] Ω and phase velocity against the axial mode number")
    dense = ctx.res.modes()
    whole = np.arange(1.0, ctx.res.max_mode + 1.0)
    cases = _fluids() if fluid_filled else {None: None}
    title = ("Fluid-filled" if fluid_filled else "Fluid-free") + " tube against the mode number"
    if critical_stretch:
        title += f" at λ_i = λ_z^-1/2 ≈ {stretches[0]:.3f}"
    keys = [(i, j) for i in range(len(stretches)) for j in range(len(voltages))]
    modes_of = {c: whole if c == "paper" else dense for c in cases}
    by_coupling = ctx.curves_of(cases, lambda c: [
        (dict(voltage=voltages[j], lambda_i=stretches[i], n=modes_of[c]), modes_of[c])
        for i, j in keys])
    stability = ctx.stability()
    fig, (ax_w, ax_c) = _figure(title=title)
    table = Table(name)
    for coupling, solved in by_coupling.items():
        modes = modes_of[coupling]
        v_cr = ctx.critical_voltages(lambda_i=stretches, n=modes)
        for (i, j), sol in zip(keys, solved, strict=True):
            li, v = stretches[i], voltages[j]
            first = _first_columns(stability, li)
            omega, past = _mask_past(sol.omega, v, v_cr[i])
            for n, a, w, st, p, vc in zip(modes, sol.alpha, omega, sol.status, past, v_cr[i], strict=True):
                table.add(lambda_i=li, voltage=v, n=n, coupling=coupling or "none", alpha_hat=a,
                          omega=w, phase_velocity=w / a, v_critical=vc, status=_status_name(st, p),
                          **first)
            kw = dict(color=VOLTAGE_COLORS[v], ls=_style(coupling, li), lw=1.3,
                      alpha=0.45 if v >= first["v_first"] else 1.0)
            on_mode = np.isclose(modes, np.round(modes))
            for ax, y in ((ax_w, omega), (ax_c, omega / sol.alpha)):
                _plot(ax, modes, y, None if coupling == "paper" else sol.jumps, **kw)
                ax.plot(modes[on_mode], y[on_mode], "o", ms=2.5, color=kw["color"], alpha=kw["alpha"])
    _note_unstable(ax_c, stability, stretches)
    _finish(ax_w, "axial mode number n (α̂ = n α̂_1; dots: the tube's modes)", "frequency Ω",
            legend=False)
    _legend_styles(ax_w, [(f"V̂={v}", dict(color=VOLTAGE_COLORS[v])) for v in voltages]
                   + _style_entries(cases, stretches))
    _finish(ax_c, "axial mode number n", "phase velocity ĉ_p = Ω/α̂", legend=False)
    ctx.save(name, fig, table)
    return table


# ----------------------------------------------------------------------------- Figs. 8–10


FLUID_AXES = {
    "speed_ratio": ("fig8_speed_ratio", "fluid speed ratio ĉ_f = c_f/c_s", (0.05, 1.5), False),
    "density_ratio": ("fig9_density_ratio", "fluid density ratio ρ̂_f = ρ_f/ρ_s", (0.01, 2.0), True),
    "thickness_ratio": ("fig10_thickness_ratio", "wall thickness h/R_i", (0.05, 2.0), True),
}


FLUID_VOLTAGES = (0.0, 0.15)  # V̂ of the panels (a), (b) of Figs. 8–10


def _fluid_keys():
    """(λ_i, V̂, n) indices of the curves of Figs. 8–10."""
    return [(i, iv, j) for i in range(len(STRETCHES)) for iv in range(len(FLUID_VOLTAGES))
            for j in range(len(MODES))]


def fluid_parameter_curves(ctx: Context, axis: str):
    """(the grid of ``axis``, V̂_cr (λ_i, grid, n), {coupling: the curves of :func:`_fluid_keys`})
    of :func:`figure_fluid_parameter`, solved once."""
    def solve():
        _, _, (lo, hi), log = FLUID_AXES[axis]
        k = ctx.res.fluid_points
        grid = np.geomspace(lo, hi, k) if log else np.linspace(lo, hi, k)
        abscissa = np.log(grid) if log else grid
        geometry_axes = {"thickness_ratio": grid} if axis == "thickness_ratio" else {}
        v_cr = ctx.critical_voltages(lambda_i=STRETCHES, **geometry_axes, n=MODES)
        if not geometry_axes:  # V̂_cr does not depend on the fluid: broadcast over the fluid axis
            v_cr = np.broadcast_to(v_cr[:, None, :], (len(STRETCHES), k, len(MODES)))
        curves = ctx.curves_of(_fluids(), lambda _: [
            (dict(voltage=FLUID_VOLTAGES[iv], lambda_i=STRETCHES[i], n=MODES[j], **{axis: grid}),
             abscissa) for i, iv, j in _fluid_keys()])
        return grid, v_cr, curves

    return ctx.once(("fluid", axis), solve)


def figure_fluid_parameter(ctx: Context, axis: str) -> Table:
    """Ω of n = 1, 2, 3 against ĉ_f (Fig. 8), ρ̂_f (Fig. 9) or h/R_i (Fig. 10), (a) V̂ = 0, (b) 0.15:
    continuation along the parameter (its logarithm on a log axis)."""
    name, xlabel, _, log = FLUID_AXES[axis]
    ctx.log(f"[{name}] Ω against {axis}")
    grid, v_cr, curves = fluid_parameter_curves(ctx, axis)
    voltages = FLUID_VOLTAGES
    fig, panels = _figure(title=f"Fluid-filled tube: lowest frequency of n = 1, 2, 3 against {axis}")
    table = Table(name)
    for coupling, solved in curves.items():
        for (i, iv, j), sol in zip(_fluid_keys(), solved, strict=True):
            li, v, n = STRETCHES[i], voltages[iv], MODES[j]
            omega, past = _mask_past(sol.omega, v, v_cr[i, :, j])
            for x, a, w, st, p, vc in zip(grid, sol.alpha, omega, sol.status, past, v_cr[i, :, j],
                                          strict=True):
                table.add(voltage=v, lambda_i=li, **{axis: x}, n=n, coupling=coupling, alpha_hat=a,
                          omega=w, phase_velocity=w / a, v_critical=vc, status=_status_name(st, p))
            _plot(panels[iv], grid, omega, sol.jumps, color=MODE_COLORS[n], ls=_style(coupling, li),
                  lw=1.3)
    for iv, v in enumerate(voltages):
        panels[iv].set_title(f"({'ab'[iv]}) V̂ = {v}")
        if log:
            panels[iv].set_xscale("log")
        _finish(panels[iv], xlabel, "frequency Ω", legend=False)
    _legend_styles(panels[0], [(f"n={n}", dict(color=MODE_COLORS[n])) for n in MODES]
                   + _style_entries(COUPLINGS, STRETCHES))
    ctx.save(name, fig, table)
    return table


# ----------------------------------------------------------------------------- order m


def figure_stability_map(ctx: Context) -> None:
    """V̂_cr of the orders m = 0 … 4 (a) against λ_i at n = 1, the first instability (lower envelope,
    min over m) drawn bold, and (b) against the axial mode n at λ_i = 0.9 and 1.1.

    λ_i starts at 0.9: at λ_i = 0.875 and below the ring mode (2, 1) is unstable at V̂ = 0 already
    (:func:`jaxdea.growth_rates`), and a V̂_cr found above zero there is no loss of stability."""
    name = "stability_map"
    ctx.log(f"[{name}] critical voltages of the orders m = 0 … 4")
    stability = ctx.stability()
    fig, (ax_l, ax_n) = _figure(title="Paper's tube (η = 0.85, λ_z = 1.2, G = 97.2): critical voltage "
                                      "V̂_cr of order m")
    table = Table(name)
    envelope = np.array([lowest_critical(row[:, None])[:2] for row in stability.map_voltages])
    for li, row, (v_env, m_env) in zip(stability.map_stretches, stability.map_voltages, envelope,
                                       strict=True):
        for m, v in zip(ORDERS, row, strict=True):
            table.add(panel="lambda_i", lambda_i=li, m=m, n=1, v_critical=v, v_first=v_env,
                      m_first=int(m_env), n_first=1 if m_env >= 0 else 0)
    for k, m in enumerate(ORDERS):
        ax_l.plot(stability.map_stretches, stability.map_voltages[:, k], color=ORDER_COLORS[k], lw=1.3,
                  label=f"m = {m}")
    ax_l.plot(stability.map_stretches, envelope[:, 0], color="k", ls="--", lw=2, zorder=5,
              label="first instability (min over m)")
    ax_l.fill_between(stability.map_stretches, envelope[:, 0], np.nanmax(stability.map_voltages),
                      color="0.5", alpha=0.1, lw=0)
    ax_l.set_title("(a) axial mode n = 1 (shaded: unstable)", fontsize=9)
    _finish(ax_l, "inner stretch λ_i", "critical voltage V̂_cr", legend=False)
    _legend_below(ax_l)
    modes = stability.modes
    on_mode = np.isclose(modes, np.round(modes))
    for li in STRETCHES:
        curve = stability.curves[float(li)]
        first = _first_columns(stability, li)
        for k, m in enumerate(ORDERS):
            for n, v in zip(modes, curve[k], strict=True):
                table.add(panel="n", lambda_i=li, m=m, n=n, v_critical=v, **first)
            ax_n.plot(modes, curve[k], color=ORDER_COLORS[k], ls=_style(None, li), lw=1.3)
            ax_n.plot(modes[on_mode], curve[k][on_mode], "o", color=ORDER_COLORS[k], ms=2.5)
        ax_n.plot([first["n_first"]], [first["v_first"]], "k*", ms=10)
        ax_n.annotate(f"λi={li}: ({first['m_first']}, {first['n_first']}) first", (first["n_first"],
                      first["v_first"]), xytext=(8, -4 if li == STRETCHES[0] else 4),
                      textcoords="offset points", fontsize=7)
    ax_n.set_title("(b) against the axial mode (dots: the tube's modes; * first instability)",
                   fontsize=9)
    _finish(ax_n, "axial mode number n (α̂ = n α̂_1)", "critical voltage V̂_cr", legend=False)
    _legend_styles(ax_n, [(f"m = {m}", dict(color=ORDER_COLORS[k])) for k, m in enumerate(ORDERS)]
                   + _style_entries((None,), STRETCHES))
    ctx.save(name, fig, table)


def dispersion_grid(tube: Tube, max_mode: int, steps: int) -> np.ndarray:
    """α̂ from α̂_1 to α̂_max_mode of the tube's axial modes, ``steps`` points per spacing α̂_1 (the
    modes α̂_n among them)."""
    alpha_1 = float(mode_wavenumber(tube, 1.0))
    return alpha_1 * np.linspace(1.0, max_mode, (max_mode - 1) * steps + 1)


def order_m_curves(ctx: Context, fluid: Fluid | None, orders) -> dict:
    """{m: (Ω, status, jumps, each (K, CURVE_ROOTS))} along :func:`dispersion_grid`
    of the tube of :func:`figure_dispersion_order_m`: :func:`solve_curves` of each order
    (continuation along α̂; m traced: one compiled program for every order, the axisymmetric family
    through the order-m system at m = 0), solved once per fluid."""
    def solve():
        alphas = dispersion_grid(SHAPE_TUBE, ctx.res.max_mode, ctx.res.curve_steps)
        curves = {}
        for m in orders:
            sol, = solve_curves(ctx.n_layers, fluid, [(dict(alpha=alphas), alphas)], base=SHAPE_TUBE,
                                n_roots=CURVE_ROOTS, m=m)
            curves[m] = (sol.omega, sol.status, sol.jumps)
        return curves

    return ctx.once(("order_m", None if fluid is None else fluid.coupling, tuple(orders)), solve)


def cross_section_modes(ctx: Context) -> dict:
    """{m: (Ω, r̂ (P,), fields)} of the lowest mode of each order of :data:`SHAPE_ORDERS` at n = 1,
    α̂ = α̂_1 (:func:`jaxdea.mode_shape` at the root of :func:`order_m_curves`), solved once."""
    def solve():
        curves = order_m_curves(ctx, None, EMPTY_CURVE_ORDERS)
        alpha = float(mode_wavenumber(SHAPE_TUBE, 1.0))
        shapes = {}
        for m in SHAPE_ORDERS:
            omega = float(curves[m][0][0, 0])  # the curve's first α̂ is α̂_1
            r, fields = mode_shape(SHAPE_TUBE, alpha, omega, n_layers=ctx.n_layers, m=m)
            shapes[m] = (omega, np.asarray(r), [np.asarray(x) for x in fields])
        return shapes

    return ctx.once("shapes", solve)


def solve_beside(ctx: Context) -> None:
    """The solves of Figs. 8–10 (:func:`fluid_parameter_curves`) and of the last three figures
    (:func:`order_m_curves` of both fluids, :func:`cross_section_modes`, :func:`static_response`):
    :func:`make_figures` runs them in a thread of their own beside Figs. 2–7, as it does
    :meth:`Context.stability` (computations only; every figure is drawn in the main thread, which
    solves what it needs first itself, :meth:`Context.once`): two cores solve and compile at once."""
    order_m_curves(ctx, Fluid(**PAPER_FLUID), CURVE_ORDERS)
    cross_section_modes(ctx)
    static_response(ctx)
    for axis in FLUID_AXES:
        fluid_parameter_curves(ctx, axis)


def figure_dispersion_order_m(ctx: Context) -> None:
    """Ω(α̂) of the lowest roots of m = 0, 1, 2, empty and filled with the acoustic fluid
    (:func:`order_m_curves`; the paper's coupling exists only at m = 0 and is not drawn)."""
    name = "dispersion_order_m"
    ctx.log(f"[{name}] Ω(α̂) of the orders m = 0, 1, 2")
    alphas = dispersion_grid(SHAPE_TUBE, ctx.res.max_mode, ctx.res.curve_steps)
    alpha_1 = alphas[0]
    fig, panels = _figure(title=f"Lowest {CURVE_ROOTS} roots of order m (λ_i = {SHAPE_STRETCH}, "
                                f"V̂ = {SHAPE_VOLTAGE}, η = 0.85, λ_z = 1.2): * the tube's modes α̂_n")
    table = Table(name)
    for ax, (label, fluid) in zip(panels, (("none", None), ("acoustic", Fluid(**PAPER_FLUID))),
                                  strict=True):
        curves = order_m_curves(ctx, fluid, EMPTY_CURVE_ORDERS if fluid is None else CURVE_ORDERS)
        for m in CURVE_ORDERS:
            omega, status, jumps = curves[m]
            for i, a in enumerate(alphas):
                for b in range(CURVE_ROOTS):
                    table.add(coupling=label, lambda_i=SHAPE_STRETCH, voltage=SHAPE_VOLTAGE, m=m,
                              branch=b + 1, alpha_hat=a, n=a / alpha_1, omega=omega[i, b],
                              phase_velocity=omega[i, b] / a,
                              status=Status(int(status[i, b])).name.lower())
            for b in range(CURVE_ROOTS):
                _plot(ax, alphas, omega[:, b], jumps[:, b], color=ORDER_COLORS[m], lw=1.4 - 0.3 * b,
                      label=f"m = {m}" if b == 0 else None)
            on_mode = np.isclose(alphas / alpha_1, np.round(alphas / alpha_1))
            ax.plot(alphas[on_mode], omega[on_mode, 0], "*", color=ORDER_COLORS[m], ms=5)
        ax.set_ylim(0.0, 1.1 * max(np.nanmax(curves[m][0][:, 1]) for m in CURVE_ORDERS))
        ax.set_title("(a) empty tube" if fluid is None else
                     f"(b) filled, acoustic fluid ρ̂_f = {PAPER_FLUID['density_ratio']}, "
                     f"ĉ_f = {PAPER_FLUID['speed_ratio']}", fontsize=9)
        _finish(ax, "axial wavenumber α̂ = α R_i", "frequency Ω")
    ctx.save(name, fig, table)


def figure_cross_sections(ctx: Context) -> None:
    """Cross-sections of the lowest mode of m = 1, 2, 3 at n = 1, V̂ = 0.01: the base state's inner
    and outer circles r̂_i, r̂_o and the outlines r̂(θ) = r̂ + ε ū(r̂) cos mθ of both faces, to first
    order in ε (u_r = R_i ū cos mθ, :func:`jaxdea.mode_shape`; ε makes max |ε ū| of the faces 0.15)."""
    name = "cross_sections"
    ctx.log(f"[{name}] cross-sections of the modes m = 1, 2, 3")
    shapes = cross_section_modes(ctx)
    alpha = float(mode_wavenumber(SHAPE_TUBE, 1.0))
    theta = np.linspace(0.0, 2.0 * np.pi, ctx.res.outline_points)
    fig, panels = _figure(ncols=len(SHAPE_ORDERS),
                          title=f"Lowest modes of order m at n = 1 (α̂ = {alpha:.4f}), λ_i = "
                                f"{SHAPE_STRETCH}, V̂ = {SHAPE_VOLTAGE}: cross-section, exaggerated")
    table = Table(name)
    for ax, m in zip(panels, SHAPE_ORDERS, strict=True):
        omega, r, fields = shapes[m]
        faces, u = r[[0, -1]], fields[0][[0, -1]]
        epsilon = 0.15 / np.max(np.abs(u))
        for face, r_face, u_face, color in zip(("inner", "outer"), faces, u, ("tab:blue", "tab:red"),
                                               strict=True):
            outline = r_face + epsilon * u_face * np.cos(m * theta)
            for t, rd in zip(theta, outline, strict=True):
                table.add(m=m, n=1, lambda_i=SHAPE_STRETCH, voltage=SHAPE_VOLTAGE, alpha_hat=alpha,
                          omega=omega, face=face, radius=r_face, u_bar=u_face, epsilon=epsilon, theta=t,
                          radius_deformed=rd)
            ax.plot(r_face * np.cos(theta), r_face * np.sin(theta), color="0.6", ls="--", lw=1,
                    label="base state" if face == "inner" else None)
            ax.plot(outline * np.cos(theta), outline * np.sin(theta), color=color, lw=1.6,
                    label=f"{face} face, ε ū = {epsilon * u_face:+.3f}")
        ax.set_aspect("equal")
        ax.set_title(f"m = {m}: Ω = {omega:.4f}", fontsize=9)
        _finish(ax, "x / R_i", "y / R_i")
    ctx.save(name, fig, table)


# ----------------------------------------------------------------------------- model comparison


def figure_comparison(ctx: Context, tables: dict) -> None:
    """Where and by how much the paper's coupling differs from the consistent acoustic one:
    |Ω_paper − Ω_acoustic|/Ω_acoustic of the lowest root, against n (Fig. 6 data) and ĉ_f (Fig. 8)."""
    name = "comparison_couplings"
    ctx.log(f"[{name}] paper's coupling against the acoustic one")
    fig, panels = _figure(title="Paper's fluid coupling vs the consistent acoustic coupling (lowest root)")
    table = Table(name)
    for ax, (key, xname, xlabel) in zip(panels, (("modes", "n", "axial mode number n"),
                                                 ("speed", "speed_ratio", "fluid speed ratio ĉ_f")),
                                        strict=True):
        rows = tables[key].rows
        group = {}
        for row in rows:
            tag = (row["voltage"], row["lambda_i"]) + ((row["n"],) if xname != "n" else ())
            group.setdefault(tag, {}).setdefault(row["coupling"], []).append((row[xname], row["omega"]))
        for tag, pair in sorted(group.items()):
            paper = dict(pair["paper"])  # the paper's coupling at integer n only (ν = n)
            x = np.array([p[0] for p in pair["acoustic"] if p[0] in paper])
            w_a = np.array([p[1] for p in pair["acoustic"] if p[0] in paper])
            w_p = np.array([paper[xi] for xi in x])
            rel = np.abs(w_p - w_a) / w_a
            for xi, a, p, r in zip(x, w_a, w_p, rel, strict=True):
                table.add(panel=xname, voltage=tag[0], lambda_i=tag[1],
                          n=tag[2] if len(tag) > 2 else xi, **({xname: xi} if xname != "n" else {}),
                          omega_acoustic=a, omega_paper=p, relative_difference=r)
            voltage, li = float(tag[0]), float(tag[1])
            if len(tag) > 2:  # against ĉ_f: one colour per n, V̂ = 0.15 thin
                kw = dict(color=MODE_COLORS[int(tag[2])], lw=1.5 if voltage == 0.0 else 0.8)
            else:  # against n: one colour per V̂
                kw = dict(color=VOLTAGE_COLORS[voltage], lw=1.3, marker="o", ms=2.5)
            ax.semilogy(x, rel, ls=_style(None, li), **kw)
        _finish(ax, xlabel, "|Ω_paper − Ω_acoustic| / Ω_acoustic", legend=False)
        if xname == "n":
            voltages = sorted({float(t[0]) for t in group})
            entries = [(f"V̂={v:g}", dict(color=VOLTAGE_COLORS[v])) for v in voltages]
        else:
            entries = [(f"n={n}, V̂=0", dict(color=MODE_COLORS[n], lw=1.5)) for n in MODES]
            entries += [("V̂=0.15 (thin)", dict(color="0.3", lw=0.8))]
        _legend_styles(ax, entries + _style_entries((None,), STRETCHES))
    ctx.save(name, fig, table)


# ----------------------------------------------------------------------------- static response


def locking_stretch(tube: Tube) -> float:
    """λ_i at which I_1 − 3 reaches G at the inner face (the most stretched one): Gent locking."""
    lz, gent = float(tube.lambda_z), float(tube.gent)
    lo, hi = 1.0, 1e3
    for _ in range(200):  # bisection on λ² + 1/(λλ_z)² + λ_z² − 3 − G, increasing for λ ≥ 1
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mid**2 + 1.0 / (mid * lz) ** 2 + lz**2 - 3.0 < gent else (lo, mid)
    return lo


STATIC_PRESSURES = (-0.05, 0.0, 0.05, 0.1)  # ΔP̂ of the static response


def static_response(ctx: Context):
    """(λ_i at locking, the λ_i grid, {ΔP̂: (V̂ on the grid, (λ_i, V̂, status) of pull_in)}) of the
    paper's tube (:func:`figure_static_response`), solved once."""
    def solve():
        tube = PAPER_TUBE
        lock = locking_stretch(tube)
        stretches = np.geomspace(0.6, lock, ctx.res.static_points)
        v2 = jit(jax.vmap(lambda li, dp: _squared_voltage(tube, li, dp), (0, None)))
        curves = {}
        for dp in STATIC_PRESSURES:
            vsq = np.asarray(v2(jnp.asarray(stretches), dp))
            curves[dp] = (np.where(vsq >= 0, np.sqrt(np.abs(vsq)), np.nan),
                          tuple(float(x) for x in pull_in(tube, dp)))
        return lock, stretches, curves

    return ctx.once("static", solve)


def figure_static_response(ctx: Context) -> None:
    """V̂ against λ_i at fixed ΔP̂ (theory.md Eq. 1.1 solved for V̂²), pull-in points marked.

    The pull-in point is the first maximum of V̂(λ_i) (:func:`jaxdea.base_state.pull_in`). For the
    ideal-dielectric tube held at fixed λ_z there is none: V̂ rises monotonically at every ΔP̂ (the
    neo-Hookean closed form of theory finding 4; with Gent stiffening up to locking), so the stable
    branch ends at Gent locking, marked with its voltage (the supremum that bounds the critical
    voltage search, :func:`jaxdea.base_state.voltage_limit`). A pull-in maximum, where ``pull_in``
    finds one, is marked with a star.
    """
    name = "static_response"
    ctx.log(f"[{name}] V̂ against λ_i at fixed ΔP̂, pull-in marked")
    lock, stretches, curves = static_response(ctx)
    fig, (ax,) = _figure(ncols=1)
    table = Table(name)
    found = 0
    for c, (dp, (volt, (li_pull, v_pull, status))) in enumerate(curves.items()):
        for li, v in zip(stretches, volt, strict=True):
            table.add(delta_p=dp, lambda_i=li, voltage=v, pull_in_lambda_i=li_pull, pull_in_voltage=v_pull,
                      locking_lambda_i=lock)
        ax.plot(stretches, volt, color=COLORS[c], label=f"ΔP̂ = {dp:g}")
        if int(status) == Status.CONVERGED:
            found += 1
            ax.plot([li_pull], [v_pull], "k*", ms=11)
            ax.annotate(f"pull-in ({li_pull:.2f}, {v_pull:.3f})", (li_pull, v_pull), fontsize=7,
                        xytext=(5, -12), textcoords="offset points")
        ax.plot([stretches[-1]], [volt[-1]], "o", color=COLORS[c], mfc="none", ms=8)
    ax.axvline(lock, color="gray", ls=":", lw=1)
    ax.annotate(f"Gent locking λ_i = {lock:.2f} (o: largest stable V̂)", (lock, 0.0), fontsize=7,
                xytext=(-190, 8), textcoords="offset points")
    ax.set_title("Static response at fixed ΔP̂ (η = 0.85, λ_z = 1.2, G = 97.2): "
                 + ("pull-in marked *" if found else "no pull-in maximum, V̂ rises to locking"),
                 fontsize=9)
    ax.set_xscale("log")
    _finish(ax, "inner stretch λ_i", "voltage V̂")
    ctx.save(name, fig, table)


# ----------------------------------------------------------------------------- main job


def make_figures(out="figures", *, quick: bool = False, progress: bool = True,
                 n_layers: int = 30) -> list[Path]:
    """Regenerate every figure (module docstring) into ``out``; returns the paths written.

    Args:
        out: output folder (created).
        quick: coarse grids (a smoke run in seconds after compilation).
        progress: print a line per figure and progress bars.
        n_layers: sublayers N of the laminate (laminate error ~1e-5 relative at 30).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with (concurrent.futures.ThreadPoolExecutor(2) as leaves,
          concurrent.futures.ThreadPoolExecutor(2) as pool):
        ctx = Context(out, Resolution.pick(quick), int(n_layers), progress, [], pool=leaves)
        # the stability map's critical voltages and :func:`solve_beside`, beside Figs. 2–10
        started = [pool.submit(ctx.stability), pool.submit(solve_beside, ctx)]
        _paper_figures(ctx)
        for future in started:
            future.result()
    ctx.log(f"{len(ctx.written)} files in {out} ({time.perf_counter() - start:.0f} s)")
    return ctx.written


def _paper_figures(ctx: Context) -> None:
    """Figs. 2–10, the model comparison, the stability map and the figures of order m, the cross
    sections and the static response (the last four between Figs. 7 and 8)."""
    figure_voltage(ctx, fluid_filled=False)
    figure_modes(ctx, fluid_filled=False, critical_stretch=False)
    figure_modes(ctx, fluid_filled=False, critical_stretch=True)
    figure_voltage(ctx, fluid_filled=True)
    modes = figure_modes(ctx, fluid_filled=True, critical_stretch=False)
    figure_modes(ctx, fluid_filled=True, critical_stretch=True)
    # drawn while the threads still solve Figs. 8-10 (the paper coupling scans every point), which
    # :func:`solve_beside` leaves for last: less drawing trails the computations (warm run
    # 10.45-10.53 -> 9.5-9.8 s, measured)
    figure_cross_sections(ctx)
    figure_dispersion_order_m(ctx)
    figure_static_response(ctx)
    figure_stability_map(ctx)
    speed = figure_fluid_parameter(ctx, "speed_ratio")
    figure_fluid_parameter(ctx, "density_ratio")
    figure_fluid_parameter(ctx, "thickness_ratio")
    figure_comparison(ctx, {"modes": modes, "speed": speed})
