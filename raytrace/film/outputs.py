"""All-or-nothing outputs: a command writes every file it was asked for, or none of them.

The write-to-a-temporary-file-then-``rename(2)`` idiom makes one file atomic; this module
extends it to the set of files one command writes (the EXR, ``--png``, ``--stats``, or the one
file of :meth:`raytrace.Image.save`)::

    with Outputs() as out:
        exr = out.add("a.exr", "-o", suffix=".exr")     # checked now: suffix, collisions
        png = out.add("a.png", "--png", suffix=".png")
        out.refuse_inputs([("scene.toml", "the scene file")])
        out.preflight()                                # each folder takes a new file
        ...                                            # the long work (the render)
        with out.stage(exr) as tmp:                    # written to a temporary file
            write_exr(tmp, rgb)
        with out.stage(png) as tmp:
            write_png(tmp, rgb)
        out.commit()                                   # only now: the renames

1. :meth:`Outputs.add` checks each output before any work: it has the suffix its content
   needs, and it is not the same file as another output (paths are compared resolved, so
   ``./a.exr``, ``a.exr`` and a symbolic link to it are one file; existing files are also
   compared by device and inode, which catches hard links).
2. :meth:`Outputs.refuse_inputs`: no output is a file the command reads (the scene file, its
   mesh files, its library material files).
3. :meth:`Outputs.preflight`: each output's folder exists and takes a new file (a temporary
   file is created there and removed), the target is not a folder, a device or an immutable
   file.
4. :meth:`Outputs.stage` writes one output to its own temporary file beside its target.
5. :meth:`Outputs.commit` renames every staged file over its target, once all are complete,
   with Ctrl-C held off for those few system calls (in the main thread): an interrupt that
   arrives then is raised after the last rename.

On any failure before the commit the temporary files are removed and no target changes.
Errors are :class:`OSError` (or :class:`~raytrace.errors.SceneError` for a bad path) whose
``filename`` is the path the user gave, never a temporary name; the flag or argument that named
the output is in their ``key`` attribute. A failure to write or rename says in its message what
was written (:meth:`Outputs.summary`): ``No space left on device; no output written (out.exr
left as it was)``. :attr:`Outputs.written` and
:attr:`Outputs.not_written` say exactly which targets were replaced, whatever happened.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import signal
import stat
import sys
import tempfile
import threading
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

from ..errors import SceneError

#: Linux ``FS_IOC_GETFLAGS`` (``linux/fs.h``) and its immutable and append-only bits: files
#: that not even root may replace (``chattr +i`` / ``+a``).
_FS_IOC_GETFLAGS = 0x80086601
_FS_IMMUTABLE_FL, _FS_APPEND_FL = 0x10, 0x20
#: BSD/macOS ``st_flags`` bits with the same meaning (``chflags uchg / schg / uappnd``).
_BSD_NO_REPLACE = (getattr(stat, "UF_IMMUTABLE", 0) | getattr(stat, "SF_IMMUTABLE", 0)
                   | getattr(stat, "UF_APPEND", 0) | getattr(stat, "SF_APPEND", 0))
#: Causes a library may report only as text (OpenEXR raises RuntimeError "... No space left
#: on device."): matched to their errno so the error keeps its type (e.g. ENOSPC → OSError).
_TEXT_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES,
                errno.EPERM, errno.EIO)


@dataclass(eq=False)
class Output:
    """One output: ``path`` as the user wrote it, ``key`` the flag or argument that named it,
    ``target`` the resolved file that will be replaced."""

    path: str
    key: str
    target: Path
    tmp: Path | None = None
    written: bool = False


def _same_file(a: Path, b: Path) -> bool:
    """Resolved paths equal, or (both existing) the same device and inode."""
    if a == b:
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def _error(code: int, problem: str, out: Output) -> OSError:
    e = OSError(code, problem, out.path)
    e.key = out.key
    return e


def _no_replace_flags(path: Path) -> bool:
    """Whether an existing file carries the immutable or append-only attribute."""
    try:
        st = os.stat(path)
    except OSError:
        return False
    if getattr(st, "st_flags", 0) & _BSD_NO_REPLACE:
        return True
    if not sys.platform.startswith("linux") or not stat.S_ISREG(st.st_mode):
        return False
    import array
    import fcntl

    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        flags = array.array("l", [0])
        fcntl.ioctl(fd, _FS_IOC_GETFLAGS, flags, True)
    except OSError:  # a file system without attributes
        return False
    finally:
        os.close(fd)
    return bool(flags[0] & (_FS_IMMUTABLE_FL | _FS_APPEND_FL))


def _mkstemp(target: Path) -> Path:
    """A new, empty temporary file beside ``target``, with the umask's permissions."""
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; outputs follow the umask
    return Path(tmp)


@contextlib.contextmanager
def _sigint_held() -> Iterator[None]:
    """Hold off Ctrl-C (in the main thread, with Python's default handler) until the block
    ends, then raise it."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    caught: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        if caught:
            raise KeyboardInterrupt


class Outputs:
    """The outputs of one command, written all together or not at all (module docstring)."""

    def __init__(self) -> None:
        self.items: list[Output] = []

    def __enter__(self) -> Outputs:
        return self

    def __exit__(self, *exc: object) -> None:
        self.discard()

    # -- before the work -------------------------------------------------------------------
    def add(self, path: str | os.PathLike, key: str, suffix: str | None = None) -> Output:
        """Register an output named by ``key``; it must end in ``suffix`` (any case) and
        differ from every output added before."""
        shown = os.fspath(path)
        if suffix and Path(shown).suffix.lower() != suffix:
            kind = suffix.lstrip(".").upper()
            raise SceneError(f"must be a {suffix} file (it holds {kind} data), got {shown!r}",
                             key)
        out = Output(shown, key, Path(shown).resolve())
        for other in self.items:
            if _same_file(out.target, other.target):
                raise SceneError(f"{shown} is the same file as {other.key} {other.path}: "
                                 "each output needs a file of its own", key)
        self.items.append(out)
        return out

    def refuse_inputs(self, inputs: Iterable[tuple[str | os.PathLike, str]]) -> None:
        """No output may be a file the command reads: ``inputs`` are (path, what it is)."""
        for path, what in inputs:
            source = Path(path).resolve()
            for out in self.items:
                if _same_file(out.target, source):
                    spelt = "" if os.fspath(path) == out.path else f" ({os.fspath(path)})"
                    raise SceneError(f"{out.path} is {what}{spelt}, which this command "
                                     "reads: an output never overwrites an input", out.key)

    def preflight(self) -> None:
        """Check that every output can be written, before the work: its folder exists and
        takes a new file (created and removed), and the target is a replaceable file."""
        for out in self.items:
            folder, target = out.target.parent, out.target
            if not folder.is_dir():
                raise _error(errno.ENOENT, f"folder does not exist: {Path(out.path).parent}",
                             out)
            if target.is_dir():
                raise _error(errno.EISDIR, "is a folder, not a file", out)
            if any(str(q).startswith(("/dev/", "/proc/")) for q in (target,
                                                                     Path(out.path).absolute())):
                # e.g. /dev/stdout: renaming a file over it would replace the stream's link
                # (or the file the stream is redirected to), not write into the stream.
                raise _error(errno.EINVAL, "is a device or stream, not a file: outputs are "
                                           "whole files renamed into place", out)
            if target.exists() and not target.is_file():
                raise _error(errno.EINVAL, "is not a regular file (a device, pipe or socket)",
                             out)
            if _no_replace_flags(target):
                raise _error(errno.EPERM, "cannot be replaced: the file is immutable or "
                                          "append-only (see lsattr / chattr)", out)
            try:
                _mkstemp(target).unlink()
            except OSError as e:
                raise _error(e.errno or errno.EACCES, f"cannot create a file in "
                             f"{Path(out.path).parent}: {e.strerror or e}", out) from None

    # -- the work's results ----------------------------------------------------------------
    @contextlib.contextmanager
    def stage(self, out: Output) -> Iterator[Path]:
        """A temporary file beside ``out``'s target for the block to write; kept for
        :meth:`commit` if the block completes, removed otherwise. A failure to write
        (``OSError``, or a library's ``RuntimeError`` such as OpenEXR's on a full disk) is
        raised as an :class:`OSError` naming the user's path."""
        if out.tmp is not None:
            raise RuntimeError(f"{out.path} is already staged")
        tmp = None
        try:
            tmp = _mkstemp(out.target)
            yield tmp
        except (OSError, RuntimeError) as e:
            if tmp is not None:
                tmp.unlink(missing_ok=True)
            raise self._write_error(e, out, tmp) from None
        except BaseException:
            if tmp is not None:
                tmp.unlink(missing_ok=True)
            raise
        out.tmp = tmp

    def _write_error(self, e: BaseException, out: Output, tmp: Path | None) -> OSError:
        """``e`` as one OSError naming the user's path (temporary names replaced by it) and
        saying what was written: nothing, every old file as it was (:meth:`summary`)."""
        text = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        if tmp is not None:  # any token holding the temporary name (or one derived from it)
            text = re.sub(r"['\"]?[^\s'\"]*" + re.escape(tmp.name) + r"[^\s'\"]*['\"]?",
                          lambda m: out.path, text)
        code = e.errno if isinstance(e, OSError) and e.errno else next(
            (c for c in _TEXT_ERRNOS if os.strerror(c) in text), errno.EIO)
        return _error(code, f"cannot write: {text.rstrip('.')}; {self.summary()}", out)

    def commit(self) -> None:
        """Rename every staged file over its target (all must be staged), Ctrl-C held off."""
        missing = [out.path for out in self.items if out.tmp is None]
        if missing:
            raise RuntimeError(f"not staged: {', '.join(missing)}")
        with _sigint_held():
            for out in self.items:
                try:
                    os.replace(out.tmp, out.target)
                except OSError as e:
                    raise _error(e.errno or errno.EIO, f"cannot move into place: "
                                 f"{e.strerror or e}; {self.summary()}", out) from None
                out.tmp, out.written = None, True

    def discard(self) -> None:
        """Remove every temporary file not yet renamed."""
        for out in self.items:
            if out.tmp is not None:
                out.tmp.unlink(missing_ok=True)
                out.tmp = None

    # -- what happened ---------------------------------------------------------------------
    @property
    def written(self) -> list[str]:
        """The outputs whose targets were replaced (the paths as given)."""
        return [out.path for out in self.items if out.written]

    @property
    def not_written(self) -> list[str]:
        """The outputs whose targets were left as they were."""
        return [out.path for out in self.items if not out.written]

    def summary(self) -> str:
        """Exactly which outputs were replaced and which were left as they were, for the
        one line that reports a failure or an interrupt."""
        done, left = self.written, self.not_written
        kept = f"left as {'they were' if len(left) > 1 else 'it was'}"
        if not done:
            return "no output written" + (f" ({', '.join(left)} {kept})" if left else "")
        if not left:
            return f"wrote {', '.join(done)} (every output)"
        return f"wrote {', '.join(done)}; not written: {', '.join(left)} ({kept})"
