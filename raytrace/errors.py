"""Errors a user can act on.

Every problem with input (a scene file, a mesh, a command-line flag) is raised as a
:class:`SceneError` carrying the file, the key and what is wrong, so the command line can print
one clear line and exit non-zero without a traceback.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager


class SceneError(ValueError):
    """Bad input: ``file: key: problem``.

    Parameters
    ----------
    problem : str
        What is wrong, e.g. ``"must be > 0, got -1"``.
    key : str, optional
        The dotted key path inside the scene, e.g. ``"objects[2].radius"``.
    file : str, optional
        The scene (or mesh) file; ``None`` for scenes built in Python.
    """

    def __init__(self, problem: str, key: str | None = None, file: str | None = None):
        self.problem = problem
        self.key = key
        self.file = file
        super().__init__(str(self))

    def __str__(self) -> str:
        parts = [p for p in (self.file, self.key) if p]
        return ": ".join([*parts, self.problem])

    def at(self, file: str | None = None, key_prefix: str | None = None) -> SceneError:
        """The same error, located in ``file`` and below ``key_prefix``."""
        key = self.key
        if key_prefix:
            key = f"{key_prefix}.{key}" if key and not key.startswith("[") else (
                f"{key_prefix}{key}" if key else key_prefix)
        return SceneError(self.problem, key, self.file or file)


@contextmanager
def located(file: str | os.PathLike | None) -> Iterator[None]:
    """A :class:`SceneError` raised inside, located in ``file`` (:meth:`SceneError.at`): how
    a model reader names its file on the values it checks with :mod:`raytrace.values`."""
    try:
        yield
    except SceneError as e:
        raise e.at(None if file is None else os.fspath(file)) from None


class MemoryLimitError(SceneError):
    """A render that needs, or reached, more memory than it may have: more than the machine
    has available, or than its memory ceiling (``--max-memory``, ``render(max_memory=)``;
    :mod:`raytrace.rendering`), found before it starts or while it runs. A
    :class:`SceneError` (the input asks too much): one line, exit 2; its key names the limit
    to raise."""


class RenderWarning(UserWarning):
    """A render that completes but is probably not what was meant: a scene with no objects,
    pixels that overflowed float32. The command line prints each as one line
    ``raytrace: warning: FILE: problem`` on stderr, terminal or not."""


class ClusterError(RuntimeError):
    """A Dask cluster could not do the work (no scheduler at an address, a task that killed
    its workers each time it ran): the command line prints it as one line, like a
    :class:`SceneError`."""


class EngineError(RuntimeError):
    """The rendering engine cannot run here: the Embree library is missing, not a version
    whose layouts raytrace checked, or reported an error (out of memory included). The
    command line prints it as one line naming what to install or change."""
