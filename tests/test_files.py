"""Outputs written whole or not at all (jaxdea.files) by every writer, and the input files of the
command line: peak tables (BOM, number syntax, labels, long fields) and TOML/JSON documents
(duplicate keys, nesting). The full disk is a file-size limit (RLIMIT_FSIZE) set in this process
around the write: the kernel refuses the bytes past it (EFBIG), as a full disk refuses them."""

import contextlib
import json
import os
import resource
import signal
import socket
import stat
import subprocess
import sys

import numpy as np
import pytest

import jaxdea as jd
from jaxdea import files
from jaxdea.studies.fit import FitResult, FitStatus
from jaxdea.studies.sweeps import SweepResult


def sweep_result(scale=1.0):
    """A small SweepResult built by hand (no solve): 3 α̂ × 2 roots."""
    alpha = np.array([0.5, 1.0, 2.0])
    omega = scale * np.column_stack([alpha, 2.0 * alpha + 1.0]) + np.pi
    return SweepResult(axes={"alpha": alpha}, omega=omega, status=np.zeros((3, 2), np.int32),
                       alpha=alpha, settings={"tube": {"voltage": 0.1}, "n_roots": 2})


def fit_result(scale=1.0):
    """A FitResult built by hand: two peaks, both unmatched (so that plot_fit solves nothing)."""
    return FitResult(
        estimate={"shear_modulus": scale * 1e5}, interval={"shear_modulus": (9e4, 1.1e5)},
        covariance=np.array([[1e6]]), correlation=np.array([[1.0]]),
        residuals=np.array([np.nan, np.nan]), assignment=np.full((2, 3), -1),
        status=FitStatus.CONVERGED, iterations=7, names=("shear_modulus",),
        parameters={"shear_modulus": scale * 1e5}, settings={"n_layers": 12, "coupling": None})


PEAKS = {"voltage_V": np.array([1e3, 2e3]), "frequency_Hz": np.array([40.0, 41.5])}


def _plot_sweep(result, path):
    from jaxdea.apps.cli import plot_sweep

    plot_sweep(result, "alpha", path)


def _table(scale, path):
    from jaxdea.apps.figures import Table

    table = Table("fig")
    for k in range(40):
        table.add(alpha=scale * k, omega=np.sqrt(k + scale))
    table.write(path)


def _netcdf(result, path):
    pytest.importorskip("xarray")
    pytest.importorskip("netCDF4")
    result.to_netcdf(path)


# (file name, write(version, path)): every writer of jaxdea, each given two different contents
WRITERS = {
    "csv": ("res.csv", lambda k, path: sweep_result(k).to_csv(path)),
    "npz": ("res.npz", lambda k, path: sweep_result(k).to_npz(path)),
    "netcdf": ("res.nc", lambda k, path: _netcdf(sweep_result(k), path)),
    "png": ("res.png", lambda k, path: _plot_sweep(sweep_result(k), path)),
    "peaks": ("peaks.csv", lambda k, path: jd.write_peaks(path, {**PEAKS, "sigma_Hz": [k, k]})),
    "fit_json": ("fit.json", lambda k, path: jd.write_fit(fit_result(k), PEAKS, path)),
    "fit_png": ("fit.png", lambda k, path: jd.plot_fit(fit_result(k), PEAKS, path, points=3)),
    "figure_csv": ("fig.csv", _table),
}


@contextlib.contextmanager
def disk_full_after(size):
    """Writes past ``size`` bytes of a file fail with EFBIG (SIGXFSZ ignored) inside the block."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)


def listing(folder):
    return sorted(p.name for p in folder.iterdir())


@pytest.mark.parametrize("kind", list(WRITERS))
def test_a_full_disk_keeps_the_previous_file_whole(tmp_path, kind):
    """The previous file survives byte for byte a write that fails half-way, no temporary is left,
    and the next write equals a clean one."""
    name, write = WRITERS[kind]
    path, clean = tmp_path / name, tmp_path / "clean" / name
    clean.parent.mkdir()
    write(1.0, path)
    write(2.0, clean)
    before = path.read_bytes()
    assert clean.read_bytes() != before
    # the netCDF library reports any failed write as RuntimeError("NetCDF: HDF error")
    with disk_full_after(len(clean.read_bytes()) // 2), pytest.raises(
            RuntimeError if kind == "netcdf" else OSError):
        write(2.0, path)
    assert path.read_bytes() == before
    assert listing(tmp_path) == sorted(["clean", name])
    write(2.0, path)
    assert path.read_bytes() == clean.read_bytes()


def test_a_set_is_written_together_or_not_at_all(tmp_path):
    """write_together: a writer that fails (an error, Ctrl-C) after another has finished leaves
    both previous files; a set that succeeds replaces both."""
    a, b = tmp_path / "a.csv", tmp_path / "b.npz"
    files.write_together([(a, sweep_result(1.0).to_csv), (b, sweep_result(1.0).to_npz)])
    before = a.read_bytes(), b.read_bytes()

    for error in (OSError(28, "No space left on device"), KeyboardInterrupt()):
        def failing(path, error=error):
            path.write_bytes(b"half")
            raise error

        with pytest.raises(type(error)):
            files.write_together([(a, sweep_result(2.0).to_csv), (b, failing)])
        assert (a.read_bytes(), b.read_bytes()) == before
        assert listing(tmp_path) == ["a.csv", "b.npz"]
    assert files.write_together([(a, sweep_result(2.0).to_csv), (b, sweep_result(2.0).to_npz)]) == [a, b]
    assert a.read_bytes() != before[0] and b.read_bytes() != before[1]
    np.testing.assert_array_equal(SweepResult.from_npz(b).omega, sweep_result(2.0).omega)


def test_modes_symlinks_and_file_objects(tmp_path):
    """A new file gets the mode the umask gives, a replaced one keeps its mode; a symbolic link is
    written through (the link stays); an open file object is written as given."""
    umask = os.umask(0o022)
    try:
        files.write_text(tmp_path / "new.txt", "x")
    finally:
        os.umask(umask)
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == 0o644
    os.chmod(tmp_path / "new.txt", 0o600)
    files.write_text(tmp_path / "new.txt", "y")
    assert stat.S_IMODE((tmp_path / "new.txt").stat().st_mode) == 0o600
    (tmp_path / "link.txt").symlink_to(tmp_path / "new.txt")
    files.write_text(tmp_path / "link.txt", "z")
    assert (tmp_path / "link.txt").is_symlink() and (tmp_path / "new.txt").read_text() == "z"
    with open(tmp_path / "handle.csv", "w") as handle:
        sweep_result().to_csv(handle)
    assert (tmp_path / "handle.csv").read_text().startswith("alpha,alpha_hat,omega_1")
    sweep_result().to_npz(tmp_path / "stem")  # numpy's rule: .npz appended
    assert listing(tmp_path) == ["handle.csv", "link.txt", "new.txt", "stem.npz"]


def test_temporaries_of_killed_writers_are_removed(tmp_path):
    """A temporary whose writer (this host) has ended is removed by the next write of its target;
    one of a live writer, of another host or of another target stays."""
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                           capture_output=True, text=True, check=True)
    host = socket.gethostname()
    stale = tmp_path / f".res.csv.{host}-{int(ended.stdout)}-0a1b2c3d.tmp.csv"
    live = tmp_path / f".res.csv.{host}-{os.getpid()}-0a1b2c3d.tmp.csv"
    remote = tmp_path / f".res.csv.elsewhere-{int(ended.stdout)}-0a1b2c3d.tmp.csv"
    other = tmp_path / f".res.npz.{host}-{int(ended.stdout)}-0a1b2c3d.tmp.npz"
    for path in (stale, live, remote, other):
        path.write_bytes(b"partial")
    sweep_result().to_csv(tmp_path / "res.csv")
    assert not stale.exists() and live.exists() and remote.exists() and other.exists()


# ------------------------------------------------------------------------------- reading inputs


def test_peaks_accept_a_byte_order_mark(tmp_path):
    path = tmp_path / "peaks.csv"
    path.write_bytes(b"\xef\xbb\xbfvoltage_V,frequency_Hz,m\n1000,286.62,0\n2000,2.9e2,1\n")
    peaks = jd.read_peaks(path)
    np.testing.assert_array_equal(peaks["frequency_Hz"], [286.62, 290.0])
    np.testing.assert_array_equal(peaks["m"], [0, 1])


@pytest.mark.parametrize("text, match", [
    ("voltage_V,frequency_Hz\n1000,2_86.62\n", r"line 2, column 'frequency_Hz': '2_86.62' is not a number"),
    ("voltage_V,frequency_Hz\n1_000,286.62\n", r"column 'voltage_V': '1_000' is not a number"),
    ("voltage_V,frequency_Hz,m\n1000,286.62,1e20\n",
     r"line 2, column 'm': 1e20, must be an integer >= 0 and <= 2147483647"),
    ("voltage_V,frequency_Hz,n\n1000,286.62,1e400\n", r"column 'n': '1e400' is not a finite number"),
    ("voltage_V,frequency_Hz\n1000," + "4" * 140_000 + "\n", r"line 2: field larger than field limit"),
])
def test_peaks_refuse_what_float_would_misread(tmp_path, text, match):
    """Python's float() reads 2_86.62 as 286.62; a label of 1e20 overflowed the integer array, a
    field past csv's limit raised _csv.Error: each is a ValueError naming line and column."""
    path = tmp_path / "peaks.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match=match):
        jd.read_peaks(path)


@pytest.mark.parametrize("kind, text, match", [
    ("json", '{"axes": {"n": [1]}, "axes": {"n": [2]}}', "the key 'axes' appears twice"),
    ("json", '{"a": ' * 5000 + "1" + "}" * 5000, "nest deeper than 64 levels"),
    ("json", '{"a": ' + "[" * 100_000 + "]" * 100_000 + "}", "nest deeper than 64 levels"),
    ("toml", "a = " + "[" * 5000 + "]" * 5000 + "\n", "nest deeper than 64 levels"),
    ("toml", "a = 1\na = 2\n", "invalid TOML"),
])
def test_documents_refuse_duplicates_and_deep_nesting(tmp_path, kind, text, match):
    path = tmp_path / f"doc.{kind}"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ValueError, match=match):
        files.load_document(path, kind)


def test_documents_accept_a_byte_order_mark(tmp_path):
    (tmp_path / "a.json").write_bytes(b'\xef\xbb\xbf{"axes": {"n": [1, 2]}}')
    (tmp_path / "a.toml").write_bytes(b"\xef\xbb\xbf[axes]\nn = [1, 2]\n")
    for kind in ("json", "toml"):
        assert files.load_document(tmp_path / f"a.{kind}", kind) == {"axes": {"n": [1, 2]}}
    assert json.dumps(files.load_document(tmp_path / "a.json", "json")) == '{"axes": {"n": [1, 2]}}'
