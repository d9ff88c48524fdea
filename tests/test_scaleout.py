"""Scale-out of sweeps: chunks split over several JAX devices (two forced CPU devices in a
subprocess) and chunks sent to the workers of a Dask cluster give bit-for-bit the numbers of the
single-device, single-process sweep."""

import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.studies import sweeps as sweep_module
from jaxdea.studies.sweeps import sweep

CACHE = os.path.join(os.path.dirname(os.path.dirname(__file__)), ".jax_cache", "xla")
TUBE = jd.Tube(lambda_i=1.1, lambda_z=1.2, eta=0.85)  # the configuration of test_sweep (shared compilation)
GRID = dict(voltage=np.array([0.0, 0.1, 0.2]), n=np.array([1, 2, 5]), chunk_size=4, progress=False)


def assert_identical(a, b):
    """Bit-for-bit equal results (NaN where NaN)."""
    for name in ("omega", "status", "alpha"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape
        np.testing.assert_array_equal(x.view(np.uint8), y.view(np.uint8), err_msg=name)


@pytest.mark.slow
def test_sharded_sweep_is_bit_identical_to_one_device():
    """With two CPU devices the default sweep splits every chunk over both (one executable of the
    chunk program per device) and reproduces the one-device sweep bit for bit; so does a sweep on
    the second device alone."""
    script = textwrap.dedent(f"""
        import jax, numpy as np
        jax.config.update("jax_enable_x64", True)
        jax.config.update("jax_compilation_cache_dir", {CACHE!r})
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
        import jaxdea as jd
        from jaxdea.studies import sweeps
        assert len(jax.devices()) == 2, jax.devices()
        grid = dict(voltage=np.array([0.0, 0.1, 0.2]), n=np.array([1, 2, 5]), chunk_size=4, progress=False)
        tube = jd.Tube(lambda_i=1.1, lambda_z=1.2, eta=0.85)
        one = sweeps.sweep(tube, devices=1, **grid)
        assert sweeps._sweep_chunk._cache_size() == 1
        both = sweeps.sweep(tube, **grid)
        assert sweeps._sweep_chunk._cache_size() == 2  # the second device ran its own blocks
        second = sweeps.sweep(tube, devices=jax.devices()[1:], **grid)
        assert sweeps._sweep_chunk._cache_size() == 2
        for res in (both, second):
            for name in ("omega", "status", "alpha"):
                x, y = getattr(one, name), getattr(res, name)
                assert x.dtype == y.dtype and x.shape == y.shape
                assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), name
        assert np.all(one.status == jd.Status.CONVERGED) and one.omega.shape == (3, 3, 3)
        print("identical")
    """)
    env = dict(os.environ, JAX_PLATFORMS="cpu", XLA_FLAGS="--xla_force_host_platform_device_count=2")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env,
                         timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip().splitlines()[-1] == "identical"


@pytest.mark.slow
def test_dask_cluster_sweep_is_bit_identical():
    """Three chunks on a LocalCluster of two worker processes: the same numbers bit for bit as in
    this process, and no worker compiles the chunk program more than once."""
    distributed = pytest.importorskip("distributed")
    local = sweep(TUBE, **GRID)
    with (distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                   dashboard_address=None) as cluster,
          distributed.Client(cluster) as client):
        client.run(lambda: (jax.config.update("jax_compilation_cache_dir", CACHE),
                            jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)))
        remote = sweep(TUBE, client=client, **GRID)
        compiled = client.run(lambda: sweep_module._sweep_chunk._cache_size())
    assert len(compiled) == 2 and all(c <= 1 for c in compiled.values()) and sum(compiled.values()) >= 1
    assert_identical(local, remote)
    assert np.all(remote.status == jd.Status.CONVERGED)
    assert remote.settings == local.settings and list(remote.axes) == ["voltage", "n"]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(devices=0), "devices must be between 1 and"),
        (dict(devices=len(jax.devices()) + 1), "devices must be between 1 and"),
        (dict(devices=[]), "devices must be None"),
        (dict(devices=["cpu"]), "devices must be None"),
        (dict(devices=jax.devices() * 2), "distinct"),
        (dict(client="tcp://scheduler:8786"), "client must be a distributed.Client"),
        (dict(client="tcp://scheduler:8786", devices=1), "devices must be None with a Dask client"),
    ],
)
def test_bad_scaleout_arguments(kwargs, match):
    pytest.importorskip("distributed")
    with pytest.raises(ValueError, match=match):
        sweep(TUBE, alpha=[0.4], **kwargs)
