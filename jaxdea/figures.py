"""The paper's figures (Figs. 2–10 of the seed paper, §5), the model comparison and the static response.

``make_figures(out)`` (the main job, ``jaxdea figures``) writes, for each figure, a PNG and the CSV
behind it. The tube is the paper's: η = 0.85, L = 10 R_o, λ_z = 1.2, Gent G = 97.2; the fluid
ρ̂_f = 0.13, ĉ_f = 0.27. Every curve is the lowest frequency of the axial mode n (α̂ = 2nπη/(10λ_z));
the consistent ``acoustic`` coupling is drawn solid, the paper's coupling (theory.md §4(b)) dashed
beside it wherever a fluid enters.

Past the critical voltage V̂_cr(n) the lowest frequency is imaginary (the tube buckles
axisymmetrically): such points are left blank (NaN, ``status`` = ``"past critical"`` in the CSV) and
the curves against V̂ end at (V̂_cr, 0). V̂_cr is solved directly (:func:`jaxdea.critical_voltage`), so
a blank point never hides a wrong branch: the lowest real root found above V̂_cr belongs to another
branch and is not drawn.

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
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .base_state import _squared_voltage, pull_in, voltage_limit, with_thickness_ratio_unchecked
from .compiled import cached_jit, jit
from .leaves import apply_parameters
from .modes import mode_shape
from .params import Fluid, Tube, guard, mode_wavenumber
from .roots import critical_voltage_unchecked
from .scalar import Status
from .state_matrix import ORDER_M
from .sweeps import sweep

PAPER_TUBE = Tube(lambda_z=1.2, eta=0.85, gent=97.2, length_ratio=10.0)
PAPER_FLUID = dict(density_ratio=0.13, speed_ratio=0.27)
COUPLINGS = ("acoustic", "paper")
STRETCHES = (0.9, 1.1)  # subcritical and overcritical λ_i of the paper
MODES = (1, 2, 3)
COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple")
SHAPE_STRETCH, SHAPE_VOLTAGE = 0.9, 0.01  # a stable state of the paper's tube (first instability 0.0293)
SHAPE_TUBE = PAPER_TUBE.replace(lambda_i=SHAPE_STRETCH, voltage=SHAPE_VOLTAGE)
ORDERS = (0, 1, 2, 3, 4)  # circumferential orders of the stability map and of the first instability
CRITICAL_STRETCH = 1.0 / math.sqrt(float(PAPER_TUBE.lambda_z))  # λ_i = λ_z^{-1/2} of Figs. 4 and 7
MAP_STRETCH_RANGE = (0.9, 1.4)  # below λ_i ≈ 0.9 the tube is unstable at V̂ = 0 (m = 2, n = 1: growth rate
# s = 0.35 at λ_i = 0.875, 0.96 at 0.8), where V̂_cr, the first zero of Ω² from V̂ = 0, means nothing
SHAPE_ORDERS = (1, 2, 3)
CURVE_ORDERS = (0, 1, 2)
CURVE_ROOTS = 3
EMPTY_CURVE_ORDERS = tuple(sorted(set(CURVE_ORDERS) | set(SHAPE_ORDERS)))  # the empty tube's sweep


@dataclasses.dataclass(frozen=True)
class Resolution:
    """Grid sizes: ``full`` for the figures, ``quick`` for tests and smoke runs."""

    voltages: int
    max_mode: int
    fluid_points: int
    static_points: int
    map_stretches: int  # λ_i of the stability map
    curve_steps: int  # α̂ steps of the order-m dispersion curves per mode spacing α̂_1
    outline_points: int  # angles θ of the cross-section outlines

    @classmethod
    def pick(cls, quick: bool) -> Resolution:
        if quick:
            return cls(voltages=5, max_mode=4, fluid_points=3, static_points=60, map_stretches=5,
                       curve_steps=1, outline_points=73)
        return cls(voltages=16, max_mode=15, fluid_points=10, static_points=240, map_stretches=11,
                   curve_steps=4, outline_points=361)


class Table:
    """Rows of one figure's CSV (long format, module docstring)."""

    def __init__(self, name: str):
        self.name, self.rows = name, []

    def add(self, **row):
        self.rows.append({"figure": self.name, **row})

    def write(self, path: Path) -> None:
        names = list(dict.fromkeys(k for row in self.rows for k in row))
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=names)
            writer.writeheader()
            for row in self.rows:
                writer.writerow({k: _fmt(v) for k, v in row.items()})


def _fmt(v):
    if isinstance(v, (float, np.floating)):
        return "nan" if not np.isfinite(v) else f"{float(v):.12g}"
    return v


# ----------------------------------------------------------------------------- computations


CV_CHUNK = 16  # critical voltages per compiled call: every grid pads to a multiple (one compilation)


@cached_jit(static_argnames=("n_layers",))
def _critical_voltages(tubes: Tube, orders, modes, n_layers):
    """V̂_cr of order m at α̂_n = 2nπη/(L/R_o·λ_z) for each case (tube, m, n) of a flat batch.

    The search of :func:`jaxdea.first_instability`: :func:`critical_voltage_unchecked` of the family
    ``"order_m"`` (m traced, the longitudinal family at m = 0) in (0, V̂_lim], V̂_lim the pull-in limit
    of :func:`voltage_limit`; one compiled program for every tube, m and n of every figure (a
    sequential ``lax.map``: vectorising 8 cases compiled 2.7 times longer for the same run time,
    measured); NaN where none."""
    def one(case):
        tube, order, mode = case
        ok, base, _, _ = guard(tube.replace(voltage=0.0), 1.0, None)
        voltage, _ = critical_voltage_unchecked(base, mode_wavenumber(base, mode), None, n_layers, 0,
                                                v_end=voltage_limit(base), m=order, family=ORDER_M)
        return jnp.where(ok, voltage, jnp.nan)

    return jax.lax.map(one, (tubes, orders, modes))


def critical_voltage_cases(tubes: Tube, orders, modes, n_layers: int) -> np.ndarray:
    """:func:`_critical_voltages` of a flat batch of any size, in padded chunks of CV_CHUNK cases."""
    orders, modes = np.asarray(orders, float), np.asarray(modes, float)
    size = orders.size
    padded = -(-size // CV_CHUNK) * CV_CHUNK
    pad = lambda x: jnp.asarray(np.pad(np.asarray(x), (0, padded - size), mode="edge"))  # noqa: E731
    tubes, orders, modes = jax.tree_util.tree_map(pad, (tubes, orders, modes))
    chunks = [_critical_voltages(*jax.tree_util.tree_map(lambda x, i=i: x[i:i + CV_CHUNK],
                                                         (tubes, orders, modes)), n_layers)
              for i in range(0, padded, CV_CHUNK)]
    return np.concatenate([np.asarray(c) for c in chunks])[:size]


def _tubes_with(tube: Tube, **leaves) -> Tube:
    """A flat batch of ``tube`` with the given leaves (arrays of one length) replaced."""
    size = len(next(iter(leaves.values())))
    batch = jax.tree_util.tree_map(lambda x: jnp.full(size, x, jnp.float64), tube)
    return batch.replace(**{k: jnp.asarray(v, jnp.float64) for k, v in leaves.items()})


def critical_voltage_grid(tube: Tube, n_layers: int, **axes) -> np.ndarray:
    """Axisymmetric (m = 0) V̂_cr over the grid of ``axes`` (tube leaves, ``thickness_ratio`` and
    ``n``), shape of the grid; NaN where the lowest frequency stays real up to the pull-in limit."""
    names = list(axes)
    grids = np.meshgrid(*(np.atleast_1d(np.asarray(v, float)) for v in axes.values()), indexing="ij")
    flat = {k: jnp.asarray(g.ravel()) for k, g in zip(names, grids, strict=True) if k != "n"}
    tubes, _, _ = jax.vmap(lambda vals: apply_parameters(tube, 1.0, None, vals))(flat)
    modes = grids[names.index("n")].ravel() if "n" in names else np.ones(grids[0].size)
    return critical_voltage_cases(tubes, np.zeros(modes.size), modes, n_layers).reshape(grids[0].shape)


@dataclasses.dataclass(frozen=True)
class Stability:
    """Critical voltages of the orders m = 0 … 4 (:data:`ORDERS`) of the paper's tube.

    Attributes:
        map_stretches: λ_i of the stability map, shape (L,).
        map_voltages: V̂_cr of (m, n = 1) at each of them, shape (L, len(ORDERS)).
        grids: {λ_i: V̂_cr of every (m, n), shape (len(ORDERS), max_mode)} at the λ_i of the figures.
    """

    map_stretches: np.ndarray
    map_voltages: np.ndarray
    grids: dict

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


def stability_of_paper_tube(n_layers: int, map_stretches, stretches, max_mode: int) -> Stability:
    """:class:`Stability`: V̂_cr of (λ_i, m, n = 1) over ``map_stretches`` and of (m, n ≤ max_mode) at
    each of ``stretches``, by the one compiled program of :func:`critical_voltage_cases`."""
    orders = np.asarray(ORDERS, float)
    modes = np.arange(1.0, max_mode + 1.0)
    blocks = [np.meshgrid(np.asarray(map_stretches, float), orders, [1.0], indexing="ij")]
    blocks += [np.meshgrid([li], orders, modes, indexing="ij") for li in stretches]
    cases = [np.concatenate([b[k].ravel() for b in blocks]) for k in range(3)]
    voltages = critical_voltage_cases(_tubes_with(PAPER_TUBE, lambda_i=cases[0]), cases[1], cases[2],
                                      n_layers)
    size = len(map_stretches) * len(orders)
    grids = np.split(voltages[size:], len(stretches)) if stretches else []
    return Stability(np.asarray(map_stretches, float), voltages[:size].reshape(len(map_stretches), -1),
                     {float(li): g.reshape(len(orders), max_mode) for li, g in zip(stretches, grids,
                                                                                  strict=True)})


@dataclasses.dataclass
class Context:
    out: Path
    res: Resolution
    n_layers: int
    progress: bool
    written: list
    critical: dict = dataclasses.field(default_factory=dict)
    stability_of_tube: Stability | None = None
    curves: dict = dataclasses.field(default_factory=dict)
    shapes: dict | None = None
    static: tuple | None = None
    since: float = dataclasses.field(default_factory=time.perf_counter)  # when the last figure was saved

    def log(self, message: str) -> None:
        if self.progress:
            print(message, flush=True)

    def critical_voltages(self, **axes) -> np.ndarray:
        """:func:`critical_voltage_grid` of the paper's tube, solved once per grid: V̂_cr does not
        depend on the fluid, so the empty-tube and fluid-filled figures share it."""
        key = tuple((k, tuple(np.atleast_1d(np.asarray(v, float)).tolist())) for k, v in axes.items())
        if key not in self.critical:
            self.critical[key] = critical_voltage_grid(PAPER_TUBE, self.n_layers, **axes)
        return self.critical[key]

    def stability(self) -> Stability:
        """:func:`stability_of_paper_tube` for the stability map (λ_i over :data:`MAP_STRETCH_RANGE`)
        and the λ_i of Figs. 2–7, solved once."""
        if self.stability_of_tube is None:
            stretches = np.round(np.linspace(*MAP_STRETCH_RANGE, self.res.map_stretches), 12)
            self.stability_of_tube = stability_of_paper_tube(
                self.n_layers, stretches, STRETCHES + (CRITICAL_STRETCH,), self.res.max_mode)
        return self.stability_of_tube

    def solve(self, fluid: Fluid | None, *, voltage, lambda_i, n, eta=0.85,
              density_ratio=PAPER_FLUID["density_ratio"], speed_ratio=PAPER_FLUID["speed_ratio"]):
        """Lowest root per point of the grid V̂ × λ_i × η × ρ̂_f × ĉ_f × n (a one-root
        :func:`jaxdea.sweep`); arrays of shape (V, L, E, D, S, N) (D = S = 1 without fluid).

        Every figure sweeps the same axis names in the same order, so each coupling compiles once.
        """
        axes = dict(voltage=voltage, lambda_i=lambda_i, eta=eta)
        if fluid is not None:
            axes.update(density_ratio=density_ratio, speed_ratio=speed_ratio)
        axes = {k: np.atleast_1d(np.asarray(v, float)) for k, v in axes.items()}
        res = sweep(PAPER_TUBE, fluid, n_roots=1, n_layers=self.n_layers,
                    progress=None if self.progress else False, **axes, n=np.atleast_1d(n))
        shape = res.alpha.shape if fluid is not None else res.alpha.shape[:3] + (1, 1, res.alpha.shape[3])
        return res.omega[..., 0].reshape(shape), res.status[..., 0].reshape(shape), res.alpha.reshape(shape)

    def save(self, name: str, fig, table: Table) -> None:
        import matplotlib.pyplot as plt

        png, csv_path = self.out / f"{name}.png", self.out / f"{name}.csv"
        fig.savefig(png, dpi=130, bbox_inches="tight")
        plt.close(fig)
        for row in table.rows:  # the setting behind every number: the paper's laminate
            row["discretisation"] = f"midpoint, N = {self.n_layers}"
        table.write(csv_path)
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


def _style(coupling):
    return "-" if coupling in (None, "acoustic") else "--"


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


def figure_voltage(ctx: Context, fluid_filled: bool) -> None:
    """Ω and c_p against V̂ for n = 1, 2, 3 at λ_i = 0.9, 1.1 (Fig. 2 fluid-free, Fig. 5 filled)."""
    name = "fig5_voltage_fluid" if fluid_filled else "fig2_voltage_empty"
    ctx.log(f"[{name}] Ω and phase velocity against V̂")
    v_cr = ctx.critical_voltages(lambda_i=STRETCHES, n=MODES)
    v_top = float(np.nanmax(v_cr))
    voltages = v_top * np.linspace(0.0, 1.0, ctx.res.voltages, endpoint=False)
    cases = _fluids() if fluid_filled else {None: None}
    stability = ctx.stability()
    fig, (ax_w, ax_c) = _figure(title=("Fluid-filled" if fluid_filled else "Fluid-free")
                                + " tube: lowest frequency of modes n = 1, 2, 3 (λ_z = 1.2)")
    table = Table(name)
    for coupling, fluid in cases.items():
        omegas, statuses, alphas = ctx.solve(fluid, voltage=voltages, lambda_i=STRETCHES, n=MODES)
        for i, li in enumerate(STRETCHES):
            first = _first_columns(stability, li)
            for j, n in enumerate(MODES):
                omega, past = _mask_past(omegas[:, i, 0, 0, 0, j], voltages, v_cr[i, j])
                alpha = alphas[0, i, 0, 0, 0, j]
                for v, w, s, p in zip(voltages, omega, statuses[:, i, 0, 0, 0, j], past, strict=True):
                    table.add(lambda_i=li, n=n, voltage=v, coupling=coupling or "none", alpha_hat=alpha,
                              omega=w, phase_velocity=w / alpha, v_critical=v_cr[i, j],
                              status=_status_name(s, p), **first)
                x = np.append(voltages[~past], v_cr[i, j])
                y = np.append(omega[~past], 0.0)
                label = f"n={n}, λi={li}" + (f" ({coupling})" if coupling else "")
                kw = dict(color=COLORS[j], ls=_style(coupling), lw=1.6 if li == 0.9 else 1.0,
                          marker="o" if li == 0.9 else "s", ms=2.5)
                ax_w.plot(x, y, label=label, **kw)
                ax_c.plot(x, y / alpha, **kw)
    for ax in (ax_w, ax_c):
        _shade_unstable(ax, stability, STRETCHES)
    _finish(ax_w, "voltage V̂", "frequency Ω")
    _finish(ax_c, "voltage V̂", "phase velocity ĉ_p = Ω/α̂", legend=False)
    ctx.save(name, fig, table)


# ----------------------------------------------------------------------------- Figs. 3, 4, 6, 7


def figure_modes(ctx: Context, fluid_filled: bool, critical_stretch: bool) -> None:
    """Ω and c_p against the axial mode number n (Figs. 3/6: λ_i = 0.9, 1.1 and V̂ = 0, 0.2;
    Figs. 4/7: λ_i = λ_z^{-1/2} and V̂ = 0, 0.1, 0.15, 0.2)."""
    if critical_stretch:
        name = "fig7_modes_critical_fluid" if fluid_filled else "fig4_modes_critical_empty"
        stretches, voltages = (CRITICAL_STRETCH,), (0.0, 0.1, 0.15, 0.2)
    else:
        name = "fig6_modes_fluid" if fluid_filled else "fig3_modes_empty"
        stretches, voltages = STRETCHES, (0.0, 0.2)
    ctx.log(f"[{name}] Ω and phase velocity against the axial mode number")
    modes = np.arange(1, ctx.res.max_mode + 1)
    v_cr = ctx.critical_voltages(lambda_i=stretches, n=modes)
    cases = _fluids() if fluid_filled else {None: None}
    title = ("Fluid-filled" if fluid_filled else "Fluid-free") + " tube against the mode number"
    if critical_stretch:
        title += f" at λ_i = λ_z^-1/2 ≈ {stretches[0]:.3f}"
    stability = ctx.stability()
    fig, (ax_w, ax_c) = _figure(title=title)
    table = Table(name)
    for coupling, fluid in cases.items():
        omegas, statuses, alphas = ctx.solve(fluid, voltage=voltages, lambda_i=stretches, n=modes)
        for i, li in enumerate(stretches):
            first = _first_columns(stability, li)
            for j, v in enumerate(voltages):
                omega, past = _mask_past(omegas[j, i, 0, 0, 0], v, v_cr[i])
                alpha = alphas[j, i, 0, 0, 0]
                for n, a, w, s, p, vc in zip(modes, alpha, omega, statuses[j, i, 0, 0, 0], past, v_cr[i],
                                             strict=True):
                    table.add(lambda_i=li, voltage=v, n=n, coupling=coupling or "none", alpha_hat=a,
                              omega=w, phase_velocity=w / a, v_critical=vc, status=_status_name(s, p),
                              **first)
                unstable = v >= first["v_first"]
                color = COLORS[j if critical_stretch else 2 * i + j]
                label = f"V̂={v}" + ("" if critical_stretch else f", λi={li}") + (
                    f" ({coupling})" if coupling else "") + (" unstable" if unstable else "")
                kw = dict(color=color, ls=_style(coupling), marker="o", ms=2.5,
                          alpha=0.45 if unstable else 1.0)
                ax_w.plot(modes, omega, label=label, **kw)
                ax_c.plot(modes, omega / alpha, **kw)
    _note_unstable(ax_c, stability, stretches)
    _finish(ax_w, "axial mode number n", "frequency Ω")
    _finish(ax_c, "axial mode number n", "phase velocity ĉ_p = Ω/α̂", legend=False)
    ctx.save(name, fig, table)
    return table


# ----------------------------------------------------------------------------- Figs. 8–10


FLUID_AXES = {
    "speed_ratio": ("fig8_speed_ratio", "fluid speed ratio ĉ_f = c_f/c_s", (0.05, 1.5), False),
    "density_ratio": ("fig9_density_ratio", "fluid density ratio ρ̂_f = ρ_f/ρ_s", (0.01, 2.0), True),
    "thickness_ratio": ("fig10_thickness_ratio", "wall thickness h/R_i", (0.05, 2.0), True),
}


def figure_fluid_parameter(ctx: Context, axis: str) -> Table:
    """Ω of n = 1, 2, 3 against ĉ_f (Fig. 8), ρ̂_f (Fig. 9) or h/R_i (Fig. 10), (a) V̂ = 0, (b) 0.15."""
    name, xlabel, (lo, hi), log = FLUID_AXES[axis]
    ctx.log(f"[{name}] Ω against {axis}")
    k = ctx.res.fluid_points
    grid = np.geomspace(lo, hi, k) if log else np.linspace(lo, hi, k)
    voltages = (0.0, 0.15)
    geometry_axes = {"thickness_ratio": grid} if axis == "thickness_ratio" else {}
    v_cr = ctx.critical_voltages(lambda_i=STRETCHES, **geometry_axes, n=MODES)
    if not geometry_axes:  # V̂_cr does not depend on the fluid: broadcast over the fluid axis
        v_cr = np.broadcast_to(v_cr[:, None, :], (len(STRETCHES), k, len(MODES)))
    fig, panels = _figure(title=f"Fluid-filled tube: lowest frequency of n = 1, 2, 3 against {axis}")
    table = Table(name)
    for coupling, fluid in _fluids().items():
        for i, li in enumerate(STRETCHES):
            if axis == "thickness_ratio":  # h/R_i at this λ_i set through η (same sweep axes)
                etas = np.asarray(jax.vmap(lambda h, li=li: with_thickness_ratio_unchecked(
                    PAPER_TUBE.replace(lambda_i=li), h).eta)(jnp.asarray(grid)))
                omegas, statuses, alphas = ctx.solve(fluid, voltage=voltages, lambda_i=li, eta=etas, n=MODES)
                pick = lambda a, iv, j: a[iv, 0, :, 0, 0, j]  # noqa: E731
            else:
                omegas, statuses, alphas = ctx.solve(fluid, voltage=voltages, lambda_i=li, n=MODES,
                                                     **{axis: grid})
                pick = (lambda a, iv, j: a[iv, 0, 0, :, 0, j]) if axis == "density_ratio" else (  # noqa: E731
                    lambda a, iv, j: a[iv, 0, 0, 0, :, j])
            for iv, v in enumerate(voltages):
                for j, n in enumerate(MODES):
                    omega, past = _mask_past(pick(omegas, iv, j), v, v_cr[i, :, j])
                    alpha = pick(alphas, iv, j)
                    for x, a, w, s, p, vc in zip(grid, alpha, omega, pick(statuses, iv, j), past,
                                                 v_cr[i, :, j], strict=True):
                        table.add(voltage=v, lambda_i=li, **{axis: x}, n=n, coupling=coupling,
                                  alpha_hat=a, omega=w, phase_velocity=w / a, v_critical=vc,
                                  status=_status_name(s, p))
                    label = f"n={n}, λi={li} ({coupling})"
                    panels[iv].plot(grid, omega, color=COLORS[j], ls=_style(coupling),
                                    marker="o" if li == 0.9 else "s", ms=2.5,
                                    lw=1.6 if li == 0.9 else 1.0, label=label)
    for iv, v in enumerate(voltages):
        panels[iv].set_title(f"({'ab'[iv]}) V̂ = {v}")
        if log:
            panels[iv].set_xscale("log")
        _finish(panels[iv], xlabel, "frequency Ω", legend=iv == 0)
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
        ax_l.plot(stability.map_stretches, stability.map_voltages[:, k], color=COLORS[k], marker="o",
                  ms=2.5, lw=1.2, label=f"m = {m}")
    ax_l.plot(stability.map_stretches, envelope[:, 0], color="k", ls="--", lw=2, zorder=5,
              label="first instability (min over m)")
    ax_l.fill_between(stability.map_stretches, envelope[:, 0], np.nanmax(stability.map_voltages),
                      color="0.5", alpha=0.1, lw=0)
    ax_l.set_title("(a) axial mode n = 1 (shaded: unstable)", fontsize=9)
    _finish(ax_l, "inner stretch λ_i", "critical voltage V̂_cr", legend=False)
    _legend_below(ax_l)
    modes = np.arange(1, ctx.res.max_mode + 1)
    for li, style in zip(STRETCHES, ("-", "--"), strict=True):
        grid = stability.grids[float(li)]
        first = _first_columns(stability, li)
        for k, m in enumerate(ORDERS):
            for n, v in zip(modes, grid[k], strict=True):
                table.add(panel="n", lambda_i=li, m=m, n=n, v_critical=v, **first)
            ax_n.plot(modes, grid[k], color=COLORS[k], ls=style, marker="o", ms=2.5,
                      label=f"m = {m}, λi = {li}")
        ax_n.plot([first["n_first"]], [first["v_first"]], "k*", ms=10)
        ax_n.annotate(f"λi={li}: ({first['m_first']}, {first['n_first']}) first", (first["n_first"],
                      first["v_first"]), xytext=(8, -4 if li == STRETCHES[0] else 4),
                      textcoords="offset points", fontsize=7)
    ax_n.set_title("(b) against the axial mode (* first instability)", fontsize=9)
    _finish(ax_n, "axial mode number n", "critical voltage V̂_cr", legend=False)
    ax_n.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ctx.save(name, fig, table)


def dispersion_grid(tube: Tube, max_mode: int, steps: int) -> np.ndarray:
    """α̂ from α̂_1 to α̂_max_mode of the tube's axial modes, ``steps`` points per spacing α̂_1 (the
    modes α̂_n among them)."""
    alpha_1 = float(mode_wavenumber(tube, 1.0))
    return alpha_1 * np.linspace(1.0, max_mode, (max_mode - 1) * steps + 1)


def order_m_curves(ctx: Context, fluid: Fluid | None, orders) -> dict:
    """{m: (Ω (K, CURVE_ROOTS), status (K, CURVE_ROOTS))} along :func:`dispersion_grid` of the tube of
    :func:`figure_dispersion_order_m`: a :func:`jaxdea.sweep` over the axes m (traced: one compiled
    program for every order, the longitudinal family through the order-m system at m = 0) and α̂,
    solved once per fluid."""
    key = (None if fluid is None else fluid.coupling, tuple(orders))
    if key not in ctx.curves:
        alphas = dispersion_grid(SHAPE_TUBE, ctx.res.max_mode, ctx.res.curve_steps)
        res = sweep(SHAPE_TUBE, fluid, n_roots=CURVE_ROOTS, n_layers=ctx.n_layers, progress=False,
                    m=np.asarray(orders), alpha=alphas)
        ctx.curves[key] = {m: (res.omega[k], res.status[k]) for k, m in enumerate(orders)}
    return ctx.curves[key]


def cross_section_modes(ctx: Context) -> dict:
    """{m: (Ω, r̂ (P,), fields)} of the lowest mode of each order of :data:`SHAPE_ORDERS` at n = 1,
    α̂ = α̂_1 (:func:`jaxdea.mode_shape` at the root of :func:`order_m_curves`), solved once."""
    if ctx.shapes is None:
        curves = order_m_curves(ctx, None, EMPTY_CURVE_ORDERS)
        alpha = float(mode_wavenumber(SHAPE_TUBE, 1.0))
        shapes = {}
        for m in SHAPE_ORDERS:
            omega = float(curves[m][0][0, 0])  # the curve's first α̂ is α̂_1
            r, fields = mode_shape(SHAPE_TUBE, alpha, omega, n_layers=ctx.n_layers, m=m)
            shapes[m] = (omega, np.asarray(r), [np.asarray(x) for x in fields])
        ctx.shapes = shapes
    return ctx.shapes


def solve_order_m(ctx: Context) -> None:
    """The solves of the last three figures (:func:`order_m_curves` of both fluids,
    :func:`cross_section_modes`, :func:`static_response`): :func:`make_figures` runs them beside
    Figs. 2–10 in a second thread (computations only; every figure is drawn in the main thread),
    so that their programs compile while the first figures are solved and drawn."""
    order_m_curves(ctx, Fluid(**PAPER_FLUID), CURVE_ORDERS)
    cross_section_modes(ctx)
    static_response(ctx)


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
        for k, m in enumerate(CURVE_ORDERS):
            omega, status = curves[m]
            for i, a in enumerate(alphas):
                for b in range(CURVE_ROOTS):
                    table.add(coupling=label, lambda_i=SHAPE_STRETCH, voltage=SHAPE_VOLTAGE, m=m,
                              branch=b + 1, alpha_hat=a, n=a / alpha_1, omega=omega[i, b],
                              phase_velocity=omega[i, b] / a,
                              status=Status(int(status[i, b])).name.lower())
            for b in range(CURVE_ROOTS):
                ax.plot(alphas, omega[:, b], color=COLORS[k], lw=1.4 - 0.3 * b,
                        label=f"m = {m}" if b == 0 else None)
            on_mode = np.isclose(alphas / alpha_1, np.round(alphas / alpha_1))
            ax.plot(alphas[on_mode], omega[on_mode, 0], "*", color=COLORS[k], ms=5)
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
        for c, (tag, pair) in enumerate(sorted(group.items())):
            x = np.array([p[0] for p in pair["acoustic"]])
            w_a = np.array([p[1] for p in pair["acoustic"]])
            w_p = np.array([p[1] for p in pair["paper"]])
            rel = np.abs(w_p - w_a) / w_a
            for xi, a, p, r in zip(x, w_a, w_p, rel, strict=True):
                table.add(panel=xname, voltage=tag[0], lambda_i=tag[1],
                          n=tag[2] if len(tag) > 2 else xi, **({xname: xi} if xname != "n" else {}),
                          omega_acoustic=a, omega_paper=p, relative_difference=r)
            label = f"V̂={tag[0]}, λi={tag[1]}" + (f", n={tag[2]}" if len(tag) > 2 else "")
            ax.semilogy(x, rel, marker="o", ms=2.5, color=f"C{c % 10}", label=label)
        _finish(ax, xlabel, "|Ω_paper − Ω_acoustic| / Ω_acoustic")
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
    if ctx.static is None:
        tube = PAPER_TUBE
        lock = locking_stretch(tube)
        stretches = np.geomspace(0.6, lock, ctx.res.static_points)
        v2 = jit(jax.vmap(lambda li, dp: _squared_voltage(tube, li, dp), (0, None)))
        curves = {}
        for dp in STATIC_PRESSURES:
            vsq = np.asarray(v2(jnp.asarray(stretches), dp))
            curves[dp] = (np.where(vsq >= 0, np.sqrt(np.abs(vsq)), np.nan),
                          tuple(float(x) for x in pull_in(tube, dp)))
        ctx.static = (lock, stretches, curves)
    return ctx.static


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
    ctx = Context(out, Resolution.pick(quick), int(n_layers), progress, [])
    start = time.perf_counter()
    with concurrent.futures.ThreadPoolExecutor(1) as pool:  # :func:`solve_order_m` beside Figs. 2–10
        order_m = pool.submit(solve_order_m, ctx)
        _paper_figures(ctx)
        order_m.result()
    figure_cross_sections(ctx)
    figure_dispersion_order_m(ctx)
    figure_static_response(ctx)
    ctx.log(f"{len(ctx.written)} files in {out} ({time.perf_counter() - start:.0f} s)")
    return ctx.written


def _paper_figures(ctx: Context) -> None:
    """Figs. 2–10, the model comparison and the stability map."""
    figure_voltage(ctx, fluid_filled=False)
    figure_modes(ctx, fluid_filled=False, critical_stretch=False)
    figure_modes(ctx, fluid_filled=False, critical_stretch=True)
    figure_voltage(ctx, fluid_filled=True)
    modes = figure_modes(ctx, fluid_filled=True, critical_stretch=False)
    figure_modes(ctx, fluid_filled=True, critical_stretch=True)
    speed = figure_fluid_parameter(ctx, "speed_ratio")
    figure_fluid_parameter(ctx, "density_ratio")
    figure_fluid_parameter(ctx, "thickness_ratio")
    figure_comparison(ctx, {"modes": modes, "speed": speed})
    figure_stability_map(ctx)
