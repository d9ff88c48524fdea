"""The on-disk cache of exported programs (jaxdea.compiled): a fresh process loads them without
tracing and gets the same bits; what it cannot key (tracers, debugging) goes through jax.jit; a
damaged, foreign, misplaced or unsafe entry is never run and never raises; clear removes only what
jaxdea wrote; importing jaxdea changes nothing; every public entry point survives three processes
sharing one cache."""

import ast
import json
import os
import pickle
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdea import compiled
from jaxdea.compiled import MAGIC, CacheWarning, cached_jit


def _scaled(x, n):
    return x * n


def _entries(root):
    folder = root / "programs"
    return sorted(folder.iterdir()) if folder.exists() else []


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXDEA_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_key_separates_static_arguments_and_argument_types(cache):
    fun = cached_jit(_scaled, static_argnames="n")
    x = jnp.arange(3.0)
    np.testing.assert_array_equal(fun(x, 2), 2 * x)
    np.testing.assert_array_equal(fun(x, n=2), 2 * x)  # the same program
    assert len(_entries(cache)) == 1 and fun._cache_size() == 1
    fun(x, 3)
    fun(jnp.arange(4.0), 3)
    fun(jnp.arange(3, dtype=jnp.float32), 3)
    fun(np.float64(1.5), 3)
    fun(1.5, 3)  # a weakly typed Python float: another program than the float64 scalar
    assert len(_entries(cache)) == 6 and fun._cache_size() == 6
    assert fun.counts == {"loaded": 0, "exported": 6, "stored": 6}


def test_threads_asking_for_a_new_program_export_it_once(cache):
    """Eight threads calling a new program at once: one exports and compiles it, the others wait
    for it and get the same values."""
    import concurrent.futures
    import threading

    fun = cached_jit(_scaled, static_argnames="n")
    x, start = jnp.arange(5.0), threading.Barrier(8)

    def call(_):
        start.wait()
        return np.asarray(fun(x, 7))

    with concurrent.futures.ThreadPoolExecutor(8) as pool:
        results = list(pool.map(call, range(8)))
    for got in results:
        np.testing.assert_array_equal(got, 7 * np.arange(5.0))
    assert fun.counts == {"loaded": 0, "exported": 1, "stored": 1} and len(_entries(cache)) == 1


def test_threads_trace_side_by_side(cache):
    """The library does not serialise its users' threads: while one thread is inside the trace of
    a program (held there), another thread traces, compiles and runs a different one."""
    import threading

    inside, release = threading.Event(), threading.Event()

    def blocking(x, n):
        inside.set()
        release.wait(60)
        return x * n

    slow, fast = cached_jit(blocking, static_argnames="n"), cached_jit(_scaled, static_argnames="n")
    holder = threading.Thread(target=lambda: slow(jnp.arange(2.0), 2))
    holder.start()
    try:
        assert inside.wait(60)
        done = []
        other = threading.Thread(target=lambda: done.append(np.asarray(fast(jnp.arange(3.0), 5))))
        other.start()
        other.join(20)
        assert done and np.array_equal(done[0], 5 * np.arange(3.0))  # did not wait for the first
    finally:
        release.set()
        holder.join()


def test_private_modes_and_no_pickle(cache):
    """The root and its folder 0700, entries 0600; the root holds the marker; an entry is the magic
    line, its own key, the SHA-256 of key and artifact, and the artifact (a jax.export flatbuffer,
    not a pickle)."""
    cached_jit(_scaled, static_argnames="n")(jnp.arange(3.0), 2)
    (entry,) = _entries(cache)
    assert stat.S_IMODE(cache.stat().st_mode) == 0o700
    assert stat.S_IMODE((cache / "programs").stat().st_mode) == 0o700
    assert stat.S_IMODE(entry.stat().st_mode) == 0o600
    assert (cache / compiled.MARKER).read_text().startswith("Signature: 8a477f597d28d172789f06886806bc55")
    data = entry.read_bytes()
    assert data.startswith(MAGIC + entry.stem.encode() + b"\n")
    assert not data[len(MAGIC):].startswith(b"\x80")  # pickle protocol
    with pytest.raises(pickle.UnpicklingError):
        pickle.loads(data)


def test_damaged_entry_is_exported_anew(cache):
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    good = entry.read_bytes()
    for damaged in (b"", b"not a program", good[:-10], good.replace(MAGIC, b"jaxdea-exported-0\n")):
        entry.write_bytes(damaged)
        fresh = cached_jit(_scaled, static_argnames="n")  # a new process holds nothing in memory
        np.testing.assert_array_equal(fresh(x, 2), 2 * x)
        assert fresh.counts == {"loaded": 0, "exported": 1, "stored": 1}
        assert _entries(cache) == [entry] and compiled.read_entry(entry) is not None  # rewritten
    again = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(again(x, 2), 2 * x)  # loads the rewritten entry
    assert again.counts == {"loaded": 1, "exported": 0, "stored": 0}


def _plant(entry, payload):
    """Write ``payload`` at ``entry`` as a well-formed entry (magic line, its key, valid checksum)."""
    import hashlib

    key = entry.stem.encode()
    entry.write_bytes(MAGIC + key + b"\n" + hashlib.sha256(key + b"\n" + payload).hexdigest().encode()
                      + b"\n" + payload)


def test_an_entry_copied_over_another_key_is_not_run(cache):
    """Another program's whole, valid entry copied to this program's name (the midpoint scheme's
    over the default one, say) records another key: deleted, this program exported anew."""
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (two,) = _entries(cache)
    cached_jit(_scaled, static_argnames="n")(x, 3)
    (three,) = [e for e in _entries(cache) if e != two]
    two.write_bytes(three.read_bytes())
    fresh = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(fresh(x, 2), 2 * x)  # not 3 x
    assert fresh.counts == {"loaded": 0, "exported": 1, "stored": 1}


def test_a_fifo_or_a_folder_at_an_entry_path_is_skipped(cache):
    """A FIFO at an entry's path used to hang the process forever (open blocks for a writer), and
    a folder there raised: both are skipped, the program compiled in the process."""
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    entry.unlink()
    os.mkfifo(entry, 0o600)
    assert compiled.read_entry(entry) is None  # returns at once: no writer needed
    fresh = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(fresh(x, 2), 2 * x)
    entry.unlink()
    entry.mkdir(mode=0o700)
    again = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(again(x, 2), 2 * x)
    assert again.counts["loaded"] == 0 and entry.is_dir()


def test_a_cache_that_cannot_be_written_never_raises(cache, monkeypatch):
    """A read-only cache (a read-only mount, a folder the user cannot write): a damaged entry that
    cannot be deleted, and entries that cannot be written, only cost compilations."""
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    entry.write_bytes(b"damaged")

    def refuse(*args, **kwargs):
        raise PermissionError(30, "Read-only file system")

    monkeypatch.setattr(Path, "unlink", refuse)
    monkeypatch.setattr(compiled.tempfile, "mkstemp", refuse)
    monkeypatch.setattr(compiled.os, "utime", refuse)
    for _ in range(2):
        fresh = cached_jit(_scaled, static_argnames="n")
        np.testing.assert_array_equal(fresh(x, 2), 2 * x)
        assert fresh.counts == {"loaded": 0, "exported": 1, "stored": 0}
    monkeypatch.undo()
    assert entry.read_bytes() == b"damaged"


class _Exploit:
    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (Path.touch, (Path(self.marker),))


def test_a_crafted_pickle_is_never_executed(cache, tmp_path):
    """An entry holding a pickle that would run code when unpickled (here: create a file), both
    raw and behind a valid magic line and checksum, is never unpickled: the program is exported
    anew and the marker never appears."""
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    marker = tmp_path / "owned"
    exploit = pickle.dumps(_Exploit(marker))
    pickle.loads(exploit)  # the payload works: it creates the marker when unpickled
    assert marker.exists()
    marker.unlink()
    for planted in (lambda: entry.write_bytes(exploit), lambda: _plant(entry, exploit)):
        planted()
        fresh = cached_jit(_scaled, static_argnames="n")
        np.testing.assert_array_equal(fresh(x, 2), 2 * x)
        assert fresh.counts["exported"] == 1 and not marker.exists()


def test_an_entry_writable_by_others_is_refused(cache):
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    entry.chmod(0o666)
    fresh = cached_jit(_scaled, static_argnames="n")
    with pytest.warns(CacheWarning, match="writable by group or others"):
        np.testing.assert_array_equal(fresh(x, 2), 2 * x)
    assert fresh.counts == {"loaded": 0, "exported": 1, "stored": 1}
    assert stat.S_IMODE(entry.stat().st_mode) == 0o600  # replaced by this process's own entry


@pytest.mark.skipif(not hasattr(os, "getuid") or os.getuid() != 0, reason="chown needs root")
def test_an_entry_of_another_user_is_refused(cache):
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    os.chown(entry, 4242, 4242)
    fresh = cached_jit(_scaled, static_argnames="n")
    with pytest.warns(CacheWarning, match="owned by uid 4242"):
        np.testing.assert_array_equal(fresh(x, 2), 2 * x)
    assert fresh.counts["loaded"] == 0 and entry.stat().st_uid == os.getuid()


def test_a_folder_writable_by_others_is_not_used(cache):
    """A shared, world-writable cache root: nothing is read or written there."""
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    cache.chmod(0o777)
    fresh = cached_jit(_scaled, static_argnames="n")
    with pytest.warns(CacheWarning, match="writable by group or others"):
        np.testing.assert_array_equal(fresh(x, 2), 2 * x)
    assert fresh.counts == {"loaded": 0, "exported": 1, "stored": 0}
    with pytest.warns(CacheWarning):
        assert compiled.private_folder("xla") is None  # nor JAX's cache there


def test_another_environment_does_not_load(cache, monkeypatch):
    """Entries written by another jaxdea or jax version (another environment digest) are not
    read: the key holds the sources and versions."""
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    monkeypatch.setattr(compiled, "_environment", lambda: "another jax version")
    fresh = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(fresh(x, 2), 2 * x)
    assert fresh.counts["loaded"] == 0 and len(_entries(cache)) == 2


def test_sources_changed_since_import_neither_load_nor_store(cache, monkeypatch):
    """A process whose jaxdea files changed on disk after it imported them (an upgrade in place, a
    checkout) runs the programs of the sources it imported: it neither stores them under the new
    sources' key nor loads the entries written for them (the key had been read from the disk at the
    first cached call)."""
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)  # an entry for the sources on disk
    assert len(_entries(cache)) == 1
    monkeypatch.setattr(compiled, "IMPORTED_SOURCES", "the sources of an earlier import")
    monkeypatch.setattr(compiled, "_environment", compiled.functools.cache(
        compiled._environment_digest))
    fresh = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(fresh(x, 3), 3 * x)
    np.testing.assert_array_equal(fresh(x, 2), 2 * x)
    assert fresh.counts == {"loaded": 0, "exported": 2, "stored": 0}
    assert len(_entries(cache)) == 1


def test_an_edit_after_import_is_seen(tmp_path):
    """The environment digest compares the files on disk with those imported: a copy of jaxdea
    imported, one of its modules then edited, gives no digest (None); unedited, the digest."""
    package = tmp_path / "copy"
    shutil.copytree(Path(compiled.__file__).parent, package / "jaxdea",
                    ignore=shutil.ignore_patterns("__pycache__"))
    script = ("import sys; sys.path.insert(0, sys.argv[1]); import jaxdea.compiled as c; "
              "assert c.__file__.startswith(sys.argv[1]); before = c._environment_digest(); "
              "open(sys.argv[1] + '/jaxdea/units.py', 'a').write('\\n# edited\\n'); "
              "print(before is not None, c._environment_digest() is None)")
    out = subprocess.run([sys.executable, "-c", script, str(package)], capture_output=True,
                         text=True, timeout=300, env={**os.environ, "JAX_PLATFORMS": "cpu"})
    assert out.stdout.split() == ["True", "True"], out.stderr


def test_clear_cache(cache):
    cached_jit(_scaled, static_argnames="n")(jnp.arange(3.0), 2)
    assert compiled.clear_cache() == cache and not cache.exists()


def test_clear_removes_only_what_jaxdea_wrote(cache):
    """A user's file in the cache root survives ``clear`` (and keeps the root); a folder without
    jaxdea's marker is not a cache: nothing in it is deleted."""
    cached_jit(_scaled, static_argnames="n")(jnp.arange(3.0), 2)
    (cache / "notes.txt").write_text("mine")
    assert compiled.clear_cache() == cache
    assert sorted(p.name for p in cache.iterdir()) == ["notes.txt"]
    with pytest.raises(ValueError, match="not a jaxdea cache"):
        compiled.clear_cache(cache)
    assert (cache / "notes.txt").read_text() == "mine"


def test_a_folder_holding_other_files_is_never_a_cache_root(tmp_path, monkeypatch):
    """JAXDEA_CACHE_DIR naming a folder of the user's (here: one with a file in it) is refused with
    a warning: nothing is written there. Set but empty, it means the default root, never the
    current folder."""
    own = tmp_path / "work"
    own.mkdir()
    (own / "data.csv").write_text("1,2\n")
    monkeypatch.setenv("JAXDEA_CACHE_DIR", str(own))
    fun = cached_jit(_scaled, static_argnames="n")
    with pytest.warns(CacheWarning, match="files jaxdea did not write"):
        np.testing.assert_array_equal(fun(jnp.arange(3.0), 2), [0.0, 2.0, 4.0])
    assert sorted(p.name for p in own.iterdir()) == ["data.csv"]
    monkeypatch.setenv("JAXDEA_CACHE_DIR", "")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(own)
    assert compiled.cache_root() == tmp_path / "home" / ".cache" / "jaxdea"
    cached_jit(_scaled, static_argnames="n")(jnp.arange(3.0), 2)
    assert sorted(p.name for p in own.iterdir()) == ["data.csv"]
    assert _entries(tmp_path / "home" / ".cache" / "jaxdea")


def test_least_recently_used_entries_go_beyond_the_limit(cache):
    """evict keeps the most recently read or written entries within the limit."""
    fun = cached_jit(_scaled, static_argnames="n")
    x = jnp.arange(3.0)
    entries = []
    for n in (2, 3, 4):
        fun(x, n)
        entries.append(next(e for e in _entries(cache) if e not in entries))
    for age, entry in zip((300, 200, 100), entries, strict=True):  # 2 oldest, 4 newest
        os.utime(entry, (entry.stat().st_atime - age, entry.stat().st_mtime - age))
    assert compiled.read_entry(entries[0]) is not None  # reading renews the oldest
    size = entries[0].stat().st_size
    assert compiled.evict(cache, 2 * size + 10) == 1
    assert _entries(cache) == sorted([entries[0], entries[2]])


def test_configure_repairs_damaged_jax_entries(cache):
    """JAX writes its compilation cache in place: an empty or truncated entry (a full disk) made
    every later run warn and recompile. configure deletes them and keeps the whole ones."""
    import zlib

    folder = cache / "xla"
    compiled.private_folder("xla")
    whole = zlib.compress(b"an executable" * 100)
    (folder / "a-cache").write_bytes(whole)
    (folder / "b-cache").write_bytes(b"")
    (folder / "c-cache").write_bytes(whole[:-20])
    assert compiled.repair_jax_cache(folder) == 2
    assert sorted(p.name for p in folder.glob("*-cache")) == ["a-cache"]


def test_transformations_and_debugging_go_through_jit(cache):
    """Tracers and jax.debug_nans: jax.jit, nothing stored (arrays committed to other devices, the
    blocks of a sharded sweep, are the third case: tests/test_scaleout.py)."""
    fun = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(jax.vmap(lambda x: fun(x, 2))(jnp.arange(3.0)), [0.0, 2.0, 4.0])
    assert float(jax.grad(lambda x: fun(x, 3))(1.0)) == 3.0
    with jax.debug_nans(True):
        np.testing.assert_array_equal(fun(jnp.ones(2), 2), [2.0, 2.0])
    assert _entries(cache) == [] and fun.counts == {"loaded": 0, "exported": 0, "stored": 0}


def test_off_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXDEA_CACHE_DIR", "off")
    fun = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(fun(jnp.ones(2), 2), [2.0, 2.0])
    assert fun._jit._cache_size() == 1 and not any(tmp_path.iterdir())


SURFACE = Path(__file__).with_name("public_surface.py")


def _surface_runs(tmp_path, names, processes):
    """(values, counts) of ``processes`` fresh runs of tests/public_surface.py (the entry points
    ``names``, all when empty) sharing a new cache."""
    env = dict(os.environ, JAXDEA_CACHE_DIR=str(tmp_path / "cache"))
    runs = []
    for _ in range(processes):
        out = subprocess.run([sys.executable, str(SURFACE), *names], env=env, capture_output=True,
                             text=True, timeout=900)
        assert out.returncode == 0, (out.returncode, out.stderr[-3000:])
        *values, counts = out.stdout.splitlines()
        runs.append((values, json.loads(counts)))
    return runs


def _check_stored_then_loaded(runs):
    """The first run exports and stores every program, the later ones load every one of them
    (nothing traced where a program could be loaded) and give the same bits."""
    (first, stored), *later = runs
    assert all(len(line.split()) >= 2 for line in first)
    assert {p["stored"] for p in stored.values()} != {0}
    for name, counts in stored.items():
        assert counts["stored"] == counts["exported"] > 0, name  # every program serialisable
    for values, loaded in later:
        assert values == first  # every number, to the last bit
        assert loaded.keys() == stored.keys()
        for name, counts in loaded.items():
            assert counts == {"loaded": stored[name]["exported"], "exported": 0, "stored": 0}, name


def test_mode_shape_from_the_disk_cache_in_a_second_process(tmp_path):
    """The regression of the full check below, cheaply: mode shapes (m = 0 and 2) and the solvers
    that feed them, in a fresh process that stores them and a second one that loads them. The
    second process used to die with a segmentation fault in mode_shape."""
    runs = _surface_runs(tmp_path, ["frequencies", "mode_shape", "frequencies_m2", "mode_shape_m2"],
                         2)
    _check_stored_then_loaded(runs)
    assert len(runs[0][0]) == 4


@pytest.mark.slow
def test_every_public_entry_point_in_three_processes(tmp_path):
    """Every public entry point (tests/public_surface.py) in three fresh processes sharing a new
    cache: each exits 0 with the same bits; the first exports and stores every program, the
    others load every one of them (nothing traced where a program could be loaded). This once
    caught a segmentation fault of mode_shape in every process after the first (9.7 minutes of
    the default tier: the cheap check above stays there)."""
    runs = _surface_runs(tmp_path, [], 3)
    assert len(runs[0][0]) >= 33
    _check_stored_then_loaded(runs)


def test_compiler_options_on_top_level_programs_only():
    """jaxdea.compiled.jit: a top-level call runs the program compiled with compiler_options(), a
    call inside a caller's trace (tracers, or concrete arguments staged into a jit) the plain
    jax.jit, as JAX requires (options on a nested jit raise); the values agree."""
    from jaxdea.compiled import jit

    fun = jit(_scaled, static_argnames="n")
    plain, calls = fun._nested, []
    fun._nested = lambda *a, **k: calls.append(1) or plain(*a, **k)
    x = jnp.arange(3.0)
    np.testing.assert_array_equal(fun(x, 2), 2 * x)
    assert not calls
    np.testing.assert_array_equal(jax.jit(lambda y: fun(y, 2))(x), 2 * x)  # tracers
    np.testing.assert_array_equal(jax.jit(lambda: fun(x, 3))(), 3 * x)  # concrete, staged
    assert float(jax.grad(lambda y: fun(y, 3))(1.0)) == 3.0
    assert len(calls) == 3
    with pytest.raises(ValueError, match="compiler_options"):  # why the plain jit is needed
        jax.jit(lambda: fun._top(x, 3))()


def test_cpu_options_only_on_the_cpu_backend():
    """LLVM level 1 (CPU_OPTIONS) joins COMPILER_OPTIONS on the CPU backend only, and the top-level
    program is built with them at first use."""
    from jaxdea import compiled

    expected = dict(compiled.COMPILER_OPTIONS)
    if jax.default_backend() == "cpu":
        expected.update(compiled.CPU_OPTIONS)
    assert compiled.compiler_options() == expected
    assert compiled.CPU_OPTIONS == {"xla_backend_optimization_level": 1}
    fun = compiled.jit(_scaled, static_argnames="n")
    assert fun._top_jit is None
    np.testing.assert_array_equal(fun(jnp.arange(2.0), 4), [0.0, 4.0])
    assert fun._top_jit is not None


_LOOP_PROBE = """
import os, sys
import jax
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp
import jaxdea
if sys.argv[1] == "configure":
    jaxdea.configure(cache=False)
loop = jax.jit(lambda x: jax.lax.fori_loop(0, 5, lambda i, y: jnp.sin(y) + y, x))
hlo = loop.lower(jnp.ones(10_000)).compile().as_text()  # 80 kB a step: above XLA's 1 KiB default
print(repr(os.environ.get("XLA_FLAGS", "")))
print("xla_cpu_small_call" in hlo)
"""


def _probe(env_extra, configure=True):
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAXDEA_XLA_FLAGS")}
    env.update(env_extra, JAXDEA_CACHE_DIR="off")
    out = subprocess.run([sys.executable, "-c", _LOOP_PROBE, "configure" if configure else "import"],
                         env=env, capture_output=True, text=True, timeout=300, check=True)
    flags, hoisted = out.stdout.strip().splitlines()[-2:]
    return ast.literal_eval(flags), hoisted == "True"


def test_configure_sets_the_small_loop_threshold_where_it_still_acts():
    """jaxdea.configure() gets SMALL_LOOP_BYTES into XLA_FLAGS, and XLA compiles a loop of 80 kB a
    step into one kernel (a small call), which XLA's default leaves to the thunk runtime; importing
    alone changes nothing; a user's own backend options and JAXDEA_XLA_FLAGS=off leave XLA_FLAGS as
    they are."""
    flags, hoisted = _probe({})
    assert f"xla_cpu_small_while_loop_byte_threshold={compiled.SMALL_LOOP_BYTES}" in flags
    assert hoisted
    assert _probe({}, configure=False) == ("", False)
    assert _probe({"JAXDEA_XLA_FLAGS": "off"}) == ("", False)
    own = "--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=0"
    assert _probe({"XLA_FLAGS": own}) == (own, False)


def test_import_changes_nothing_in_the_process(tmp_path):
    """A fresh process importing jaxdea with a fresh HOME (and JAXDEA_CACHE_DIR unset) finds
    XLA_FLAGS, JAX's compilation-cache setting and HOME as they were, and JAX unstarted."""
    script = ("import os, jax\nimport jaxdea\nfrom jax._src import xla_bridge\n"
              "print(repr(os.environ.get('XLA_FLAGS')), jax.config.jax_compilation_cache_dir,"
              " xla_bridge.backends_are_initialized())")
    env = {k: v for k, v in os.environ.items()
           if k not in ("XLA_FLAGS", "JAXDEA_CACHE_DIR", "JAXDEA_XLA_FLAGS", "XDG_CACHE_HOME")}
    home = tmp_path / "home"
    home.mkdir()
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                         check=True, env={**env, "HOME": str(home)}, cwd=tmp_path)
    assert out.stdout.strip().splitlines()[-1] == "None None False"
    assert list(home.iterdir()) == [] and sorted(p.name for p in tmp_path.iterdir()) == ["home"]


def test_configure_xla_leaves_a_started_backend_and_the_users_flags_alone():
    jax.devices()  # started: XLA has read its flags, a new value would not act
    environ = {"XLA_FLAGS": "--xla_dump_to=/tmp/x"}
    assert not compiled.configure_xla(environ)
    assert environ == {"XLA_FLAGS": "--xla_dump_to=/tmp/x"}


def test_materialized_is_the_value_and_is_formed_once():
    """compiled.materialized: the same values (NaN, ±inf, booleans, a pytree), and a producer read
    by three outputs is emitted once in the optimised program instead of once per output (the
    duplication it exists to stop; this fails if XLA starts simplifying it away)."""
    x = jnp.array([1.5, -2.0, jnp.nan, jnp.inf, -jnp.inf, 1e-300])  # (XLA:CPU flushes subnormals)
    got = compiled.materialized({"x": x, "flag": x > 0})
    np.testing.assert_array_equal(np.asarray(got["x"]), np.asarray(x))
    np.testing.assert_array_equal(np.asarray(got["flag"]), np.asarray(x > 0))

    def outputs(once):
        def f(a, b, c):
            ok = jnp.isfinite(a) & (a > 0) & jnp.isfinite(b) & (b < 1)
            ok = once(ok)
            return jnp.where(ok, a, 0.0), jnp.where(ok, b, 1.0) * c, jnp.where(ok, c, 2.0) + a
        return jax.jit(f).lower(1.0, 0.5, 2.0).compile(
            compiler_options=compiled.compiler_options()).as_text().count("is-finite(")

    assert outputs(lambda v: v) == 6  # XLA:CPU recomputes the two checks in each output
    assert outputs(compiled.materialized) == 2
