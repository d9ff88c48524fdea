"""Compiled programs kept on disk between processes and found without tracing (:func:`cached_jit`),
and :func:`configure`, the one opt-in that switches this cache and XLA's loop threshold on.

Importing jaxdea changes nothing in the process: no environment variable, no JAX option, no file.
After :func:`configure` (the command line, the notebooks and the tests call it), two caches live
under one root (``JAXDEA_CACHE_DIR``, default ``~/.cache/jaxdea``):

* ``<root>/xla``: JAX's persistent compilation cache. Its entries are XLA:CPU machine code, which
  JAX loads and runs as it is; JAX writes them in place, and :func:`configure` deletes the ones a
  full disk or a killed process left damaged (:func:`repair_jax_cache`).
* ``<root>/programs``: a fresh process must still trace and lower a solver to compute JAX's key,
  which takes 3–6 s for a first ``frequencies`` call. :func:`cached_jit` keeps each program's
  lowered form instead, as a serialised ``jax.export`` artifact (StableHLO in JAX's flatbuffer
  format, no machine code: XLA compiles it on this machine, or JAX's cache supplies the
  compilation), keyed by what determines the program without tracing it: the function and its
  static arguments; the pytree structure and the type of every other argument; the source of every
  jaxdea module (subpackages included), the versions of jax and jaxlib, the JAX options that
  change a program (:data:`KEYED_OPTIONS`) and the devices. The process that writes an entry runs
  the same exported program, so every process gets the same bits.

Why StableHLO and not the compiled executable: a deserialised XLA:CPU executable skips lowering,
and jaxlib fills the function pointers of its LAPACK kernels only while it lowers a linear-algebra
operation: a second process that loaded such a program called a null pointer and died.

What the cache trusts and what it survives:

* The root is used only if it is new, empty or already jaxdea's (it holds :data:`MARKER`), owned by
  the user and writable by nobody else; folders are created 0700 and entries 0600. A root, folder
  or entry that fails this is refused with a :class:`CacheWarning` and not used. This keeps the
  caches same-user only: it does not make JAX's machine code safe against the user's own
  processes.
* Every entry is written to a temporary file and renamed, and records its own key and a SHA-256
  checksum: an entry copied over another one's name, truncated or of another format is deleted and
  the program exported anew. Reading never raises and never blocks: a read-only cache is only
  read; a FIFO, a folder or an unreadable file at an entry's path is skipped.
* The root is held to a size limit (:data:`DEFAULT_CACHE_BYTES`), least recently used entries
  deleted first (:func:`evict`). ``jaxdea cache clear`` deletes only :data:`SUBFOLDERS` and the
  marker (:func:`clear_cache`).

Everything else goes through ``jax.jit`` as usual: calls under a transformation (tracers in the
arguments), arrays committed to a device where there are several (an exported program runs on the
default device), JAX's debugging options (:data:`BYPASS_OPTIONS`) switched on, and every call when
the cache is off. The key holds the source of jaxdea, not the values of its module constants at
run time: a process that changes them (monkeypatching) must run with the cache off.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import inspect
import json
import os
import shutil
import stat
import tempfile
import threading
import time
import warnings
import weakref
import zlib
from pathlib import Path

import jax
import jax.numpy as jnp
import jaxlib
from jax import export

KEYED_OPTIONS = ("jax_enable_x64", "jax_default_matmul_precision", "jax_numpy_rank_promotion",
                 "jax_numpy_dtype_promotion", "jax_default_prng_impl", "jax_threefry_partitionable",
                 "jax_platforms", "jax_use_shardy_partitioner")
"""JAX options that enter the key (they change the program a function traces to)."""
COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
"""XLA options of every program jaxdea compiles (:func:`jit`). XLA:CPU's newer fusion emitters
(the default) took 1.6–1.9× longer to compile the solvers for no faster code here: the first
``frequencies`` call 6.1 → 4.0 s, ``critical_voltage`` 12.8 → 8.1 s, ``characteristic`` 1.25 →
0.78 s (caches off), while ``characteristic`` at batch 4096, the Fig. 3 sweep and the continuation
curves ran as fast or 5–10 % faster (benchmarks/). Other backends ignore the option."""
CPU_OPTIONS = {"xla_backend_optimization_level": 1}
"""Added on the CPU backend only (:func:`compiler_options`): LLVM optimisation level 1 instead of 3
compiled the order-m continuation program in 17.2 s instead of 19.0 s for the same run time
(0.52 s) and the same ``characteristic`` rate at batch 4096 (108 k/s against 101 k/s, within the
noise); ``jaxdea figures`` cold 60.8 → 58.7 s. Level 0 compiled in 13 s but ran 3.5× slower. GPU
backends use the level for their kernels too, so it stays off there."""


def materialized(x):
    """``x`` (an array, or a pytree of them), computed once in a compiled program and read by every
    consumer: the exact sum x + 0 as the last entry of a cumulative sum (a reduce-window, which XLA
    neither simplifies away nor fuses into other consumers; a plain reduction of a scalar it
    simplifies to x). XLA:CPU fuses a cheap elementwise producer into each consumer fusion
    instead, so a value used by many outputs (a root solver's lane state, the admissibility of the
    inputs) is emitted once per output: the 3×3 determinant's slope 18 times, the admissibility
    43 times in every ``frequencies`` program (22 744 → 18 651 lines of optimised HLO, its
    compilation 12 % shorter). The value is x (x + 0 = x; −0 + 0 = +0; subnormals flush to zero,
    as everywhere in XLA:CPU), booleans pass as 0.0 and 1.0; but a value XLA no longer recomputes
    inside a consumer's kernel is no longer contracted with its arithmetic (fused multiply-adds),
    so the results around it may round differently, by an ulp or a few."""
    def once(v):
        v = jnp.asarray(v)
        if v.dtype == jnp.bool_:
            return once(v.astype(jnp.float64)) > 0.5
        return jnp.cumsum(jnp.stack([v, jnp.zeros_like(v)]), axis=0)[1]

    return jax.tree_util.tree_map(once, x)


def compiler_options() -> dict:
    """:data:`COMPILER_OPTIONS`, with :data:`CPU_OPTIONS` where the default backend is the CPU."""
    return {**COMPILER_OPTIONS, **(CPU_OPTIONS if jax.default_backend() == "cpu" else {})}


SMALL_LOOP_BYTES = 1 << 20
"""XLA:CPU's small-while-loop threshold that :func:`configure` sets (:func:`configure_xla`): a while
loop whose iteration accesses fewer bytes (and holds no dot, convolution or custom call) is
compiled into one kernel instead of running its body thunk by thunk (XLA's default: 1 KiB). The
continuation's loops (lanes × sublayers × 4×4 matrices, tens of KiB) then stop paying the runtime's
per-thunk dispatch, and their thunks no longer migrate between the two threads of a 2-core
machine, which made every other call of the same curve 1.5× slower. Measured side by side in fresh
processes (benchmarks/README.md, section k): the unstretched 200-α̂ curve 12.5 → 10.5 ms best and
18.9 → 13.0 ms median; the first calls unchanged; the roots and values of seven workloads
bit-identical, a gradient 2 ulp apart. Loops over large batches (a 4096-point ``characteristic``)
keep the thunk runtime and its threads."""


def configure_xla(environ=os.environ) -> bool:
    """Set :data:`SMALL_LOOP_BYTES` in ``XLA_FLAGS`` (``--xla_backend_extra_options``), where it can
    still act and the user has not chosen otherwise: JAX's backends not yet started (XLA reads its
    flags once, then), no ``xla_backend_extra_options`` in ``XLA_FLAGS`` already, and
    ``JAXDEA_XLA_FLAGS`` not ``off``. Called by :func:`configure` only (never at import). Returns
    whether it set the flag. The flag changes how XLA compiles; results agree to rounding
    (bit-identical on the solvers and curves measured, a gradient 2 ulp apart)."""
    flags = environ.get("XLA_FLAGS", "")
    if environ.get("JAXDEA_XLA_FLAGS", "").lower() == "off" or "xla_backend_extra_options" in flags:
        return False
    try:  # XLA reads XLA_FLAGS when the first backend starts; no public JAX call says whether it has
        from jax._src import xla_bridge
        started = xla_bridge.backends_are_initialized()
    except (ImportError, AttributeError):  # another JAX: leave XLA's defaults
        return False
    if started:
        return False
    option = f"--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}"
    environ["XLA_FLAGS"] = f"{flags} {option}".strip()
    return True


BYPASS_OPTIONS = ("jax_debug_nans", "jax_debug_infs", "jax_disable_jit", "jax_enable_checks",
                  "jax_check_tracer_leaks", "jax_default_device")
"""JAX options under which every call goes through ``jax.jit`` (they act at tracing or dispatch)."""
MAGIC = b"jaxdea-exported-1\n"
"""First line of an entry; the second is the SHA-256 of the artifact (hex), then the artifact."""
PROGRAMS: list[CachedJit] = []
"""Every :class:`CachedJit` defined (the cross-process tests check that each one is stored)."""


class CacheWarning(UserWarning):
    """A cache folder or entry refused: not the current user's, writable by group or others, or a
    folder that holds files jaxdea did not write."""


DEFAULT_CACHE_BYTES = 1 << 30
"""Size limit of a cache root (programs and JAX's compilations together) unless :func:`configure`
says otherwise; the least recently used entries go first."""
MIN_FREE_BYTES = 64 << 20
"""JAX's compilation cache is switched on only where its disk has this much free space."""
MARKER = "CACHEDIR.TAG"
"""The file that marks a folder as a jaxdea cache root (the Cache Directory Tagging format, which
backup tools honour). jaxdea stores entries, and ``jaxdea cache clear`` deletes, only under a root
that holds it."""
MARKER_TEXT = ("Signature: 8a477f597d28d172789f06886806bc55\n"
               "# This file is a cache directory tag created by jaxdea (compiled programs).\n")
SUBFOLDERS = ("programs", "xla")
"""What jaxdea writes under a root besides :data:`MARKER`: its exported programs and JAX's
compilation cache."""


@dataclasses.dataclass(frozen=True)
class Configuration:
    """What :func:`configure` switched on: the cache root (None: no disk cache), whether XLA's
    small-loop threshold was set, and the cache's size limit in bytes."""
    cache_root: Path | None
    xla_flags: bool
    cache_bytes: int


_SETTINGS = {"configured": False, "root": None, "bytes": DEFAULT_CACHE_BYTES, "jax_cache": None}
"""The process's :func:`configure` choices: whether the disk cache is on, an explicit root (None:
``JAXDEA_CACHE_DIR`` or the default, read at every call), the size limit, and the folder jaxdea
gave JAX's compilation cache (so that ``configure(cache=False)`` can take it back)."""


def configure(*, cache: bool | str | os.PathLike = True, xla_flags: bool = True,
              cache_bytes: int = DEFAULT_CACHE_BYTES) -> Configuration:
    """Opt in to what makes jaxdea's first calls and curves fast; importing jaxdea does none of it.

    * ``cache``: keep compiled programs on disk between processes: jaxdea's exported programs
      (StableHLO, checked against their key and a checksum) in ``<root>/programs`` and JAX's own
      compilation cache (XLA machine code, which JAX loads and runs as it is) in ``<root>/xla``,
      unless the process already set ``jax_compilation_cache_dir`` or the disk has less than
      :data:`MIN_FREE_BYTES` free. ``True``: the root is
      ``JAXDEA_CACHE_DIR`` (an empty value means the default), else ``~/.cache/jaxdea``; a path:
      that root; ``False``: no disk cache. ``JAXDEA_CACHE_DIR=off`` turns the cache off whatever
      the call says. The root must be new, empty, or already jaxdea's (:data:`MARKER`), owned by
      the user and writable by nobody else; otherwise it is refused with a :class:`CacheWarning`.
      Damaged JAX entries are deleted here; beyond ``cache_bytes`` the least recently used entries
      are.
    * ``xla_flags``: XLA:CPU's small-while-loop threshold (:data:`SMALL_LOOP_BYTES`) in
      ``XLA_FLAGS``, which also applies to the rest of the process's programs; effective only
      before JAX's first computation, and left alone if ``XLA_FLAGS`` already sets backend options
      or ``JAXDEA_XLA_FLAGS=off``.

    The command line, the notebooks and the tests call it first. Returns a :class:`Configuration`.
    """
    if isinstance(cache_bytes, bool) or not isinstance(cache_bytes, int) or cache_bytes < 1 << 20:
        raise ValueError(f"cache_bytes must be an int >= {1 << 20} (1 MiB), got {cache_bytes!r}")
    explicit = None if isinstance(cache, bool) else Path(cache).expanduser()
    _SETTINGS.update(configured=cache is not False, root=explicit, bytes=cache_bytes)
    flags = configure_xla() if xla_flags else False
    root = cache_root()
    jax_cache = private_folder("xla") if root is not None else None
    if jax_cache is not None:
        repair_jax_cache(jax_cache)
        evict(root, cache_bytes)
        if shutil.disk_usage(jax_cache).free < MIN_FREE_BYTES:
            jax_cache = None  # JAX writes in place and warns on a failed write: not on a full disk
    given = _SETTINGS["jax_cache"]
    if jax.config.jax_compilation_cache_dir in (None, given and str(given)):
        jax.config.update("jax_compilation_cache_dir", None if jax_cache is None else str(jax_cache))
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
        _SETTINGS["jax_cache"] = jax_cache
    return Configuration(root if private_folder("programs") is not None else None, flags, cache_bytes)


def cache_off() -> bool:
    """No disk cache: :func:`configure` not called (or with ``cache=False``), or
    ``JAXDEA_CACHE_DIR=off`` (read at every call, cheaply)."""
    return not _SETTINGS["configured"] or os.environ.get("JAXDEA_CACHE_DIR", "").lower() == "off"


def configured_root() -> Path:
    """The root the cache uses when on: :func:`configure`'s path, else ``JAXDEA_CACHE_DIR`` (an empty
    value means the default), else ``~/.cache/jaxdea``."""
    if _SETTINGS["root"] is not None:
        return _SETTINGS["root"]
    return Path(os.environ.get("JAXDEA_CACHE_DIR") or os.path.join("~", ".cache", "jaxdea")).expanduser()


def cache_root() -> Path | None:
    """The cache root in use (:func:`configured_root`), or None when the cache is off."""
    return None if cache_off() else configured_root()


def unsafe_reason(info: os.stat_result) -> str | None:
    """Why a cache file or folder with this ``stat`` must not be trusted, or None: it must belong to
    the current user and be writable by nobody else (another user could otherwise plant a program
    that every process loading it runs)."""
    uid = os.getuid() if hasattr(os, "getuid") else info.st_uid
    if info.st_uid != uid:
        return f"owned by uid {info.st_uid}, not by the current user (uid {uid})"
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"writable by group or others (mode {stat.filemode(info.st_mode)})"
    return None


def _refuse(path, reason):
    warnings.warn(f"jaxdea cache: ignoring {path}: {reason}; compiling in this process instead "
                  "(fix the permissions, choose another JAXDEA_CACHE_DIR, or set JAXDEA_CACHE_DIR=off)",
                  CacheWarning, stacklevel=3)


def _unlink(path: Path) -> None:
    """Delete a file jaxdea may repair; a read-only folder keeps it (the cache is then only read)."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass


def claim_root(root: Path) -> str | None:
    """Make ``root`` a jaxdea cache root (0700, :data:`MARKER` written) if it is new, empty or holds
    only jaxdea's folders; returns why it cannot be used, or None. Never writes into a folder that
    holds anything else: an unset-looking ``JAXDEA_CACHE_DIR`` cannot turn the user's own folder
    into a cache that ``jaxdea cache clear`` would empty."""
    try:
        root.mkdir(mode=0o700, parents=True)
    except FileExistsError:
        pass
    info = os.stat(root)  # a link is judged by its target
    reason = unsafe_reason(info) or (None if stat.S_ISDIR(info.st_mode) else "not a folder")
    if reason:
        return reason
    if (root / MARKER).is_file():
        return None
    foreign = sorted(set(os.listdir(root)) - set(SUBFOLDERS))
    if foreign:
        return (f"it holds files jaxdea did not write ({', '.join(foreign[:3])}"
                f"{', ...' if len(foreign) > 3 else ''}) and no {MARKER}; use a new or empty folder")
    write_atomically(root / MARKER, MARKER_TEXT.encode())
    return None


def private_folder(name: str) -> Path | None:
    """``<root>/<name>``, created with the root (:func:`claim_root`) mode 0700 where missing, or None:
    the cache is off, cannot be made (a read-only home), or the root or the folder is refused
    (:func:`unsafe_reason`, :func:`claim_root`: with a :class:`CacheWarning`)."""
    root = cache_root()
    if root is None:
        return None
    try:
        reason = claim_root(root)
        if reason:
            _refuse(root, reason)
            return None
        folder = root / name
        try:
            folder.mkdir(mode=0o700)
        except FileExistsError:
            pass
        info = os.stat(folder)
        reason = unsafe_reason(info) or (None if stat.S_ISDIR(info.st_mode) else "not a folder")
        if reason:
            _refuse(folder, reason)
            return None
    except OSError:
        return None
    return folder


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path`` (mode 0600), flush it to disk and rename
    it over ``path``: readers see the old file or the whole new one. Raises OSError (the temporary
    file removed)."""
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(data)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(name, path)
    except BaseException:
        _unlink(Path(name))
        raise


def _decompress(data: bytes) -> bytes:
    """Undo JAX's compression of a compilation-cache entry (zstd where a zstd module is installed,
    as JAX chooses, else zlib)."""
    try:
        import zstandard
    except ImportError:
        return zlib.decompress(data)
    return zstandard.ZstdDecompressor().decompress(data)


def repair_jax_cache(folder: Path) -> int:
    """Delete JAX compilation-cache entries in ``folder`` that are empty or do not decompress (JAX
    writes them in place, so a full disk or a killed process leaves them truncated, and JAX then
    warns and recompiles on every later run). Only entries newer than the last check are read.
    Returns how many were deleted."""
    stamp = folder / ".jaxdea-checked"
    try:
        since = stamp.stat().st_mtime_ns
    except OSError:
        since = 0
    deleted = 0
    for path in folder.glob("*-cache"):
        try:
            info = path.stat()
            if info.st_mtime_ns < since or not stat.S_ISREG(info.st_mode):
                continue
            data = path.read_bytes()
            if data:
                _decompress(data)
                continue
        except OSError:
            continue
        except Exception:  # noqa: BLE001 - zlib.error, zstd.ZstdError: a damaged entry
            pass
        _unlink(path)
        deleted += 1
    try:
        stamp.touch()
    except OSError:
        pass
    return deleted


def _entries(root: Path):
    """(recency, size, path) of every entry under a root: programs and JAX's compilations."""
    out = []
    for path in [*(root / "programs").glob("*.jaxexport"), *(root / "xla").glob("*-cache")]:
        try:
            info = path.stat()
        except OSError:
            continue
        if stat.S_ISREG(info.st_mode):
            out.append((max(info.st_mtime, info.st_atime), info.st_size, path))
    return out


def evict(root: Path, limit: int) -> int:
    """Delete the least recently used entries under ``root`` until they take at most ``limit``
    bytes (a read renews an entry's time), and temporary files that a killed writer left more than
    an hour ago. Returns how many entries were deleted."""
    now = time.time()
    for folder in SUBFOLDERS:
        for tmp in (root / folder).glob(".*.tmp"):
            try:
                if now - tmp.stat().st_mtime > 3600:
                    _unlink(tmp)
            except OSError:
                pass
    entries = sorted(_entries(root))
    total = sum(size for _, size, _ in entries)
    deleted = 0
    for _, size, path in entries:
        if total <= limit:
            break
        _unlink(path)
        total -= size
        deleted += 1
    return deleted


def _sources_digest() -> str:
    """Digest of jaxdea's source files as they are on disk now (every module, subpackages too)."""
    digest = hashlib.sha256()
    package = Path(__file__).parent
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


IMPORTED_SOURCES = _sources_digest()
"""The digest of jaxdea's sources when it was imported (reading them only). The files can change
under a running process (an upgrade in place, a checkout): its programs are those of the sources
it imported, so it must not store them under, or load those of, the sources on disk."""


def _environment_digest() -> str | None:
    """Digest of everything a program depends on besides its function and arguments, or None where
    the sources on disk are no longer those this process imported (measured: a process that
    imported one version and made its first cached call after the files changed had keyed its
    programs on the new files); then no program is read from or written to the disk cache."""
    sources = _sources_digest()
    if sources != IMPORTED_SOURCES:
        return None
    digest = hashlib.sha256(sources.encode() + b"\0")
    devices = [(d.platform, d.device_kind, d.id) for d in jax.devices()]
    for part in (jax.__version__, jaxlib.__version__, repr(devices)):
        digest.update(part.encode() + b"\0")
    return digest.hexdigest()


_environment = functools.cache(_environment_digest)  # devices and sources are fixed in a process


@functools.cache
def _several_devices() -> bool:
    return len(jax.devices()) > 1


def _options(names):
    return tuple(getattr(jax.config, name, None) for name in names)


def serializable(cls):
    """Class decorator: register a pytree type that a :func:`cached_jit` program returns for
    ``jax.export`` serialisation under the name ``<module>.<name>``: a NamedTuple, or a dataclass
    registered with ``jax.tree_util.register_dataclass`` whose static fields are JSON values
    (strings, numbers, None), stored as JSON (no pickle)."""
    name = f"{cls.__module__}.{cls.__qualname__}"
    if hasattr(cls, "_fields"):
        export.register_namedtuple_serialization(cls, serialized_name=name)
    else:
        export.register_pytree_node_serialization(
            cls, serialized_name=name,
            serialize_auxdata=lambda aux: json.dumps(list(aux)).encode(),
            deserialize_auxdata=lambda data: tuple(json.loads(data)))
    return cls


def read_entry(path: Path, key: str | None = None) -> bytes | None:
    """The artifact stored at ``path`` for ``key`` (the entry's name), or None. Never raises and
    never blocks: a missing or unreadable entry, a FIFO or a folder at its path is skipped; one
    refused (:func:`unsafe_reason`) is skipped with a warning; one damaged, of another format or
    recorded under another key is deleted where the folder is writable. A read renews the entry's
    time for :func:`evict`."""
    key = path.stem if key is None else key
    try:
        handle = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError:
        return None
    try:
        with os.fdopen(handle, "rb") as stream:
            info = os.fstat(stream.fileno())
            reason = unsafe_reason(info)
            if reason:
                _refuse(path, reason)
                return None
            if not stat.S_ISREG(info.st_mode):
                return None
            data = stream.read()
    except OSError:
        return None
    head, _, rest = data.partition(b"\n")
    recorded, _, rest = rest.partition(b"\n")
    checksum, _, payload = rest.partition(b"\n")
    if (head + b"\n" != MAGIC or recorded != key.encode()
            or hashlib.sha256(recorded + b"\n" + payload).hexdigest().encode() != checksum):
        _unlink(path)
        return None
    try:
        os.utime(path)
    except OSError:
        pass
    return payload


def write_entry(path: Path, payload: bytes, key: str | None = None) -> bool:
    """Store ``payload`` at ``path`` for ``key`` (the entry's name) atomically (readers see the
    whole entry or none), mode 0600, then :func:`evict` beyond the size limit. Returns whether it
    was stored: a read-only or full disk only costs the next process its compilation."""
    key = (path.stem if key is None else key).encode()
    try:
        write_atomically(path, MAGIC + key + b"\n" + hashlib.sha256(key + b"\n" + payload).hexdigest()
                         .encode() + b"\n" + payload)
    except OSError:
        return False
    try:
        evict(path.parent.parent, _SETTINGS["bytes"])
    except OSError:
        pass
    return True


def clear_cache(root: Path | None = None) -> Path:
    """Delete what jaxdea wrote under the cache root (``jaxdea cache clear``): its folders
    :data:`SUBFOLDERS` and :data:`MARKER`, then the root if nothing else is left. Returns the root.
    Raises ValueError for a folder that is not a jaxdea cache root (no :data:`MARKER`): nothing is
    deleted there."""
    root = configured_root() if root is None else root
    if not root.exists():
        return root
    if not root.is_dir() or not (root / MARKER).is_file():
        raise ValueError(f"{root} is not a jaxdea cache (no {MARKER}): nothing deleted")
    for name in SUBFOLDERS:
        if (root / name).exists():
            shutil.rmtree(root / name)
    (root / MARKER).unlink()
    try:
        root.rmdir()
    except OSError:  # the user's own files stay, and so does the root
        pass
    return root


_PROGRAMS: weakref.WeakSet = weakref.WeakSet()
"""Every :class:`CachedJit` of the process (for :func:`clear_memory`)."""


def clear_memory() -> None:
    """Drop the compiled programs this process holds in memory (every :func:`cached_jit`'s loaded
    programs and JAX's own jit caches): a long session, or a test run, that has compiled many
    configurations frees their executables. The disk cache is kept, so the next call of a program
    loads it again (≈ 0.1–0.6 s) instead of compiling it."""
    for program in list(_PROGRAMS):
        program._calls.clear()
    jax.clear_caches()


class CachedJit:
    """``jax.jit(fun, static_argnames=...)`` whose first call in a process may load the program's
    exported form from disk instead of tracing it (module docstring). Other attributes (``lower``,
    ``trace``, ...) are those of the underlying jitted function."""

    def __init__(self, fun, static_argnames=()):
        self._fun = fun
        self._static = (static_argnames,) if isinstance(static_argnames, str) else tuple(
            static_argnames)
        self._jit = jit(fun, static_argnames=self._static)
        self._signature = inspect.signature(fun)
        self._name = f"{fun.__module__}.{fun.__qualname__}"
        self._calls = {}  # key -> jax.jit of the exported program, this process
        self._lock, self._key_locks = threading.Lock(), {}  # key -> the lock of its first call
        _PROGRAMS.add(self)
        self.counts = {"loaded": 0, "exported": 0, "stored": 0}  # entries read / traced here / written
        functools.update_wrapper(self, fun)
        PROGRAMS.append(self)

    def __getattr__(self, name):
        return getattr(self._jit, name)

    def _cache_size(self) -> int:
        """Programs this process holds: exported or loaded here, and those of ``jax.jit``."""
        return len(self._calls) + self._jit._cache_size()

    def _key(self, args, kwargs):
        """(key, static arguments, dynamic leaves, their tree), or None where the call must go
        through ``jax.jit``."""
        if any(_options(BYPASS_OPTIONS)):
            return None
        bound = self._signature.bind(*args, **kwargs)
        bound.apply_defaults()
        statics = {k: bound.arguments[k] for k in self._static}
        dynamic = {k: v for k, v in bound.arguments.items() if k not in self._static}
        leaves, tree = jax.tree_util.tree_flatten(dynamic)
        placed = _several_devices()  # committed arrays then choose their device: jax.jit
        types = []
        for leaf in leaves:
            if isinstance(leaf, jax.core.Tracer) or (
                    placed and isinstance(leaf, jax.Array) and leaf.committed):
                return None
            aval = jax.typeof(leaf)
            types.append((aval.shape, aval.dtype, aval.weak_type))
        key = (tuple((k, repr(v)) for k, v in statics.items()), str(tree), tuple(types),
               _options(KEYED_OPTIONS))
        return key, statics, leaves, tree

    def _entry(self, key) -> str | None:
        """The entry's file name: a digest of the environment, the function and the key (None where
        the sources changed since import: :func:`_environment_digest`)."""
        environment = _environment()
        if environment is None:
            return None
        return hashlib.sha256(f"{environment}\0{self._name}\0{key!r}".encode()).hexdigest()

    def _export(self, statics, leaves, tree):
        """Trace and lower the program for these arguments as a flat function of the leaves."""
        def flat(*values):
            return self._fun(**jax.tree_util.tree_unflatten(tree, values), **statics)

        return export.export(jax.jit(flat))(*leaves)

    def _program(self, key, statics, leaves, tree):
        """The exported program: read from the cache, else traced here and written."""
        folder = private_folder("programs")
        name = self._entry(key)
        path = None if folder is None or name is None else folder / f"{name}.jaxexport"
        payload = None if path is None else read_entry(path, name)
        exported = None
        if payload is not None:
            try:
                exported = export.deserialize(bytearray(payload))
                self.counts["loaded"] += 1
            except Exception:  # noqa: BLE001 - another format despite the key: export anew
                _unlink(path)
        if exported is None:
            exported = self._export(statics, leaves, tree)
            self.counts["exported"] += 1
            if path is not None:
                try:
                    payload = exported.serialize()
                except Exception:  # noqa: BLE001 - an output type not registered (serializable)
                    return jax.jit(exported.call, compiler_options=compiler_options())
                self.counts["stored"] += write_entry(path, payload, name)
        return jax.jit(exported.call, compiler_options=compiler_options())

    def __call__(self, *args, **kwargs):
        found = None if cache_off() else self._key(args, kwargs)
        if found is None:
            return self._jit(*args, **kwargs)
        key, statics, leaves, tree = found
        call = self._calls.get(key)
        if call is None:  # threads asking for the same new program: one loads and compiles it
            with self._lock:
                key_lock = self._key_locks.setdefault(key, threading.Lock())
            try:
                with key_lock:
                    call = self._calls.get(key)
                    if call is None:
                        call = self._program(key, statics, leaves, tree)
                        out = call(*leaves)  # compiled here, under the lock
                        self._calls[key] = call
                        return out
            finally:
                with self._lock:
                    self._key_locks.pop(key, None)
        return call(*leaves)


class Jitted:
    """``jax.jit(fun, ...)`` compiled with :func:`compiler_options` where it is the top-level
    program; inside another trace (a caller's ``jit``, ``grad``, ``lax.map``...) it is the plain
    ``jax.jit``, since JAX accepts compiler options on top-level programs only (the enclosing
    program's options then apply). Other attributes (``lower``, ``trace``...) are the top-level
    function's."""

    def __init__(self, fun, **kwargs):
        self._fun, self._kwargs, self._top_jit = fun, kwargs, None
        self._nested = jax.jit(fun, **kwargs)
        functools.update_wrapper(self, fun)

    @property
    def _top(self):
        """The top-level ``jax.jit``, made at first use (:func:`compiler_options` asks for the
        default backend, which must not be started at import)."""
        if self._top_jit is None:
            self._top_jit = jax.jit(self._fun, compiler_options=compiler_options(), **self._kwargs)
        return self._top_jit

    def __getattr__(self, name):
        return getattr(self._top, name)

    def _cache_size(self) -> int:
        return self._top._cache_size() + self._nested._cache_size()

    def __call__(self, *args, **kwargs):
        if any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves((args, kwargs))):
            return self._nested(*args, **kwargs)
        try:
            return self._top(*args, **kwargs)
        except ValueError as error:  # concrete arguments, but staged into a caller's trace
            if "compiler_options" not in str(error):
                raise
            return self._nested(*args, **kwargs)


def jit(fun=None, **kwargs):
    """:class:`Jitted`: ``jax.jit`` with jaxdea's :func:`compiler_options` (``@jit`` or
    ``@jit(static_argnames=...)``).

    A caller's own ``jax.jit`` around jaxdea functions compiles with the caller's options: pass
    ``compiler_options=jaxdea.compiled.compiler_options()`` to it for the same compile settings and
    times. The values agree with jaxdea's own calls to rounding: inside the caller's program XLA may
    fuse differently (under either options: a group velocity came out 1 ulp apart)."""
    if fun is None:
        return functools.partial(jit, **kwargs)
    return Jitted(fun, **kwargs)


def cached_jit(fun=None, *, static_argnames=()):
    """Decorator: :class:`CachedJit` of ``fun`` (``@cached_jit`` or
    ``@cached_jit(static_argnames=(...))``)."""
    if fun is None:
        return functools.partial(cached_jit, static_argnames=static_argnames)
    return CachedJit(fun, static_argnames)
