"""The SciPy baseline of the benchmarks (benchmarks/scipy_baseline.py) against jaxdea.

The baseline is an independent NumPy/SciPy implementation of the same method (base state by
``scipy.integrate.quad``, ``scipy.linalg.expm`` per sublayer, a 6×6 product, QR, ``scipy.special``
Bessel functions, ``brentq``): at the same N it must give the same characteristic function (its
normalised form det(B Q) is unique, |f| ≤ 1, and its raw det(B A S) has the same signs) and the
same roots. Measured: |Δf| ≈ 2e-15, roots to ≈ 1e-15 relative. It runs in a subprocess with
single-threaded BLAS (threaded OpenBLAS makes 6×6 products 100× slower on a loaded machine).
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import jaxdea

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OMEGAS = [0.3, 1.1, 2.7, 7.5, 18.0]
CASES = {
    "empty": (dict(), None, 1),
    "stretched_voltage": (dict(voltage=0.2, lambda_i=1.1, lambda_z=1.2), None, 3),
    "acoustic_fluid": (dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2), (0.13, 0.27), 2),
}

N = 30  # the baseline implements the paper's laminate (midpoint sublayers)

BASELINE = """
import json, sys
sys.path.insert(0, "benchmarks")
import scipy_baseline as sb
out = {}
cases, omegas = json.loads(sys.argv[1])
for name, (kw, fl, n) in cases.items():
    tube = sb.Tube(**kw)
    fluid = None if fl is None else sb.Fluid(*fl)
    alpha = sb.axial_wavenumber(tube, n)
    wall = sb.discretize(tube, 30)
    values = [sb.characteristic_on_wall(wall, om, alpha, fluid, normalise=True) for om in omegas]
    raw = [sb.characteristic_on_wall(wall, om, alpha, fluid) for om in omegas]
    roots, _ = sb.frequencies(tube, alpha, fluid, n_roots=3, wall=wall)
    out[name] = dict(alpha=alpha, values=values, raw=raw, roots=roots.tolist())
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def baseline():
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1")
    done = subprocess.run([sys.executable, "-c", BASELINE, json.dumps([CASES, OMEGAS])], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300, check=True)
    return json.loads(done.stdout)


@pytest.mark.parametrize("name", list(CASES))
def test_baseline_matches_jaxdea(baseline, name):
    kw, fl, n = CASES[name]
    tube = jaxdea.Tube(**kw)
    fluid = None if fl is None else jaxdea.Fluid(*fl)
    alpha = jaxdea.axial_wavenumber(tube, n)
    ref = baseline[name]
    np.testing.assert_allclose(ref["alpha"], alpha, rtol=1e-15)
    values = np.array([jaxdea.characteristic(tube, om, alpha, fluid, n_layers=N) for om in OMEGAS])
    np.testing.assert_allclose(values, ref["values"], rtol=0, atol=1e-12)
    assert np.min(np.abs(values)) > 1e-3  # a real comparison, not of numbers near zero
    # the unnormalised det(B A S) = det(B Q) det R with det R > 0: same signs
    np.testing.assert_array_equal(np.sign(ref["raw"]), np.sign(values))
    roots = np.asarray(jaxdea.frequencies(tube, alpha, fluid, n_layers=N))
    assert np.all(np.isfinite(roots))
    np.testing.assert_allclose(roots, ref["roots"], rtol=1e-12)

