"""Files written whole or not at all, and the input documents of the command line.

Every file jaxdea writes goes through :func:`atomic_write` (one file) or :func:`write_together` (the
set of outputs of one command). The content goes to a temporary file in the target's folder
(``.NAME.HOST-PID-TOKEN.tmpSUFFIX``: hidden, on the same file system, the target's suffix kept for
writers that choose the format by it), which is flushed to the disk (``fsync``) and then renamed over
the target (``os.replace``, atomic on POSIX). A failed write (an exception, a full disk, Ctrl-C)
removes its temporaries and leaves every previous file as it was. A set is renamed only once all of
its files are written, with SIGINT and SIGTERM held back during the renames (they take effect after
the last one). A process killed outright (SIGKILL, power loss) leaves at most a hidden temporary;
the next write of the same target on that host removes it once its writer has ended.

:func:`read_text` and :func:`load_document` read the inputs of ``jaxdea sweep`` and ``jaxdea fit``:
UTF-8 with or without a byte-order mark, JSON with every key once, nesting within
:data:`MAX_NESTING`.
"""

from __future__ import annotations

import contextlib
import glob
import json
import os
import secrets
import signal
import socket
import stat
import threading
import tomllib
from pathlib import Path

_local = threading.local()  # the temporaries of the sets being written in this thread
MAX_NESTING = 64
"""The deepest nesting of tables and lists accepted in a TOML or JSON document (jaxdea's own
configurations use 3)."""


def _pending() -> set:
    if not hasattr(_local, "paths"):
        _local.paths = set()
    return _local.paths


def _temporary(path: Path) -> Path:
    """A new empty temporary beside ``path``, with the mode a new file gets (the umask applied) or
    that of the file it replaces."""
    token = f"{socket.gethostname()}-{os.getpid()}-{secrets.token_hex(4)}"
    tmp = path.with_name(f".{path.name}.{token}.tmp{path.suffix}")
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        os.chmod(tmp, stat.S_IMODE(path.stat().st_mode))
    except FileNotFoundError:
        pass
    return tmp


def _remove_stale(path: Path) -> None:
    """Remove the temporaries of ``path`` left by writers of this host that have ended."""
    host, tail = socket.gethostname(), f".tmp{path.suffix}"
    head = f".{path.name}."
    for name in glob.glob(glob.escape(str(path.with_name(head))) + "*" + glob.escape(tail)):
        token = Path(name).name[len(head):-len(tail)]
        writer, _, pid = token.rpartition("-")[0].rpartition("-")
        if writer != host or not pid.isdigit():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            with contextlib.suppress(OSError):
                os.unlink(name)
        except OSError:  # alive (another user's process) or unknown: left alone
            pass


def _sync(path) -> None:
    """fsync a file, or a folder (where the file system allows it)."""
    folder = os.path.isdir(path)
    try:
        fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if folder else 0))
    except OSError:
        if folder:
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not folder:
            raise
    finally:
        os.close(fd)


@contextlib.contextmanager
def _signals_held():
    """SIGINT and SIGTERM deferred until the block ends (main thread only), then raised again."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received = []
    held = {}
    for number in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(number) is not None:
            held[number] = signal.signal(number, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        for number, handler in held.items():
            signal.signal(number, handler)
        if received:
            signal.raise_signal(received[0])


@contextlib.contextmanager
def _staged(paths):
    """Temporaries for ``paths`` (yielded in order); on success each is synced and all are renamed
    over their targets, on any failure all are removed and the targets left as they were."""
    targets = [Path(os.path.realpath(p)) if os.path.islink(p) else Path(p) for p in paths]
    created, pending = [], _pending()
    try:
        for target in targets:
            _remove_stale(target)
            created.append(_temporary(target))
            pending.add(created[-1])
        yield list(created)
        for tmp in created:
            _sync(tmp)
        with _signals_held():
            for tmp, target in zip(created, targets, strict=True):
                os.replace(tmp, target)
    finally:
        pending.difference_update(created)
        for tmp in created:  # those not renamed: a failure
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
    for folder in {target.parent for target in targets}:
        _sync(folder)


@contextlib.contextmanager
def atomic_write(path):
    """Write one file whole or not at all: yields the temporary path to write to.

    ``path`` may also be an open file object (it is yielded as it is), or a temporary of an
    enclosing :func:`write_together` (written directly: the set commits it).

    Example:
        >>> with atomic_write("table.csv") as tmp:
        ...     np.savetxt(tmp, table, delimiter=",")
    """
    if hasattr(path, "write") or Path(path) in _pending():
        yield path
        return
    with _staged([path]) as (tmp,):
        yield tmp


def write_together(items) -> list:
    """Write a set of files together or not at all.

    Args:
        items: ``(path, write)`` pairs; ``write(tmp)`` writes the content of ``path`` to the path
            ``tmp`` (writers that use :func:`atomic_write` themselves write it directly).

    Returns:
        The paths, in order.

    Raises:
        Whatever a writer raises (OSError for a full disk or a missing folder, KeyboardInterrupt);
        then no target has changed and no temporary is left.

    Example:
        >>> write_together([("res.csv", result.to_csv), ("res.npz", result.to_npz)])
    """
    items = [(Path(path), write) for path, write in items]
    with _staged([path for path, _ in items]) as temporaries:
        for tmp, (_, write) in zip(temporaries, items, strict=True):
            write(tmp)
    return [path for path, _ in items]


def save_figure(fig, path, **options) -> None:
    """``fig.savefig`` whole or not at all, in the format of the suffix of ``path`` (matplotlib's
    ``savefig.format``, PNG by default, without one)."""
    from matplotlib import rcParams

    suffix = "" if hasattr(path, "write") else Path(path).suffix[1:].lower()
    options.setdefault("format", suffix or rcParams["savefig.format"])
    with atomic_write(path) as tmp:
        fig.savefig(tmp, **options)


def write_text(path, text: str) -> None:
    """A text file (UTF-8) whole or not at all."""
    with atomic_write(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")


# ---------------------------------------------------------------------------------------- reading


def read_text(path) -> str:
    """A UTF-8 text file, a leading byte-order mark dropped (Excel's "CSV UTF-8" writes one).

    Raises:
        OSError: the file cannot be read. UnicodeDecodeError: it is no UTF-8.
    """
    return Path(path).read_text(encoding="utf-8-sig")


def _unique_keys(pairs):
    table = {}
    for key, value in pairs:
        if key in table:
            raise ValueError(f"the key {key!r} appears twice in one table")
        table[key] = value
    return table


def _depth(value, limit: int, level: int = 0) -> int:
    """Raise ValueError where tables and lists nest deeper than ``limit``."""
    if level > limit:
        raise ValueError(f"tables and lists nest deeper than {limit} levels")
    children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else ()
    for child in children:
        _depth(child, limit, level + 1)
    return level


def load_document(path, kind: str) -> dict:
    """A TOML (``kind="toml"``) or JSON (``"json"``) document as a dict.

    Raises:
        ValueError: "PATH: ..." for an unreadable file, text that is no UTF-8, a syntax error, a
            key given twice in one table (TOML rejects it by itself) or nesting deeper than
            :data:`MAX_NESTING`.
    """
    path = Path(path)
    try:
        text = read_text(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        if kind == "toml":
            data = tomllib.loads(text)
        else:
            data = json.loads(text, object_pairs_hook=_unique_keys)
        _depth(data, MAX_NESTING)
    except RecursionError:
        raise ValueError(f"{path}: tables and lists nest deeper than {MAX_NESTING} levels") from None
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path}: invalid {kind.upper()}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return data
