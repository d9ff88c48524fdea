"""The static kinds a problem is made of: its mode family and its inner face.

A :class:`Family` picks the state matrix, basis and outer rows (docs/theory/order_m.md §3–§5): the
axisymmetric longitudinal modes (6×6, m = 0), the modes of order m (8×8, m traced) and the torsional
modes (2×2, m = 0). A :class:`Face` is the inner face, read from the fluid: empty, the consistent
acoustic fluid (docs/theory/axisymmetric.md §4(c)) or the paper's coupling (§4(b)).

Both are string enums: hashable, compared by value and printed as their names, so that they serve
as static arguments of the compiled programs exactly as the family names did before them. The
solvers ask them (:attr:`Family.carries_m`, :meth:`Family.safe_m`, :attr:`Face.has_poles`, …)
instead of comparing names.
"""

import enum

import jax.numpy as jnp

from ..params import as_float


class Face(enum.StrEnum):
    """The inner face of the tube, from its fluid (:meth:`of`); the outer face is traction-free."""

    EMPTY = "empty"
    ACOUSTIC = "acoustic"
    PAPER = "paper"

    __repr__ = str.__repr__

    @classmethod
    def of(cls, fluid, strict: bool = True) -> "Face":
        """The face of a :class:`~jaxdea.Fluid` (its static ``coupling``), EMPTY for None.
        ``strict=False`` (a fluid not validated yet): EMPTY where the coupling names no face."""
        if fluid is None:
            return cls.EMPTY
        if not strict and not (isinstance(fluid.coupling, str) and fluid.coupling in {*cls}):
            return cls.EMPTY
        return cls(fluid.coupling)

    @property
    def has_poles(self) -> bool:
        """The paper's coupling (docs/theory/axisymmetric.md §4(b)): f has the poles of B̂_ν in Ω
        (scanned as grid points), ν is its static Bessel order (``bessel_order`` or the axial mode
        number n), and it is axisymmetric (m = 0 only). The empty and acoustic faces (static order 0;
        the acoustic fluid takes m) are smooth in Ω and α̂ (continuation along α̂ applies)."""
        return self is Face.PAPER

    @property
    def has_pressure(self) -> bool:
        """A fluid whose pressure field in the cavity follows from the wall's motion (acoustic)."""
        return self is Face.ACOUSTIC


class Family(enum.StrEnum):
    """The mode family (docs/theory/order_m.md §3): which state matrix, basis and outer rows."""

    LONGITUDINAL = "longitudinal"
    ORDER_M = "order_m"
    TORSIONAL = "torsional"

    __repr__ = str.__repr__  # the programs' cache keys read as before the enum

    @property
    def size(self) -> int:
        """Size of the state vector: 6 (Y = [ū, w̄, Φ, T̄, S̄, D̄]), 8 (Y = [U, V, W, Φ, T, Q, S, D]), 2
        (Y = [V, Q])."""
        return {Family.LONGITUDINAL: 6, Family.ORDER_M: 8, Family.TORSIONAL: 2}[self]

    @property
    def carries_m(self) -> bool:
        """Whether the family's programs take the order m (traced) and the family: every family
        but the longitudinal one, whose 6×6 programs are written in Ω and take neither."""
        return self is not Family.LONGITUDINAL

    @property
    def in_omega_squared(self) -> "Family":
        """The family evaluated in w = Ω² of either sign (growth rates): the longitudinal modes
        through the 8×8 system at m = 0 (docs/theory/order_m.md §6), the others as they are."""
        return Family.ORDER_M if self is Family.LONGITUDINAL else self

    @property
    def reads_m(self) -> bool:
        """Whether the family's state matrix reads the order m (order m; 0 for the others)."""
        return self is Family.ORDER_M

    @property
    def moves_fluid(self) -> bool:
        """Whether the family's modes move an inviscid fluid (a torsional mode, pure shear at the
        face, leaves it at rest)."""
        return self is not Family.TORSIONAL

    @property
    def order_m_rows(self) -> tuple:
        """The rows of the order-m state [U, V, W, Φ, T, Q, S, D] (docs/theory/order_m.md §1) that the
        family's state holds, in its order."""
        return {Family.LONGITUDINAL: (0, 2, 3, 4, 6, 7), Family.ORDER_M: tuple(range(8)),
                Family.TORSIONAL: (1, 5)}[self]

    def arguments(self, m) -> dict:
        """The keywords ``m`` and ``family`` of a program of this family, none for the
        longitudinal one (its programs as before order m existed)."""
        return dict(m=m, family=self) if self.carries_m else {}

    def admissible(self, m, fluid=None):
        """True where a (traced) order m is admissible: a finite integer ≥ 0; 0 for the torsional
        family and for the paper's coupling (an axisymmetric model). Always True for the
        longitudinal family (m is not used there)."""
        if not self.carries_m:
            return jnp.asarray(True)
        m = as_float(m)
        ok = jnp.isfinite(m) & (m >= 0) & (m == jnp.round(m))
        if self is Family.TORSIONAL or Face.of(fluid).has_poles:
            ok &= m == 0
        return ok

    def safe_m(self, m, ok):
        """The order the state matrix is formed with: m where ``ok``, else 0 (order m); 0 for the
        families that do not read it."""
        return jnp.where(ok, as_float(m), 0.0) if self.reads_m else 0.0

    def slowest_shear(self, coef):
        """c_min² over the wall: the shear moduli c − εd² and a, and e = 2W_1λ² off the axisymmetric
        family (θ-shear, docs/theory/order_m.md §2)."""
        shear = jnp.minimum(coef.c - coef.eps * coef.d**2, coef.a)
        return jnp.min(jnp.minimum(shear, coef.e) if self.carries_m else shear)
