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

Data layout of every CSV: one row per point and coupling, long format (``figure``, the swept
parameters, ``coupling``, ``alpha_hat``, ``omega``, ``phase_velocity`` = Ω/α̂, ``v_critical``,
``status``).
"""

from __future__ import annotations

import csv
import dataclasses
import math
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .base_state import _squared_voltage, pull_in, with_thickness_ratio_unchecked
from .compiled import cached_jit, jit
from .leaves import apply_parameters
from .params import Fluid, Tube
from .roots import critical_voltage_unchecked
from .scalar import Status
from .sweeps import sweep

PAPER_TUBE = Tube(lambda_z=1.2, eta=0.85, gent=97.2, length_ratio=10.0)
PAPER_FLUID = dict(density_ratio=0.13, speed_ratio=0.27)
COUPLINGS = ("acoustic", "paper")
STRETCHES = (0.9, 1.1)  # subcritical and overcritical λ_i of the paper
MODES = (1, 2, 3)
COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red")


@dataclasses.dataclass(frozen=True)
class Resolution:
    """Grid sizes: ``full`` for the figures, ``quick`` for tests and smoke runs."""

    voltages: int
    max_mode: int
    fluid_points: int
    static_points: int

    @classmethod
    def pick(cls, quick: bool) -> Resolution:
        return cls(voltages=5, max_mode=4, fluid_points=3, static_points=60) if quick else \
            cls(16, 15, 10, 240)


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


CV_CHUNK = 8  # critical voltages solved per compiled call
VOLTAGE_SEARCH_END = 0.5  # V̂_cr is searched in (0, 0.5]: every figure stays below V̂ = 0.2


@cached_jit(static_argnames=("n_layers",))
def _critical_voltages(tubes: Tube, alphas, n_layers):
    """V̂_cr at each (tube, α̂) of a flat batch (:func:`critical_voltage_unchecked` in (0, 0.5])."""
    def one(t, a):
        return critical_voltage_unchecked(t, a, None, n_layers, 0, v_end=VOLTAGE_SEARCH_END)[0]

    return jax.lax.map(lambda ta: one(*ta), (tubes, alphas))


def critical_voltage_grid(tube: Tube, n_layers: int, **axes) -> np.ndarray:
    """V̂_cr over the grid of ``axes`` (tube leaves, ``thickness_ratio`` and ``n``), shape of the grid;
    NaN where the lowest frequency stays real up to V̂ = 0.5."""
    names = list(axes)
    grids = np.meshgrid(*(np.atleast_1d(np.asarray(v, float)) for v in axes.values()), indexing="ij")
    size = grids[0].size
    padded = -(-size // CV_CHUNK) * CV_CHUNK  # fixed-size chunks: one compilation for every grid
    flat = {k: jnp.asarray(np.pad(g.ravel(), (0, padded - size), mode="edge"))
            for k, g in zip(names, grids, strict=True)}
    tubes, alphas, _ = jax.vmap(lambda vals: apply_parameters(tube, 1.0, None, vals))(flat)
    chunks = [_critical_voltages(*jax.tree_util.tree_map(lambda x, i=i: x[i:i + CV_CHUNK], (tubes, alphas)),
                                 n_layers) for i in range(0, padded, CV_CHUNK)]
    return np.concatenate([np.asarray(c) for c in chunks])[:size].reshape(grids[0].shape)


@dataclasses.dataclass
class Context:
    out: Path
    res: Resolution
    n_layers: int
    progress: bool
    written: list
    critical: dict = dataclasses.field(default_factory=dict)

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
        table.write(csv_path)
        self.written += [png, csv_path]
        self.log(f"  wrote {png} and {csv_path.name}")


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
        ax.legend(fontsize=7)


# ----------------------------------------------------------------------------- Figs. 2 and 5


def figure_voltage(ctx: Context, fluid_filled: bool) -> None:
    """Ω and c_p against V̂ for n = 1, 2, 3 at λ_i = 0.9, 1.1 (Fig. 2 fluid-free, Fig. 5 filled)."""
    name = "fig5_voltage_fluid" if fluid_filled else "fig2_voltage_empty"
    ctx.log(f"[{name}] Ω and phase velocity against V̂")
    v_cr = ctx.critical_voltages(lambda_i=STRETCHES, n=MODES)
    v_top = float(np.nanmax(v_cr))
    voltages = v_top * np.linspace(0.0, 1.0, ctx.res.voltages, endpoint=False)
    cases = _fluids() if fluid_filled else {None: None}
    fig, (ax_w, ax_c) = _figure(title=("Fluid-filled" if fluid_filled else "Fluid-free")
                                + " tube: lowest frequency of modes n = 1, 2, 3 (λ_z = 1.2)")
    table = Table(name)
    for coupling, fluid in cases.items():
        omegas, statuses, alphas = ctx.solve(fluid, voltage=voltages, lambda_i=STRETCHES, n=MODES)
        for i, li in enumerate(STRETCHES):
            for j, n in enumerate(MODES):
                omega, past = _mask_past(omegas[:, i, 0, 0, 0, j], voltages, v_cr[i, j])
                alpha = alphas[0, i, 0, 0, 0, j]
                for v, w, s, p in zip(voltages, omega, statuses[:, i, 0, 0, 0, j], past, strict=True):
                    table.add(lambda_i=li, n=n, voltage=v, coupling=coupling or "none", alpha_hat=alpha,
                              omega=w, phase_velocity=w / alpha, v_critical=v_cr[i, j],
                              status=_status_name(s, p))
                x = np.append(voltages[~past], v_cr[i, j])
                y = np.append(omega[~past], 0.0)
                label = f"n={n}, λi={li}" + (f" ({coupling})" if coupling else "")
                kw = dict(color=COLORS[j], ls=_style(coupling), lw=1.6 if li == 0.9 else 1.0,
                          marker="o" if li == 0.9 else "s", ms=2.5)
                ax_w.plot(x, y, label=label, **kw)
                ax_c.plot(x, y / alpha, **kw)
    _finish(ax_w, "voltage V̂", "frequency Ω")
    _finish(ax_c, "voltage V̂", "phase velocity ĉ_p = Ω/α̂", legend=False)
    ctx.save(name, fig, table)


# ----------------------------------------------------------------------------- Figs. 3, 4, 6, 7


def figure_modes(ctx: Context, fluid_filled: bool, critical_stretch: bool) -> None:
    """Ω and c_p against the axial mode number n (Figs. 3/6: λ_i = 0.9, 1.1 and V̂ = 0, 0.2;
    Figs. 4/7: λ_i = λ_z^{-1/2} and V̂ = 0, 0.1, 0.15, 0.2)."""
    if critical_stretch:
        name = "fig7_modes_critical_fluid" if fluid_filled else "fig4_modes_critical_empty"
        stretches, voltages = (1.0 / math.sqrt(float(PAPER_TUBE.lambda_z)),), (0.0, 0.1, 0.15, 0.2)
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
    fig, (ax_w, ax_c) = _figure(title=title)
    table = Table(name)
    for coupling, fluid in cases.items():
        omegas, statuses, alphas = ctx.solve(fluid, voltage=voltages, lambda_i=stretches, n=modes)
        for i, li in enumerate(stretches):
            for j, v in enumerate(voltages):
                omega, past = _mask_past(omegas[j, i, 0, 0, 0], v, v_cr[i])
                alpha = alphas[j, i, 0, 0, 0]
                for n, a, w, s, p, vc in zip(modes, alpha, omega, statuses[j, i, 0, 0, 0], past, v_cr[i],
                                             strict=True):
                    table.add(lambda_i=li, voltage=v, n=n, coupling=coupling or "none", alpha_hat=a,
                              omega=w, phase_velocity=w / a, v_critical=vc, status=_status_name(s, p))
                color = COLORS[j if critical_stretch else 2 * i + j]
                label = f"V̂={v}" + ("" if critical_stretch else f", λi={li}") + (
                    f" ({coupling})" if coupling else "")
                kw = dict(color=color, ls=_style(coupling), marker="o", ms=2.5)
                ax_w.plot(modes, omega, label=label, **kw)
                ax_c.plot(modes, omega / alpha, **kw)
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
    tube = PAPER_TUBE
    lock = locking_stretch(tube)
    stretches = np.geomspace(0.6, lock, ctx.res.static_points)
    fig, (ax,) = _figure(ncols=1)
    table = Table(name)
    v2 = jit(jax.vmap(lambda li, dp: _squared_voltage(tube, li, dp), (0, None)))
    found = 0
    for c, dp in enumerate((-0.05, 0.0, 0.05, 0.1)):
        vsq = np.asarray(v2(jnp.asarray(stretches), dp))
        volt = np.where(vsq >= 0, np.sqrt(np.abs(vsq)), np.nan)
        li_pull, v_pull, status = (float(x) for x in pull_in(tube, dp))
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
    figure_static_response(ctx)
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
    ctx.log(f"{len(ctx.written)} files in {out} ({time.perf_counter() - start:.0f} s)")
    return ctx.written
