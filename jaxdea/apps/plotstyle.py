"""One plotting style for every figure jaxdea draws (``jaxdea figures``, ``jaxdea sweep``, ``jaxdea fit``).

Figures are built with matplotlib's object API (:class:`matplotlib.figure.Figure`, constrained layout):
no pyplot state is touched and the user's backend is never changed. Labels are mathtext
(:data:`LABELS`, :data:`SYMBOLS`); files are written at :data:`SAVE_DPI`; legend handles are long
enough to tell the dash patterns apart (:data:`RC`).

One rule marks a state past the tube's first instability, the smallest critical voltage over the
orders m and axial modes n searched (:func:`jaxdea.first_instability`): V̂ ≥ V̂_first
(:func:`past_first_instability`). Every figure draws such states faded (:data:`PAST_ALPHA`), and
every CSV and table that has a voltage carries ``v_first`` and ``past_first_instability``.
"""

from __future__ import annotations

import contextlib

import numpy as np

SAVE_DPI = 300  # PNG resolution: journals ask 300 dpi for line art
PAST_ALPHA = 0.3  # opacity of a curve (part) at a state past the first instability
UNSTABLE_SHADE = "0.55"  # colour of the region past the first instability
RC = {
    "font.size": 9.0,
    "axes.titlesize": 9.0,
    "axes.labelsize": 9.0,
    "legend.fontsize": 8.0,
    "xtick.labelsize": 8.0,
    "ytick.labelsize": 8.0,
    "figure.titlesize": 10.0,
    "legend.handlelength": 4.5,  # a dash-dot-dot pattern shows twice in a handle
    "legend.frameon": False,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "lines.linewidth": 1.3,
    "mathtext.fontset": "dejavusans",
    "savefig.dpi": SAVE_DPI,
}

# the symbol of each quantity (mathtext), and its axis label
SYMBOLS = {
    "voltage": r"$\hat V$", "lambda_i": r"$\lambda_i$", "lambda_z": r"$\lambda_z$", "eta": r"$\eta$",
    "gent": r"$G$", "length_ratio": r"$L/R_o$", "thickness_ratio": r"$h/R_i$",
    "density_ratio": r"$\hat\rho_f$", "speed_ratio": r"$\hat c_f$", "alpha": r"$\hat\alpha$", "n": r"$n$",
    "m": r"$m$",
}
LABELS = {
    "voltage": r"voltage $\hat V = V\sqrt{\varepsilon/\mu}\,/R_i$",
    "lambda_i": r"inner circumferential stretch $\lambda_i = r_i/R_i$",
    "lambda_z": r"axial stretch $\lambda_z = l/L$",
    "eta": r"radius ratio $\eta = R_i/R_o$",
    "gent": r"Gent constant $G$",
    "length_ratio": r"length ratio $L/R_o$",
    "thickness_ratio": r"wall thickness $h/R_i$",
    "density_ratio": r"fluid density ratio $\hat\rho_f = \rho_f/\rho_s$",
    "speed_ratio": r"fluid sound speed ratio $\hat c_f = c_f/c_s$",
    "alpha": r"axial wavenumber $\hat\alpha = \alpha R_i$",
    "n": r"axial mode number $n$ ($\hat\alpha = 2n\pi\eta/(\lambda_z L/R_o)$)",
    "m": r"circumferential order $m$ (modes $\propto \cos m\theta$)",
}
OMEGA_LABEL = r"frequency $\Omega = \omega R_i/c_s$,  $c_s = \sqrt{\mu/\rho_s}$"
SHORT_LABELS = {
    "omega": r"frequency $\Omega$",
    "phase_velocity": r"phase velocity $\hat c_p = \Omega/\hat\alpha$",
    "v_critical": r"critical voltage $\hat V_{cr}$",
    "voltage": r"voltage $\hat V$",
    "n": r"axial mode number $n$ ($\hat\alpha = n\hat\alpha_1$)",
}


@contextlib.contextmanager
def style():
    """The figures' rc settings (:data:`RC`) for the figures created inside the block; the user's
    settings are restored on exit."""
    import matplotlib

    with matplotlib.rc_context(RC):
        yield


def new_figure(ncols: int = 1, nrows: int = 1, *, width: float | None = None, height: float = 3.6,
               sharex=False, sharey=False, title: str | None = None):
    """(figure, axes (nrows·ncols,)): a :class:`matplotlib.figure.Figure` with constrained layout,
    not registered with pyplot (no global state; it is shown where returned in a notebook)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width or 4.6 * ncols, height + (0.3 if title else 0.0)), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex=sharex, sharey=sharey)
    if title:
        fig.suptitle(title)
    return fig, axes.ravel()


def legend_below(fig, handles, labels=None, ncol: int = 3) -> None:
    """One legend for the whole figure, below its panels (outside them: it covers no curve)."""
    if labels is None:
        labels = [h.get_label() for h in handles]
    fig.legend(handles, labels, loc="outside lower center", ncol=ncol)


def line_handle(label: str, **kw):
    """A legend handle of a line style (colour, dashes, width, marker) drawn apart from the data."""
    from matplotlib.lines import Line2D

    return Line2D([], [], label=label, **{"color": "0.25", **kw})


def patch_handle(label: str, **kw):
    """A legend handle of a shaded region."""
    from matplotlib.patches import Patch

    return Patch(label=label, **kw)


def plain_log(axis) -> None:
    """Label a logarithmic axis with plain numbers at 1, 2 and 5 times the powers of ten (0.05, 0.1,
    0.2, …), not 10^k alone."""
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter

    axis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FormatStrFormatter("%g"))
    axis.set_minor_formatter(NullFormatter())


def past_first_instability(voltage, v_first):
    """The one rule that marks a state past the first instability: V̂ ≥ V̂_first (False where
    V̂_first is NaN: none found). Arrays broadcast."""
    voltage, v_first = np.asarray(voltage, float), np.asarray(v_first, float)
    return np.isfinite(v_first) & (voltage >= v_first)


def plot_marked(ax, x, y, past=None, **kw):
    """Plot a curve whose points ``past`` (V̂ ≥ V̂_first) are drawn faded (:data:`PAST_ALPHA`): the
    stable part at full opacity, the part past the first instability faded, joined at the boundary.
    Returns the stable part's line (None if every point is past)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    past = np.zeros(x.shape, bool) if past is None else np.broadcast_to(np.asarray(past, bool), x.shape)
    alpha = kw.pop("alpha", 1.0)
    stable = np.where(~past, y, np.nan)
    faded = np.where(past, y, np.nan)
    # join the parts: a faded point next to a stable one is drawn in both
    edge = np.zeros(x.shape, bool)
    edge[:-1] |= past[:-1] != past[1:]
    edge[1:] |= past[1:] != past[:-1]
    faded = np.where(edge & ~past, y, faded)
    line = None
    if np.any(np.isfinite(stable)):
        line, = ax.plot(x, stable, alpha=alpha, **kw)
    if np.any(np.isfinite(faded)):
        kw.pop("label", None)
        ax.plot(x, faded, alpha=alpha * PAST_ALPHA, **kw)
    return line


def source_stamp(*modules) -> str:
    """A hash of the code of ``modules`` (docstrings and comments left out): written into every PNG
    (:func:`png_metadata`), so that a stored figure drawn by older code is found stale."""
    import ast
    import hashlib
    import inspect

    digest = hashlib.sha256()
    for module in modules:
        tree = ast.parse(inspect.getsource(module))
        for node in ast.walk(tree):
            body = getattr(node, "body", None)
            if (isinstance(body, list) and body and isinstance(body[0], ast.Expr)
                    and isinstance(body[0].value, ast.Constant) and isinstance(body[0].value.value, str)):
                body[0] = ast.Pass()
        digest.update(ast.dump(tree).encode())
    return digest.hexdigest()[:16]


def png_metadata(stamp: str) -> dict:
    """PNG text chunks of a figure: the software and the code stamp (:func:`source_stamp`)."""
    return {"Software": "jaxdea (matplotlib)", "Source": f"jaxdea figures {stamp}"}
