"""Compiled programs kept on disk between processes and found without tracing (:func:`cached_jit`).

JAX's persistent cache (``<root>/xla``, switched on in :mod:`jaxdea`) keeps the XLA compilation, but
a fresh process must still trace and lower a solver to compute its key before it can load it: with a
warm JAX cache alone the first ``frequencies`` call takes 3–6 s, almost all of it tracing.
:func:`cached_jit` keeps each program's lowered form instead, as a serialised ``jax.export``
artifact (StableHLO in JAX's flatbuffer format), keyed by what determines the program without
tracing it:

* the function (module and name) and its static arguments;
* the pytree structure (static fields included) and the type of every other argument (shape,
  dtype, weak type);
* the source of every jaxdea module, the versions of jax and jaxlib, the JAX options that change a
  program (:data:`KEYED_OPTIONS`) and the devices.

A fresh process deserialises the artifact and runs it through ``jax.jit(exported.call)``, whose
compilation JAX's persistent cache then serves (≈ 0.6 s for a first ``frequencies`` call). The
process that writes an entry runs the same exported program, so every process computes with the
same program and gets the same bits.

Why StableHLO and not the compiled executable (what this module stored before): a deserialised
XLA:CPU executable skips lowering, and jaxlib fills the function pointers of its LAPACK kernels
(``lapack_dgesdd_ffi``, ``lapack_dtrsm_ffi``… of the mode shapes' SVD and solves) only while it
lowers a linear-algebra operation (``jaxlib.lapack.prepare_lapack_call``): a second process that
loaded such a program called a null pointer and died with a segmentation fault. Deserialising a
``jax.export`` artifact initialises those kernels (``jax._src.export._export``), and an artifact
holds no machine code: XLA compiles it on this machine (or JAX's cache supplies the compilation).
Nothing is pickled: entries are the artifact's bytes behind a magic line and a SHA-256 checksum.

The cache never runs someone else's program: the root and its folders are created 0700 and entries
0600; a folder or entry that is not owned by the current user or is writable by group or others is
refused with a :class:`CacheWarning` (the folder is then not used at all: no entry is read or
written there), and :mod:`jaxdea` switches JAX's own cache on only under the same conditions. An
entry that is damaged (checksum), of another format, or fails to deserialise is deleted and the
program exported anew; an entry that cannot be written is skipped: the cache never changes a
result. Everything else goes through ``jax.jit`` as usual: calls under a transformation (tracers in
the arguments), arrays committed to a device where there are several (the blocks of a sharded
sweep; an exported program runs on the default device), JAX's debugging options
(:data:`BYPASS_OPTIONS`) switched on, and every call when the cache is off
(``JAXDEA_CACHE_DIR=off``).

The key holds the source of jaxdea, not the values of its module constants at run time: a process
that changes them (monkeypatching) must run with the cache off. Entries live in
``<root>/programs`` (root: ``JAXDEA_CACHE_DIR``, by default ``~/.cache/jaxdea``), 0.1–2 MB each;
``jaxdea cache clear`` empties the root, ``jaxdea cache info`` lists it.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import os
import shutil
import stat
import tempfile
import threading
import warnings
import weakref
from pathlib import Path

import jax
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


def compiler_options() -> dict:
    """:data:`COMPILER_OPTIONS`, with :data:`CPU_OPTIONS` where the default backend is the CPU."""
    return {**COMPILER_OPTIONS, **(CPU_OPTIONS if jax.default_backend() == "cpu" else {})}


SMALL_LOOP_BYTES = 1 << 20
"""XLA:CPU's small-while-loop threshold that jaxdea sets at import (:func:`configure_xla`): a while
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
    ``JAXDEA_XLA_FLAGS`` not ``off``. Called when :mod:`jaxdea` is imported, like its JAX
    compilation cache. Returns whether it set the flag. The flag changes how XLA compiles; results
    agree to rounding (bit-identical on the solvers and curves measured, a gradient 2 ulp apart)."""
    flags = environ.get("XLA_FLAGS", "")
    if environ.get("JAXDEA_XLA_FLAGS", "").lower() == "off" or "xla_backend_extra_options" in flags:
        return False
    try:
        from jax._src import xla_bridge
        started = xla_bridge.backends_are_initialized()
    except (ImportError, AttributeError):  # another JAX: leave XLA's defaults
        return False
    if started:
        return False
    option = f"--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold={SMALL_LOOP_BYTES}"
    environ["XLA_FLAGS"] = f"{flags} {option}".strip()
    return True


configure_xla()  # at import, before any jaxdea module can start a backend (this one is imported first)


BYPASS_OPTIONS = ("jax_debug_nans", "jax_debug_infs", "jax_disable_jit", "jax_enable_checks",
                  "jax_check_tracer_leaks", "jax_default_device")
"""JAX options under which every call goes through ``jax.jit`` (they act at tracing or dispatch)."""
MAGIC = b"jaxdea-exported-1\n"
"""First line of an entry; the second is the SHA-256 of the artifact (hex), then the artifact."""
PROGRAMS: list[CachedJit] = []
"""Every :class:`CachedJit` defined (the cross-process tests check that each one is stored)."""


class CacheWarning(UserWarning):
    """A cache folder or entry refused: not the current user's, or writable by group or others."""


def cache_off() -> bool:
    """``JAXDEA_CACHE_DIR=off``: no cache on disk (read at every call, cheaply)."""
    return os.environ.get("JAXDEA_CACHE_DIR", "").lower() == "off"


def cache_root() -> Path | None:
    """The cache root (``JAXDEA_CACHE_DIR``, default ``~/.cache/jaxdea``), or None when it is off."""
    if cache_off():
        return None
    return Path(os.environ.get("JAXDEA_CACHE_DIR", os.path.join("~", ".cache", "jaxdea"))).expanduser()


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
                  "(fix the permissions, run `jaxdea cache clear`, or set JAXDEA_CACHE_DIR=off)",
                  CacheWarning, stacklevel=3)


def private_folder(name: str) -> Path | None:
    """``<root>/<name>``, created with the root mode 0700 where missing, or None: the cache is off,
    cannot be made (a read-only home), or the root or the folder is not safe (:func:`unsafe_reason`;
    refused with a :class:`CacheWarning`)."""
    root = cache_root()
    if root is None:
        return None
    try:
        root.parent.mkdir(parents=True, exist_ok=True)
        for folder in (root, root / name):
            try:
                folder.mkdir(mode=0o700)
            except FileExistsError:
                pass
            info = os.stat(folder)  # a link is judged by its target
            reason = unsafe_reason(info) or (None if stat.S_ISDIR(info.st_mode) else "not a folder")
            if reason:
                _refuse(folder, reason)
                return None
    except OSError:
        return None
    return root / name


def _environment_digest() -> str:
    """Digest of everything a program depends on besides its function and arguments."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
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


def read_entry(path: Path) -> bytes | None:
    """The artifact stored at ``path``, or None: missing; refused (:func:`unsafe_reason`, with a
    warning); damaged or of another format (deleted)."""
    try:
        with open(path, "rb") as stream:
            info = os.fstat(stream.fileno())
            reason = unsafe_reason(info) or (None if stat.S_ISREG(info.st_mode) else "not a file")
            if reason:
                _refuse(path, reason)
                return None
            data = stream.read()
    except FileNotFoundError:
        return None
    except OSError:
        return None
    head, _, rest = data.partition(b"\n")
    checksum, _, payload = rest.partition(b"\n")
    if head + b"\n" != MAGIC or hashlib.sha256(payload).hexdigest().encode() != checksum:
        path.unlink(missing_ok=True)
        return None
    return payload


def write_entry(path: Path, payload: bytes) -> None:
    """Store ``payload`` at ``path`` atomically (readers see the whole entry or none), mode 0600;
    a read-only or full disk only costs the next process its compilation."""
    try:
        handle, name = tempfile.mkstemp(dir=path.parent, suffix=".tmp")  # mode 0600
        with os.fdopen(handle, "wb") as stream:
            stream.write(MAGIC + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)
        os.replace(name, path)
    except OSError:
        if "name" in locals():
            Path(name).unlink(missing_ok=True)


def clear_cache() -> Path | None:
    """Delete the cache root (``jaxdea cache clear``); returns it, or None when the cache is off."""
    root = cache_root()
    if root is not None and root.exists():
        shutil.rmtree(root)
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


_TRACING = threading.RLock()
"""Held while a :class:`CachedJit` traces and lowers a program. Tracing is Python and holds the GIL,
so threads that trace at the same time only interleave: each finished when all of them had, and no
compilation (which releases the GIL) could start before. One at a time, the first program compiles
beside the next one's tracing: ``jaxdea figures`` with an empty cache began its first compilation
at 3.4 s instead of 5.4 s and ran 41.2–42.2 s instead of 43.0–43.6 s in two pairs side by side
(a third pair was equal: 42.2 against 42.0 s)."""
TRACING_WAIT = 30.0
"""Seconds a trace waits for :data:`_TRACING` before it goes on without it: the lock only orders
work: a program traced inside another one's trace while a thread that waits for the lock holds its
first call would otherwise wait forever."""


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

    def _entry(self, key) -> str:
        """The entry's file name: a digest of the environment, the function and the key."""
        return hashlib.sha256(f"{_environment()}\0{self._name}\0{key!r}".encode()).hexdigest()

    def _export(self, statics, leaves, tree):
        """Trace and lower the program for these arguments as a flat function of the leaves."""
        def flat(*values):
            return self._fun(**jax.tree_util.tree_unflatten(tree, values), **statics)

        return export.export(jax.jit(flat))(*leaves)

    def _program(self, key, statics, leaves, tree):
        """The exported program: read from the cache, else traced here and written."""
        folder = private_folder("programs")
        path = None if folder is None else folder / f"{self._entry(key)}.jaxexport"
        payload = None if path is None else read_entry(path)
        exported = None
        if payload is not None:
            try:
                exported = export.deserialize(bytearray(payload))
                self.counts["loaded"] += 1
            except Exception:  # noqa: BLE001 - another format despite the key: export anew
                path.unlink(missing_ok=True)
        if exported is None:
            # one trace at a time (:data:`_TRACING`); one that waits longer goes on beside the others
            tracing = _TRACING.acquire(timeout=TRACING_WAIT)
            try:
                exported = self._export(statics, leaves, tree)
            finally:
                if tracing:
                    _TRACING.release()
            self.counts["exported"] += 1
            if path is not None:
                try:
                    payload = exported.serialize()
                except Exception:  # noqa: BLE001 - an output type not registered (serializable)
                    return jax.jit(exported.call, compiler_options=compiler_options())
                write_entry(path, payload)
                self.counts["stored"] += 1
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
            with key_lock:
                call = self._calls.get(key)
                if call is None:
                    call = self._program(key, statics, leaves, tree)
                    out = call(*leaves)  # compiled here, under the lock
                    self._calls[key] = call
                    return out
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
