"""Fault injection on ``jaxdea sweep`` in fresh processes: a full disk (a file-size limit,
RLIMIT_FSIZE, with SIGXFSZ ignored: the kernel refuses the bytes past it with EFBIG, as a full disk
refuses them with ENOSPC), a writer killed with SIGKILL at random moments, and Ctrl-C (SIGINT) at
random moments of the solve. Every case checks that the previous results survive byte for byte and
that the next successful run is bit-identical to a clean run.

Each run is a subprocess of a few seconds once the programs are in the cache (the first run of the
module compiles them), hence the slow tier."""

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_cli import SWEEP_TOML  # fluid, jacobian, N = 8, K = 2: the suite's sweep program

import jaxdea as jd

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
# the CLI after its imports: "ready" on stdout, an optional file-size limit and, with "chunks", a
# line "chunk" on stdout after each chunk of the sweep is solved; then jaxdea.apps.cli.main
DRIVER = """\
import resource, signal, sys
import jaxdea.apps.cli, jaxdea.studies.sweeps
limit, report = int(sys.argv[1]), sys.argv[2] == "chunks"
if limit:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
if report:
    solve = jaxdea.studies.sweeps._solve_chunk
    def reported(*args):
        out = solve(*args)
        print("chunk", flush=True)
        return out
    jaxdea.studies.sweeps._solve_chunk = reported
print("ready", flush=True)
sys.exit(jaxdea.apps.cli.main(sys.argv[3:]))
"""
OUTPUTS = ("grid.csv", "grid.npz", "grid.png")


def start(folder, config, limit=0, report="-"):
    """``jaxdea --quiet sweep CONFIG --out folder`` through the driver, started (Popen)."""
    argv = [sys.executable, "-c", DRIVER, str(limit), report, "--quiet", "sweep", str(config),
            "--out", str(folder)]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})


def run(folder, config, limit=0):
    proc = start(folder, config, limit)
    out, err = proc.communicate(timeout=600)
    return proc.returncode, out, err


def snapshot(folder):
    """{name: bytes} of every file in ``folder`` (hidden temporaries included)."""
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Configs A (the previous run) and B (the next one) of 4 points, the clean outputs of each,
    and a config C of 128 points (4 chunks) with its clean outputs and the seconds its solve and
    writing took after the imports."""
    base = tmp_path_factory.mktemp("faults")
    configs = {name: base / f"{name}.toml" for name in "ABC"}
    for name, axis in (("A", "stop = 0.1, num = 2"), ("B", "stop = 0.15, num = 2"),
                       ("C", "stop = 0.15, num = 64")):
        text = SWEEP_TOML.replace("stop = 0.15, num = 2", axis)
        configs[name].write_text(text, encoding="utf-8")
    clean, seconds = {}, {}
    for name, path in configs.items():
        folder = base / f"clean_{name}"
        proc = start(folder, path)
        assert proc.stdout.readline() == "ready\n"
        began = time.perf_counter()
        out, err = proc.communicate(timeout=900)
        assert proc.returncode == 0, err
        seconds[name] = time.perf_counter() - began
        clean[name] = snapshot(folder)
        assert sorted(clean[name]) == list(OUTPUTS)
    assert clean["A"]["grid.csv"] != clean["B"]["grid.csv"]
    return configs, clean, seconds


def previous(folder, files):
    """``folder`` holding exactly ``files`` (the previous run's outputs)."""
    folder.mkdir(exist_ok=True)
    for path in folder.iterdir():
        path.unlink()
    for name, data in files.items():
        (folder / name).write_bytes(data)


@pytest.mark.parametrize("limit", [1000, 16_000])
def test_a_full_disk_keeps_the_previous_results(runs, tmp_path, limit):
    """The disk fills (1000 bytes: while the CSV is written; 16 kB: while the PNG is) during a
    sweep whose previous outputs are in the folder: one line, exit status 2, the previous three
    files byte for byte and nothing else; then the run succeeds and equals the clean run."""
    configs, clean, _ = runs
    folder = tmp_path / "out"
    previous(folder, clean["A"])
    status, out, err = run(folder, configs["B"], limit)
    assert snapshot(folder) == clean["A"]
    assert status == 2 and out == "ready\n", err
    assert err.count("\n") == 1 and "File too large (the previous files are unchanged)" in err, err
    status, _, err = run(folder, configs["B"])
    assert status == 0, err
    assert snapshot(folder) == clean["B"]


def test_a_killed_writer_leaves_whole_results(runs, tmp_path):
    """SIGKILL at random moments of a run (one anywhere in it, two within 20 ms of its first
    temporary file, while the outputs are written): the folder holds the previous three files or
    the three new ones, each byte for byte, never a mix or a truncated file; hidden temporaries
    may be left, and the next run removes them and equals the clean run."""
    configs, clean, seconds = runs
    folder = tmp_path / "out"
    rng = random.Random(48)
    outcomes = []
    for case in range(3):
        previous(folder, clean["A"])
        proc = start(folder, configs["B"])
        assert proc.stdout.readline() == "ready\n"
        if case < 1:
            time.sleep(rng.uniform(0.0, 1.2 * seconds["B"]))
        else:
            while proc.poll() is None and not any(p.name.startswith(".") for p in folder.iterdir()):
                time.sleep(0.0005)
            time.sleep(rng.uniform(0.0, 0.02))
        proc.kill()
        proc.communicate(timeout=60)
        left = snapshot(folder)
        results = {name: data for name, data in left.items() if not name.startswith(".")}
        assert results in (clean["A"], clean["B"]), sorted(left)
        assert all(name.startswith(".grid.") and ".tmp." in name for name in left if name not in results)
        outcomes.append((results == clean["B"], len(left) - len(results)))
        status, _, err = run(folder, configs["B"])
        assert status == 0, err
        assert snapshot(folder) == clean["B"]
    assert any(temporaries for _, temporaries in outcomes), outcomes  # some kills hit the writing


def test_ctrl_c_saves_the_solved_points_and_keeps_the_previous_results(runs, tmp_path):
    """SIGINT after the first chunk of a 128-point sweep (4 chunks of 32) has been solved, at once
    and after a random delay, with the previous outputs in the folder: one line on stderr and exit
    status 130, the previous files byte for byte; the points solved before it in grid.partial.*
    equal the clean run's, bit for bit, the others NaN with status NOT_SOLVED. The next run equals
    the clean run and removes the partial files."""
    configs, clean, _ = runs
    folder = tmp_path / "out"
    (tmp_path / "clean.npz").write_bytes(clean["C"]["grid.npz"])
    reference = jd.SweepResult.from_npz(tmp_path / "clean.npz")
    rng = random.Random(130)
    partial_seen = 0
    for delay in (0.0, rng.uniform(0.0, 0.3)):
        previous(folder, clean["A"])
        proc = start(folder, configs["C"], report="chunks")
        assert proc.stdout.readline() == "ready\n" and proc.stdout.readline() == "chunk\n"
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
        left = snapshot(folder)
        if proc.returncode == 0:  # finished before the signal
            assert left == clean["C"]
        else:
            assert proc.returncode == 130 and err.count("\n") == 1, err
            assert err.startswith("jaxdea sweep: interrupted by SIGINT: "), err
            if "grid.partial.npz" in left:
                assert {k: v for k, v in left.items() if k in OUTPUTS} == clean["A"]
                partial_seen += 1
                assert sorted(left) == sorted([*OUTPUTS, "grid.partial.csv", "grid.partial.npz",
                                               "grid.partial.png"])
                part = jd.SweepResult.from_npz(folder / "grid.partial.npz")
                solved = np.all(part.status != jd.Status.NOT_SOLVED, axis=-1)
                assert part.settings["incomplete"] is True and solved.sum() > 0
                np.testing.assert_array_equal(part.omega[solved], reference.omega[solved])
                np.testing.assert_array_equal(part.jacobian[solved], reference.jacobian[solved])
                assert np.all(np.isnan(part.omega[~solved]))
                assert f"{solved.sum()} of 128 points solved" in err
            else:  # before a point was solved, or while writing: all previous or all new
                assert left in (clean["A"], clean["C"]), sorted(left)
        status, _, err = run(folder, configs["C"])
        assert status == 0, err
        assert snapshot(folder) == clean["C"]
    assert partial_seen, "no interrupt fell into the solve"  # the first one does
