"""A render's progress as tqdm's bar, with the time left and the rate: ``tqdm.auto``, so a
widget in Jupyter and a line of text elsewhere.

    image = raytrace.render(scene, progress=raytrace.ProgressBar())

It is a ``progress(done, total)`` callback as :func:`raytrace.render` and
:func:`raytrace.render_frames` call it, and the command line's bar on a terminal
(:class:`raytrace.cli.Progress`). Only this module imports tqdm, and only code that shows a
bar imports this module (``raytrace.ProgressBar`` is loaded on first use), so a render
without a bar never loads tqdm.
"""

from __future__ import annotations

import os
from typing import TextIO

from tqdm.auto import tqdm

#: The size tqdm is given for a file that is no sized terminal: on a pseudo-terminal nobody
#: gave a size (``os.openpty``, ``script``) it measures 0 or -1 and draws nothing.
COLUMNS, ROWS = 80, 24


class ProgressBar:
    """A ``progress(done, total)`` callback drawn as a tqdm bar of ``total`` ``unit``:
    the count, the elapsed and estimated remaining time, and the rate
    (``42%|####      | 129k/307k [00:01<00:01, 98.2k camera rays/s]``).

    ``unit`` names what the render counts: its camera rays (one a sample, the default),
    rows with adaptive anti-aliasing, frames for :func:`raytrace.render_frames`. ``file``:
    where a text bar is written, as wide as the terminal (:data:`COLUMNS` where it has no
    width); None: tqdm's choice (stderr, or a widget in Jupyter). The bar is closed when
    ``done`` reaches ``total``; a second render with the same callback starts a new one.
    """

    def __init__(self, unit: str = "camera rays", file: TextIO | None = None):
        self.unit = unit
        self.file = file
        self._bar: tqdm | None = None

    def __call__(self, done: int, total: int) -> None:
        if self._bar is None:
            size = ({"dynamic_ncols": True} if self.file is None or _sized(self.file)
                    else {"ncols": COLUMNS, "nrows": ROWS})  # no file: Jupyter's widget
            self._bar = tqdm(total=total, unit=f" {self.unit}", unit_scale=total >= 1000,
                             file=self.file, **size)  # 129k/307k, or 2/3 rows
        self._bar.update(done - self._bar.n)
        if done >= total:
            self._bar.close()  # the finished bar stays on its line
            self._bar = None

    def abandon(self) -> None:
        """Stop drawing and leave the bar's line as it is (a render that was interrupted:
        tqdm would otherwise redraw it after the message that says so)."""
        if self._bar is not None:
            self._bar.disable = True  # close() is then a no-op
            self._bar = None


def _sized(file: TextIO) -> bool:
    """Whether ``file`` is a terminal that knows its size."""
    try:
        return min(os.get_terminal_size(file.fileno())) > 0
    except (AttributeError, OSError, ValueError):  # no file descriptor, or not a terminal
        return False
