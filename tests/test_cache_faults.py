"""Fault injection on the disk cache (jaxdea.configure): concurrent processes on an empty cache, a
read-only cache holding a damaged entry, and a cache on a disk that fills up. In every case each
process exits 0, warns nothing (user warnings are errors here), and gives the same bits as a
process with the cache off. Slow tier: every case runs fresh processes that compile."""

import os
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

SURFACE = Path(__file__).with_name("public_surface.py")
NAMES = ["frequencies", "mode_shape"]


def _start(root):
    env = dict(os.environ, JAXDEA_CACHE_DIR=str(root))
    return subprocess.Popen([sys.executable, "-W", "error::UserWarning", str(SURFACE), *NAMES], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(process):
    out, err = process.communicate(timeout=900)
    assert process.returncode == 0, err[-3000:]
    *values, _counts = out.splitlines()
    return values


def _run(root):
    return _finish(_start(root))


@pytest.fixture(scope="module")
def reference():
    """The bits with the cache off."""
    return _run("off")


def test_concurrent_processes_on_an_empty_cache(tmp_path, reference):
    processes = [_start(tmp_path / "cache") for _ in range(3)]
    for process in processes:
        assert _finish(process) == reference
    assert _run(tmp_path / "cache") == reference  # and a later process loading what they stored


@pytest.fixture
def small_disk(tmp_path):
    """A tmpfs of its own (mounting needs root and a kernel that allows it: skipped otherwise)."""
    mount = tmp_path / f"disk-{uuid.uuid4().hex[:6]}"
    mount.mkdir()

    def remount(options):
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(mount)],
                              capture_output=True, text=True)
        if done.returncode:
            pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")

    yield mount, remount
    subprocess.run(["umount", str(mount)], capture_output=True)


def test_a_read_only_cache_with_a_damaged_entry(small_disk, reference):
    mount, remount = small_disk
    remount("size=64m,mode=0700")
    root = mount / "cache"
    assert _run(root) == reference
    entry = sorted((root / "programs").iterdir())[0]
    entry.write_bytes(entry.read_bytes()[:100])  # damaged, then the disk becomes read-only
    remount("remount,ro")
    assert _run(root) == reference
    assert len(entry.read_bytes()) == 100  # could not be repaired: skipped


def test_a_full_disk_under_the_cache(small_disk, reference):
    """A 1 MiB disk fills while the first process writes its programs (JAX's cache, which writes in
    place and warns on a failed write, stays off on a disk this full); the next process skips or
    repairs what is damaged and computes the same bits, and the next with a JAX entry truncated
    by hand too."""
    mount, remount = small_disk
    remount("size=1m,mode=0700")
    root = mount / "cache"
    assert _run(root) == reference
    assert _run(root) == reference
    assert not list((root / "xla").glob("*-cache"))
    (root / "xla" / "truncated-cache").write_bytes(b"\x28\xb5")
    assert _run(root) == reference
    assert not (root / "xla" / "truncated-cache").exists()
