"""Compiled programs kept on disk between processes and found without tracing (:func:`cached_jit`).

JAX's persistent cache (``<root>/xla``, switched on in :mod:`jaxdea`) keeps the XLA compilation, but
a fresh process must still trace and lower a solver to compute its key before it can load it: with a
warm cache the first ``characteristic`` call took 1.5 s and the first ``frequencies`` call 3.3–6 s
(benchmarks/, (d)), almost all of it tracing. :func:`cached_jit` keys the serialised executable by
what determines the program without tracing it, and loads it instead (≈ 0.6 s for ``frequencies``):

* the function (module and name) and its static arguments;
* the pytree structure (static fields included) and the type of every other argument (shape,
  dtype, weak type);
* the source of every jaxdea module, the versions of jax and jaxlib, the JAX options that change a
  program (:data:`KEYED_OPTIONS`), ``XLA_FLAGS``, the devices and the host CPU (its model and
  instruction-set flags: an executable is machine code for this CPU).

Everything else goes through ``jax.jit`` as usual: calls under a transformation (tracers in the
arguments), arrays committed to a device where there are several (e.g. the blocks of a sharded
sweep; a loaded program runs on the default device), JAX's debugging options
(:data:`BYPASS_OPTIONS`) switched on, and every call when the cache is off
(``JAXDEA_CACHE_DIR=off``). An entry that cannot be loaded or run is deleted and the program compiled
anew; an entry that cannot be written is skipped: the cache never changes a result, it only saves
the first call its compilation (the loaded executable is the compiled one, bit for bit). Only
programs that XLA compiled in the process are written: one that JAX took from its own persistent
cache serialises into an entry that fails to run (XLA:CPU, measured), so after an upgrade whose
programs JAX's cache still holds, first calls trace as before until that cache is cleared.

The key holds the source of jaxdea, not the values of its module constants at run time: a process
that changes them (monkeypatching) must run with the cache off. Entries are pickled files in
``<root>/executables`` (root: ``JAXDEA_CACHE_DIR``, by default ``~/.cache/jaxdea``), a few MB
each; like JAX's own cache they are trusted as the user's files. Delete the directory to empty it.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import os
import pickle
import platform
import tempfile
from pathlib import Path

import jax
import jaxlib
from jax.experimental import serialize_executable

KEYED_OPTIONS = ("jax_enable_x64", "jax_default_matmul_precision", "jax_numpy_rank_promotion",
                 "jax_numpy_dtype_promotion", "jax_default_prng_impl", "jax_threefry_partitionable",
                 "jax_platforms", "jax_use_shardy_partitioner")
"""JAX options that enter the key (they change the program a function traces to)."""
COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
"""XLA options of every program jaxdea compiles (:func:`jit`). XLA:CPU's newer fusion emitters
(the default) took 1.6–1.9× longer to compile the solvers for no faster code here: the first
``frequencies`` call 6.1 → 4.0 s, ``critical_voltage`` 12.8 → 8.1 s, ``characteristic`` 1.25 →
0.78 s (caches off), while ``characteristic`` at batch 4096, the Fig. 3 sweep and the continuation
curves ran as fast or 5–10 % faster (README, Performance). Other backends ignore the option."""
BYPASS_OPTIONS = ("jax_debug_nans", "jax_debug_infs", "jax_disable_jit", "jax_enable_checks",
                  "jax_check_tracer_leaks", "jax_default_device")
"""JAX options under which every call goes through ``jax.jit`` (they act at tracing or dispatch)."""


def cache_off() -> bool:
    """``JAXDEA_CACHE_DIR=off``: no cache on disk (read at every call, cheaply)."""
    return os.environ.get("JAXDEA_CACHE_DIR", "").lower() == "off"


def cache_root() -> Path | None:
    """The cache root (``JAXDEA_CACHE_DIR``, default ``~/.cache/jaxdea``), or None when it is off."""
    if cache_off():
        return None
    return Path(os.environ.get("JAXDEA_CACHE_DIR", os.path.join("~", ".cache", "jaxdea"))).expanduser()


def _cpu() -> str:
    """The host CPU: model and instruction-set flags (Linux), else what ``platform`` knows."""
    try:
        with open("/proc/cpuinfo") as info:
            lines = [line for line in info.read().splitlines()
                     if line.startswith(("model name", "flags", "Features", "CPU part"))]
        return "\n".join(sorted(set(lines)))
    except OSError:
        return f"{platform.machine()} {platform.processor()}"


@functools.cache
def _environment() -> str:
    """Digest of everything a program depends on besides its function and arguments, computed once
    per process (devices and sources do not change while it runs)."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    devices = [(d.platform, d.device_kind, d.id) for d in jax.devices()]
    for part in (jax.__version__, jaxlib.__version__, os.environ.get("XLA_FLAGS", ""),
                 repr(devices), _cpu()):
        digest.update(part.encode() + b"\0")
    return digest.hexdigest()


@functools.cache
def _several_devices() -> bool:
    return len(jax.devices()) > 1


def _options(names):
    return tuple(getattr(jax.config, name, None) for name in names)


_XLA_CACHE_HITS = [0]
jax.monitoring.register_event_listener(
    lambda event, **_: _XLA_CACHE_HITS.__setitem__(0, _XLA_CACHE_HITS[0] + 1)
    if event == "/jax/compilation_cache/cache_hits" else None)


def _compile(lowered):
    """(compiled, storable): ``lowered.compile()``, storable unless JAX loaded it from its own
    persistent cache. Such an executable serialises into an entry that fails to run in the next
    process (XLA:CPU, measured: "Function broadcast_select_fusion.1 not found"), so only programs
    that XLA compiled in this process are written."""
    hits = _XLA_CACHE_HITS[0]
    compiled = lowered.compile()
    return compiled, _XLA_CACHE_HITS[0] == hits


class CachedJit:
    """``jax.jit(fun, static_argnames=...)`` whose first call in a process may load the compiled
    program from disk (module docstring). Other attributes (``lower``, ``trace``, ...) are those of
    the underlying jitted function."""

    def __init__(self, fun, static_argnames=()):
        self._static = (static_argnames,) if isinstance(static_argnames, str) else tuple(
            static_argnames)
        self._jit = jit(fun, static_argnames=self._static)
        self._signature = inspect.signature(fun)
        self._name = f"{fun.__module__}.{fun.__qualname__}"
        self._loaded = {}  # key -> compiled program, this process
        self.counts = {"loaded": 0, "compiled": 0}  # programs read from disk / compiled here
        functools.update_wrapper(self, fun)

    def __getattr__(self, name):
        return getattr(self._jit, name)

    def _cache_size(self) -> int:
        """Programs this process holds: loaded or compiled here, and those of ``jax.jit``."""
        return len(self._loaded) + self._jit._cache_size()

    def _key(self, args, kwargs):
        """(key, dynamic arguments by name), or None where the call must go through ``jax.jit``."""
        if any(_options(BYPASS_OPTIONS)):
            return None
        bound = self._signature.bind(*args, **kwargs)
        bound.apply_defaults()
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
        statics = tuple((k, repr(bound.arguments[k])) for k in self._static)
        return (statics, str(tree), tuple(types), _options(KEYED_OPTIONS)), bound.arguments

    def _entry(self, key) -> Path:
        digest = hashlib.sha256(f"{_environment()}\0{self._name}\0{key!r}".encode()).hexdigest()
        return cache_root() / "executables" / f"{digest}.pkl"

    def _load(self, path):
        try:
            with open(path, "rb") as stream:
                payload, in_tree, out_tree = pickle.load(stream)
            return serialize_executable.deserialize_and_load(payload, in_tree, out_tree)
        except FileNotFoundError:
            return None
        except Exception:  # noqa: BLE001 - a damaged or foreign entry: compile anew
            path.unlink(missing_ok=True)
            return None

    @staticmethod
    def _store(path, compiled):
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            data = pickle.dumps(serialize_executable.serialize(compiled))
            with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".tmp", delete=False) as stream:
                stream.write(data)
            os.replace(stream.name, path)  # atomic: readers see the whole entry or none
        except Exception:  # noqa: BLE001 - a read-only or full disk only costs the next process
            if "stream" in locals():
                Path(stream.name).unlink(missing_ok=True)

    def __call__(self, *args, **kwargs):
        found = None if cache_off() else self._key(args, kwargs)
        if found is None:
            return self._jit(*args, **kwargs)
        key, arguments = found
        dynamic = {k: v for k, v in arguments.items() if k not in self._static}
        compiled = self._loaded.get(key)
        if compiled is None:
            path = self._entry(key)
            compiled = self._load(path)
            if compiled is not None:
                try:  # a loaded program's first run, checked (an entry that fails to run: jax.jit)
                    out = jax.block_until_ready(compiled(**dynamic))
                except Exception:  # noqa: BLE001
                    path.unlink(missing_ok=True)
                    compiled = None
                else:
                    self.counts["loaded"] += 1
                    self._loaded[key] = compiled
                    return out
            compiled, storable = _compile(self._jit.lower(**arguments))
            if storable:
                self._store(path, compiled)
            self.counts["compiled"] += 1
            self._loaded[key] = compiled
        return compiled(**dynamic)


class Jitted:
    """``jax.jit(fun, ...)`` compiled with :data:`COMPILER_OPTIONS` where it is the top-level
    program; inside another trace (a caller's ``jit``, ``grad``, ``lax.map``...) it is the plain
    ``jax.jit``, since JAX accepts compiler options on top-level programs only (the enclosing
    program's options then apply). Other attributes (``lower``, ``trace``...) are the top-level
    function's."""

    def __init__(self, fun, **kwargs):
        self._top = jax.jit(fun, compiler_options=COMPILER_OPTIONS, **kwargs)
        self._nested = jax.jit(fun, **kwargs)
        functools.update_wrapper(self, fun)

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
    """:class:`Jitted`: ``jax.jit`` with jaxdea's :data:`COMPILER_OPTIONS` (``@jit`` or
    ``@jit(static_argnames=...)``).

    A caller's own ``jax.jit`` around jaxdea functions compiles with the caller's options: pass
    ``compiler_options=jaxdea.compiled.COMPILER_OPTIONS`` to it for the same compile times."""
    if fun is None:
        return functools.partial(jit, **kwargs)
    return Jitted(fun, **kwargs)


def cached_jit(fun=None, *, static_argnames=()):
    """Decorator: :class:`CachedJit` of ``fun`` (``@cached_jit`` or
    ``@cached_jit(static_argnames=(...))``)."""
    if fun is None:
        return functools.partial(cached_jit, static_argnames=static_argnames)
    return CachedJit(fun, static_argnames)
