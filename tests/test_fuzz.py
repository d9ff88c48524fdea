"""Random and extreme inputs to every public entry point (hypothesis).

The contract (API.md, README "Statuses"): a call gives either

* a ``ValueError`` whose message names an offending parameter (past Gent locking: the message
  states the largest I_1 - 3 in the wall against G), or
* a result: finite where the inputs are valid; functions that return a status may give NaN with a
  status other than CONVERGED, never a number for invalid inputs; every CONVERGED value is checked
  to be what it claims (a sign change of the characteristic function, a point of the static
  response, a round trip of a conversion).

Any other exception (TypeError, IndexError, AttributeError, an error from inside JAX) fails.

Inputs: valid values drawn from the physical ranges in various containers (float, NumPy scalar,
0-d NumPy/JAX array), with up to two parameters replaced by random or extreme floats (±0,
subnormals, ±1e±300, ±max, ±inf, NaN, negatives), wrong types (str, None, lists, complex,
objects) or wrong shapes (1-D and 2-D arrays where a scalar is expected). ``_problems`` is an
independent oracle of which parameters are invalid.

Static arguments (n_roots, n_layers, coupling, along, shapes) are fixed within a test so each entry
point compiles once; the default run uses a few examples per entry point (``SMALL``; the solvers
whose compilation dominates get mostly invalid inputs there, rejected before compiling), ``-m slow``
runs ``LARGE`` each.
"""

import math
import os
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import jaxdea as jd
from jaxdea import units
from jaxdea.params import ALPHA_MIN, GENT_MIN, TINY
from jaxdea.physics.transfer import AUTO_SCHEME, TRACED_LAYERS, Layers, laminate

SMALL = 6
LARGE = int(os.environ.get("JAXDEA_FUZZ_EXAMPLES", "1000"))  # examples per entry point, -m slow
PROFILE = dict(deadline=None, suppress_health_check=list(HealthCheck))
N_LAYERS = 30
TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)

# ------------------------------------------------------------------------------------ strategies
EXTREMES = (0.0, -0.0, 5e-324, -5e-324, 1e-310, 1e-300, -1e-300, 1e300, -1e300,
            1.7976931348623157e308, -1.7976931348623157e308, math.inf, -math.inf, math.nan, -1.0)
JUNK = ("x", "", "0.9", None, 10**400, [0.9, 1.1], (0.9,), np.ones((2, 2)), np.array([0.9, 1.1]), np.ones(3),
        1 + 1j, np.complex128(0.9), object(), {"value": 0.9})
CONTAINERS = (float, np.float64, np.array, jnp.asarray, np.float32)
bad_value = st.one_of(st.sampled_from(EXTREMES), st.floats(allow_nan=True, allow_infinity=True),
                      st.sampled_from(JUNK))
bad_scalar = st.one_of(st.sampled_from(EXTREMES), st.floats(allow_nan=True, allow_infinity=True),
                      st.sampled_from([j for j in JUNK if not isinstance(j, (list, tuple, np.ndarray))]))
# always invalid, whatever the parameter: the default run fuzzes the validation of the solvers whose
# compilation would dominate its time (their valid inputs are fuzzed under -m slow)
ALWAYS_BAD = st.sampled_from([math.nan, math.inf, -math.inf, "x", None, 1j, np.ones((2, 2)), object()])
bad_real = st.one_of(st.sampled_from(EXTREMES), st.floats(allow_nan=True, allow_infinity=True))

TUBE_RANGES = dict(voltage=(-0.25, 0.25), lambda_i=(0.75, 1.25), lambda_z=(0.85, 1.4),
                   eta=(0.6, 0.92), gent=(30.0, 200.0), length_ratio=(2.0, 20.0))
FLUID_RANGES = dict(density_ratio=(0.01, 2.0), speed_ratio=(0.1, 3.0))
TUBE_FIELDS = tuple(TUBE_RANGES)
FLUID_FIELDS = tuple(FLUID_RANGES)
BAD_COUNTS = (0, -1, 2.5, True, "3", None, np.ones(2))


def _is(value, n):
    """value is exactly the int n (not a bool, a float or an array)."""
    return type(value) is int and value == n


@st.composite
def faulty(draw, ranges, max_faults=2, values=bad_value, min_faults=0):
    """Valid values from ``ranges`` (in random containers), ``min_faults`` to ``max_faults`` of them
    replaced by bad ones: a dict name -> value."""
    out = {}
    for name, (lo, hi) in ranges.items():
        x = draw(st.floats(lo, hi))
        out[name] = draw(st.sampled_from(CONTAINERS))(x) if draw(st.booleans()) else x
    broken = draw(st.lists(st.sampled_from(sorted(ranges)), unique=True, min_size=min_faults,
                           max_size=max_faults))
    for name in broken:
        out[name] = draw(values)
    return out


# ---------------------------------------------------------------------------------------- oracle
def _real_array(x):
    """x as a float64 array if it is real (scalar or array), else None."""
    if x is None or isinstance(x, (str, bytes, dict)) or np.iscomplexobj(x):
        return None
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return None


def _scalar(x):
    """x as a Python float if it is a real scalar, else None."""
    a = _real_array(x)
    return float(a) if a is not None and a.ndim == 0 else None


def POSITIVE(a):  # noqa: N802 - a rule, like the entries of RULES
    """Finite and > 0 as XLA sees it (it flushes subnormals to 0)."""
    return np.isfinite(a) & (a >= TINY)


FINITE = np.isfinite
RULES = dict(  # elementwise on float64 arrays
    voltage=FINITE, lambda_i=POSITIVE, lambda_z=POSITIVE, eta=lambda x: (x >= TINY) & (x < 1),
    gent=lambda x: x >= GENT_MIN, length_ratio=POSITIVE, density_ratio=POSITIVE,
    speed_ratio=POSITIVE, alpha=lambda x: np.isfinite(x) & (x >= ALPHA_MIN), omega=FINITE,
    guess=POSITIVE, omega_max=POSITIVE, delta_p=FINITE, h_over_Ri=POSITIVE, stop=POSITIVE,
    max_step=POSITIVE, n=POSITIVE,
)
LOCKING = "Gent locking"
WIDE = "too wide"
WIDTH_MAX = 1e6  # README: λ_z r̂_o² <= 1e6 (rounding of the radii in the stretches <= 2.2e-10)


def width(lambda_i, lambda_z, eta):
    """λ_z r̂_o² = λ_z λ_i² + η⁻² − 1 (inf on overflow), computed independently (elementwise)."""
    lambda_i, lambda_z, eta = (np.asarray(x, dtype=np.float64) for x in (lambda_i, lambda_z, eta))
    with np.errstate(all="ignore"):
        w = lambda_z * lambda_i**2 + 1.0 / eta**2 - 1.0
    return np.where(np.isfinite(w), w, np.inf)


def wall_problems(lambda_i, lambda_z, eta, gent, material="gent"):
    """(problems, ambiguous) of a wall with valid fields: ``WIDE`` past λ_z r̂_o² = WIDTH_MAX,
    ``LOCKING`` past Gent locking; ambiguous within rounding of either limit."""
    bad, ambiguous = set(), False
    w = width(lambda_i, lambda_z, eta)
    if np.any(w > WIDTH_MAX):
        bad.add(WIDE)
    ambiguous |= bool(np.any(np.abs(w - WIDTH_MAX) <= 1e-9 * WIDTH_MAX))
    if material == "gent":
        excess = np.vectorize(gent_excess)(lambda_i, lambda_z, eta)
        if np.any(excess >= gent):
            bad.add(LOCKING)
        with np.errstate(invalid="ignore"):
            ambiguous |= bool(np.any(np.isfinite(gent) & (np.abs(excess - gent) <= 1e-9 * gent)))
    return bad, ambiguous


def gent_excess(lambda_i, lambda_z, eta):
    """max(I_1) - 3 over the two faces of the wall (inf on overflow), computed independently
    (elementwise)."""
    lambda_i, lambda_z, eta = (np.asarray(x, dtype=np.float64) for x in (lambda_i, lambda_z, eta))
    with np.errstate(all="ignore"):
        r_o = np.sqrt(lambda_i**2 + (1.0 / eta**2 - 1.0) / lambda_z)
        i1 = [lam**2 + 1.0 / (lam * lambda_z) ** 2 + lambda_z**2 for lam in (lambda_i, r_o * eta)]
        worst = np.maximum(i1[0], i1[1]) - 3.0
    worst = np.where(np.isfinite(worst), worst, np.inf)
    return float(worst) if worst.ndim == 0 else worst


def _problems(values, material="gent", arrays=False, thickness=True):
    """(set of invalid parameter names, ambiguous): ``WIDE`` and ``LOCKING`` as in
    :func:`wall_problems`; ambiguous within rounding of either limit (either outcome is fine).
    With ``arrays`` real arrays that broadcast together are valid (elementwise helpers); otherwise
    only scalars. With ``thickness`` (concrete calls; traced ones do not check it) an α̂ with
    α̂ĥ > 150 on a valid wall is invalid too (ĥ the deformed thickness)."""
    bad, x = set(), {}
    for name, value in values.items():
        x[name] = _real_array(value) if arrays else _scalar(value)
        with np.errstate(invalid="ignore"):
            if x[name] is None or not np.all(RULES[name](np.asarray(x[name]))):
                bad.add(name)
    if arrays:
        shaped = {k: v for k, v in x.items() if v is not None and np.ndim(v)}
        try:
            np.broadcast_shapes(*(v.shape for v in shaped.values()))
        except ValueError:
            bad |= set(shaped)
    keys = ("lambda_i", "lambda_z", "eta")  # gent: the Tube's default where not drawn
    if all(k in x for k in keys) and not bad & {*keys, "gent"}:
        gent = x.get("gent", jd.Tube().gent)
        wall, ambiguous = wall_problems(*(x[k] for k in keys), gent, material=material)
        if thickness and "alpha" in x and "alpha" not in bad and not wall:
            li, lz, eta = (np.asarray(x[k], dtype=np.float64) for k in keys)
            c = (1.0 / eta**2 - 1.0) / lz
            with np.errstate(over="ignore"):  # α̂ near the float64 maximum: inf, past the limit
                product = np.max(np.asarray(x["alpha"]) * c / (np.sqrt(li**2 + c) + li))
            if product > 150.0:
                bad.add("alpha")
            ambiguous |= bool(abs(product - 150.0) <= 1e-9 * 150.0)
        return bad | wall, ambiguous
    return bad, False


def _names(message, names):
    for name in names:
        pattern = {LOCKING: r"I_1 - 3 must stay below gent = ",
                   WIDE: r"lambda_z \* r_o\*\*2 must be <= "}.get(name, rf"\b{name}\b")
        if re.search(pattern, message):
            return True
    return False


REJECTED = object()


def run(call, problems, ambiguous=False):
    """The result of ``call()``, or REJECTED for a ValueError naming one of ``problems``; a
    ValueError for valid inputs, or one naming none of the problems, fails. Any other exception
    propagates (and fails the test)."""
    try:
        return call()
    except ValueError as exc:
        message = str(exc)
        if ambiguous:
            return REJECTED
        assert problems, f"valid inputs rejected: {message}"
        assert _names(message, problems), f"ValueError names none of {sorted(problems)}: {message}"
        return REJECTED


def solved(call, problems, ambiguous=False):
    """The Roots of a solver call with valid inputs; None when rejected by a ValueError (checked by
    :func:`run`) or when the inputs are invalid (then no status may be CONVERGED)."""
    out = run(call, problems, ambiguous)
    if out is REJECTED:
        return None
    assert_statuses(out.omega, out.status)
    if problems and not ambiguous:
        assert_invalid(out.status)
        return None
    return out


def _fields(values, names):
    return {k: values[k] for k in names if k in values}


def _tube(values, material="gent"):
    return jd.Tube(**_fields(values, TUBE_FIELDS), material=material)


def _valid_tube(values, material="gent"):
    """The tube with float leaves (for the checks that re-evaluate a valid case)."""
    return jd.Tube(**{k: _scalar(values[k]) for k in TUBE_FIELDS}, material=material)


# -------------------------------------------------------------------------------- result checks
def _f(tube, omega, alpha, fluid=None, layers=N_LAYERS):
    return float(jd.characteristic(tube, omega, alpha, fluid, layers))


def assert_root(tube, alpha, omega, fluid=None, what="root", layers=N_LAYERS):
    """omega is a root of the characteristic function on the discretisation ``layers``: a sign
    change across ω(1 ± 1e-7), or |f(ω)| at rounding level against its neighbours at ω(1 ± 1e-4)
    (a touching pair)."""
    lo, hi = (_f(tube, omega * (1 + s * 1e-7), alpha, fluid, layers) for s in (-1, 1))
    if lo * hi <= 0:
        return
    here = abs(_f(tube, omega, alpha, fluid, layers))
    near = max(abs(_f(tube, omega * (1 + s * 1e-4), alpha, fluid, layers)) for s in (-1, 1))
    assert here <= 1e-6 * near, f"{what} {omega!r} is no root: f = {here:.3g}, nearby {near:.3g}"


def assert_no_root_below(tube, alpha, omega, fluid=None, layers=N_LAYERS):
    """No sign change of f on [0, ω): f at 0, ω/4, ω/2, 3ω/4 has one sign (a missed lowest root
    shows up as a flip)."""
    values = [_f(tube, omega * t, alpha, fluid, layers) for t in (0.0, 0.25, 0.5, 0.75)]
    assert all(v != 0 for v in values), f"f vanishes below the first root {omega!r}: {values}"
    assert len({np.sign(v) for v in values}) == 1, \
        f"a root below the first root {omega!r} was missed: f = {values}"


def assert_statuses(omega, status, found=(jd.Status.CONVERGED,)):
    """A value where the status is one of ``found`` (INACCURATE too where the default
    discretisation serves traced inputs), NaN elsewhere."""
    omega, status = np.asarray(omega), np.asarray(status)
    assert omega.shape == status.shape and status.dtype == np.int32
    assert set(np.unique(status)) <= {int(s) for s in jd.Status}
    np.testing.assert_array_equal(np.isfinite(omega), np.isin(status, found))


def assert_roots(tube, alpha, fluid, roots, omega_max=None, complete=True,
                 found=(jd.Status.CONVERGED,), layers=N_LAYERS):
    """Statuses consistent, converged roots ascending, positive, below omega_max, genuine (on the
    discretisation ``layers`` that solved them), and (``complete``) none missed below the first."""
    assert_statuses(roots.omega, roots.status, found)
    omega = np.asarray(roots.omega)
    found = omega[np.isfinite(omega)]
    np.testing.assert_array_equal(np.isfinite(omega), np.arange(omega.size) < found.size)
    assert np.all(found > 0) and np.all(np.diff(found) >= 0), omega
    if omega_max is not None:
        assert np.all(found <= omega_max * (1 + 1e-12)), (omega, omega_max)
    for w in found:
        assert_root(tube, alpha, w, fluid, layers=layers)
    if complete and found.size:
        assert_no_root_below(tube, alpha, found[0], fluid, layers)


def assert_invalid(*statuses):
    for s in statuses:
        assert np.all(np.asarray(s) != jd.Status.CONVERGED), f"invalid input CONVERGED: {s}"


def _moderate(values, *names, limit=50.0):
    """All the named values are real scalars of magnitude <= limit, and the wall is not within 10 %
    of Gent locking: the range where the README promises finite numbers (beyond it the exponential
    of a sublayer or the Bessel integrals may overflow: NaN, status NOT_FINITE)."""
    if not all(abs(_scalar(values[k])) <= limit for k in names if k in values):
        return False
    x = {k: _scalar(values.get(k)) for k in ("lambda_i", "lambda_z", "eta", "gent")}
    if any(v is None for v in x.values()):
        return True
    return gent_excess(x["lambda_i"], x["lambda_z"], x["eta"]) < 0.9 * x["gent"]


def _moderate_fluid(values, fluid_values):
    """The fluid is inside the range of the Bessel integrals (README: χ̂ r̂_i + ν < 472) with
    ρ̂_f, ĉ_f in [1e-6, 1e6] (no overflow of Ω²ρ̂_f or Ω/ĉ_f)."""
    if not fluid_values:
        return True
    rho, c = (_scalar(fluid_values[k]) for k in FLUID_FIELDS)
    w, a, li = (_scalar(values[k]) for k in ("omega", "alpha", "lambda_i"))
    if any(v is None for v in (rho, c, w, a, li)) or not (1e-6 <= rho <= 1e6 and 1e-6 <= c <= 1e6):
        return False
    return math.sqrt(abs((w / c) ** 2 - a**2)) * li < 400


def fuzz(strategy, small=SMALL, small_strategy=None):
    """A check as two tests: ``small`` examples of ``small_strategy`` (default: ``strategy``) in the
    default run (none with ``small=0``), LARGE of ``strategy`` under ``-m slow``.

    The default run is derandomised (the same examples every run, so CI passes or fails on the code,
    not on the draw); the slow tier explores with fresh random examples each time."""
    def make(check):
        @pytest.mark.skipif(small == 0, reason="run with -m slow (compilation dominates)")
        @settings(max_examples=max(small, 1), derandomize=True, **PROFILE)
        @given(strategy if small_strategy is None else small_strategy)
        def test_small(case):
            check(case)

        @pytest.mark.slow
        @settings(max_examples=LARGE, **PROFILE)
        @given(strategy)
        def test_large(case):
            check(case)

        for fn, suffix in ((test_small, ""), (test_large, "_slow")):
            fn.__name__ = fn.__qualname__ = f"test_{check.__name__}{suffix}"
            # one example database entry per test (the wrappers share their source code)
            fn.hypothesis.inner_test._hypothesis_internal_add_digest = fn.__name__.encode()
        return test_small, test_large

    return make


# ------------------------------------------------------------------------------------- fluids
@st.composite
def fluids(draw, kinds=("none", "acoustic", "paper1", "paper_mode", "bad")):
    """(fluid, extra problems, values): None, an acoustic or a paper fluid (ν = 1, explicit or
    inferred from α̂ = α̂_1) with faulty values, or a fluid with a bad static field."""
    kind = draw(st.sampled_from(kinds))
    if kind == "none":
        return None, set(), {}
    values = draw(faulty(FLUID_RANGES, max_faults=1))
    if kind == "bad":
        field, value = draw(st.sampled_from([
            ("coupling", "bogus"), ("coupling", None), ("coupling", 3), ("bessel_order", -1),
            ("bessel_order", 1.5), ("bessel_order", True), ("bessel_order", "1"),
            ("coupling", np.array(["acoustic"])),
        ]))
        base = dict(coupling="paper", bessel_order=1)
        base[field] = value
        return jd.Fluid(**_fields(values, FLUID_FIELDS), **base), {field}, values
    if kind == "acoustic":
        return jd.Fluid(**values), set(), values
    order = 1 if kind == "paper1" else None
    return jd.Fluid(**values, coupling="paper", bessel_order=order), set(), values


def _mode_alpha(values, n=1):
    """α̂ of axial mode n of the tube in ``values`` (float, or None if the tube is not real)."""
    x = {k: _scalar(values[k]) for k in ("eta", "length_ratio", "lambda_z")}
    if any(v is None for v in x.values()):
        return None
    with np.errstate(all="ignore"):
        return float(np.float64(2.0 * math.pi * n) * x["eta"] / (x["length_ratio"] * x["lambda_z"]))


def _paper_mode_problem(fluid, values, alpha):
    """The paper coupling with bessel_order=None needs α̂ to be an integer axial mode."""
    if fluid is None or fluid.coupling != "paper" or fluid.bessel_order is not None:
        return set()
    a = _scalar(alpha)
    x = {k: _scalar(values[k]) for k in ("eta", "length_ratio", "lambda_z")}
    if a is None or any(v is None for v in x.values()):
        return {"alpha"}
    with np.errstate(all="ignore"):
        n = a * x["length_ratio"] * x["lambda_z"] / (2.0 * math.pi * x["eta"])
    if not math.isfinite(n) or abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
        return {"alpha"}
    return set()


# ------------------------------------------------------------------------------ characteristic
@st.composite
def characteristic_cases(draw):
    values = draw(faulty(dict(TUBE_RANGES, omega=(-20.0, 20.0), alpha=(0.01, 10.0))))
    fluid, extra, fluid_values = draw(fluids())
    if fluid is not None and fluid.coupling == "paper" and fluid.bessel_order is None \
            and draw(st.booleans()):
        values["alpha"] = _mode_alpha(values)
    return values, fluid, extra, fluid_values


def characteristic(case):
    values, fluid, extra, fluid_values = case
    problems, ambiguous = _problems({k: values[k] for k in (*TUBE_FIELDS, "alpha", "omega")})
    problems |= extra | _problems(fluid_values)[0]
    if not (problems & {"eta", "length_ratio", "lambda_z"}):
        problems |= _paper_mode_problem(fluid, values, values["alpha"])
    tube = _tube(values)
    out = run(lambda: jd.characteristic(tube, values["omega"], values["alpha"], fluid, N_LAYERS),
              problems, ambiguous)
    if out is REJECTED:
        return
    assert not problems or ambiguous, f"invalid input {problems} accepted: {out}"
    f = float(out)
    if math.isnan(f):
        assert not (_moderate(values, "omega", "alpha", "voltage")
                    and _moderate_fluid(values, fluid_values)), f"NaN for moderate inputs {case}"
        return
    assert abs(f) <= 1.0 + 1e-12
    mirrored = float(jd.characteristic(tube, -_scalar(values["omega"]), values["alpha"], fluid, N_LAYERS))
    np.testing.assert_allclose(mirrored, f, rtol=1e-10, atol=1e-300)  # f is even in Ω


test_characteristic, test_characteristic_slow = fuzz(characteristic_cases())(characteristic)


# ------------------------------------------------------------------------- frequencies (scan)
@st.composite
def frequency_scan_cases(draw):
    ranges = dict(TUBE_RANGES, alpha=(1e-3, 8.0), omega_max=(0.5, 30.0))
    values = draw(faulty(ranges))
    if draw(st.booleans()):
        values["omega_max"] = None
    fluid, extra, fluid_values = draw(fluids(kinds=("none", "acoustic", "bad")))
    statics = {}
    if draw(st.integers(0, 9)) == 0:
        name = draw(st.sampled_from(["n_roots", "n_layers"]))
        # n_layers=None is the automatic count (valid), n_roots=None is not
        bad = [c for c in BAD_COUNTS if not (name == "n_layers" and c is None)]
        statics[name] = draw(st.sampled_from(bad))
    return values, fluid, extra, fluid_values, statics, draw(st.booleans())


def frequency_scan(case):
    values, fluid, extra, fluid_values, statics, wrapper = case
    checked = {k: v for k, v in values.items() if not (k == "omega_max" and v is None)}
    problems, ambiguous = _problems(checked)
    problems |= extra | _problems(fluid_values)[0] | set(statics)
    tube, alpha, omega_max = _tube(values), values["alpha"], values["omega_max"]
    kwargs = dict(n_roots=3, n_layers=N_LAYERS, omega_max=omega_max) | statics
    out = run(lambda: jd.solve_frequencies(tube, alpha, fluid, **kwargs), problems, ambiguous)
    if out is REJECTED:
        return
    if problems and not ambiguous:
        assert_statuses(out.omega, out.status)
        assert_invalid(out.status)
        return
    assert out.omega.shape == (3,)
    assert_roots(_valid_tube(values), _scalar(alpha), fluid, out,
                 None if omega_max is None else _scalar(omega_max))
    if wrapper:
        np.testing.assert_array_equal(jd.frequencies(tube, alpha, fluid, **kwargs), out.omega)


test_frequency_scan, test_frequency_scan_slow = fuzz(frequency_scan_cases())(frequency_scan)


# ---------------------------------------------------------------------- frequency (Newton)
@st.composite
def newton_cases(draw):
    values = draw(faulty(dict(TUBE_RANGES, alpha=(1e-3, 8.0), guess=(0.05, 20.0))))
    return values, draw(st.booleans())


def newton(case):
    values, wrapper = case
    problems, ambiguous = _problems(values)
    tube = _tube(values)
    out = solved(lambda: jd.solve_frequency(tube, values["alpha"], values["guess"], n_layers=N_LAYERS),
                 problems,
                 ambiguous)
    if out is None:
        return
    if out.status == jd.Status.CONVERGED:
        assert float(out.omega) > 0
        assert_root(_valid_tube(values), _scalar(values["alpha"]), float(out.omega))
    if wrapper:
        again = jd.frequency(tube, values["alpha"], values["guess"], n_layers=N_LAYERS)
        np.testing.assert_array_equal(again, out.omega)


test_newton, test_newton_slow = fuzz(newton_cases())(newton)


# -------------------------------------------------------------------------- group velocity
NOT_A_ROOT = object()


def _not_a_root(call, tube, alpha, omega, fluid, values=None, fluid_values=None):
    """``call()``, or NOT_A_ROOT where it refuses ``omega`` as no root; the refusal is checked
    independently: f changes sign nowhere within half the tolerance (5e-5 relative) of omega.
    With the drawn ``values`` (and ``fluid_values``), a refusal where f itself is not finite there
    is accepted beyond the moderate range of the tube or the fluid only (where NaN is allowed)."""
    try:
        return call()
    except ValueError as exc:
        if "is not a root" not in str(exc):
            raise
        with np.errstate(over="ignore"):
            points = [np.float64(omega) * (1 + e) for e in (-5e-5, 5e-5)]
        # an Ω within 5e-5 of the largest float: its neighbourhood overflows (no f to look at)
        ends = [float(jd.characteristic(tube, p, alpha, fluid, N_LAYERS)) if np.isfinite(p) else math.nan
                for p in points]
        if values is not None and not all(map(math.isfinite, ends)):
            at = dict(values, omega=omega)
            assert not (_moderate(at, "omega", "alpha", "voltage") and _moderate_fluid(at, fluid_values)), \
                f"f = {ends} for moderate inputs {at}, fluid {fluid_values}"
            return NOT_A_ROOT
        assert ends[0] * ends[1] > 0, f"a root within 5e-5 of omega = {omega} was refused: {exc}"
        return NOT_A_ROOT


@st.composite
def group_velocity_cases(draw):
    """(values, at_root, k): the tube, α̂ and a drawn Ω; with ``at_root`` (3 in 4) and valid inputs
    Ω is replaced by root k of the tube at α̂ (group_velocity refuses a non-root)."""
    values = draw(faulty(dict(TUBE_RANGES, alpha=(0.01, 8.0), omega=(0.05, 20.0))))
    return values, draw(st.integers(0, 3)) > 0, draw(st.integers(0, 2))


def group_velocity(case):
    values, at_root, k = case
    problems, ambiguous = _problems(values)
    w = _scalar(values["omega"])
    if w is not None and not POSITIVE(w):
        problems.add("omega")  # a root Ω > 0 as XLA sees it (∂f/∂Ω = 0 at Ω = 0)
    tube, alpha, omega = _tube(values), values["alpha"], values["omega"]
    at_root = at_root and not problems and not ambiguous
    if at_root:  # a root (else Ω is almost surely none)
        omega = float(jd.frequencies(tube, alpha, n_roots=3, n_layers=N_LAYERS)[k])
        assume(np.isfinite(omega))
        values = dict(values, omega=omega)
    out = run(lambda: _not_a_root(lambda: jd.group_velocity(tube, alpha, omega, n_layers=N_LAYERS),
                                  tube, alpha, omega, None, values),
              problems, ambiguous)
    if out is REJECTED:
        return
    if out is NOT_A_ROOT:
        assert not at_root, f"the root {omega!r} of jaxdea.frequencies was refused: {values}"
        return
    assert not problems or ambiguous, f"invalid input {problems} accepted: {out}"
    g = float(out)
    if not math.isfinite(g):
        assert not _moderate(values, "omega", "alpha", "voltage"), f"{g} for moderate inputs {values}"
        return
    # dΩ/dα̂ along the branch: central differences of the root that Newton finds from Ω at α̂(1 ± h)
    # (differences of f itself lose the slope in its rounding where f_α is small, e.g. α̂ → 0, where
    # f is even in α̂: 1e-3 off at α̂ = 0.01, the slow tier found)
    t, a, w = _valid_tube(values), _scalar(values["alpha"]), _scalar(values["omega"])
    h = 1e-4
    ends = [jd.solve_frequency(t, a * (1 + s * h), w, n_layers=N_LAYERS) for s in (1, -1)]
    if all(e.status == jd.Status.CONVERGED and abs(float(e.omega) - w) < 1e-2 * w for e in ends):
        slope = (float(ends[0].omega) - float(ends[1].omega)) / (2 * h * a)
        np.testing.assert_allclose(g, slope, rtol=1e-3, atol=1e-9 * w / a)


test_group_velocity, test_group_velocity_slow = fuzz(group_velocity_cases())(group_velocity)


def test_group_velocity_regression_wall_of_radius_ratio_2e17():
    """Found by the slow tier: η = 4.6e-18 (R_o/R_i = 2e17, short of Gent locking: λ at the outer
    face stays near 1) gave NaN, its sublayers far past ‖hM‖∞ = 1.1e4; it is rejected as too wide
    (λ_z r̂_o² ≈ 4.7e34)."""
    group_velocity(({"voltage": 0.1, "lambda_i": 0.9, "lambda_z": 1.2, "eta": 4.6e-18, "gent": 97.2,
                     "length_ratio": 10.0, "alpha": 1.0, "omega": 1.0}, False, 0))


# ----------------------------------------------------------------------- critical voltage(s)
@st.composite
def critical_voltage_cases(draw, bad=bad_value, min_faults=0):
    values = draw(faulty(dict(TUBE_RANGES, alpha=(0.05, 8.0)), values=bad, min_faults=min_faults))
    fluid, extra, fluid_values = draw(fluids(kinds=("none", "acoustic", "bad")))
    return values, fluid, extra, fluid_values, draw(st.booleans())


def assert_critical(tube, alpha, v_cr, layers=N_LAYERS):
    """V̂_cr > 0 is a sign change of f(Ω = 0; V̂) on the discretisation ``layers`` that solved it,
    and f(0; V̂) has one sign on [0, V̂_cr)."""
    assert v_cr > 0
    at = lambda v: _f(tube.replace(voltage=v), 0.0, alpha, None, layers)  # noqa: E731
    assert at(v_cr * (1 - 1e-7)) * at(v_cr * (1 + 1e-7)) <= 0, f"V_cr {v_cr!r} is no sign change"
    below = [at(v_cr * t) for t in (0.0, 0.25, 0.5, 0.75)]
    assert len({np.sign(v) for v in below}) == 1, f"a smaller critical voltage was missed: {below}"


def critical_voltage(case):
    values, fluid, extra, fluid_values, wrapper = case
    problems, ambiguous = _problems(values)
    problems |= extra | _problems(fluid_values)[0]
    tube = _tube(values)
    out = solved(lambda: jd.solve_critical_voltage(tube, values["alpha"], fluid, n_layers=N_LAYERS),
                 problems, ambiguous)
    if out is None:
        return
    if out.status == jd.Status.CONVERGED:
        assert_critical(_valid_tube(values), _scalar(values["alpha"]), float(out.omega))
    if wrapper:
        again = jd.critical_voltage(tube, values["alpha"], fluid, n_layers=N_LAYERS)
        np.testing.assert_array_equal(again, out.omega)


test_critical_voltage, test_critical_voltage_slow = fuzz(
    critical_voltage_cases(), small_strategy=critical_voltage_cases(ALWAYS_BAD, 1))(critical_voltage)


@st.composite
def critical_voltages_cases(draw, bad=bad_value, min_faults=0):
    values = draw(faulty(TUBE_RANGES, values=bad, min_faults=min_faults))
    n_max = 2 if draw(st.integers(0, 7)) else draw(st.sampled_from(BAD_COUNTS))
    return values, n_max, draw(st.booleans())


def critical_voltages(case):
    values, n_max, wrapper = case
    problems, ambiguous = _problems(values)
    if not _is(n_max, 2):
        problems.add("n_max")
    tube = _tube(values)
    out = run(lambda: jd.solve_critical_voltages(tube, n_max, n_layers=N_LAYERS), problems, ambiguous)
    if out is REJECTED:
        return
    assert_statuses(out.omega, out.status)
    assert out.omega.shape == (2,)
    if problems and not ambiguous:
        assert_invalid(out.status)
        return
    for n, (v, s) in enumerate(zip(np.asarray(out.omega), np.asarray(out.status), strict=True), 1):
        if s == jd.Status.CONVERGED:
            assert_critical(_valid_tube(values), _mode_alpha(values, n), float(v))
    if wrapper:
        np.testing.assert_array_equal(jd.critical_voltages(tube, n_max, n_layers=N_LAYERS), out.omega)


test_critical_voltages, test_critical_voltages_slow = fuzz(
    critical_voltages_cases(), small_strategy=critical_voltages_cases(ALWAYS_BAD, 1))(critical_voltages)


# --------------------------------------------------------------------- mode shape, pressure
N_POINTS = 16


@st.composite
def mode_cases(draw):
    values = draw(faulty(dict(TUBE_RANGES, alpha=(0.01, 8.0), omega=(-20.0, 20.0))))
    fluid, extra, fluid_values = draw(fluids(kinds=("none", "acoustic", "acoustic", "bad")))
    n_points = N_POINTS if draw(st.integers(0, 7)) else draw(st.sampled_from(BAD_COUNTS))
    return values, fluid, extra, fluid_values, n_points, draw(st.booleans()), draw(st.booleans())


def mode(case):
    values, fluid, extra, fluid_values, n_points, pressure, at_root = case
    problems, ambiguous = _problems(values)
    problems |= extra | _problems(fluid_values)[0]
    if not _is(n_points, N_POINTS):
        problems.add("n_points")
    tube, alpha, omega = _tube(values), values["alpha"], values["omega"]
    if at_root and not problems and not ambiguous:  # a root (else Ω is almost surely none)
        omega = float(jd.frequencies(tube, alpha, fluid, n_roots=1, n_layers=N_LAYERS)[0])
        assume(np.isfinite(omega))
    if pressure:
        if fluid is None:
            problems.add("fluid")
        elif isinstance(fluid.coupling, str) and fluid.coupling == "paper":
            problems.add("paper")
        out = run(lambda: _not_a_root(lambda: jd.fluid_pressure(tube, alpha, omega, fluid, n_points, N_LAYERS),
                                      tube, alpha, omega, fluid, values, fluid_values), problems, ambiguous)
    else:
        out = run(lambda: _not_a_root(lambda: jd.mode_shape(tube, alpha, omega, fluid, n_points, N_LAYERS),
                                      tube, alpha, omega, fluid, values, fluid_values), problems, ambiguous)
    if out is REJECTED or out is NOT_A_ROOT:
        return
    assert not problems or ambiguous, f"invalid input {problems} accepted"
    r, field = (np.asarray(x) for x in out)
    assert r.shape == (n_points,) and field.shape == ((n_points,) if pressure else (6, n_points))
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(field))):
        assert not (_moderate(values, "omega", "alpha", "voltage", limit=20.0)
                    and _moderate_fluid(values, fluid_values)), \
            f"non-finite fields for moderate inputs {case}"
        return
    li = _scalar(values["lambda_i"])
    assert np.all(np.diff(r) > 0)
    if pressure:
        assert r[0] == 0.0 and r[-1] == pytest.approx(li, rel=1e-14)
    else:
        assert r[0] == pytest.approx(li, rel=1e-14)
        displacement = np.max(np.abs(field[:2]))
        if displacement > 1e-13 * np.max(np.abs(field)):
            assert displacement == pytest.approx(1.0, rel=1e-12)
        else:  # an electrical direction (no displacement, at V̂ = 0): its largest entry is 1
            assert np.max(np.abs(field)) == pytest.approx(1.0, rel=1e-12)


test_mode, test_mode_slow = fuzz(mode_cases())(mode)


# ------------------------------------------------------------------------------ static state
@st.composite
def static_cases(draw):
    which = draw(st.sampled_from(["pressure_difference", "thickness_ratio", "with_thickness_ratio",
                                  "inner_stretch", "pull_in"]))
    # with_thickness_ratio accepts arrays elementwise: its oracle here is for scalars only
    bad = bad_value if which != "with_thickness_ratio" else bad_scalar
    values = draw(faulty(dict(TUBE_RANGES, h_over_Ri=(0.02, 1.0), delta_p=(-0.3, 0.3)), values=bad))
    return values, which


def _excess_after(values):
    """Problems of the tube that with_thickness_ratio returns (η from h/R_i)."""
    li, lz, h = (_scalar(values[k]) for k in ("lambda_i", "lambda_z", "h_over_Ri"))
    with np.errstate(all="ignore"):
        eta = float(1.0 / np.sqrt(1.0 + np.float64(lz) * h * (2.0 * li + h)))
    if not 0 < eta < 1:
        return {"h_over_Ri"}, False
    return _problems({k: values[k] for k in TUBE_FIELDS} | {"eta": eta})


def static(case):
    values, which = case
    tube = _tube(values)
    tube_values = _fields(values, TUBE_FIELDS)
    if which in ("inner_stretch", "pull_in"):  # λ_i (and for pull_in V̂) are ignored: placeholders
        ignored = dict(lambda_i=1.0) | (dict(voltage=0.0) if which == "pull_in" else {})
        problems, ambiguous = _problems(tube_values | ignored | {"delta_p": values["delta_p"]})
        fn = getattr(jd, which)
        out = run(lambda: fn(tube, values["delta_p"]), problems, ambiguous)
        if out is REJECTED:
            return
        *result, status = (np.asarray(x) for x in out)
        for x in result:
            assert_statuses(x, status)
        if problems and not ambiguous:
            assert_invalid(status)
            return
        if status == jd.Status.CONVERGED:  # a point of the static response at ΔP̂
            li = float(result[0])
            voltage = float(result[1]) if which == "pull_in" else _scalar(values["voltage"])
            state = _valid_tube(values).replace(lambda_i=li, voltage=voltage)
            dp = float(jd.pressure_difference(state))
            np.testing.assert_allclose(dp, _scalar(values["delta_p"]), rtol=1e-8, atol=1e-10)
        return
    if which == "with_thickness_ratio":
        problems, ambiguous = _problems(_fields(values, ("lambda_i", "lambda_z", "h_over_Ri")))
        if not problems:
            problems, ambiguous = _excess_after(values)
        out = run(lambda: jd.with_thickness_ratio(tube, values["h_over_Ri"]), problems, ambiguous)
        if out is REJECTED:
            return
        assert not problems or ambiguous, f"invalid input {problems} accepted: {out}"
        assert 0 < float(out.eta) < 1
        h = float(jd.thickness_ratio(out))
        h0, li, lz = (_scalar(values[k]) for k in ("h_over_Ri", "lambda_i", "lambda_z"))
        # η⁻² − 1 = λ_z h (2λ_i + h) carries the thickness: rounding of η is amplified for thin walls
        np.testing.assert_allclose(h, h0, rtol=1e-10 + 4e-16 * (1 + 1 / (lz * h0 * (2 * li + h0))))
        return
    elementwise = which == "thickness_ratio"  # arrays that broadcast are fine there
    problems, ambiguous = _problems(tube_values, arrays=elementwise)
    out = run(lambda: getattr(jd, which)(tube), problems, ambiguous)
    if out is REJECTED:
        return
    assert not problems or ambiguous, f"invalid input {problems} accepted: {out}"
    if elementwise:  # r̂_o = r̂_i + h (compared without the cancellation)
        li, lz, eta = (_real_array(values[k]) for k in ("lambda_i", "lambda_z", "eta"))
        want = np.sqrt(li**2 + (eta**-2 - 1) / lz)
        np.testing.assert_allclose(np.asarray(out) + li, want, rtol=1e-14)
        # one entry per tube: admissibility (NaN where a traced tube is not) involves every field
        shapes = (np.shape(_real_array(values[k])) for k in TUBE_FIELDS if k in values)
        assert np.shape(out) == np.broadcast_shapes(np.shape(want), *shapes)
        return
    x = float(out)
    if not math.isfinite(x):  # V̂² overflows only for absurd voltages
        assert not _moderate(values, "voltage", limit=1e100), f"pressure difference {x} for {values}"


test_static, test_static_slow = fuzz(static_cases())(static)


def test_static_regression_thickness_ratio_of_a_gent_array():
    """Found by the fuzz: a Tube whose only array field is ``gent`` gives one thickness per tube
    (shape (2,)), equal to the closed form of its scalar λ_i, λ_z, η."""
    static(({"voltage": 0.0, "lambda_i": 1.0, "lambda_z": 1.0, "eta": 0.75, "gent": [0.9, 1.1],
             "length_ratio": 2.0, "h_over_Ri": 1.0, "delta_p": 0.0}, "thickness_ratio"))


def test_static_regression_too_wide_tube():
    """Found by the slow tier: λ_i = 6.7e7 (G = 1e300, short of locking) gave ΔP̂ = NaN, r̂_o − r̂_i
    rounding to 0. Such a tube (λ_z r̂_o² = 5.4e15) is rejected as too wide to resolve in float64."""
    for which in ("pressure_difference", "thickness_ratio"):
        static(({"voltage": 0.1, "lambda_i": 6.7e7, "lambda_z": 1.2, "eta": 0.85, "gent": 1e300,
                 "length_ratio": 10.0, "h_over_Ri": 0.5, "delta_p": 0.0}, which))


# ------------------------------------------------------- axial wavenumber, phase velocity
N_VALUES = st.one_of(st.integers(1, 50), st.lists(st.integers(1, 50), min_size=1, max_size=4)
                     .map(np.array), bad_value)


@st.composite
def wavenumber_cases(draw):
    return draw(faulty(TUBE_RANGES, max_faults=1)), draw(N_VALUES)


def axial_wavenumber(case):
    """Elementwise in the tube's leaves and n: the closed form 2nπη/(L/R_o · λ_z), or a ValueError."""
    values, n = case
    problems, ambiguous = _problems(dict(values, n=n), arrays=True)
    out = run(lambda: jd.axial_wavenumber(_tube(values), n), problems, ambiguous)
    if out is REJECTED:
        return
    assert not problems or ambiguous, f"invalid input {problems} accepted: {out}"
    x = {k: _real_array(values[k]) for k in TUBE_FIELDS}
    with np.errstate(over="ignore"):  # n near the float64 maximum: inf in both
        want = 2 * math.pi * np.asarray(n, dtype=np.float64) * x["eta"] / (x["length_ratio"] * x["lambda_z"])
    want = want * np.ones(np.broadcast_shapes(*(v.shape for v in x.values())))  # shape of the tube
    assert np.shape(out) == np.shape(want)
    # below the normal range (n ≈ 1e-308) XLA flushes the subnormal α̂ to 0, never another number
    flushed = (np.abs(want) < TINY) & (np.asarray(out) == 0)
    np.testing.assert_allclose(np.where(flushed, 0.0, out), np.where(flushed, 0.0, want), rtol=1e-14)


test_axial_wavenumber, test_axial_wavenumber_slow = fuzz(wavenumber_cases())(axial_wavenumber)


@pytest.mark.parametrize("gent", [[0.9, 1.1], np.ones((2, 2))])
def test_axial_wavenumber_regression_fields_that_do_not_broadcast(gent):
    """Found by the slow fuzz: a Tube field that does not broadcast with n (here ``gent``, which
    enters only the admissibility) gives a ValueError naming both, not JAX's shape error."""
    axial_wavenumber(({"voltage": 0.0, "lambda_i": 1.0, "lambda_z": 1.0, "eta": 0.75, "gent": gent,
                       "length_ratio": 2.0}, np.array([1, 1, 1])))


@st.composite
def phase_velocity_cases(draw):
    omega = draw(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                           st.lists(st.floats(0, 50) | st.just(math.nan), min_size=1, max_size=3)
                           .map(np.array), bad_value))
    return omega, draw(st.floats(1e-6, 1e3) | bad_value)


def phase_velocity(case):
    """Ω/α̂ elementwise (NaN-padded roots stay NaN), or a ValueError naming Ω (±inf, not real) or α̂
    (not finite and > 0)."""
    omega, alpha = case
    problems = set()
    w, a = _real_array(omega), _real_array(alpha)
    if w is None or np.any(np.isinf(w)):
        problems.add("omega")
    if a is None or not np.all(POSITIVE(a)):
        problems.add("alpha")
    if not problems:
        try:
            np.broadcast_shapes(w.shape, a.shape)
        except ValueError:
            problems |= {"omega", "alpha"}
    out = run(lambda: jd.phase_velocity(omega, alpha), problems)
    if out is REJECTED:
        return
    assert not problems, f"invalid input {problems} accepted: {out}"
    with np.errstate(over="ignore", under="ignore"):  # ±inf and 0 in both
        want = np.where(np.abs(w) < TINY, 0.0, w) / a  # XLA flushes a subnormal Ω to 0
    assert np.shape(out) == np.shape(want)
    # XLA flushes subnormal results to 0
    np.testing.assert_array_equal(np.asarray(out), np.where(np.abs(want) < TINY, 0.0, want))


test_phase_velocity, test_phase_velocity_slow = fuzz(phase_velocity_cases())(phase_velocity)


# -------------------------------------------------------------------------------------- sweep
@st.composite
def sweep_cases(draw, bad=bad_value, min_faults=0):
    fixed = {k: v for k, v in TUBE_RANGES.items() if k != "voltage" or not min_faults}  # V̂: an axis
    values = dict(voltage=0.0) | draw(faulty(fixed, max_faults=1, values=bad, min_faults=min_faults))
    axis = lambda lo, hi: st.lists(st.floats(lo, hi) | bad_real, min_size=2, max_size=2)  # noqa: E731
    axes = dict(alpha=draw(axis(0.05, 5.0)), voltage=draw(axis(-0.25, 0.25)))
    problems = set()
    if draw(st.integers(0, 5)) == 0:  # an axis of the wrong type or shape
        name = draw(st.sampled_from(sorted(axes)))
        axes[name] = draw(st.sampled_from(["x", [0.1, "x"], [0.1, 1j], np.ones((2, 2)), [], None]))
        problems.add(name)
    settings_ = {}
    if draw(st.integers(0, 7)) == 0:
        name, value = draw(st.sampled_from([
            ("omega_max", -1.0), ("omega_max", math.nan), ("omega_max", "x"), ("omega_max", [1.0]),
            ("chunk_size", 0), ("chunk_size", 2.5), ("n_roots", True), ("jacobian", 1.5),
            ("jacobian", ["alpha"]), ("jacobian", [1, 2]), ("progress", "yes"),
            ("batch_size", -1)]))
        settings_[name] = value
        problems.add(name)
    return values, axes, settings_, problems


def sweep(case):
    """Tiny fixed grid (2 × 2, chunk 4): one compilation. Values are not validated point by point:
    an invalid point must give NaN and status INVALID, a valid one verified roots."""
    values, axes, settings_, problems = case
    for name in TUBE_FIELDS:
        if name != "voltage" and _scalar(values[name]) is None:
            problems.add(name)  # the fixed fields must be real scalars
    kwargs = dict(n_roots=2, chunk_size=4, progress=False, n_layers=N_LAYERS) | settings_
    out = run(lambda: jd.sweep(_tube(values), **kwargs, **axes), problems)
    if out is REJECTED:
        return
    assert not problems, f"bad arguments {problems} accepted"
    assert out.omega.shape == (2, 2, 2)
    for i, a in enumerate(axes["alpha"]):
        for j, v in enumerate(axes["voltage"]):
            point = dict(_fields(values, TUBE_FIELDS), voltage=v)
            bad, ambiguous = _problems(point | {"alpha": a}, thickness=False)
            omega, status = out.omega[i, j], out.status[i, j]
            assert_statuses(omega, status)
            if ambiguous:
                continue
            if bad:
                assert np.all(status == jd.Status.INVALID), (point, a, status)
                continue
            assert out.alpha[i, j] == a
            roots = jd.Roots(omega, status)
            assert_roots(_valid_tube(point), a, None, roots)


test_sweep, test_sweep_slow = fuzz(
    sweep_cases(), small_strategy=sweep_cases(ALWAYS_BAD, 1))(sweep)


# ------------------------------------------------------------------------------ trace_branch
@st.composite
def trace_cases(draw, bad=bad_value, min_faults=0):
    ranges = dict(TUBE_RANGES, alpha=(0.1, 3.0), omega=(0.1, 5.0), stop=(0.1, 3.0),
                  max_step=(0.05, 0.5))
    values = draw(faulty(ranges, values=bad, min_faults=min_faults))
    statics = {}
    if draw(st.integers(0, 7)) == 0:
        statics = dict([draw(st.sampled_from([
            ("along", "n"), ("along", "bogus"), ("along", 3), ("along", None),
            ("max_points", 1), ("max_points", 2.5), ("max_points", True), ("max_points", "16")]))])
    return values, statics


def trace(case):
    values, statics = case
    # max_step=None is trace_branch's default (the automatic step), not a bad value
    problems, ambiguous = _problems({k: v for k, v in values.items()
                                     if not (k == "max_step" and v is None)})
    omega = _scalar(values["omega"])
    if omega is not None and not POSITIVE(np.asarray(omega)):  # a root Ω_0 > 0 (docstring)
        problems.add("omega")
    problems |= set(statics)
    stop = _scalar(values["stop"])
    if statics.get("along", "alpha") == "alpha" and stop is not None and not RULES["alpha"](stop):
        problems.add("stop")  # along α̂, stop is an α̂ too (>= ALPHA_MIN)
    if "alpha" in problems or "stop" in problems:  # messages: "stop ... outside the range of 'alpha'"
        problems |= {"alpha", "stop"}
    kwargs = dict(along="alpha", max_points=16, n_layers=N_LAYERS) | statics
    tube = _tube(values)
    out = run(lambda: jd.trace_branch(tube, values["alpha"], values["omega"], stop=values["stop"],
                                      max_step=values["max_step"], **kwargs), problems, ambiguous)
    if out is REJECTED:
        return
    assert not problems or ambiguous, f"invalid input {problems} accepted"
    b = jax.tree_util.tree_map(np.asarray, out)
    n = int(b.n_points)
    assert int(b.status) in {int(s) for s in jd.BranchEnd} and 0 <= n <= 16
    assert (n == 0) == (b.status == jd.BranchEnd.NO_START)
    for arr in (b.parameter, b.omega):
        assert np.all(np.isfinite(arr[:n])) and np.all(np.isnan(arr[n:]))
    if n == 0:
        return
    s0, stop = _scalar(values["alpha"]), _scalar(values["stop"])
    assert b.parameter[0] == s0
    assert np.all(np.diff(b.parameter[:n]) * np.sign(stop - s0) >= 0), b.parameter[:n]
    if b.status == jd.BranchEnd.REACHED_STOP:
        assert b.parameter[n - 1] == stop and b.event_parameter == stop
    events = b.status in (jd.BranchEnd.TURNING_POINT, jd.BranchEnd.ZERO_FREQUENCY)
    t = _valid_tube(values)
    for k in range(n - 1 if events else n):
        assert_root(t, float(b.parameter[k]), float(b.omega[k]), what=f"trace point {k}")


test_trace, test_trace_slow = fuzz(
    trace_cases(), small_strategy=trace_cases(ALWAYS_BAD, 1))(trace)


def test_trace_regression_start_at_zero_frequency():
    """Found by the slow fuzz: Ω_0 = 0 is outside trace_branch's range (a root Ω_0 > 0), so the
    ValueError may name omega (here next to a bad max_step)."""
    trace(({"voltage": 0.0, "lambda_i": 1.0, "lambda_z": 1.0, "eta": 0.75, "gent": 30.0,
            "length_ratio": 2.0, "alpha": 1.0, "omega": 0.0, "stop": 1.0, "max_step": 0.0}, {}))


# -------------------------------------------------------------------------------------- units
SCALE_RANGES = dict(shear_modulus=(1e3, 1e7), density=(500.0, 2000.0), permittivity=(1e-12, 1e-9),
                    inner_radius=(1e-4, 1e-1))
SCALE_FIELDS = tuple(SCALE_RANGES)
CONVERSIONS = {  # method: (argument name, reference from (x, μ, ρ, ε, R))
    "length_to_si": ("length", lambda x, mu, rho, eps, r: x * r),
    "length_from_si": ("length", lambda x, mu, rho, eps, r: x / r),
    "omega_to_si": ("omega", lambda x, mu, rho, eps, r: x / (r / np.sqrt(mu / rho))),
    "omega_from_si": ("omega", lambda x, mu, rho, eps, r: x * (r / np.sqrt(mu / rho))),
    "omega_to_hz": ("omega", lambda x, mu, rho, eps, r: x / (r / np.sqrt(mu / rho)) / (2 * np.pi)),
    "hz_to_omega": ("frequency", lambda x, mu, rho, eps, r: 2 * np.pi * x * (r / np.sqrt(mu / rho))),
    "wavenumber_to_si": ("alpha", lambda x, mu, rho, eps, r: x / r),
    "wavenumber_from_si": ("alpha", lambda x, mu, rho, eps, r: x * r),
    "wavelength_to_si": ("alpha", lambda x, mu, rho, eps, r: 2 * np.pi / (x / r)),
    "wavelength_from_si": ("wavelength", lambda x, mu, rho, eps, r: 2 * np.pi * r / x),
    "speed_to_si": ("speed", lambda x, mu, rho, eps, r: x * np.sqrt(mu / rho)),
    "speed_from_si": ("speed", lambda x, mu, rho, eps, r: x / np.sqrt(mu / rho)),
    "pressure_to_si": ("pressure", lambda x, mu, rho, eps, r: x * mu),
    "pressure_from_si": ("pressure", lambda x, mu, rho, eps, r: x / mu),
    "voltage_to_si": ("voltage", lambda x, mu, rho, eps, r: x * (r * np.sqrt(mu / eps))),
    "voltage_from_si": ("voltage", lambda x, mu, rho, eps, r: x / (r * np.sqrt(mu / eps))),
    "displacement_field_to_si": ("displacement", lambda x, mu, rho, eps, r: x * np.sqrt(mu * eps)),
    "displacement_field_from_si": ("displacement",
                                   lambda x, mu, rho, eps, r: x / np.sqrt(mu * eps)),
}
RECIPROCAL = ("wavelength_to_si", "wavelength_from_si")


def _in_range(a):
    """|a| is 0 or within 1e±290 (a conversion's scale factors keep it inside the normal range)."""
    a = np.abs(np.asarray(a, dtype=np.float64))
    with np.errstate(invalid="ignore"):
        return (a == 0) | ((a >= 1e-290) & (a <= 1e290))


def _array_problems(values, rules):
    """Elementwise oracle for the functions that accept arrays (Scales, the SI constructors)."""
    bad, arrays = set(), {}
    for name, value in values.items():
        a = _real_array(value)
        with np.errstate(invalid="ignore"):
            if a is None or not np.all(rules[name](a)):
                bad.add(name)
            else:
                arrays[name] = a
    try:
        np.broadcast_shapes(*(a.shape for a in arrays.values()))
    except ValueError:
        bad |= set(arrays)
    return bad, arrays


ARRAY_VALUES = st.sampled_from([np.array([1.0, 2.0]), np.array([[1.0], [3.0]]), np.ones(3)])


@st.composite
def unit_cases(draw):
    scales = draw(faulty(SCALE_RANGES, max_faults=1,
                         values=bad_value | ARRAY_VALUES.map(lambda a: a * 1e-3)))
    method = draw(st.sampled_from(sorted(CONVERSIONS)))
    x = draw(st.floats(-1e3, 1e3) | bad_value | ARRAY_VALUES)
    return scales, method, x


def unit_conversion(case):
    """ValueError naming a scale or the argument, or exactly the reference scaling (NaN and ±inf
    pass through the linear conversions; the reciprocal ones need > 0 or NaN)."""
    values, method, x = case
    problems, scales = _array_problems(values, dict.fromkeys(SCALE_FIELDS, POSITIVE))
    name, reference = CONVERSIONS[method]
    xa = _real_array(x)
    if xa is None:
        problems.add(name)
    elif method in RECIPROCAL:
        with np.errstate(invalid="ignore"):
            if not np.all(np.isnan(xa) | (np.isfinite(xa) & (xa >= TINY))):
                problems.add(name)
    if not problems:
        try:
            np.broadcast_shapes(xa.shape, *(a.shape for a in scales.values()))
        except ValueError:
            problems.add(name)
    s = units.Scales(**values)
    out = run(lambda: getattr(s, method)(x), problems)
    if out is REJECTED:
        return
    assert not problems, f"invalid input {problems} accepted: {out}"
    with np.errstate(all="ignore"):
        want = reference(xa, *(scales[k] for k in SCALE_FIELDS))
    out = np.asarray(out)
    assert out.dtype == np.float64 and out.shape == np.shape(want)
    exact = _in_range(xa) & np.isfinite(want) & _in_range(want)
    np.testing.assert_allclose(out[exact], want[exact], rtol=1e-13, atol=0)
    # near the ends of the float64 range a scaling may over- or underflow (XLA flushes subnormals
    # to 0): then 0 or ±inf, never a different finite number
    wrong = ~exact & np.isfinite(out) & (out != 0) & ~np.isnan(want)
    assert not np.any(wrong & ~np.isclose(out, want, rtol=1e-13, atol=0)), (out, want)


test_unit_conversion, test_unit_conversion_slow = fuzz(unit_cases())(unit_conversion)


SI_RANGES = dict(outer_radius=(6e-3, 2e-2), length=(1e-2, 1.0), voltage=(-2e4, 2e4),
                 lambda_i=(0.75, 1.25), lambda_z=(0.85, 1.4), gent=(30.0, 200.0))
SI_RULES = dict(outer_radius=POSITIVE, length=POSITIVE, voltage=np.isfinite, lambda_i=POSITIVE,
                lambda_z=POSITIVE, gent=lambda a: a >= 1e-6)
VHB = units.Scales(shear_modulus=20e3, density=960.0, permittivity=4.7 * units.VACUUM_PERMITTIVITY,
                   inner_radius=5e-3)


@st.composite
def constructor_cases(draw):
    values = draw(faulty(SI_RANGES, values=bad_value | ARRAY_VALUES.map(lambda a: a * 1e-2 + 6e-3)))
    material = draw(st.sampled_from(["gent", "gent", "neo_hookean", "mooney", None, 3]))
    fluid = draw(faulty(dict(fluid_density=(1.0, 2000.0), sound_speed=(300.0, 2000.0)),
                        max_faults=1))
    coupling = draw(st.sampled_from(["acoustic", "paper", "bogus", None]))
    return values, material, fluid, coupling


def si_constructors(case):
    values, material, fluid_values, coupling = case
    # lambda_i=None is tube_from_si's default, the unstretched inner face (valid)
    problems, arrays = _array_problems(
        {k: 1.0 if k == "lambda_i" and v is None else v for k, v in values.items()}, SI_RULES)
    good_material = isinstance(material, str) and material in ("gent", "neo_hookean")
    ambiguous = False
    given_arrays = arrays
    if not problems:  # the geometry, whatever the material (either error may come first)
        arrays = dict(zip(arrays, np.broadcast_arrays(*arrays.values()), strict=True))
        with np.errstate(all="ignore"):
            if np.any(arrays["outer_radius"] <= VHB.inner_radius):
                problems.add("outer_radius")
            else:
                ratio = arrays["length"] / arrays["outer_radius"]
                if not np.all(np.isfinite(ratio) & (ratio >= TINY)):
                    problems |= {"length", "outer_radius"}
                if np.any(VHB.inner_radius / arrays["outer_radius"] < TINY):
                    problems |= {"inner_radius", "outer_radius"}
            if not problems and good_material:
                eta = VHB.inner_radius / arrays["outer_radius"]
                wall, ambiguous = wall_problems(arrays["lambda_i"], arrays["lambda_z"], eta,
                                                arrays["gent"], material)
                problems |= wall
    if not good_material:
        problems.add("material")
    out = run(lambda: units.tube_from_si(VHB, **values, material=material), problems, ambiguous)
    if out is not REJECTED:
        assert not problems or ambiguous, f"invalid input {problems} accepted: {out}"
        back = units.tube_to_si(VHB, out)
        for name in ("outer_radius", "length", "voltage", "lambda_i", "lambda_z", "gent"):
            given = np.broadcast_to(given_arrays[name], np.shape(getattr(back, name)))
            exact = _in_range(given)  # beyond, the scalings may over- or underflow (0 or inf)
            np.testing.assert_allclose(np.asarray(getattr(back, name))[exact], given[exact],
                                       rtol=1e-12, err_msg=name)
    rules = dict(fluid_density=POSITIVE, sound_speed=POSITIVE)
    problems, arrays = _array_problems(fluid_values, rules)
    if not problems:
        with np.errstate(all="ignore"):
            for name, ratio in (("fluid_density", arrays["fluid_density"] / VHB.density),
                                ("sound_speed", arrays["sound_speed"] / float(VHB.shear_speed))):
                if not np.all(np.isfinite(ratio) & (ratio >= TINY)):
                    problems.add(name)
    if coupling not in ("acoustic", "paper"):
        problems.add("coupling")
    out = run(lambda: units.fluid_from_si(VHB, **fluid_values, coupling=coupling), problems)
    if out is not REJECTED:
        assert not problems, f"invalid input {problems} accepted: {out}"
        back = units.fluid_to_si(VHB, out)
        for name in ("fluid_density", "sound_speed"):
            got = np.asarray(getattr(back, name))
            given = np.broadcast_to(arrays[name], got.shape)
            exact = _in_range(given)
            np.testing.assert_allclose(got[exact], given[exact], rtol=1e-13, err_msg=name)


test_si_constructors, test_si_constructors_slow = fuzz(constructor_cases())(si_constructors)


def test_units_reject_wrong_objects():
    for call, name in [
        (lambda: units.tube_from_si("vhb", 0.01, 0.1), "scales"),
        (lambda: units.fluid_from_si(None, 1000.0, 1480.0), "scales"),
        (lambda: units.tube_to_si(VHB, "tube"), "tube"),
        (lambda: units.fluid_to_si(VHB, None), "fluid"),
        (lambda: units.tube_to_si(VHB, jd.Tube(lambda_i=3.0, gent=2.0)), "I_1 - 3"),
        (lambda: units.Scales(np.ones(2), 960.0, np.ones(3), 5e-3).voltage_scale, "permittivity"),
    ]:
        with pytest.raises(ValueError, match=re.escape(name)):
            call()


# ----------------------------------------------------------------- traced inputs (jit / vmap)
BATCH = 4


@st.composite
def batch_cases(draw):
    """A batch of tubes (and α̂) whose values are valid or bad reals (NaN, ±inf, negative, ...)."""
    rows = [draw(faulty(dict(TUBE_RANGES, alpha=(0.05, 5.0)), values=bad_real)) for _ in range(BATCH)]
    return {k: np.array([_scalar(r[k]) for r in rows]) for k in rows[0]}


def traced(columns):
    """Under vmap nothing raises and nothing is validated: invalid rows give NaN (status INVALID),
    valid rows the same checks as a concrete call."""
    tubes = jd.Tube(**{k: jnp.asarray(columns[k]) for k in TUBE_FIELDS})
    alpha = jnp.asarray(columns["alpha"])
    roots = jax.vmap(jd.solve_frequencies)(tubes, alpha)
    cv = jax.vmap(jd.solve_critical_voltage)(tubes, alpha)
    dp = jax.vmap(jd.pressure_difference)(tubes)
    h = jax.vmap(jd.thickness_ratio)(tubes)
    stretch, status = jax.vmap(jd.inner_stretch)(tubes, jnp.zeros(BATCH))
    _, fields = jax.vmap(lambda t, a: jd.mode_shape(t, a, 1.0, n_points=N_POINTS))(tubes, alpha)
    for i in range(BATCH):
        row = {k: float(columns[k][i]) for k in columns}
        bad, ambiguous = _problems(row, thickness=False)
        tube_bad, _ = _problems(_fields(row, TUBE_FIELDS))
        if ambiguous:
            continue
        if tube_bad:  # the static state alone
            assert np.isnan(dp[i]) and np.isnan(h[i]), (row, dp[i], h[i])
        placeholder, _ = _problems(_fields(row, TUBE_FIELDS) | dict(lambda_i=1.0))
        if placeholder:  # inner_stretch ignores λ_i
            assert status[i] == jd.Status.INVALID and np.isnan(stretch[i])
        cv_bad, _ = _problems(row | dict(voltage=0.0), thickness=False)  # the critical voltage ignores V̂
        if cv_bad:
            assert cv.status[i] == jd.Status.INVALID and np.isnan(cv.omega[i])
        if bad:
            assert np.all(np.asarray(roots.status[i]) == jd.Status.INVALID)
            assert np.all(np.isnan(np.asarray(roots.omega[i])))
            assert np.all(np.isnan(np.asarray(fields[i])))
            continue
        t, a = _valid_tube(row), row["alpha"]
        # the default discretisation of traced inputs (N = 16): its roots are INACCURATE exactly
        # where the rule would give the point alone more sublayers
        short = laminate(None, None, t, a).count > TRACED_LAYERS
        found = np.asarray(roots.omega[i])[np.isfinite(np.asarray(roots.omega[i]))]
        expected = jd.Status.INACCURATE if short else jd.Status.CONVERGED
        assert np.all(np.asarray(roots.status[i])[: found.size] == expected), (row, roots.status[i])
        # checked on the discretisation that solved them (a root of N = 16 graded sixth-order
        # Magnus is 1e-8 from the exact one, not a sign change of the N = 30 midpoint wall)
        assert_roots(t, a, None, jd.Roots(roots.omega[i], roots.status[i]),
                     found=(jd.Status.CONVERGED, jd.Status.INACCURATE),
                     layers=Layers(TRACED_LAYERS, AUTO_SCHEME, True))
        if cv.status[i] == jd.Status.CONVERGED:
            assert_critical(t, a, float(cv.omega[i]), Layers(TRACED_LAYERS, AUTO_SCHEME, True))
        if _moderate(row, "voltage", limit=1e100):
            assert np.isfinite(dp[i])
        assert np.isfinite(h[i])


test_traced, test_traced_slow = fuzz(batch_cases(), small=0)(traced)


# ---------------------------------------------------------------- Gent locking, everywhere
@st.composite
def locked_tubes(draw):
    """A wall past Gent locking: G drawn below max(I_1) - 3 (by at least 1e-6 relative)."""
    li, lz, eta = draw(st.floats(0.3, 4.0)), draw(st.floats(0.4, 3.0)), draw(st.floats(0.2, 0.95))
    excess = gent_excess(li, lz, eta)
    assume(excess > 1e-3)
    gent = excess * draw(st.floats(1e-3, 1 - 1e-6))
    return jd.Tube(voltage=0.1, lambda_i=li, lambda_z=lz, eta=eta, gent=gent), excess


LOCKED_CALLS = {
    "characteristic": lambda t: jd.characteristic(t, 1.0, 0.445),
    "frequencies": lambda t: jd.frequencies(t, 0.445),
    "solve_frequencies": lambda t: jd.solve_frequencies(t, 0.445),
    "frequency": lambda t: jd.frequency(t, 0.445, 0.7),
    "solve_frequency": lambda t: jd.solve_frequency(t, 0.445, 0.7),
    "group_velocity": lambda t: jd.group_velocity(t, 0.445, 0.7),
    "critical_voltage": lambda t: jd.critical_voltage(t, 0.445),
    "solve_critical_voltage": lambda t: jd.solve_critical_voltage(t, 0.445),
    "critical_voltages": lambda t: jd.critical_voltages(t, 2),
    "solve_critical_voltages": lambda t: jd.solve_critical_voltages(t, 2),
    "mode_shape": lambda t: jd.mode_shape(t, 0.445, 0.7),
    "fluid_pressure": lambda t: jd.fluid_pressure(t, 0.445, 0.7, jd.Fluid()),
    "pressure_difference": jd.pressure_difference,
    "thickness_ratio": jd.thickness_ratio,
    "with_thickness_ratio": lambda t: jd.with_thickness_ratio(t, float(jd.thickness_ratio(
        t.replace(gent=jnp.inf)))),
    "trace_branch": lambda t: jd.trace_branch(t, 0.445, 0.7, stop=0.6),
    "tube_to_si": lambda t: units.tube_to_si(VHB, t),
    "tube_from_si": lambda t: units.tube_from_si(
        VHB, VHB.inner_radius / float(t.eta), 0.1, lambda_i=t.lambda_i, lambda_z=t.lambda_z,
        gent=t.gent),
}
LOCK_MESSAGE = re.compile(r"I_1 - 3 must stay below gent = (\S+) everywhere in the wall, but "
                          r"reaches (\S+)")


def locked(case):
    """Every entry point taking a tube rejects a wall past Gent locking, and the message states the
    largest I_1 - 3 against G (the numbers are checked)."""
    tube, excess = case
    for name, call in LOCKED_CALLS.items():
        with pytest.raises(ValueError, match=LOCK_MESSAGE) as info:
            call(tube)
        gent, reached = LOCK_MESSAGE.search(str(info.value)).groups()
        assert float(gent) == float(tube.gent), (name, str(info.value))
        assert float(reached) == pytest.approx(excess, rel=1e-5), (name, str(info.value))
    # inner_stretch and pull_in solve for λ_i: locked at their placeholder λ_i = 1 only
    at_one = gent_excess(1.0, float(tube.lambda_z), float(tube.eta))
    if at_one >= float(tube.gent) * (1 + 1e-9):
        for fn in (jd.inner_stretch, jd.pull_in):
            with pytest.raises(ValueError, match=LOCK_MESSAGE):
                fn(tube, 0.0)


test_locked, test_locked_slow = fuzz(locked_tubes(), small=10)(locked)


@pytest.mark.parametrize("along, stop", [("lambda_i", 12.0), ("gent", 0.05), ("lambda_z", 12.0)])
def test_trace_towards_a_locked_wall_is_refused(along, stop):
    with pytest.raises(ValueError, match=LOCK_MESSAGE) as info:
        jd.trace_branch(TUBE, 0.445, 0.7, along=along, stop=stop)
    assert f"stop = {stop!r}" in str(info.value)


def test_invalid_points_of_a_sweep_are_invalid():
    """Sweeps do not raise on values: a locked point or α̂ below ALPHA_MIN gives NaN and status
    INVALID, the other points their roots."""
    res = jd.sweep(jd.Tube(lambda_z=1.2), lambda_i=[1.0, 12.0], alpha=[0.445, ALPHA_MIN / 10],
                   n_roots=2, chunk_size=4, batch_size=1, progress=False,
                   n_layers=N_LAYERS)  # as in test_determinism
    valid = np.array([[True, False], [False, False]])
    assert np.all(res.status[~valid] == jd.Status.INVALID) and np.all(np.isnan(res.omega[~valid]))
    assert np.all(res.status[0, 0] == jd.Status.CONVERGED)
    assert_roots(jd.Tube(lambda_z=1.2), 0.445, None, jd.Roots(res.omega[0, 0], res.status[0, 0]))


# ------------------------------------------------------------- arguments validated everywhere
NOT_A_NUMBER = [math.nan, math.inf, -math.inf, None, "x", 1j, [1.0, 2.0], np.ones((2, 2))]


@pytest.mark.parametrize("omega", NOT_A_NUMBER, ids=repr)
def test_characteristic_validates_omega(omega):
    with pytest.raises(ValueError, match=r"\bomega\b"):
        jd.characteristic(TUBE, omega, 0.445)


@pytest.mark.parametrize("omega", [*NOT_A_NUMBER, 0.0, -0.0, -0.7], ids=repr)
def test_group_velocity_validates_omega(omega):
    with pytest.raises(ValueError, match=r"\bomega\b"):
        jd.group_velocity(TUBE, 0.445, omega)


@pytest.mark.parametrize("call, name", [
    (lambda: jd.axial_wavenumber("tube", 1), "tube"),
    (lambda: jd.axial_wavenumber(TUBE.replace(eta=2.0), 1), "eta"),
    (lambda: jd.axial_wavenumber(TUBE.replace(lambda_z=-1.0), 1), "lambda_z"),
    (lambda: jd.axial_wavenumber(TUBE.replace(lambda_i=3.0, gent=2.0), 1), "I_1 - 3"),
    (lambda: jd.axial_wavenumber(TUBE, -1), "n"),
    (lambda: jd.axial_wavenumber(TUBE, math.nan), "n"),
    (lambda: jd.axial_wavenumber(TUBE, 1j), "n"),
    (lambda: jd.axial_wavenumber(TUBE.replace(eta=np.array([0.8, 0.85])), np.arange(1, 4)), "eta (2,)"),
    (lambda: jd.phase_velocity(1.0, 0.0), "alpha"),
    (lambda: jd.phase_velocity(1.0, -1.0), "alpha"),
    (lambda: jd.phase_velocity(1.0, 5e-324), "subnormal"),
    (lambda: jd.phase_velocity(math.inf, 1.0), "omega"),
    (lambda: jd.phase_velocity("x", 1.0), "omega"),
    (lambda: jd.phase_velocity(np.ones(2), np.ones(3)), "omega (2,)"),
], ids=["not-a-tube", "eta", "lambda_z", "locked", "n<0", "n-nan", "n-complex", "n-shape",
        "alpha-0", "alpha<0", "alpha-subnormal", "omega-inf", "omega-str", "shapes"])
def test_conversions_validate(call, name):
    with pytest.raises(ValueError, match=re.escape(name)):
        call()


def test_conversions_traced_bad_values_give_nan():
    """Under jit nothing is validated: invalid values give NaN, valid ones the closed forms."""
    alpha = jax.jit(jd.axial_wavenumber)(jd.Tube(eta=jnp.array([0.85, 1.5, 0.5]), lambda_z=1.25),
                                         jnp.array([2.0, 1.0, -1.0]))
    np.testing.assert_allclose(alpha, [2 * math.pi * 2 * 0.85 / 12.5, np.nan, np.nan], rtol=1e-15)
    speed = jax.jit(jd.phase_velocity)(jnp.array([1.0, 1.0, jnp.inf, jnp.nan]),
                                       jnp.array([0.5, -0.5, 1.0, 1.0]))
    np.testing.assert_array_equal(speed, [2.0, np.nan, np.nan, np.nan])


TRACED_NAMES = ("lambda_i", "eta", "gent", "density_ratio", "alpha", "omega", "root")
TRACED_ROOT = 0.11762865422385121  # the lowest root of TUBE with jd.Fluid() at α̂ = 0.445 (N = 30)
TRACED_VALID = (0.9, 0.85, 97.2, 0.13, 0.445, 1.0, TRACED_ROOT)  # f at Ω = 1, the velocity at the root
TRACED_CHANGES = [{}, dict(alpha=-1.0), dict(alpha=0.0), dict(alpha=ALPHA_MIN / 2), dict(eta=1.5),
                  dict(gent=-1.0), dict(gent=GENT_MIN / 2), dict(lambda_i=12.0),
                  dict(density_ratio=-1.0), dict(omega=math.inf, root=math.inf),
                  dict(omega=math.nan, root=math.nan)]


def _traced_rows():
    return [[c.get(k, v) for k, v in zip(TRACED_NAMES, TRACED_VALID, strict=True)]
            for c in TRACED_CHANGES]


def _assert_only_first_row_valid(f, g):
    f, g = np.asarray(f), np.asarray(g)
    assert np.all(np.isnan(f[1:])) and np.all(np.isnan(g[1:])), (f, g)
    np.testing.assert_allclose(f[0], jd.characteristic(TUBE, 1.0, 0.445, jd.Fluid(), N_LAYERS), rtol=1e-13)
    np.testing.assert_allclose(g[0], jd.group_velocity(TUBE, 0.445, TRACED_ROOT, jd.Fluid(), N_LAYERS),
                               rtol=1e-13)


def test_compiled_characteristic_and_group_velocity_give_nan_for_invalid_values():
    """The compiled programs behind the public functions (what runs under jit/vmap, where nothing
    is validated) give NaN for invalid values (a past-locking stretch, η > 1, α̂ below ALPHA_MIN,
    G below GENT_MIN, a non-finite Ω, ...), never a finite number; the group velocity is taken at
    a root (a non-root gives NaN too: tests/test_api.py)."""
    from jaxdea.params import canonical
    from jaxdea.physics.dispersion import _characteristic
    from jaxdea.solve.roots import _group_velocity

    f, g = [], []
    for li, eta, gent, rho, alpha, omega, root in _traced_rows():
        tube, fluid = TUBE.replace(lambda_i=li, eta=eta, gent=gent), jd.Fluid(density_ratio=rho)
        tube, fluid, alpha, omega, root = canonical(tube, fluid, alpha, omega, root)
        f.append(_characteristic(tube, omega, alpha, fluid, N_LAYERS, 0))
        g.append(_group_velocity(tube, alpha, root, fluid, N_LAYERS, 0)[0])
    _assert_only_first_row_valid(f, g)


@pytest.mark.slow
def test_traced_characteristic_and_group_velocity_give_nan():
    """The same under jax.vmap of the public functions (on the N = 30 laminate of the reference
    values: the default discretisation differs from it by ~1e-5)."""
    columns = [jnp.array(col) for col in zip(*_traced_rows(), strict=True)]

    def both(li, eta, gent, rho, alpha, omega, root):
        tube, fluid = TUBE.replace(lambda_i=li, eta=eta, gent=gent), jd.Fluid(density_ratio=rho)
        return (jd.characteristic(tube, omega, alpha, fluid, N_LAYERS),
                jd.group_velocity(tube, alpha, root, fluid, N_LAYERS))

    _assert_only_first_row_valid(*jax.vmap(both)(*columns))


# -------------------------------------------------------------------- the range of alpha
def test_alpha_down_to_its_minimum():
    """α̂ >= ALPHA_MIN = 1e-12 is accepted and its lowest root is the long-wave bar mode: for the
    undeformed tube at V̂ = 0 (isotropic, incompressible: Young's modulus 3μ) Ω/α̂ → sqrt(3) as
    α̂ → 0, up to the O(N⁻²) laminate error of the 1/r̂ terms (4e-7 at N = 30). Below ALPHA_MIN a
    ValueError states the range (traced: status INVALID, test_invalid_points_of_a_sweep_are_invalid)."""
    tube = jd.Tube()
    roots = jd.solve_frequencies(tube, ALPHA_MIN, n_layers=N_LAYERS)
    assert roots.status[0] == jd.Status.CONVERGED
    assert float(roots.omega[0]) / ALPHA_MIN == pytest.approx(math.sqrt(3.0), rel=1e-6)
    assert_roots(tube, ALPHA_MIN, None, roots)
    for alpha in (ALPHA_MIN * (1 - 1e-15), 1e-200, 5e-324):
        with pytest.raises(ValueError, match=r"alpha must be >= 1e-12"):
            jd.frequencies(tube, alpha)


@pytest.mark.slow
def test_traced_bad_values_give_nan_and_status():
    """Under vmap nothing is validated: a negative stretch or η ≥ 1 gives NaN and status INVALID."""
    tubes = jd.Tube(lambda_i=jnp.array([-1.0, 1.0]), eta=jnp.array([0.85, 1.5]))
    axes = jd.Tube(voltage=None, lambda_i=0, lambda_z=None, eta=0, gent=None, length_ratio=None)
    out = jax.vmap(lambda t: jd.solve_frequencies(t, 0.445), in_axes=(axes,))(tubes)
    assert np.all(np.isnan(np.asarray(out.omega)))
    assert np.all(np.asarray(out.status) == jd.Status.INVALID)
