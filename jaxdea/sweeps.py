"""Sweeps: the K lowest frequencies (and optionally their derivatives) over a grid of parameters.

A grid is the Cartesian product of 1-D axes named after the parameters of :mod:`jaxdea.leaves`
(any Tube or Fluid float field, ``thickness_ratio`` h/R_i, and ``alpha`` α̂ or ``n`` the axial mode
number). Its points are solved in fixed-size chunks by one jit-compiled, vmapped program: memory is
bounded by the chunk (plus the result arrays), and every chunk reuses the same compilation. Points
that fail (no root, non-finite transfer, inputs past Gent locking or out of range) give NaN and
their status (:class:`jaxdea.Status`) without stopping the sweep.

Derivatives (``jacobian=``) come from the implicit function theorem at each root,
dΩ/dθ = −(∂f/∂θ)/(∂f/∂Ω), with ∂f by forward-mode autodiff of the characteristic function f: the
partial derivatives are taken in the coordinates named (e.g. (V̂, λ_i, λ_z, ρ̂_f, ĉ_f, h/R_i, G):
dΩ/dλ_i at fixed h/R_i, with η following). On a grid over ``n`` the wavenumber α̂ of mode n follows
λ_z and η; on a grid over ``alpha`` α̂ is held. The group velocity dΩ/dα̂ = −f_α̂/f_Ω comes with them.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math

import jax
import jax.numpy as jnp
import numpy as np

from .dispersion import characteristic_on_wall
from .leaves import FLUID_LEAVES, TUBE_LEAVES, apply_parameters, check_names, get_parameter
from .params import (
    Fluid,
    Tube,
    as_float,
    real_value,
    require_x64,
    validate_fluid,
    validate_layers,
    validate_positive,
)
from .roots import frequencies_unchecked, guard
from .scalar import Status
from .transfer import discretize

SENSITIVITY = ("voltage", "lambda_i", "lambda_z", "density_ratio", "speed_ratio", "thickness_ratio",
               "gent")
CHUNK_SIZE = 32


@dataclasses.dataclass(frozen=True)
class SweepResult:
    """Frequencies over a grid.

    Attributes:
        axes: the grid axes, ``{name: 1-D array}`` in grid order.
        omega: Ω, shape (*grid_shape, n_roots), ascending per point, NaN where no root.
        status: :class:`jaxdea.Status` per root, same shape (int32).
        alpha: α̂ at each grid point, shape grid_shape.
        jacobian: dΩ/dθ, shape (*grid_shape, n_roots, len(jacobian_names)), or None.
        jacobian_names: the coordinates θ of ``jacobian``.
        group_velocity: dΩ/dα̂ per root (with the jacobian), or None.
        settings: the fixed parameters and solver settings (JSON-serialisable dict).
    """

    axes: dict
    omega: np.ndarray
    status: np.ndarray
    alpha: np.ndarray
    jacobian: np.ndarray | None = None
    jacobian_names: tuple = ()
    group_velocity: np.ndarray | None = None
    settings: dict = dataclasses.field(default_factory=dict)

    @property
    def shape(self) -> tuple:
        """The grid shape."""
        return self.alpha.shape

    @property
    def phase_velocity(self) -> np.ndarray:
        """Ω/α̂ per root, shape (*grid_shape, n_roots)."""
        return self.omega / self.alpha[..., None]

    def derivative(self, name: str) -> np.ndarray:
        """dΩ/d``name`` per root, shape (*grid_shape, n_roots)."""
        if self.jacobian is None or name not in self.jacobian_names:
            raise ValueError(f"no derivative with respect to {name!r}: computed for "
                             f"{self.jacobian_names or 'nothing'} (pass jacobian=... to sweep)")
        return self.jacobian[..., self.jacobian_names.index(name)]

    def columns(self) -> dict:
        """One flat column per quantity, one row per grid point (the CSV layout)."""
        grids = np.meshgrid(*self.axes.values(), indexing="ij")
        cols = {name: g.ravel() for name, g in zip(self.axes, grids, strict=True)}
        cols["alpha_hat"] = self.alpha.ravel()
        k = self.omega.shape[-1]
        flat = lambda a: a.reshape(-1, k)  # noqa: E731
        for j in range(k):
            cols[f"omega_{j + 1}"] = flat(self.omega)[:, j]
        for j in range(k):
            cols[f"status_{j + 1}"] = flat(self.status)[:, j]
        if self.group_velocity is not None:
            for j in range(k):
                cols[f"group_velocity_{j + 1}"] = flat(self.group_velocity)[:, j]
        for m, name in enumerate(self.jacobian_names):
            for j in range(k):
                cols[f"d_omega_{j + 1}/d_{name}"] = flat(self.jacobian[..., m])[:, j]
        return cols

    def to_csv(self, path) -> None:
        """Write one row per grid point (axes, α̂, Ω_k, status_k, derivatives); header line first."""
        cols = self.columns()
        table = np.column_stack(list(cols.values()))
        fmt = ["%d" if name.startswith("status") else "%.17g" for name in cols]
        np.savetxt(path, table, delimiter=",", header=",".join(cols), comments="", fmt=fmt)

    def to_npz(self, path) -> None:
        """Save everything (read back with :meth:`from_npz`)."""
        arrays = {f"axis:{name}": np.asarray(v) for name, v in self.axes.items()}
        arrays.update(omega=self.omega, status=self.status, alpha=self.alpha,
                      settings=np.array(json.dumps(self.settings)),
                      axis_order=np.array(json.dumps(list(self.axes))),
                      jacobian_names=np.array(json.dumps(list(self.jacobian_names))))
        if self.jacobian is not None:
            arrays.update(jacobian=self.jacobian, group_velocity=self.group_velocity)
        np.savez(path, **arrays)

    @classmethod
    def from_npz(cls, path) -> SweepResult:
        """Load a result saved by :meth:`to_npz`."""
        with np.load(path) as data:
            order = json.loads(str(data["axis_order"]))
            return cls(
                axes={name: data[f"axis:{name}"] for name in order},
                omega=data["omega"], status=data["status"], alpha=data["alpha"],
                jacobian=data["jacobian"] if "jacobian" in data else None,
                jacobian_names=tuple(json.loads(str(data["jacobian_names"]))),
                group_velocity=data["group_velocity"] if "group_velocity" in data else None,
                settings=json.loads(str(data["settings"])),
            )

    def __repr__(self) -> str:
        axes = ", ".join(f"{k}[{len(v)}]" for k, v in self.axes.items())
        ok = int(np.sum(self.status == Status.CONVERGED))
        return (f"SweepResult({axes}; {self.omega.shape[-1]} roots per point, "
                f"{ok}/{self.status.size} converged)")


def _point(values, tube, alpha, fluid, omega_max, n_roots, n_layers, order, jac_names):
    """Roots (and derivatives) at one grid point; ``values`` maps axis names to scalars."""
    point = apply_parameters(tube, alpha, fluid, values)
    nu = values["n"] if order == "n" else order
    roots = frequencies_unchecked(*point, omega_max, n_roots, n_layers, nu)
    alpha_point = as_float(point[1])
    if jac_names is None:
        return roots.omega, roots.status, alpha_point
    held = {k: v for k, v in values.items() if k == "n"}  # α̂ of mode n follows the tube

    def residual(x):  # x = [Ω, δα̂, θ...]: f at the point moved by θ, α̂ shifted by δα̂
        moved = dict(zip(jac_names, x[2:], strict=True), **held)
        t, a, f = apply_parameters(*point, moved)
        _, t, a, f = guard(t, as_float(a) + x[1], f)
        return characteristic_on_wall(discretize(t, n_layers), x[0], a, f, nu)

    theta = [get_parameter(*point, name) for name in jac_names]

    def derivatives(omega):
        x = jnp.stack([omega, jnp.zeros_like(omega), *theta])
        grad = jax.jacfwd(residual)(jnp.where(jnp.isfinite(x), x, 0.0))
        d = -grad[1:] / grad[0]
        return jnp.where(jnp.isfinite(omega), d, jnp.nan)

    d = jax.vmap(derivatives)(roots.omega)  # (n_roots, 1 + len(jac_names))
    jac = (d[:, 1:],) if jac_names else ()  # no zero-size outputs (lax.map cannot batch them)
    return roots.omega, roots.status, alpha_point, d[:, 0], *jac


@functools.partial(jax.jit, static_argnames=("names", "n_roots", "n_layers", "order", "jac_names",
                                             "batch_size"))
def _sweep_chunk(columns, tube, alpha, fluid, omega_max, names, n_roots, n_layers, order, jac_names,
                 batch_size):
    """One chunk of grid points (columns: one array per axis): ``lax.map`` over the points,
    ``batch_size`` of them vectorised at a time."""
    def one(vals):
        return _point(dict(zip(names, vals, strict=True)), tube, alpha, fluid, omega_max,
                      n_roots, n_layers, order, jac_names)

    return jax.lax.map(one, columns, batch_size=batch_size if batch_size > 1 else None)


def _axis(name, values):
    arr = real_value(f"axis {name!r}", values, scalar=False)
    if arr is None:
        raise ValueError(f"axis {name!r} must be concrete values (sweep is not traceable)")
    if arr.ndim > 1:
        raise ValueError(f"axis {name!r} must be a scalar or a 1-D array, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"axis {name!r} is empty")
    return np.atleast_1d(arr)


def sweep(tube: Tube, fluid: Fluid | None = None, *, n_roots: int = 3, omega_max=None,
          n_layers: int = 30, jacobian=None, chunk_size: int = CHUNK_SIZE, batch_size=None,
          progress=None, **axes) -> SweepResult:
    """The ``n_roots`` lowest frequencies over the grid spanned by ``axes``.

    Args:
        tube: the base :class:`~jaxdea.Tube`; grid axes override its fields.
        fluid: a :class:`~jaxdea.Fluid` or None.
        n_roots: K, roots per point (static).
        omega_max: upper end of each root search (None: automatic, see :func:`jaxdea.frequencies`).
        n_layers: sublayers N (static).
        jacobian: None (no derivatives), True (the sensitivity set (V̂, λ_i, λ_z, ρ̂_f, ĉ_f, h/R_i,
            G), fluid names dropped for an empty tube), or a sequence of parameter names. With it
            come the group velocities dΩ/dα̂.
        chunk_size: points per compiled chunk (memory ∝ chunk_size; one compilation for all chunks;
            the progress bar moves once per chunk).
        batch_size: points of a chunk solved side by side with ``vmap`` (the rest in sequence).
            None: 1 on CPU, where a vmapped root search runs as long as its slowest point and one
            point already vectorises its scan (measured 4.5× slower at 64 than at 1), else
            ``chunk_size`` (accelerators).
        progress: None (a tqdm bar once the run takes more than 2 s), True (always) or False.
        **axes: ``name=values`` grid axes (1-D arrays, or scalars for a fixed value) over the names
            of :mod:`jaxdea.leaves`; exactly one of ``alpha`` / ``n`` is required.

    Returns:
        :class:`SweepResult` with Ω of shape (*grid_shape, n_roots) in the order of ``axes``.

    Raises:
        ValueError: an unknown or repeated axis, a missing ``alpha``/``n``, bad settings. Values of
            the axes are not validated point by point: an invalid point gives NaN, status INVALID.

    Example:
        >>> res = sweep(Tube(lambda_z=1.2), voltage=np.linspace(0, 0.2, 5), n=np.arange(1, 11))
        >>> res.omega.shape  # (5, 10, 3)
    """
    require_x64()
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    validate_fluid(fluid)  # its static choices and, when concrete, its values
    # the tube's values are not range-checked (an invalid value gives NaN and status INVALID at
    # every point, as on an axis), but they must be real scalars; fields set by an axis are not
    # used (placeholders NaN)
    overridden = set(axes) | ({"eta"} if "thickness_ratio" in axes else set())
    unused = {}
    for name in TUBE_LEAVES:
        try:
            real_value(name, getattr(tube, name))
        except ValueError:
            if name not in overridden:
                raise
            unused[name] = math.nan
    tube = tube.replace(**unused)
    if not isinstance(tube.material, str):
        raise ValueError(f"material must be a str, got {tube.material!r}")
    if progress is not None and not isinstance(progress, bool):
        raise ValueError(f"progress must be None, True or False, got {progress!r}")
    validate_layers(n_layers)
    if batch_size is None:
        batch_size = 1 if jax.default_backend() == "cpu" else chunk_size
    for name, value, low in (("n_roots", n_roots, 1), ("chunk_size", chunk_size, 1),
                             ("batch_size", batch_size, 1)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    check_names(list(axes), fluid)
    if "alpha" not in axes and "n" not in axes:
        raise ValueError("give the wavenumber axis: alpha=... (α̂) or n=... (axial mode numbers)")
    axes = {name: _axis(name, v) for name, v in axes.items()}
    jac_names = _jacobian_names(jacobian, fluid)
    if omega_max is not None:
        validate_positive("omega_max", omega_max, "a finite number > 0")
        omega_max = float(omega_max)
    order = _order(fluid, axes)

    shape = tuple(len(v) for v in axes.values())
    total = math.prod(shape)
    size = min(int(chunk_size), 1 << (total - 1).bit_length())  # power of two ≤ chunk_size
    grids = [g.ravel() for g in np.meshgrid(*axes.values(), indexing="ij")]
    names = tuple(axes)
    base = jax.tree_util.tree_map(as_float, (tube, 1.0, fluid))
    outputs = None
    bar = _progress_bar(total, progress)
    for start in range(0, total, size):
        stop = min(start + size, total)
        cols = [np.concatenate([g[start:stop], np.repeat(g[stop - 1], size - (stop - start))])
                for g in grids]  # the last chunk is padded with its last point
        out = _sweep_chunk(tuple(jnp.asarray(c) for c in cols), *base,
                           None if omega_max is None else as_float(omega_max), names, int(n_roots),
                           int(n_layers), order, jac_names, min(int(batch_size), size))
        out = [np.asarray(o)[: stop - start] for o in out]
        if outputs is None:
            outputs = [np.empty((total, *o.shape[1:]), o.dtype) for o in out]
        for buf, o in zip(outputs, out, strict=True):
            buf[start:stop] = o
        bar.update(stop - start)
    bar.close()
    omega, status, alpha = outputs[:3]
    reshape = lambda a: a.reshape(*shape, *a.shape[1:])  # noqa: E731
    return SweepResult(
        axes=axes, omega=reshape(omega), status=reshape(status).astype(np.int32),
        alpha=reshape(alpha),
        jacobian=None if jac_names is None else (
            reshape(outputs[4]) if jac_names else np.empty((*shape, n_roots, 0))),
        jacobian_names=jac_names or (),
        group_velocity=None if jac_names is None else reshape(outputs[3]),
        settings=_settings(tube, fluid, n_roots, omega_max, n_layers),
    )


def _jacobian_names(jacobian, fluid):
    if jacobian is None or jacobian is False:
        return None
    if jacobian is True:
        return tuple(n for n in SENSITIVITY if fluid is not None or n not in FLUID_LEAVES)
    try:
        names = (jacobian,) if isinstance(jacobian, str) else tuple(jacobian)
    except TypeError:
        names = None
    if names is None or not all(isinstance(n, str) for n in names):
        raise ValueError("jacobian must be None, True, a parameter name or a sequence of names, "
                         f"got {jacobian!r}")
    check_names(names, fluid, allow_n=False)
    if "alpha" in names:
        raise ValueError("jacobian: dΩ/dα̂ is the group velocity, returned with every jacobian; "
                         "drop 'alpha' from the names")
    if len(set(names)) != len(names):
        raise ValueError(f"jacobian names repeat: {names}")
    return names


def _order(fluid, axes):
    """The Bessel order: static int, or "n" (the paper's ν = n read from the n axis, traced)."""
    if fluid is None or fluid.coupling == "acoustic":
        return 0
    if fluid.bessel_order is not None:
        return int(fluid.bessel_order)
    if "n" not in axes:
        raise ValueError("the paper coupling with bessel_order=None uses ν = n: sweep over n=... "
                         "(axial mode numbers), or set Fluid(bessel_order=...)")
    n = axes["n"]
    if np.any(n != np.round(n)) or np.any(n < 1):
        raise ValueError(f"n must hold integers >= 1 for the paper coupling (ν = n), got {n}")
    return "n"


def _settings(tube, fluid, n_roots, omega_max, n_layers):
    leaf = lambda x: float(np.asarray(x)) if np.ndim(x) == 0 else np.asarray(x).tolist()  # noqa: E731
    out = {"tube": {k: leaf(getattr(tube, k)) for k in TUBE_LEAVES}, "material": tube.material,
           "n_roots": int(n_roots), "omega_max": omega_max, "n_layers": int(n_layers)}
    if fluid is not None:
        out["fluid"] = {k: leaf(getattr(fluid, k)) for k in FLUID_LEAVES}
        out["coupling"] = fluid.coupling
        out["bessel_order"] = fluid.bessel_order
    return out


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def _progress_bar(total, progress):
    if progress is False:
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="pt", desc="jaxdea sweep", delay=0.0 if progress else 2.0,
                leave=bool(progress))

