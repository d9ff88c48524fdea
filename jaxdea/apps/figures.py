"""The paper's figures (Figs. 2–10 of the seed paper, §5), the model comparison and the static response.

``make_figures(out)`` (the main job, ``jaxdea figures``) writes, for each figure, a PNG and the CSV
behind it. The tube is the paper's: η = 0.85, L = 10 R_o, λ_z = 1.2, Gent G = 97.2; the fluid
ρ̂_f = 0.13, ĉ_f = 0.27. Every curve is the lowest frequency of the axial mode n (α̂ = 2nπη/(10λ_z)),
solved by certified continuation along the figure's own axis (V̂, n, ĉ_f, ρ̂_f, h/R_i:
:func:`solve_curves`, the roots of :func:`jaxdea.frequencies` at every point); the critical voltages
likewise along theirs (:func:`critical_curves`). The figures against n follow α̂ = n α̂_1 through
fractional n (the infinite tube's curve) and mark the tube's modes, the integers; the paper's
coupling, whose Bessel order is ν = n, exists at integer n only and is drawn there.

Styles are the same in every figure (:mod:`jaxdea.apps.plotstyle`: mathtext, 300 dpi, one legend below
the panels): one colour per axial mode n (:data:`MODE_COLORS`), per order m (:data:`ORDER_COLORS`)
or, against n, per V̂ (:data:`VOLTAGE_COLORS`); one line style per coupling and λ_i (:func:`_style`:
the empty tube and the acoustic coupling solid-based, the paper's dashed-based). A curve breaks only
where its root changes branch (:func:`solve_curves`), the point after the break circled. Each
figure's caption (``figures/README.md``, :func:`write_index`) explains its marks.

Past the critical voltage V̂_cr(n) the lowest frequency is imaginary (the tube buckles
axisymmetrically): the curves against V̂ run from V̂ = 0 to V̂_cr(n), where they end at Ω = 0 (the
points crowd there, V̂ = V̂_cr(1 − (1 − t)²) for t uniform: Ω falls like √(V̂_cr − V̂)); elsewhere such
points are left blank (NaN, ``status`` = ``"past critical"`` in the CSV). V̂_cr is solved directly
(:func:`jaxdea.critical_voltage`'s problem), so a blank point never hides a wrong branch.

The tube loses stability earlier in a non-axisymmetric order m (docs/theory/order_m.md): for λ_i = 0.9 the
ring mode (m, n) = (2, 1) at V̂ ≈ 0.029, a tenth of the axisymmetric V̂_cr. The first instability
(the smallest V̂_cr over m ≤ 4, n ≤ max_mode, as :func:`jaxdea.first_instability`) marks the states
past it by one rule, V̂ ≥ V̂_first (:func:`jaxdea.apps.plotstyle.past_first_instability`): faded in every
figure, shaded on those against V̂ (Figs. 2, 5), and ``past_first_instability`` in every CSV. Three
figures of order m follow: the stability map (V̂_cr of m = 0 … 4 against λ_i and n),
the cross-sections of the lowest m = 1, 2, 3 modes, and the dispersion curves Ω(α̂) of m = 0, 1, 2.
The figure ``damping`` gives the quality factor Q = Re Ω/(2 Im Ω) of n = 1 against V̂ and the
attenuation |Im α̂| against frequency of the tube with a VHB-like and a silicone-like wall
(:func:`damping_sets`, :func:`damped_curves`).

Data layout of every CSV: one row per point and coupling, long format (``figure``, the swept
parameters, ``coupling``, ``alpha_hat``, ``omega``, ``phase_velocity`` = Ω/α̂, ``v_critical``,
``status``; every table with a voltage adds ``v_first``, ``m_first``, ``n_first``, the first
instability at the row's state, and ``past_first_instability``).
"""

from __future__ import annotations

import concurrent.futures
import csv
import dataclasses
import functools
import math
import threading
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import jit
from ..files import atomic_write, save_figure, write_together
from ..materials import Gent, NeoHookean
from ..numerics.scalar import Status
from ..params import Fluid, Layer, Tube, axial_wavenumber, mode_wavenumber
from ..physics.base_state import pull_in, squared_voltage
from ..physics.leaves import apply_parameters
from ..physics.state_matrix import ORDER_M
from ..solve.curves import solve_critical_path, solve_path
from ..solve.instability import first_instability
from ..solve.modes import mode_shape
from ..solve.roots import critical_voltage, frequencies
from . import plotstyle
from .plotstyle import SHORT_LABELS, line_handle, new_figure, past_first_instability, patch_handle

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
SAVE_DPI = plotstyle.SAVE_DPI  # resolution of the PNGs
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
    encapsulation_shares: int  # encapsulation shares of the wall in [0, 0.5]
    damping_points: int  # voltages of the damped roots (continuation from V̂ = 0)
    attenuation_points: int  # frequencies of the damped wavenumbers (continuation from the lowest)

    @classmethod
    def pick(cls, quick: bool) -> Resolution:
        if quick:
            return cls(voltages=8, max_mode=4, mode_steps=2, fluid_points=6, static_points=60,
                       map_stretches=5, curve_steps=2, outline_points=73, encapsulation_shares=2,
                       damping_points=4, attenuation_points=4)
        return cls(voltages=64, max_mode=15, mode_steps=5, fluid_points=40, static_points=240,
                   map_stretches=44, curve_steps=16, outline_points=361, encapsulation_shares=6,
                   damping_points=14, attenuation_points=16)

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
    (:func:`jaxdea.physics.leaves.apply_parameters`, one point per entry of the arrays)."""
    return jax.vmap(lambda vals: apply_parameters(base, 1.0, fluid, vals))(values)


def _strong(tree):
    """Every leaf a strong float64 array of PATH_POINTS values (whichever parameters vary: one
    compiled program)."""
    return jax.tree_util.tree_map(
        lambda x: jnp.asarray(np.broadcast_to(np.asarray(x, float), PATH_POINTS)), tree)


def critical_curves(n_layers: int, curves: list, base: Tube = PAPER_TUBE) -> list[np.ndarray]:
    """V̂_cr along each curve (values, abscissa) of the tube ``base`` (``values``: names of
    :mod:`jaxdea.physics.leaves` and ``m``, the circumferential order, 0 if absent), by continuation along
    the curve (:func:`jaxdea.solve.curves.critical_path_unchecked`: the first zero of f(Ω = 0; V̂) in
    (0, V̂_lim], V̂_lim the pull-in limit; NaN where none); one compiled program for every curve."""
    out = [None] * len(curves)
    for members, lengths, values, abscissa, starts in _packed(curves):
        orders = values.pop("m", np.zeros(PATH_POINTS))
        tubes, alphas, _ = _points(base, None, {k: jnp.asarray(v) for k, v in values.items()})
        voltage, *_ = solve_critical_path(*_strong((tubes, alphas)), jnp.asarray(abscissa),
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
    ``base``, by continuation along the curve (:func:`jaxdea.solve.curves.path_unchecked`; of order m
    where ``m`` is not None, the order-m family with m traced).

    A curve is (values, abscissa): ``values`` maps parameter names of :mod:`jaxdea.physics.leaves` (the same
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
            omega, status, _, restarted = solve_path(*args, decoupled=False)
        else:
            omega, status, _, restarted = solve_path(*args, jnp.float64(m), ORDER_M)
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
    captions: dict = dataclasses.field(default_factory=dict)  # {figure name: caption} (:meth:`save`)
    figures: dict = dataclasses.field(default_factory=dict)  # {figure name: the Figure} (:meth:`save`)

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

    def save(self, name: str, fig, table: Table, caption: str = "") -> None:
        """Write the figure (PNG at :data:`SAVE_DPI`, stamped with :func:`figures_stamp`) and its
        table (CSV); keep its caption for the index (:func:`write_index`)."""
        png, csv_path = self.out / f"{name}.png", self.out / f"{name}.csv"
        self.captions[name], self.figures[name] = caption, fig
        # constrained layout keeps the legends and titles inside the canvas: no tight-bbox pass
        for row in table.rows:  # the setting behind every number: the paper's laminate
            row["discretisation"] = f"midpoint, N = {self.n_layers}"
        metadata = plotstyle.png_metadata(figures_stamp())
        # the PNG and its CSV together, or neither
        write_together([(png, lambda tmp: save_figure(fig, tmp, dpi=SAVE_DPI, metadata=metadata)),
                        (csv_path, table.write)])
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


def _styled(draw):
    """Draw a figure in the style of :mod:`jaxdea.apps.plotstyle` (its rc settings, restored after)."""
    @functools.wraps(draw)
    def styled(*args, **kwargs):
        with plotstyle.style():
            return draw(*args, **kwargs)

    return styled


@functools.cache
def figures_stamp() -> str:
    """The stamp of the code that draws the figures (:func:`jaxdea.apps.plotstyle.source_stamp` of this
    module and the style module), written into every PNG."""
    import sys

    return plotstyle.source_stamp(sys.modules[__name__], plotstyle)


def _style(coupling, lambda_i):
    """The line style of a coupling and λ_i, the same in every figure: the empty tube and the
    acoustic coupling solid-based (λ_i = 0.9 solid, 1.1 dash-dot, λ_z^{-1/2} long dashes), the
    paper's coupling dashed-based (0.9 dashed, 1.1 dash-dot-dot, λ_z^{-1/2} dotted)."""
    k = min(range(3), key=lambda i: abs((STRETCHES + (CRITICAL_STRETCH,))[i] - float(lambda_i)))
    if coupling == "paper":
        return ("--", (0, (6, 2, 1, 2, 1, 2)), (0, (1, 1.5)))[k]
    return ("-", "-.", (0, (8, 2)))[k]


def _stretch_text(lambda_i) -> str:
    """λ_i in mathtext: λ_z^{-1/2} by name."""
    if abs(float(lambda_i) - CRITICAL_STRETCH) < 1e-12:
        return rf"$\lambda_i = \lambda_z^{{-1/2}} \approx {CRITICAL_STRETCH:.3f}$"
    return rf"$\lambda_i = {float(lambda_i):g}$"


def _plot(ax, x, y, jumps=None, past=None, **kw):
    """A curve that breaks where the lowest root changes branch (``jumps``): the segments are drawn
    apart and the first point after a break is marked with an open circle; its points ``past`` the
    first instability are drawn faded (:func:`jaxdea.apps.plotstyle.plot_marked`)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    past = np.zeros(x.shape, bool) if past is None else np.broadcast_to(np.asarray(past, bool), x.shape)
    drawn = np.isfinite(y) & np.concatenate([[False], np.isfinite(y[:-1])])  # a start after a gap is none
    breaks = np.flatnonzero(np.asarray(jumps) & drawn) if jumps is not None else np.zeros(0, int)
    x_line, y_line, past_line = x, y, past
    if breaks.size:
        x_line, y_line = np.insert(x, breaks, np.nan), np.insert(y, breaks, np.nan)
        past_line = np.insert(past, breaks, False)
    line = plotstyle.plot_marked(ax, x_line, y_line, past_line, **kw)
    for b in breaks:
        ax.plot([x[b]], [y[b]], "o", mfc="none", color=kw.get("color"), ms=5,
                alpha=kw.get("alpha", 1.0) * (plotstyle.PAST_ALPHA if past[b] else 1.0))
    return line


def _axes_labels(ax, xlabel, ylabel):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)


def _style_entries(couplings, stretches):
    """Legend handles of the line styles of :func:`_style`."""
    names = {None: "", "acoustic": ", acoustic", "paper": ", paper's coupling"}
    return [line_handle(_stretch_text(li) + names[c], ls=_style(c, li))
            for c in couplings for li in stretches]


def _common_handles(jumps: bool = True):
    """Legend handles of the marks every figure shares: faded curves (past the first instability)
    and the open circle of a branch change."""
    handles = [line_handle(r"faded: past the first instability ($\hat V \geq \hat V_{first}$)",
                           alpha=plotstyle.PAST_ALPHA, lw=2)]
    if jumps:
        handles.append(line_handle("first point after a branch change", ls="none", marker="o",
                                   mfc="none", ms=5))
    return handles


def _first_columns(stability: Stability, lambda_i) -> dict:
    """The CSV columns of the first instability at λ_i: ``v_first``, ``m_first``, ``n_first``."""
    v, m, n = stability.first(lambda_i)
    return dict(v_first=v, m_first=m, n_first=n)


def _first_text(v, m, n) -> str:
    return rf"$(m, n) = ({m}, {n})$ at $\hat V_{{first}} = {v:.4f}$" if np.isfinite(v) else "none found"


HATCHES = (None, "////", "\\\\\\\\")  # the regions past the first instability, one per λ_i


def _shade_unstable(ax, stability: Stability, stretches) -> list:
    """Shade V̂ ≥ V̂_first of each λ_i (the tube has buckled in the (m, n) that fails first), up to
    the axes' right end; returns their legend handles."""
    right = ax.get_xlim()[1]
    handles = []
    for k, li in enumerate(stretches):
        v, m, n = stability.first(li)
        if not np.isfinite(v) or v >= right:
            continue
        face = dict(facecolor=(0.5, 0.5, 0.5, 0.13), edgecolor=(0.35, 0.35, 0.35, 0.5), hatch=HATCHES[k],
                    lw=0)
        ax.axvspan(v, right, **face)
        ax.axvline(v, color="0.3", ls=":", lw=1)
        handles.append(patch_handle(rf"unstable at {_stretch_text(li)}: " + _first_text(v, m, n), **face))
    ax.set_xlim(right=right)
    return handles


def _first_line(stability: Stability, stretches) -> str:
    """One line naming the first instability of each λ_i."""
    return ";  ".join(f"{_stretch_text(li)}: " + _first_text(*stability.first(li)) for li in stretches)


# ----------------------------------------------------------------------------- Figs. 2 and 5


def voltage_path(v_cr: float, v_top: float, points: int):
    """(V̂, abscissa t) of a curve against V̂: V̂ = V̂_cr (1 − (1 − t)²), t = k/points (k < points),
    where Ω ∝ √(V̂_cr − V̂) falls to zero: linear in t, and the points crowd where the curve is
    steep; V̂ = v_top·t where there is no V̂_cr below the pull-in limit."""
    t = np.arange(points) / points
    if not np.isfinite(v_cr):
        return v_top * t, t
    return v_cr * (1.0 - (1.0 - t) ** 2), t


@_styled
def figure_voltage(ctx: Context, fluid_filled: bool):
    """Ω and c_p against V̂ for n = 1, 2, 3 at λ_i = 0.9, 1.1 (Fig. 2 fluid-free, Fig. 5 filled):
    continuation along V̂ up to V̂_cr(n), where the curve ends at Ω = 0. Returns (figure, axes)."""
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
    fig, (ax_w, ax_c) = new_figure(2, title=("Fluid-filled" if fluid_filled else "Fluid-free")
                                   + r" tube: lowest frequency of the axial modes $n$ = 1, 2, 3"
                                   + r" ($\lambda_z = 1.2$)")
    table = Table(name)
    fluid_branch = []  # phase velocities of the acoustic coupling's lowest (fluid) branch
    for coupling, solved in by_coupling.items():
        for (i, j), sol in zip(keys, solved, strict=True):
            li, n, voltages = STRETCHES[i], MODES[j], grids[i, j][0]
            first = _first_columns(stability, li)
            past = past_first_instability(voltages, first["v_first"])
            for v, w, a, st, p in zip(voltages, sol.omega, sol.alpha, sol.status, past, strict=True):
                table.add(lambda_i=li, n=n, voltage=v, coupling=coupling or "none", alpha_hat=a,
                          omega=w, phase_velocity=w / a, v_critical=v_cr[i, j],
                          status=_status_name(st, False), **first, past_first_instability=bool(p))
            ends = np.isfinite(v_cr[i, j])
            x = np.append(voltages, v_cr[i, j]) if ends else voltages
            y = np.append(sol.omega, 0.0) if ends else sol.omega
            jumps = np.append(sol.jumps, False) if ends else sol.jumps
            kw = dict(color=MODE_COLORS[n], ls=_style(coupling, li),
                      past=past_first_instability(x, first["v_first"]))
            _plot(ax_w, x, y, jumps, **kw)
            _plot(ax_c, x, y / sol.alpha[0], jumps, **kw)
            if coupling == "acoustic":
                fluid_branch.append(sol.omega / sol.alpha[0])
    _note_fluid_branch(ax_c, fluid_branch)
    shades = []
    for ax in (ax_w, ax_c):
        ax.set_xlim(0.0, ax.get_xlim()[1])
        ax.set_ylim(bottom=0.0)
        shades = _shade_unstable(ax, stability, STRETCHES)
    _axes_labels(ax_w, SHORT_LABELS["voltage"], SHORT_LABELS["omega"])
    _axes_labels(ax_c, SHORT_LABELS["voltage"], SHORT_LABELS["phase_velocity"])
    ax_w.set_title("(a) frequency")
    ax_c.set_title("(b) phase velocity")
    plotstyle.legend_below(fig, [line_handle(f"$n = {n}$", color=MODE_COLORS[n]) for n in MODES]
                           + _style_entries(cases, STRETCHES) + shades + _common_handles(), ncol=3)
    caption = (f"{'Fluid-filled' if fluid_filled else 'Fluid-free'} tube (the paper's Fig. "
               f"{5 if fluid_filled else 2}): the lowest frequency Ω (a) and phase velocity Ω/α̂ (b) "
               "of the axial modes n = 1, 2, 3 (colours) against the voltage V̂, at λ_i = 0.9 and 1.1 "
               "(line styles"
               + ("; solid-based: the consistent acoustic coupling, dashed-based: the paper's coupling"
                  if fluid_filled else "") + "). Each curve ends at Ω = 0 at the critical voltage "
               "V̂_cr(n) of the axisymmetric mode. The shaded regions (plain for λ_i = 0.9, hatched for "
               "1.1) lie past the tube's first instability, the smallest critical voltage over the "
               "orders m ≤ 4 and modes n searched (" + _plain_first(stability, STRETCHES) + "); the "
               "curves are faded there. An open circle marks the first point after a branch change."
               + (" The acoustic coupling's lowest root is the fluid (Korteweg) branch: its phase velocity "
                  "lies just below ĉ_f for every n and λ_i, so its six curves coincide in (b) (the box "
                  "gives their range)." if fluid_filled else ""))
    ctx.save(name, fig, table, caption)
    return fig, (ax_w, ax_c)


def _note_fluid_branch(ax, curves, side: str = "left") -> None:
    """Say where the acoustic coupling's phase velocities lie: its lowest root is the fluid
    (Korteweg) branch, just below ĉ_f for every n, λ_i and V̂, so those curves coincide. The note
    sits just above them, at the ``side`` of the axes that the other curves leave free."""
    if not curves:
        return
    speeds = np.concatenate(curves)
    speeds = speeds[np.isfinite(speeds) & (speeds > 0.5 * PAPER_FLUID["speed_ratio"])]
    typical, high = np.median(speeds), np.max(speeds)
    ax.annotate(rf"acoustic coupling: its {len(curves)} curves coincide near $\hat c_p$ = {typical:.3f}"
                "\n" rf"(the fluid branch, just below $\hat c_f$ = {PAPER_FLUID['speed_ratio']})",
                (0.03 if side == "left" else 0.97, high), xycoords=("axes fraction", "data"),
                xytext=(0, 12), textcoords="offset points", ha=side, va="bottom", fontsize=7.5,
                bbox=dict(fc="white", ec="0.6", lw=0.5, pad=2))


def _plain_first(stability: Stability, stretches) -> str:
    """The first instability of each λ_i in plain text (captions)."""
    parts = []
    for li in stretches:
        v, m, n = stability.first(li)
        parts.append(f"λ_i = {float(li):.3g}: (m, n) = ({m}, {n}) at V̂_first = {v:.4f}")
    return "; ".join(parts)


# ----------------------------------------------------------------------------- Figs. 3, 4, 6, 7


@_styled
def figure_modes(ctx: Context, fluid_filled: bool, critical_stretch: bool):
    """Ω and c_p against the axial mode number n (Figs. 3/6: λ_i = 0.9, 1.1 and V̂ = 0, 0.2;
    Figs. 4/7: λ_i = λ_z^{-1/2} and V̂ = 0, 0.1, 0.15, 0.2): continuation along α̂ = α̂_1 n through
    fractional n (the curve Ω(α̂) of the infinite tube), the tube's modes (integer n) marked. The
    paper's coupling is defined at integer n only (its Bessel order is ν = n): drawn there, without
    jump marks (a grid of whole modes is too coarse to tell a branch change from the root's own
    variation).
    Past V̂_cr(n) the lowest root is imaginary and the point is blank. Returns the table (the
    rows of the CSV); the figure is ``ctx.figures[name]``."""
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
    title = ("Fluid-filled" if fluid_filled else "Fluid-free") + " tube against the axial mode number"
    if critical_stretch:
        title += " at " + _stretch_text(stretches[0])
    keys = [(i, j) for i in range(len(stretches)) for j in range(len(voltages))]
    modes_of = {c: whole if c == "paper" else dense for c in cases}
    by_coupling = ctx.curves_of(cases, lambda c: [
        (dict(voltage=voltages[j], lambda_i=stretches[i], n=modes_of[c]), modes_of[c])
        for i, j in keys])
    stability = ctx.stability()
    fig, (ax_w, ax_c) = new_figure(2, height=3.8, title=title + "\nfirst instability: "
                                   + _first_line(stability, stretches))
    table = Table(name)
    fluid_branch = []  # phase velocities of the acoustic coupling's lowest (fluid) branch
    for coupling, solved in by_coupling.items():
        modes = modes_of[coupling]
        v_cr = ctx.critical_voltages(lambda_i=stretches, n=modes)
        for (i, j), sol in zip(keys, solved, strict=True):
            li, v = stretches[i], voltages[j]
            first = _first_columns(stability, li)
            unstable = bool(past_first_instability(v, first["v_first"]))
            omega, past = _mask_past(sol.omega, v, v_cr[i])
            for n, a, w, st, p, vc in zip(modes, sol.alpha, omega, sol.status, past, v_cr[i], strict=True):
                table.add(lambda_i=li, voltage=v, n=n, coupling=coupling or "none", alpha_hat=a,
                          omega=w, phase_velocity=w / a, v_critical=vc, status=_status_name(st, p),
                          **first, past_first_instability=unstable)
            kw = dict(color=VOLTAGE_COLORS[v], ls=_style(coupling, li), past=unstable)
            on_mode = np.isclose(modes, np.round(modes))
            for ax, y in ((ax_w, omega), (ax_c, omega / sol.alpha)):
                _plot(ax, modes, y, None if coupling == "paper" else sol.jumps, **kw)
                ax.plot(modes[on_mode], y[on_mode], "o", ms=2.5, color=kw["color"],
                        alpha=plotstyle.PAST_ALPHA if unstable else 1.0)
            if coupling == "acoustic":
                fluid_branch.append(omega / sol.alpha)
    _note_fluid_branch(ax_c, fluid_branch, side="right")
    for ax in (ax_w, ax_c):
        ax.set_ylim(bottom=0.0)
    _axes_labels(ax_w, SHORT_LABELS["n"], SHORT_LABELS["omega"])
    _axes_labels(ax_c, SHORT_LABELS["n"], SHORT_LABELS["phase_velocity"])
    ax_w.set_title("(a) frequency (dots: the tube's modes, whole $n$)")
    ax_c.set_title("(b) phase velocity")
    plotstyle.legend_below(fig, [line_handle(rf"$\hat V = {v:g}$", color=VOLTAGE_COLORS[v]) for v in voltages]
                           + _style_entries(cases, stretches)
                           + _common_handles(jumps=True), ncol=3)
    figure_number = {"fig3": 3, "fig4": 4, "fig6": 6, "fig7": 7}[name[:4]]
    caption = (f"{'Fluid-filled' if fluid_filled else 'Fluid-free'} tube (the paper's Fig. {figure_number}):"
               " the lowest frequency Ω (a) and phase velocity Ω/α̂ (b) against the axial mode number n,"
               f" at V̂ = {', '.join(f'{v:g}' for v in voltages)} (colours) and "
               + ("λ_i = λ_z^(-1/2) ≈ 0.913, the homogeneous state" if critical_stretch
                  else "λ_i = 0.9, 1.1 (line styles)")
               + ". The curves follow α̂ = n α̂_1 through fractional n (the infinite tube); dots mark "
               "the tube's own modes, whole n. Blank points: past the critical voltage of that mode "
               "(its lowest frequency is imaginary). Faded curves: states past the tube's first "
               "instability (" + _plain_first(stability, stretches) + ")."
               + (" The paper's coupling (dashed-based) exists at whole n only. The acoustic "
                  "coupling's lowest root is the fluid (Korteweg) branch: its phase velocity lies just "
                  "below ĉ_f for every case, so those curves coincide in (b)." if fluid_filled else ""))
    ctx.save(name, fig, table, caption)
    return table


# ----------------------------------------------------------------------------- Figs. 8–10


FLUID_AXES = {
    "speed_ratio": ("fig8_speed_ratio", plotstyle.LABELS["speed_ratio"], (0.05, 1.5), False),
    "density_ratio": ("fig9_density_ratio", plotstyle.LABELS["density_ratio"], (0.01, 2.0), True),
    "thickness_ratio": ("fig10_thickness_ratio", plotstyle.LABELS["thickness_ratio"], (0.05, 2.0), True),
}
FLUID_WORDS = {"speed_ratio": "the fluid's sound speed ratio ĉ_f",
               "density_ratio": "the fluid's density ratio ρ̂_f", "thickness_ratio": "the wall thickness h/R_i"}


FLUID_VOLTAGES = (0.0, 0.15)  # V̂ of the panels (a), (b) of Figs. 8–10


def _fluid_keys():
    """(λ_i, V̂, n) indices of the curves of Figs. 8–10."""
    return [(i, iv, j) for i in range(len(STRETCHES)) for iv in range(len(FLUID_VOLTAGES))
            for j in range(len(MODES))]


def fluid_parameter_curves(ctx: Context, axis: str):
    """(the grid of ``axis``, V̂_cr (λ_i, grid, n), first instability (V̂, m, n) (λ_i, grid),
    {coupling: the curves of :func:`_fluid_keys`}) of :func:`figure_fluid_parameter`, solved once.

    The first instability does not depend on the fluid: that of :meth:`Context.stability` at every
    point of Figs. 8 and 9; along h/R_i (Fig. 10) the smallest V̂_cr over m ≤ 4 and the modes drawn,
    n ≤ 3, at each thickness."""
    def solve():
        _, _, (lo, hi), log = FLUID_AXES[axis]
        k = ctx.res.fluid_points
        grid = np.geomspace(lo, hi, k) if log else np.linspace(lo, hi, k)
        abscissa = np.log(grid) if log else grid
        geometry_axes = {"thickness_ratio": grid} if axis == "thickness_ratio" else {}
        v_cr = ctx.critical_voltages(lambda_i=STRETCHES, **geometry_axes, n=MODES)
        if geometry_axes:
            orders = ctx.critical_voltages(lambda_i=STRETCHES, **geometry_axes, m=ORDERS, n=MODES)
            first = np.array([[lowest_critical(orders[i, x]) for x in range(k)]
                              for i in range(len(STRETCHES))])
        else:  # V̂_cr does not depend on the fluid: broadcast over the fluid axis
            v_cr = np.broadcast_to(v_cr[:, None, :], (len(STRETCHES), k, len(MODES)))
            stability = ctx.stability()
            first = np.array([[stability.first(li)] * k for li in STRETCHES])
        curves = ctx.curves_of(_fluids(), lambda _: [
            (dict(voltage=FLUID_VOLTAGES[iv], lambda_i=STRETCHES[i], n=MODES[j], **{axis: grid}),
             abscissa) for i, iv, j in _fluid_keys()])
        return grid, v_cr, first, curves

    return ctx.once(("fluid", axis), solve)


@_styled
def figure_fluid_parameter(ctx: Context, axis: str) -> Table:
    """Ω of n = 1, 2, 3 against ĉ_f (Fig. 8), ρ̂_f (Fig. 9) or h/R_i (Fig. 10), (a) V̂ = 0, (b) 0.15:
    continuation along the parameter (its logarithm on a log axis). Returns the table."""
    name, xlabel, _, log = FLUID_AXES[axis]
    ctx.log(f"[{name}] Ω against {axis}")
    grid, v_cr, first, curves = fluid_parameter_curves(ctx, axis)
    voltages = FLUID_VOLTAGES
    fig, panels = new_figure(2, sharex=True, title=r"Fluid-filled tube: lowest frequency of $n$ = 1, 2, 3 "
                             "against " + FLUID_WORDS[axis].replace("ĉ_f", r"$\hat c_f$")
                             .replace("ρ̂_f", r"$\hat\rho_f$").replace("h/R_i", "$h/R_i$"))
    table = Table(name)
    for coupling, solved in curves.items():
        for (i, iv, j), sol in zip(_fluid_keys(), solved, strict=True):
            li, v, n = STRETCHES[i], voltages[iv], MODES[j]
            omega, past = _mask_past(sol.omega, v, v_cr[i, :, j])
            unstable = past_first_instability(v, first[i, :, 0])
            for x, a, w, st, p, vc, (vf, mf, nf), u in zip(grid, sol.alpha, omega, sol.status, past,
                                                           v_cr[i, :, j], first[i], unstable, strict=True):
                table.add(voltage=v, lambda_i=li, **{axis: x}, n=n, coupling=coupling, alpha_hat=a,
                          omega=w, phase_velocity=w / a, v_critical=vc, status=_status_name(st, p),
                          v_first=vf, m_first=int(mf), n_first=int(nf), past_first_instability=bool(u))
            _plot(panels[iv], grid, omega, sol.jumps, past=unstable, color=MODE_COLORS[n],
                  ls=_style(coupling, li))
    for iv, v in enumerate(voltages):
        all_past = bool(np.all(past_first_instability(v, first[:, :, 0])))
        panels[iv].set_title(rf"({'ab'[iv]}) $\hat V = {v:g}$"
                             + (": every state past the first instability" if all_past else ""))
        if log:
            panels[iv].set_xscale("log")
            plotstyle.plain_log(panels[iv].xaxis)
        panels[iv].set_ylim(bottom=0.0)
        _axes_labels(panels[iv], xlabel, SHORT_LABELS["omega"])
    panels[0].set_xlim(grid[0], grid[-1])
    plotstyle.legend_below(fig, [line_handle(f"$n = {n}$", color=MODE_COLORS[n]) for n in MODES]
                           + _style_entries(COUPLINGS, STRETCHES) + _common_handles(), ncol=3)
    search = "m ≤ 4, n ≤ 3 at each thickness" if axis == "thickness_ratio" else "m ≤ 4 and the modes n searched"
    caption = (f"Fluid-filled tube (the paper's Fig. {name[3:name.index('_')]}): the lowest frequency Ω of "
               f"the axial modes n = 1, 2, 3 (colours) against {FLUID_WORDS[axis]}, at (a) V̂ = 0 and "
               "(b) V̂ = 0.15, for λ_i = 0.9, 1.1 and both fluid couplings (line styles: solid-based the "
               "consistent acoustic coupling, dashed-based the paper's). Both panels share the x axis. "
               "Blank points: past the critical voltage of that mode. Faded curves: states past the "
               f"tube's first instability (smallest critical voltage over {search}; CSV columns v_first, "
               "m_first, n_first, past_first_instability). An open circle marks the first point after a "
               "branch change.")
    ctx.save(name, fig, table, caption)
    return table


# ----------------------------------------------------------------------------- order m


def _envelope_orders(stretches, orders) -> str:
    """Which m the lower envelope follows, as runs of λ_i (legend)."""
    runs = []
    for li, m in zip(stretches, orders, strict=True):
        if m < 0:
            continue
        if runs and runs[-1][0] == m:
            runs[-1][2] = li
        else:
            runs.append([m, li, li])
    if len(runs) == 1:
        return f"$m = {runs[0][0]}$ throughout"
    return ", ".join(rf"$m = {m}$ ($\lambda_i$ {a:.2f}–{b:.2f})" for m, a, b in runs)


@_styled
def figure_stability_map(ctx: Context):
    """V̂_cr of the orders m = 0 … 4 (a) against λ_i at n = 1, the first instability (lower envelope,
    min over m) drawn bold, and (b) against the axial mode n at λ_i = 0.9 and 1.1. Returns
    (figure, axes).

    λ_i starts at 0.9: at λ_i = 0.875 and below the ring mode (2, 1) is unstable at V̂ = 0 already
    (:func:`jaxdea.growth_rates`), and a V̂_cr found above zero there is no loss of stability."""
    name = "stability_map"
    ctx.log(f"[{name}] critical voltages of the orders m = 0 … 4")
    stability = ctx.stability()
    fig, (ax_l, ax_n) = new_figure(2, title=r"Critical voltage $\hat V_{cr}$ of the orders $m$ = 0 … 4 "
                                   r"(the paper's tube: $\eta = 0.85$, $\lambda_z = 1.2$, $G = 97.2$)")
    table = Table(name)
    envelope = np.array([lowest_critical(row[:, None])[:2] for row in stability.map_voltages])
    for li, row, (v_env, m_env) in zip(stability.map_stretches, stability.map_voltages, envelope,
                                       strict=True):
        for m, v in zip(ORDERS, row, strict=True):
            table.add(panel="lambda_i", lambda_i=li, m=m, n=1, v_critical=v, v_first=v_env,
                      m_first=int(m_env), n_first=1 if m_env >= 0 else 0)
    for k in range(len(ORDERS)):
        ax_l.plot(stability.map_stretches, stability.map_voltages[:, k], color=ORDER_COLORS[k])
    top = 1.05 * float(np.nanmax(stability.map_voltages))
    ax_l.plot(stability.map_stretches, envelope[:, 0], color="k", ls="--", lw=2.2, zorder=5)
    ax_l.fill_between(stability.map_stretches, envelope[:, 0], 2.0 * top, color="0.5", alpha=0.13, lw=0)
    ax_l.set_ylim(0.0, top)
    ax_l.set_xlim(stability.map_stretches[0], stability.map_stretches[-1])
    ax_l.set_title("(a) axial mode $n = 1$, against the inner stretch")
    _axes_labels(ax_l, plotstyle.LABELS["lambda_i"], SHORT_LABELS["v_critical"])
    modes = stability.modes
    on_mode = np.isclose(modes, np.round(modes))
    stars = []
    for li in STRETCHES:
        curve = stability.curves[float(li)]
        first = _first_columns(stability, li)
        for k, m in enumerate(ORDERS):
            for n, v in zip(modes, curve[k], strict=True):
                table.add(panel="n", lambda_i=li, m=m, n=n, v_critical=v, **first)
            ax_n.plot(modes, curve[k], color=ORDER_COLORS[k], ls=_style(None, li))
            ax_n.plot(modes[on_mode], curve[k][on_mode], "o", color=ORDER_COLORS[k], ms=2.5)
        marker = "*" if li == STRETCHES[0] else "P"
        ax_n.plot([first["n_first"]], [first["v_first"]], marker, color="k", ms=10, mfc="gold", zorder=6)
        stars.append(line_handle(f"first instability at {_stretch_text(li)}: "
                                 + _first_text(first["v_first"], first["m_first"], first["n_first"]),
                                 ls="none", marker=marker, ms=9, mfc="gold", color="k"))
    ax_n.set_ylim(bottom=0.0)
    ax_n.set_title("(b) against the axial mode (dots: the tube's modes)")
    _axes_labels(ax_n, SHORT_LABELS["n"], SHORT_LABELS["v_critical"])
    handles = [line_handle(f"$m = {m}$", color=ORDER_COLORS[k]) for k, m in enumerate(ORDERS)]
    handles += [line_handle("(a) first instability, min over $m$: "
                            + _envelope_orders(stability.map_stretches, envelope[:, 1].astype(int)),
                            color="k", ls="--", lw=2.2),
                patch_handle("(a) unstable: above the first instability", facecolor="0.5", alpha=0.13)]
    handles += _style_entries((None,), STRETCHES) + stars
    plotstyle.legend_below(fig, handles, ncol=2)
    caption = ("Critical voltages V̂_cr of the circumferential orders m = 0 … 4 of the paper's tube: (a) "
               "against the inner stretch λ_i for the axial mode n = 1, the lower envelope (black, dashed)"
               " being the first instability and the shaded region above it unstable; (b) against the "
               "axial mode number n at λ_i = 0.9 (solid) and 1.1 (dash-dot), dots on the tube's modes, "
               "the marked points the first instability of each λ_i (" + _plain_first(stability, STRETCHES)
               + "). The map starts at λ_i = 0.9: below about 0.88 the ring mode (m, n) = (2, 1) is "
               "unstable already at V̂ = 0.")
    ctx.save(name, fig, table, caption)
    return fig, (ax_l, ax_n)


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


@_styled
def figure_dispersion_order_m(ctx: Context):
    """Ω(α̂) of the lowest roots of m = 0, 1, 2, empty and filled with the acoustic fluid
    (:func:`order_m_curves`; the paper's coupling exists only at m = 0 and is not drawn). Returns
    (figure, axes)."""
    name = "dispersion_order_m"
    ctx.log(f"[{name}] Ω(α̂) of the orders m = 0, 1, 2")
    alphas = dispersion_grid(SHAPE_TUBE, ctx.res.max_mode, ctx.res.curve_steps)
    alpha_1 = alphas[0]
    fig, panels = new_figure(2, title=rf"Lowest {CURVE_ROOTS} roots of the orders $m$ = 0, 1, 2 "
                             rf"($\lambda_i = {SHAPE_STRETCH}$, $\hat V = {SHAPE_VOLTAGE}$, $\eta = 0.85$, "
                             r"$\lambda_z = 1.2$)")
    table = Table(name)
    v_first, m_first, n_first = ctx.stability().first(SHAPE_STRETCH)
    stable = not past_first_instability(SHAPE_VOLTAGE, v_first)
    clipped = []
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
                              status=Status(int(status[i, b])).name.lower(), v_first=v_first,
                              m_first=m_first, n_first=n_first, past_first_instability=not stable)
            for b in range(CURVE_ROOTS):
                _plot(ax, alphas, omega[:, b], jumps[:, b], past=not stable, color=ORDER_COLORS[m],
                      lw=2.0 if b == 0 else 0.9)
            on_mode = np.isclose(alphas / alpha_1, np.round(alphas / alpha_1))
            ax.plot(alphas[on_mode], omega[on_mode, 0], "*", color=ORDER_COLORS[m], ms=6)
        second = max(np.nanmax(curves[m][0][:, 1]) for m in CURVE_ORDERS)
        highest = max(np.nanmax(curves[m][0]) for m in CURVE_ORDERS)
        top = 1.05 * min(highest, 1.1 * second)  # the third roots (a thickness branch) would squeeze the rest
        ax.set_ylim(0.0, top)
        ax.set_xlim(alphas[0], alphas[-1])
        note = ""
        if highest > top:
            clipped.append(label)
            note = f" (third roots clipped above $\\Omega$ = {top:.2f})"
        ax.set_title(("(a) empty tube" if fluid is None else
                      rf"(b) filled, acoustic fluid $\hat\rho_f = {PAPER_FLUID['density_ratio']}$, "
                      rf"$\hat c_f = {PAPER_FLUID['speed_ratio']}$") + note)
        _axes_labels(ax, plotstyle.LABELS["alpha"], SHORT_LABELS["omega"])
    handles = [line_handle(f"$m = {m}$", color=ORDER_COLORS[m]) for m in CURVE_ORDERS]
    handles += [line_handle("thick: the lowest root of each $m$", lw=2.0),
                line_handle("thin: the second and third roots", lw=0.9),
                line_handle(r"the tube's axial modes $\hat\alpha_n$ (lowest root)", ls="none",
                            marker="*", ms=7),
                line_handle("first point after a branch change", ls="none", marker="o", mfc="none", ms=5)]
    plotstyle.legend_below(fig, handles, ncol=3)
    caption = (f"Dispersion curves Ω(α̂) of the circumferential orders m = 0, 1, 2 (colours): the lowest "
               f"root of each order thick, the second and third thin, at λ_i = {SHAPE_STRETCH}, "
               f"V̂ = {SHAPE_VOLTAGE} (a stable state: the first instability is (m, n) = ({m_first}, "
               f"{n_first}) at V̂_first = {v_first:.4f}); (a) empty, (b) filled with the acoustic fluid. "
               "Stars mark the tube's axial modes α̂_n on the lowest root. "
               + ("The third roots of " + " and ".join(clipped) + " leave the axes at the top (noted in "
                  "the panel); the CSV holds them. " if clipped else "")
               + "The paper's coupling exists at m = 0 only and is not drawn.")
    ctx.save(name, fig, table, caption)
    return fig, panels


@_styled
def figure_cross_sections(ctx: Context):
    """Cross-sections of the lowest mode of m = 1, 2, 3 at n = 1, V̂ = 0.01: the base state's inner
    and outer circles r̂_i, r̂_o and the outlines r̂(θ) = r̂ + ε ū(r̂) cos mθ of both faces, to first
    order in ε (u_r = R_i ū cos mθ, :func:`jaxdea.mode_shape`; ε makes max |ε ū| of the faces 0.15).
    Returns (figure, axes)."""
    name = "cross_sections"
    ctx.log(f"[{name}] cross-sections of the modes m = 1, 2, 3")
    shapes = cross_section_modes(ctx)
    alpha = float(mode_wavenumber(SHAPE_TUBE, 1.0))
    theta = np.linspace(0.0, 2.0 * np.pi, ctx.res.outline_points)
    fig, panels = new_figure(len(SHAPE_ORDERS), width=9.0, height=3.4,
                             title=rf"Lowest modes of order $m$ at $n = 1$ ($\hat\alpha = {alpha:.4f}$), "
                             rf"$\lambda_i = {SHAPE_STRETCH}$, $\hat V = {SHAPE_VOLTAGE}$: cross-sections, "
                             "displacement exaggerated")
    table = Table(name)
    v_first, m_first, n_first = ctx.stability().first(SHAPE_STRETCH)
    first = dict(v_first=v_first, m_first=m_first, n_first=n_first,
                 past_first_instability=bool(past_first_instability(SHAPE_VOLTAGE, v_first)))
    reach = 1.1 * max(float(shapes[m][1][-1]) * 1.0 + 0.15 for m in SHAPE_ORDERS)  # r̂_o + max |ε ū|
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
                          radius_deformed=rd, **first)
            ax.plot(r_face * np.cos(theta), r_face * np.sin(theta), color="0.6", ls="--", lw=1)
            ax.plot(outline * np.cos(theta), outline * np.sin(theta), color=color, lw=1.6)
        ax.set_aspect("equal")
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-reach, reach)
        ax.set_title(rf"$m = {m}$: $\Omega = {omega:.4f}$")
        _axes_labels(ax, r"$x/R_i$", r"$y/R_i$" if m == SHAPE_ORDERS[0] else "")
    plotstyle.legend_below(fig, [line_handle("base state (undisturbed faces)", color="0.6", ls="--", lw=1),
                                 line_handle(r"inner face $\hat r_i + \varepsilon\bar u_i\cos m\theta$",
                                             color="tab:blue", lw=1.6),
                                 line_handle(r"outer face $\hat r_o + \varepsilon\bar u_o\cos m\theta$",
                                             color="tab:red", lw=1.6)], ncol=3)
    caption = (f"Cross-sections of the lowest modes of the orders m = 1 (bending), 2 (ovalisation) and 3 "
               f"at the axial mode n = 1, λ_i = {SHAPE_STRETCH}, V̂ = {SHAPE_VOLTAGE} (a stable state): "
               "the undisturbed inner and outer faces (grey, dashed) and the faces displaced by the mode, "
               "r̂ + ε ū cos mθ, with ε scaled so that the larger face displacement is 0.15 R_i "
               "(first order in ε; jaxdea.mode_shape).")
    ctx.save(name, fig, table, caption)
    return fig, panels


# ----------------------------------------------------------------------------- model comparison


@_styled
def figure_comparison(ctx: Context, tables: dict):
    """Where and by how much the paper's coupling differs from the consistent acoustic one:
    |Ω_paper − Ω_acoustic|/Ω_acoustic of the lowest root, against n (Fig. 6 data) and ĉ_f (Fig. 8).
    Returns (figure, axes)."""
    name = "comparison_couplings"
    ctx.log(f"[{name}] paper's coupling against the acoustic one")
    fig, panels = new_figure(2, title="The paper's fluid coupling against the consistent acoustic "
                             "coupling (lowest root)")
    table = Table(name)
    stability = ctx.stability()
    for ax, (key, xname, xlabel) in zip(panels, (("modes", "n", SHORT_LABELS["n"]),
                                                 ("speed", "speed_ratio", plotstyle.LABELS["speed_ratio"])),
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
            voltage, li = float(tag[0]), float(tag[1])
            first = _first_columns(stability, li)
            unstable = bool(past_first_instability(voltage, first["v_first"]))
            for xi, a, p, r in zip(x, w_a, w_p, rel, strict=True):
                table.add(panel=xname, voltage=tag[0], lambda_i=tag[1],
                          n=tag[2] if len(tag) > 2 else xi, **({xname: xi} if xname != "n" else {}),
                          omega_acoustic=a, omega_paper=p, relative_difference=r, **first,
                          past_first_instability=unstable)
            if len(tag) > 2:  # against ĉ_f: one colour per n, V̂ = 0.15 thin
                kw = dict(color=MODE_COLORS[int(tag[2])], lw=1.5 if voltage == 0.0 else 0.8)
            else:  # against n: one colour per V̂
                kw = dict(color=VOLTAGE_COLORS[voltage], marker="o", ms=2.5)
            plotstyle.plot_marked(ax, x, rel, unstable, ls=_style(None, li), **kw)
        ax.set_yscale("log")
        plotstyle.plain_log(ax.yaxis)
        _axes_labels(ax, xlabel, r"$|\Omega_{paper} - \Omega_{acoustic}|\,/\,\Omega_{acoustic}$")
        ax.set_title("(a) against the axial mode (Fig. 6 data)" if xname == "n"
                     else r"(b) against $\hat c_f$ (Fig. 8 data)")
    voltages = sorted({float(r["voltage"]) for r in tables["modes"].rows})
    handles = [line_handle(rf"(a) $\hat V = {v:g}$", color=VOLTAGE_COLORS[v], marker="o", ms=2.5)
               for v in voltages]
    handles += [line_handle(rf"(b) $n = {n}$, $\hat V = 0$", color=MODE_COLORS[n], lw=1.5) for n in MODES]
    handles += [line_handle(r"(b) thin: $\hat V = 0.15$", lw=0.8)]
    handles += _style_entries((None,), STRETCHES) + _common_handles(jumps=False)
    plotstyle.legend_below(fig, handles, ncol=3)
    caption = ("Relative difference |Ω_paper − Ω_acoustic|/Ω_acoustic between the lowest roots of the "
               "paper's fluid coupling and of the consistent acoustic coupling, (a) against the axial mode"
               " number n (whole n: the paper's coupling exists there only) at the voltages of Fig. 6, (b) "
               "against ĉ_f for n = 1, 2, 3 at V̂ = 0 (thick) and 0.15 (thin); line styles: λ_i = 0.9 "
               "solid, 1.1 dash-dot. Faded: states past the tube's first instability ("
               + _plain_first(stability, STRETCHES) + "): every curve at V̂ = 0.15 and 0.2.")
    ctx.save(name, fig, table, caption)
    return fig, panels


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
        v2 = jit(jax.vmap(lambda li, dp: squared_voltage(tube, li, dp), (0, None)))
        curves = {}
        for dp in STATIC_PRESSURES:
            vsq = np.asarray(v2(jnp.asarray(stretches), dp))
            curves[dp] = (np.where(vsq >= 0, np.sqrt(np.abs(vsq)), np.nan),
                          tuple(float(x) for x in pull_in(tube, dp)))
        return lock, stretches, curves

    return ctx.once("static", solve)


def static_stability(stretches, voltage, map_stretches, v_first) -> tuple[float, float]:
    """(λ_i, V̂) where a static curve V̂(λ_i) first reaches the first instability V̂_first(λ_i) of the
    stability map (linear interpolation of both between grid points, within the map's λ_i range):
    the largest stable V̂ along the curve; (NaN, NaN) where it does not reach it there, or where the
    curve enters the map's range past it (its stable part lies outside the map)."""
    inside = (stretches >= map_stretches[0]) & (stretches <= map_stretches[-1]) & np.isfinite(voltage)
    x, v = stretches[inside], voltage[inside]
    if x.size == 0:
        return math.nan, math.nan
    gap = v - np.interp(x, map_stretches, v_first)
    reached = np.flatnonzero(gap >= 0.0)
    if reached.size == 0:
        return math.nan, math.nan
    k = int(reached[0])
    if k == 0:  # already past it where the curve enters the map: unknown unless it starts there
        return (float(x[0]), float(v[0])) if stretches[np.isfinite(voltage)][0] >= map_stretches[0] else \
            (math.nan, math.nan)
    t = gap[k - 1] / (gap[k - 1] - gap[k])
    return float(x[k - 1] + t * (x[k] - x[k - 1])), float(v[k - 1] + t * (v[k] - v[k - 1]))


@_styled
def figure_static_response(ctx: Context):
    """V̂ against λ_i at fixed ΔP̂ (docs/theory/axisymmetric.md Eq. 1.1 solved for V̂²), pull-in points
    marked, with the first instability of the stability map (n = 1, m ≤ 4). Returns (figure, axes).

    The pull-in point is the first maximum of V̂(λ_i) (:func:`jaxdea.physics.base_state.pull_in`). For the
    ideal-dielectric tube held at fixed λ_z there is none: V̂ rises monotonically at every ΔP̂ (the
    neo-Hookean closed form of theory finding 4; with Gent stiffening up to locking), so the static
    branch ends at Gent locking, marked with its voltage (the supremum that bounds the critical
    voltage search, :func:`jaxdea.physics.base_state.voltage_limit`). A pull-in maximum, where ``pull_in``
    finds one, is marked with a star. The tube loses stability long before: the largest stable V̂ of
    each curve is where it meets the first instability V̂_first(λ_i) (:func:`static_stability`).
    """
    name = "static_response"
    ctx.log(f"[{name}] V̂ against λ_i at fixed ΔP̂, pull-in marked")
    lock, stretches, curves = static_response(ctx)
    stability = ctx.stability()
    envelope = np.array([lowest_critical(row[:, None])[0] for row in stability.map_voltages])
    fig, (ax,) = new_figure(1, width=6.4, height=4.2,
                            title=r"Static response at fixed $\Delta\hat P$ ($\eta = 0.85$, "
                            r"$\lambda_z = 1.2$, $G = 97.2$)")
    table = Table(name)
    found, limits = 0, {}
    for c, (dp, (volt, (li_pull, v_pull, status))) in enumerate(curves.items()):
        li_stable, v_stable = static_stability(stretches, volt, stability.map_stretches, envelope)
        limits[dp] = (li_stable, v_stable)
        first = np.interp(stretches, stability.map_stretches, envelope, left=np.nan, right=np.nan)
        past = past_first_instability(volt, first)  # the rule; unknown (not marked) outside the map
        for li, v, vf, p in zip(stretches, volt, first, past, strict=True):
            table.add(delta_p=dp, lambda_i=li, voltage=v, pull_in_lambda_i=li_pull, pull_in_voltage=v_pull,
                      locking_lambda_i=lock, v_first=vf, past_first_instability=bool(p),
                      largest_stable_lambda_i=li_stable, largest_stable_voltage=v_stable)
        plotstyle.plot_marked(ax, stretches, volt, past, color=COLORS[c])
        if int(status) == Status.CONVERGED:
            found += 1
            ax.plot([li_pull], [v_pull], "k*", ms=11)
        if np.isfinite(li_stable):
            ax.plot([li_stable], [v_stable], "o", color=COLORS[c], mfc="white", ms=7, mew=1.5, zorder=6)
        ax.plot([stretches[-1]], [volt[-1]], "s", color=COLORS[c], mfc="none", ms=7)
    ax.plot(stability.map_stretches, envelope, color="k", ls="--", lw=1.8)
    ax.fill_between(stability.map_stretches, envelope, 10.0, color="0.5", alpha=0.13, lw=0)
    ax.axvline(lock, color="gray", ls=":", lw=1)
    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullLocator

    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(0.01, 3.0)
    ax.set_xlim(stretches[0], 1.15 * lock)
    for axis, ticks in ((ax.xaxis, (0.6, 0.8, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0)),
                        (ax.yaxis, (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0))):
        axis.set_major_locator(FixedLocator(ticks))
        axis.set_major_formatter(FormatStrFormatter("%g"))
        axis.set_minor_locator(NullLocator())
    _axes_labels(ax, plotstyle.LABELS["lambda_i"], SHORT_LABELS["voltage"])
    handles = [line_handle(rf"$\Delta\hat P = {dp:g}$", color=COLORS[c]) for c, dp in enumerate(curves)]
    handles += [line_handle(r"first instability $\hat V_{first}(\lambda_i)$ ($n = 1$, $m \leq 4$; "
                            "shaded above: unstable)", color="k", ls="--", lw=1.8),
                line_handle("largest stable $\\hat V$ of a curve (where it meets the dashed line)", ls="none",
                            marker="o", mfc="white", ms=7),
                line_handle(rf"Gent locking, $\lambda_i = {lock:.2f}$ (dotted): the static supremum "
                            r"of $\hat V$", ls="none", marker="s", mfc="none", ms=7)]
    if found:
        handles.append(line_handle("pull-in (a maximum of $\\hat V$)", ls="none", marker="*", ms=9,
                                   color="k"))
    plotstyle.legend_below(fig, handles, ncol=2)
    stable = "; ".join(f"ΔP̂ = {dp:g}: V̂ = {v:.4f} at λ_i = {li:.3f}" if np.isfinite(v) else
                       f"ΔP̂ = {dp:g}: not reached for λ_i ≤ {stability.map_stretches[-1]:g}"
                       for dp, (li, v) in limits.items())
    caption = ("Static response of the paper's tube: the voltage V̂ that holds the inner stretch λ_i at "
               "fixed pressure difference ΔP̂ (both axes logarithmic). "
               + ("Pull-in maxima are starred. " if found else
                  "No curve has a pull-in maximum: at fixed λ_z, V̂ rises to Gent locking "
                  f"(λ_i = {lock:.2f}, squares), its static supremum. ")
               + "The dashed line is the tube's first instability V̂_first(λ_i) over m ≤ 4 at n = 1 (the "
               f"stability map, λ_i from {stability.map_stretches[0]:g} to {stability.map_stretches[-1]:g}"
               "), the shaded region above it unstable: a curve is faded where it lies there, and the voltage "
               "at which it first meets the line, its largest stable voltage, is circled (" + stable
               + "). Outside that λ_i range the first instability was not computed and nothing is marked.")
    ctx.save(name, fig, table, caption)
    return fig, (ax,)


ENCAPSULATION_STRETCH = 0.9
"""λ_i of the encapsulation study: the paper's subcritical tube, which ovalises first ((m, n) = (2, 1)
at V̂ = 0.029)."""
ENCAPSULATION_STIFFNESS = (0.3, 1.0, 3.0, 10.0)
"""Shear moduli of the encapsulation over the DE's."""
ENCAPSULATION_M_MAX, ENCAPSULATION_N_MAX = 4, 2
"""The orders and axial modes searched for the first instability (over m ≤ 8, n ≤ 3 on this grid it
is (2, 1) or (3, 1) everywhere, measured)."""


def encapsulated_tube(share: float, stiffness: float, lambda_i: float = ENCAPSULATION_STRETCH) -> Tube:
    """The paper's tube (DE wall η = 0.85, L = 10 R_o) inside a neo-Hookean encapsulation of
    ``share`` of the new wall and ``stiffness`` × the DE's shear modulus, bonded outside, stretched
    with it (same λ_i, λ_z) and of the same length, so the axial modes keep their α̂. ``share`` 0:
    the bare tube."""
    bare = PAPER_TUBE.replace(lambda_i=lambda_i)
    if share == 0.0:
        return bare
    eta = 1.0 / (1.0 + (1.0 / bare.eta - 1.0) / (1.0 - share))
    layers = (Layer(1.0 - share, Gent(bare.gent), active=True),
              Layer(share, NeoHookean(), shear_ratio=stiffness))
    return Tube(lambda_i=lambda_i, lambda_z=bare.lambda_z, eta=eta,
                length_ratio=bare.length_ratio * eta / bare.eta, layers=layers)


@_styled
def figure_encapsulation(ctx: Context):
    """The first instability V̂_first over (m ≤ 4, n ≤ 2) and the two lowest frequencies of the
    n = 1 mode at V̂ = 0 of the paper's tube (λ_i = 0.9) inside a passive encapsulation of 0–50 % of
    the wall and 0.3–10× the DE's stiffness (:func:`encapsulated_tube`; issue "real walls").
    Returns (figure, axes)."""
    name = "encapsulation"
    ctx.log(f"[{name}] an encapsulation: first instability and lowest frequencies")
    shares = np.linspace(0.0, 0.5, ctx.res.encapsulation_shares)
    alpha = float(axial_wavenumber(PAPER_TUBE.replace(lambda_i=ENCAPSULATION_STRETCH), 1))
    fig, (left, right) = new_figure(2, title=r"The paper's tube in an encapsulation ($\lambda_i = 0.9$, "
                                    r"$\lambda_z = 1.2$, DE wall $\eta = 0.85$)")
    table = Table(name)
    summary = {}

    def solve(share, stiffness):
        tube = encapsulated_tube(float(share), stiffness)
        inst = first_instability(tube, n_max=ENCAPSULATION_N_MAX, m_max=ENCAPSULATION_M_MAX,
                                 n_layers=ctx.n_layers)
        return tube, inst, np.asarray(frequencies(tube, alpha, n_roots=2, n_layers=ctx.n_layers))

    for c, stiffness in enumerate(ENCAPSULATION_STIFFNESS):
        first, lowest = [], []
        for share in shares:  # in turn: two threads on two cores were slower (36 s against 23 s)
            tube, inst, omega = solve(share, stiffness)
            first.append(float(inst.voltage))
            lowest.append(omega)
            table.add(encapsulation_share=share, stiffness_ratio=stiffness, eta=tube.eta,
                      v_first=float(inst.voltage), m_first=int(inst.m), n_first=int(inst.n),
                      alpha_hat=alpha, omega_1=omega[0], omega_2=omega[1])
            summary[(float(share), stiffness)] = (float(inst.voltage), int(inst.m), int(inst.n))
        lowest = np.array(lowest)
        label = rf"$\mu_{{enc}}/\mu = {stiffness:g}$"
        left.plot(shares * 100, first, "o-", color=COLORS[c], label=label)
        right.plot(shares * 100, lowest[:, 0], "o-", color=COLORS[c], lw=2.0)
        right.plot(shares * 100, lowest[:, 1], "o--", color=COLORS[c], lw=0.9)
    left.set_title(r"(a) first instability $\hat V_{first}$ over $m \leq 4$, $n \leq 2$")
    right.set_title(r"(b) lowest two roots of $n = 1$ at $\hat V = 0$ ($m = 0$)")
    _axes_labels(left, "encapsulation share of the wall (%)", SHORT_LABELS["voltage"])
    _axes_labels(right, "encapsulation share of the wall (%)", SHORT_LABELS["omega"])
    handles = [line_handle(rf"encapsulation $\mu_{{enc}}/\mu = {s:g}$", color=COLORS[c])
               for c, s in enumerate(ENCAPSULATION_STIFFNESS)]
    handles += [line_handle("lowest root", lw=2.0), line_handle("second root", ls="--", lw=0.9)]
    plotstyle.legend_below(fig, handles, ncol=3)
    bare = summary[(0.0, ENCAPSULATION_STIFFNESS[0])]
    top = max(summary.items(), key=lambda kv: kv[1][0])
    orders = sorted({(m, n) for (_, _), (_, m, n) in summary.items()})
    caption = ("The paper's tube (λ_i = 0.9, λ_z = 1.2, DE wall η = 0.85, Gent G = 97.2) bonded inside a "
               "neo-Hookean encapsulation that takes 0–50 % of the new wall, with 0.3–10× the DE's shear "
               "modulus, stretched with it and of the same length. (a) The first instability over m ≤ 4, "
               "n ≤ 2 (m ≤ 8, n ≤ 3 gives the same modes and the same largest value, measured): the "
               f"bare tube ovalises, (m, n) = ({bare[1]}, {bare[2]}), at V̂ = {bare[0]:.4f}; the "
               f"largest V̂_first here is {top[1][0]:.4f}, (m, n) = ({top[1][1]}, {top[1][2]}), at "
               f"{100 * top[0][0]:.0f} % and {top[0][1]:g}×. The first unstable (m, n) over the grid: "
               + ", ".join(f"({m}, {n})" for m, n in orders) + ". (b) The two lowest axisymmetric "
               "frequencies of the n = 1 mode at V̂ = 0. Layered walls: docs/howto/real_tubes.md.")
    ctx.save(name, fig, table, caption)
    return fig, (left, right)


SURROUNDING_SCALES = dict(shear_modulus=20e3, density=960.0)
"""The VHB-like wall of :mod:`jaxdea.units`' worked example (μ = 20 kPa, ρ_s = 960 kg/m³, c_s = 4.56 m/s):
the scales of the fluids' ratios in :func:`figure_surrounding_fluid`."""
SURROUNDING_STRETCH = 1.1
"""λ_i of the surrounding-fluid study: the paper's overcritical tube."""


def surrounding_cases() -> dict:
    """(fluid, outer) by label: the paper's tube in vacuum, in air, in water, filled with water, and
    filled with and surrounded by water (acoustic couplings; SI presets of :mod:`jaxdea.units` on
    :data:`SURROUNDING_SCALES`)."""
    from ..physics.units import AIR, VACUUM_PERMITTIVITY, WATER, Scales, fluid_from_si

    scales = Scales(permittivity=4.7 * VACUUM_PERMITTIVITY, inner_radius=5e-3, **SURROUNDING_SCALES)
    air, water = (fluid_from_si(scales, preset) for preset in (AIR, WATER))
    return {"in vacuum": (None, None), "in air": (None, air), "in water": (None, water),
            "filled with water": (water, None), "filled with and in water": (water, water)}


def _surrounding_style(case: int) -> dict:
    """The tube in vacuum black and dashed, on top (air lies on it within 0.03 %), the others in
    :data:`COLORS`."""
    if case == 0:
        return dict(color="k", ls="--", lw=1.4, zorder=5)
    return dict(color=COLORS[case], ls="-")


@_styled
def figure_surrounding_fluid(ctx: Context):
    """The lowest axisymmetric frequency of the paper's tube (λ_i = 1.1) in vacuum, in air, in water
    and filled with water (:func:`surrounding_cases`): (a) against the axial mode n at V̂ = 0,
    (b) of n = 1 against V̂ up to 0.9 V̂_cr(n = 1, m = 0), faded past the first instability (an
    inviscid fluid leaves the critical voltages unchanged: Ω = 0). Returns (figure, axes)."""
    name = "surrounding_fluid"
    ctx.log(f"[{name}] the tube in air, in water, filled with water")
    base = PAPER_TUBE.replace(lambda_i=SURROUNDING_STRETCH)
    modes = np.arange(1, ctx.res.max_mode + 1)
    alpha_1 = float(axial_wavenumber(base, 1))
    v_cr = float(critical_voltage(base, alpha_1, n_layers=ctx.n_layers))
    voltages = np.linspace(0.0, 0.9 * v_cr, ctx.res.voltages // 4 + 2)
    first = first_instability(base, n_max=2, m_max=4, n_layers=ctx.n_layers)
    v_first = float(first.voltage)
    fig, (left, right) = new_figure(2, title=r"The paper's tube in a surrounding fluid ($\lambda_i = 1.1$, "
                                    r"$\lambda_z = 1.2$, $\eta = 0.85$; VHB-like wall, $c_s = 4.56$ m/s)")
    table = Table(name)
    lowest_n1 = {}
    for c, (label, (fluid, outer)) in enumerate(surrounding_cases().items()):
        def lowest(tube, alpha, fluid=fluid, outer=outer):
            return float(frequencies(tube, alpha, fluid, n_roots=1, n_layers=ctx.n_layers,
                                     outer=outer)[0])

        by_mode = [lowest(base, float(axial_wavenumber(base, int(n)))) for n in modes]
        by_voltage = [lowest(base.replace(voltage=float(v)), alpha_1) for v in voltages]
        lowest_n1[label] = by_mode[0]
        for n, omega in zip(modes, by_mode, strict=True):
            table.add(case=label, n=int(n), voltage=0.0, alpha_hat=float(axial_wavenumber(base, int(n))),
                      omega=omega, v_first=v_first, past_first_instability=False)
        for v, omega in zip(voltages, by_voltage, strict=True):
            table.add(case=label, n=1, voltage=float(v), alpha_hat=alpha_1, omega=omega,
                      v_first=v_first, past_first_instability=bool(v >= v_first))
        style = _surrounding_style(c)
        left.plot(modes, by_mode, marker="o", ms=4, **style)
        plotstyle.plot_marked(right, voltages, by_voltage, voltages >= v_first, **style)
    right.axvline(v_first, color="gray", ls=":", lw=1)
    left.set_yscale("log")
    left.set_title(r"(a) lowest root against the axial mode $n$ ($\hat V = 0$, $m = 0$)")
    right.set_title(r"(b) lowest root of $n = 1$ against $\hat V$")
    _axes_labels(left, SHORT_LABELS["n"], SHORT_LABELS["omega"])
    _axes_labels(right, SHORT_LABELS["voltage"], SHORT_LABELS["omega"])
    handles = [line_handle(label, **_surrounding_style(c)) for c, label in enumerate(surrounding_cases())]
    handles.append(line_handle(rf"first instability $\hat V_{{first}} = {v_first:.4f}$ "
                               rf"($m = {int(first.m)}$, $n = {int(first.n)}$; dotted)", color="gray",
                               ls=":"))
    plotstyle.legend_below(fig, handles, ncol=3)
    vacuum = lowest_n1["in vacuum"]
    shifts = ", ".join(f"{label} {omega:.4f} ({100 * (omega / vacuum - 1):+.2f} %)"
                       for label, omega in lowest_n1.items() if label != "in vacuum")
    caption = ("The paper's tube (λ_i = 1.1, λ_z = 1.2, η = 0.85, Gent G = 97.2) with a VHB-like wall "
               "(μ = 20 kPa, ρ_s = 960 kg/m³: c_s = 4.56 m/s) in vacuum, in air and in water (an unbounded "
               "acoustic fluid outside, docs/theory/real_tubes.md §6), filled with water, and both: "
               "water's sound speed is 325 c_s, so every mode here is subsonic and the water adds mass. "
               f"Lowest root of n = 1 at V̂ = 0: in vacuum {vacuum:.4f}; {shifts}. (a) Against n at "
               "V̂ = 0. (b) Of n = 1 against V̂, to 0.9 V̂_cr(n = 1, m = 0), faded past the first "
               "instability over m ≤ 4, n ≤ 2, which an inviscid fluid leaves where it is (Ω = 0).")
    ctx.save(name, fig, table, caption)
    return fig, (left, right)


# ----------------------------------------------------------------------------- damping


DAMPING_STRETCH = 1.1
"""λ_i of the damping figure: the paper's overcritical tube (as the surrounding-fluid study)."""
DAMPING_RADIUS = 5e-3
"""R_i in m of the damping figure's two walls (the size of :func:`surrounding_cases`)."""
VHB_PRONY_KPA = ((26.0, 27.0, 11.0), 15.0)
"""VHB 4910's three Maxwell branches and its equilibrium shear modulus in kPa (Hossain, Vu and
Steinmann, Comput. Mater. Sci. 59 (2012) 65–74: 26.06, 26.53, 10.83 against 15.36 kPa)."""
VHB_TIMES_S = (0.6, 6.0, 60.0)
"""The branches' relaxation times in s: assumed, a decade apart, of the order published for VHB 4910
(0.1–100 s, quasi-static relaxation tests)."""
ECOFLEX_FRACTIONAL = dict(time_s=330e-6, order=0.32, modulus=1.0)
"""Ecoflex 00-30 as a fractional Kelvin–Voigt solid, μ*(ω) = μ(1 + (iωτ)^n): τ = 330 µs and n = 0.32
(issue 45); the springpot's modulus g = 1 (equal to μ at ωτ = 1) is our choice."""
DAMPING_SI = {"VHB 4910 (Prony)": (15e3, 960.0, 4.7), "Ecoflex 00-30 (fractional KV)": (23e3, 1070.0, 2.8)}
"""(μ in Pa, ρ_s in kg/m³, relative permittivity) of the two walls: VHB's equilibrium modulus, Ecoflex's
small-strain shear modulus (assumed)."""
DAMPING_COLORS = ("tab:red", "tab:blue")


def damping_sets() -> dict:
    """{label: (Scales, damping law)} of the damping figure: a VHB-like wall (:class:`jaxdea.Prony`
    of :data:`VHB_PRONY_KPA`, :data:`VHB_TIMES_S`) and a silicone-like one
    (:class:`jaxdea.FractionalKelvinVoigt` of :data:`ECOFLEX_FRACTIONAL`), times in units of R_i/c_s
    of each wall's :class:`jaxdea.units.Scales` (R_i = :data:`DAMPING_RADIUS`)."""
    from ..materials import FractionalKelvinVoigt, Prony
    from ..physics.units import VACUUM_PERMITTIVITY, Scales

    out = {}
    for label, (mu, rho, eps) in DAMPING_SI.items():
        scales = Scales(mu, rho, eps * VACUUM_PERMITTIVITY, DAMPING_RADIUS)
        unit = float(scales.time_scale)
        if label.startswith("VHB"):
            branches, equilibrium = VHB_PRONY_KPA
            law = Prony(moduli=tuple(g / equilibrium for g in branches),
                        times=tuple(t / unit for t in VHB_TIMES_S))
        else:
            law = FractionalKelvinVoigt(modulus=ECOFLEX_FRACTIONAL["modulus"],
                                        time=ECOFLEX_FRACTIONAL["time_s"] / unit,
                                        order=ECOFLEX_FRACTIONAL["order"])
        out[label] = (scales, law)
    return out


@functools.partial(jit, static_argnames=("n_layers",))
def _damped_root(tube: Tube, alpha, guess, n_layers: int):
    """(Ω, status): :func:`jaxdea.solve_complex_frequency` from ``guess``, compiled once per law."""
    from ..solve.complex_frequencies import solve_complex_frequency

    return solve_complex_frequency(tube, alpha, guess, n_layers=n_layers)


@functools.partial(jit, static_argnames=("problem", "n_layers"))
def _damped_wavenumber(problem, tube: Tube, omega, guess, n_layers: int):
    """(α̂, converged): complex Newton on F(α̂; Ω) from ``guess`` (the Newton of
    :func:`jaxdea.wavenumbers`, :func:`jaxdea.solve.wavenumbers.complex_newton`)."""
    from ..physics.characteristic import Unknown
    from ..physics.transfer import discretize
    from ..solve.wavenumbers import complex_newton

    return complex_newton(problem, discretize(tube, n_layers), omega, None, jnp.asarray(0.0), guess,
                          Unknown.ALPHA)


def _continued(solve, first, xs):
    """The roots along ``xs`` from the root ``first`` at xs[0]: Newton (``solve(x, guess)`` →
    (root, ok)) from the linear extrapolation of the last two roots (the last root at the second
    point); (roots, ok)."""
    roots, ok = [complex(first)], [True]
    for k in range(1, len(xs)):
        guess = roots[-1] if k == 1 else roots[-1] + (roots[-1] - roots[-2]) * (
            (xs[k] - xs[k - 1]) / (xs[k - 1] - xs[k - 2]))
        root, good = solve(float(xs[k]), complex(guess))
        roots.append(complex(root))
        ok.append(bool(good))
    return np.array(roots), np.array(ok)


def damped_curves(ctx: Context) -> dict:
    """{label: dict(voltages, omega, elastic, ok, frequencies, alpha, alpha_ok, v_cr)} of the damping
    figure, solved once: the lowest complex root Ω of n = 1 against V̂ in [0, 0.9 V̂_cr(n = 1)]
    (:func:`jaxdea.complex_frequencies` at V̂ = 0, then :func:`jaxdea.solve_complex_frequency`
    continued in V̂) and the least attenuated wavenumber α̂ of the lowest branch at V̂ = 0 against
    real Ω from 0.25 to 4 × Re Ω(n = 1) (:func:`jaxdea.wavenumbers` at the lowest Ω, then Newton in
    α̂ continued in Ω)."""
    from ..physics.problem import NO_ALPHA, describe
    from ..solve.complex_frequencies import complex_frequencies
    from ..solve.wavenumbers import wavenumbers

    def solve():
        base = PAPER_TUBE.replace(lambda_i=DAMPING_STRETCH)
        alpha = float(axial_wavenumber(base, 1))
        v_cr = float(critical_voltage(base, alpha, n_layers=ctx.n_layers))
        voltages = np.linspace(0.0, 0.9 * v_cr, ctx.res.damping_points)
        elastic = np.array([float(frequencies(base.replace(voltage=float(v)), alpha, n_roots=1,
                                              n_layers=ctx.n_layers)[0]) for v in voltages])
        out = {}
        for label, (_, law) in damping_sets().items():
            tube = base.replace(damping=law)
            first = complex(complex_frequencies(tube, alpha, n_roots=1, n_layers=ctx.n_layers).omega[0])

            def at_voltage(v, guess, tube=tube):
                root, status = _damped_root(tube.replace(voltage=v), alpha, guess, ctx.n_layers)
                return root, int(status) == Status.CONVERGED

            omega, ok = _continued(at_voltage, first, voltages)
            freqs = first.real * np.geomspace(0.25, 4.0, ctx.res.attenuation_points)
            problem = describe(tube, NO_ALPHA, None, ctx.n_layers, damped=True)
            start = complex(wavenumbers(tube, float(freqs[0]), n_roots=1, n_layers=ctx.n_layers).alpha[0])

            def at_frequency(w, guess, tube=tube, problem=problem):
                root, good = _damped_wavenumber(problem, tube, w, guess, ctx.n_layers)
                return root, bool(good)

            alphas, alpha_ok = _continued(at_frequency, start, freqs)
            out[label] = dict(voltages=voltages, omega=omega, elastic=elastic, ok=ok, frequencies=freqs,
                              alpha=alphas, alpha_ok=alpha_ok, v_cr=v_cr, alpha_1=alpha)
        return out

    return ctx.once("damping", solve)


@_styled
def figure_damping(ctx: Context):
    """The quality factor Q = Re Ω/(2 Im Ω) of the lowest root of n = 1 against V̂, and the attenuation
    |Im α̂| (dB/m) of the lowest branch against frequency, of the paper's tube (λ_i = 1.1) with a
    VHB-like and a silicone-like wall (:func:`damping_sets`, :func:`damped_curves`). Returns (figure,
    axes)."""
    name = "damping"
    ctx.log(f"[{name}] quality factor and attenuation of a VHB-like and a silicone-like wall")
    curves = damped_curves(ctx)
    sets = damping_sets()
    first = _first_columns(ctx.stability(), DAMPING_STRETCH)
    fig, (left, right) = new_figure(2, title=r"Damping of the paper's tube ($\lambda_i = 1.1$, "
                                    r"$\lambda_z = 1.2$, $\eta = 0.85$, $R_i = 5$ mm)")
    table = Table(name)
    summary = {}
    for c, (label, d) in enumerate(curves.items()):
        scales, _ = sets[label]
        color = DAMPING_COLORS[c]
        q = np.real(d["omega"]) / (2.0 * np.imag(d["omega"]))
        past = past_first_instability(d["voltages"], first["v_first"])
        for v, w, we, qk, ok, p in zip(d["voltages"], d["omega"], d["elastic"], q, d["ok"], past,
                                       strict=True):
            table.add(panel="quality_factor", material=label, voltage=v, n=1, alpha_hat=d["alpha_1"],
                      omega_real=w.real, omega_imag=w.imag, quality_factor=qk, omega_elastic=we,
                      frequency_hz=float(scales.omega_to_hz(w.real)), attenuation=math.nan,
                      attenuation_db_per_m=math.nan, v_critical=d["v_cr"], **first,
                      past_first_instability=bool(p), status="converged" if ok else "max_iter")
        hz = np.asarray(scales.omega_to_hz(d["frequencies"]))
        attenuation = np.abs(np.imag(d["alpha"]))
        db = np.asarray(scales.attenuation_to_db_per_m(attenuation))
        for w, f, a, att, dbm, ok in zip(d["frequencies"], hz, d["alpha"], attenuation, db, d["alpha_ok"],
                                         strict=True):
            table.add(panel="attenuation", material=label, voltage=0.0, n=math.nan, alpha_real=a.real,
                      alpha_imag=a.imag, omega_real=w, omega_imag=0.0, frequency_hz=f,
                      attenuation=att, attenuation_db_per_m=dbm, **first, past_first_instability=False,
                      status="converged" if ok else "max_iter")
        summary[label] = (q[0], d["omega"][0], float(scales.omega_to_hz(d["omega"][0].real)))
        plotstyle.plot_marked(left, d["voltages"], q, past, color=color, marker="o", ms=3)
        right.plot(hz, db, "o-", color=color, ms=3)
    left.axvline(first["v_first"], color="gray", ls=":", lw=1)
    for ax in (left, right):
        ax.set_yscale("log")
    right.set_xscale("log")
    radius = DAMPING_RADIUS
    right.secondary_yaxis("right", functions=(lambda y: y / (20 * math.log10(math.e)) * radius,
                                              lambda y: y * (20 * math.log10(math.e)) / radius)
                          ).set_ylabel(r"$|\mathrm{Im}\,\hat\alpha|$ (per $R_i$)")
    left.set_title(r"(a) quality factor $Q$ of the lowest root of $n = 1$")
    right.set_title(r"(b) attenuation of the lowest branch ($\hat V = 0$, $m = 0$)")
    _axes_labels(left, SHORT_LABELS["voltage"], r"$Q = \mathrm{Re}\,\Omega\,/\,(2\,\mathrm{Im}\,\Omega)$")
    _axes_labels(right, "frequency (Hz)", "attenuation (dB/m)")
    handles = [line_handle(label, color=DAMPING_COLORS[c], marker="o", ms=3)
               for c, label in enumerate(curves)]
    handles.append(line_handle(rf"first instability $\hat V_{{first}} = {first['v_first']:.4f}$ "
                               rf"($m = {first['m_first']}$, $n = {first['n_first']}$; dotted)",
                               color="gray", ls=":"))
    plotstyle.legend_below(fig, handles, ncol=3)
    at_rest = "; ".join(f"{label}: Ω = {w.real:.4f} + {w.imag:.2e}i ({hz:.1f} Hz), Q = {q:.3g}"
                        for label, (q, w, hz) in summary.items())
    caption = ("The paper's tube (λ_i = 1.1, λ_z = 1.2, η = 0.85, Gent G = 97.2, R_i = 5 mm) with two "
               "damped walls (docs/theory/real_tubes.md §4; time factor e^{iΩt}). VHB-like: μ = 15 kPa, "
               "ρ_s = 960 kg/m³, Prony branches 26, 27 and 11 kPa (Hossain, Vu and Steinmann 2012) with "
               "relaxation times 0.6, 6 and 60 s (assumed, of the published order); at these frequencies "
               "ωτ ≫ 1, so the branches stiffen the wall (Ω about 2.2× the elastic one) and lose little. "
               "Silicone-like: Ecoflex 00-30, μ = 23 kPa, ρ_s = 1070 kg/m³, fractional Kelvin–Voigt "
               "μ(1 + (iωτ)^n) with τ = 330 µs, n = 0.32 (the springpot's modulus equal to μ: our choice). "
               f"At V̂ = 0, n = 1: {at_rest}. (a) Q = Re Ω/(2 Im Ω) of the lowest root of n = 1 "
               "(α̂ = 0.445) against V̂ to 0.9 V̂_cr(n = 1, m = 0) (complex_frequencies at V̂ = 0, then "
               "solve_complex_frequency continued in V̂), faded past the first instability "
               "(η*(0) = 0: damping leaves the critical voltages where they are). (b) The attenuation "
               "|Im α̂| of the lowest axisymmetric branch against the real frequency, 0.25–4× that of "
               "n = 1 (wavenumbers at the lowest frequency, then Newton continued), in dB/m "
               "(20 log10(e)|Im α̂|/R_i) and per R_i (right axis). The peak is where the branch bends "
               "from the bar wave (Ω/α̂ ≈ 4 c_s for VHB, 2.1 c_s for Ecoflex) towards slow short waves: "
               "there its group velocity dΩ/dα̂ is lowest (0.6 c_s for VHB against 3.9 for long waves), "
               "and the attenuation of a root Im Ω in time is about Im Ω/(dΩ/dα̂) in space.")
    ctx.save(name, fig, table, caption)
    return fig, (left, right)


# ----------------------------------------------------------------------------- main job


def write_index(out: Path, captions: dict) -> Path:
    """``out/README.md``: one section per figure, its image, its caption and its CSV."""
    lines = ["# Figures", "",
             "Written by `jaxdea figures` (the analogues of Figs. 2–10 of the seed paper, J. Appl. Mech., "
             "DOI 10.1115/1.4065794, the stability of order m and the static response). Each PNG has the "
             "CSV of its numbers beside it. States past the tube's first instability (V̂ ≥ V̂_first, the "
             "smallest critical voltage over the orders m and axial modes n searched) are drawn faded "
             "in every figure, and the CSVs say so in `v_first` and `past_first_instability`.", ""]
    for name, caption in captions.items():
        lines += [f"## {name}", "", f"![{name}]({name}.png)", "", caption, "",
                  f"Data: [{name}.csv]({name}.csv)", ""]
    path = out / "README.md"
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def make_figures(out="figures", *, quick: bool = False, progress: bool = True,
                 n_layers: int = 30) -> list[Path]:
    """Regenerate every figure (module docstring) into ``out``, with ``README.md``, one caption per
    figure (:func:`write_index`); returns the paths written.

    Args:
        out: output folder (created).
        quick: coarse grids (a smoke run in seconds after compilation).
        progress: print a line per figure and progress bars.
        n_layers: sublayers N of the laminate (laminate error ~1e-5 relative at 30).
    """
    return run_figures(out, quick=quick, progress=progress, n_layers=n_layers).written


def run_figures(out="figures", *, quick: bool = False, progress: bool = True, n_layers: int = 30) -> Context:
    """:func:`make_figures`, returning its :class:`Context`: ``written`` (the paths), ``figures``
    and ``captions`` (by figure name) and the solved data."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    with (concurrent.futures.ThreadPoolExecutor(2) as leaves,
          concurrent.futures.ThreadPoolExecutor(2) as pool):
        ctx = Context(out, Resolution.pick(quick), int(n_layers), progress, [], pool=leaves)
        ctx.log("compiling the solvers (once; later runs load them from the cache)…")
        # the stability map's critical voltages and :func:`solve_beside`, beside Figs. 2–10
        started = [pool.submit(ctx.stability), pool.submit(solve_beside, ctx)]
        _paper_figures(ctx)
        for future in started:
            future.result()
    order = {name: k for k, name in enumerate(FIGURE_ORDER)}
    ctx.written.append(write_index(out, dict(sorted(ctx.captions.items(), key=lambda c: order[c[0]]))))
    ctx.log(f"{len(ctx.written)} files in {out} ({time.perf_counter() - start:.0f} s)")
    return ctx


FIGURE_ORDER = ("fig2_voltage_empty", "fig3_modes_empty", "fig4_modes_critical_empty", "fig5_voltage_fluid",
                "fig6_modes_fluid", "fig7_modes_critical_fluid", "fig8_speed_ratio", "fig9_density_ratio",
                "fig10_thickness_ratio", "comparison_couplings", "stability_map", "dispersion_order_m",
                "cross_sections", "static_response", "encapsulation",
                "surrounding_fluid", "damping")  # the order of the index


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
    figure_encapsulation(ctx)
    figure_surrounding_fluid(ctx)
    figure_damping(ctx)
