"""The files an input names (a scene file, a mesh, an MTL library, a texture, a Python file of
frames): each is checked here, once, to be a regular file before it is read, so that a folder
or a device given in its place is reported as what it is, not as "not found". Being the one
door every reader's file passes, it also lists them: inside :func:`recording`, each file
checked is noted as a :class:`Read` (what a scene sends to a cluster's workers:
:mod:`raytrace.readers.bundle`), and :func:`cached_reads` keeps a cached loader's list."""

from __future__ import annotations

import codecs
import contextvars
import functools
import os
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NamedTuple

from ..errors import SceneError


def input_file(path: str | os.PathLike, what: str, key: str | None = None,
               file: str | None = None, *, a: str = "a") -> Path:
    """``path`` when it is a regular file (or a link to one); otherwise a
    :class:`~raytrace.errors.SceneError` with ``key`` and ``file`` saying what it is instead:
    ``{what} not found``, ``is a folder, not {a} {what}`` or ``is not a regular file (a device,
    pipe or socket), not {a} {what}``, followed by ``: path`` unless ``file`` is the path.

    >>> input_file(".", "mesh file", "file")
    Traceback (most recent call last):
    ...
    raytrace.errors.SceneError: file: is a folder, not a mesh file: .
    """
    p = Path(path)
    if p.is_file():
        _note(p)
        return p
    if p.is_dir():
        problem = f"is a folder, not {a} {what}"
    elif p.exists():
        problem = f"is not a regular file (a device, pipe or socket), not {a} {what}"
    else:
        problem = f"{what} not found"
    shown = "" if file is not None and file == os.fspath(path) else f": {os.fspath(path)}"
    raise SceneError(problem + shown, key, file)


class Read(NamedTuple):
    """A file an input read: its absolute path (``os.path.abspath``: made absolute against
    the working folder, ``..`` taken lexically), and its modification time (ns) and size when
    it was checked, by which a later reader sees whether it is still the same file."""

    path: str
    mtime_ns: int
    size: int


#: The lists of the :func:`recording` blocks open in this context (thread), innermost last.
_recorders: contextvars.ContextVar[tuple[list[Read], ...]] = contextvars.ContextVar(
    "raytrace_reads", default=())


@contextmanager
def recording() -> Iterator[list[Read]]:
    """A list that collects every file :func:`input_file` passes in this thread while the
    block runs (also the files of blocks nested in it), in the order they were checked."""
    reads: list[Read] = []
    token = _recorders.set((*_recorders.get(), reads))
    try:
        yield reads
    finally:
        _recorders.reset(token)


def _note(path: Path) -> None:
    """``path`` noted in every open :func:`recording` list (nothing when none is open)."""
    lists = _recorders.get()
    if lists:
        st = path.stat()
        read = Read(os.path.abspath(path), st.st_mtime_ns, st.st_size)
        for reads in lists:
            reads.append(read)


def cached_reads(maxsize: int) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """``functools.lru_cache(maxsize)`` for a loader that reads files: a call answered from
    the cache notes the files the loader read when it ran (:func:`recording`), as if it had
    read them again."""
    def wrap(load: Callable[..., Any]) -> Callable[..., Any]:
        @functools.lru_cache(maxsize=maxsize)
        def cached(*args: Any) -> tuple[Any, tuple[Read, ...]]:
            reads: list[Read] = []
            token = _recorders.set((reads,))  # its own list only: the caller's get them below
            try:
                return load(*args), tuple(reads)
            finally:
                _recorders.reset(token)

        @functools.wraps(load)
        def call(*args: Any) -> Any:
            result, reads = cached(*args)
            for reads_now in _recorders.get():
                reads_now.extend(reads)
            return result

        call.cache_clear, call.cache_info = cached.cache_clear, cached.cache_info
        return call

    return wrap


#: Byte-order marks of the encodings a text editor may save in instead of UTF-8 (UTF-32's
#: first, as UTF-32-LE's begins with UTF-16-LE's).
BOMS = ((codecs.BOM_UTF32_LE, "UTF-32"), (codecs.BOM_UTF32_BE, "UTF-32"),
        (codecs.BOM_UTF16_LE, "UTF-16"), (codecs.BOM_UTF16_BE, "UTF-16"))
#: Bytes no text file holds: the C0 controls but tab, newline, vertical tab, form feed and
#: carriage return, and DEL.
NOT_TEXT = re.compile(rb"[\x00-\x08\x0e-\x1f\x7f]")


def read_text(path: str | os.PathLike, what: str, key: str | None = None,
              file: str | None = None, *, a: str = "a", strict: bool = True) -> str:
    """The text of the input file ``path`` (checked by :func:`input_file`), which must be
    UTF-8 (a UTF-8 byte-order mark is dropped). A :class:`~raytrace.errors.SceneError` with
    ``key`` and ``file`` when it is UTF-16 or UTF-32 (named from its byte-order mark, or
    from its NUL bytes without one) or not text; with ``strict``, also where a byte is not
    UTF-8 (naming its line); without, such bytes read as U+FFFD (an MTL or OBJ file in
    Latin-1 keeps its statements)."""
    p = input_file(path, what, key, file, a=a)
    try:
        data = p.read_bytes()
    except OSError as e:
        raise SceneError(f"cannot read {what}: {e.strerror or e}", key, file) from None
    must = f"{a} {what} must be {'UTF-8 ' if strict else ''}text"
    for bom, encoding in BOMS:
        if data.startswith(bom):
            raise SceneError(f"is {encoding} text (its byte-order mark says so): {must}", key,
                             file)
    bad = NOT_TEXT.search(data)
    if bad:
        line = data.count(b"\n", 0, bad.start()) + 1
        kind = (" (UTF-16 or UTF-32 text without a byte-order mark, or a binary file)"
                if bad.group() == b"\0" else "")
        raise SceneError(f"byte 0x{bad.group()[0]:02x} on line {line} is not text{kind}: "
                         f"{must}", key, file)
    try:
        return data.decode("utf-8-sig", errors="strict" if strict else "replace")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise SceneError(f"byte 0x{data[e.start]:02x} on line {line} is not UTF-8 (Latin-1 "
                         f"or another encoding?): {must}", key, file) from None
