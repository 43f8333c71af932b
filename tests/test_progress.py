"""raytrace.progress: a render's progress(done, total) as tqdm's bar, with the time left and
the rate in what the render counts; tqdm loaded only where a bar is shown."""

from __future__ import annotations

import io
import re
import select
import subprocess
import sys

import raytrace
from raytrace.progress import ProgressBar

#: tqdm's ``[elapsed<remaining, rate]``, the rate in camera rays a second.
TIMES = re.compile(r"\[(\d\d:\d\d)<(\d\d:\d\d|\?), ([\d.]+[kMG]?|\?) camera rays/s\]")


def test_the_bar_shows_the_time_left_and_the_rate():
    out = io.StringIO()
    bar = ProgressBar(file=out)
    for done in (0, 1000, 3000, 4000):
        bar(done, 4000)
    lines = out.getvalue().split("\n")
    assert lines[-1] == ""  # the finished bar keeps its line
    last = lines[-2].split("\r")[-1]
    assert "100%|" in last and "4.00k/4.00k" in last, last
    times = TIMES.search(last)
    assert times and times.group(2) == "00:00" and times.group(3) != "?", last


def test_a_second_render_with_the_same_callback_gets_its_own_bar():
    out = io.StringIO()
    bar = ProgressBar("rows", file=out)
    for total in (2, 3):
        for done in range(1, total + 1):
            bar(done, total)
    done_lines = [line.split("\r")[-1] for line in out.getvalue().split("\n")[:-1]]
    assert [line.split("|")[2].split()[0] for line in done_lines] == ["2/2", "3/3"]
    assert all("rows/s]" in line for line in done_lines)


def test_an_abandoned_bar_is_not_drawn_again():
    out = io.StringIO()
    bar = ProgressBar(file=out)
    bar(1, 4)
    drawn = out.getvalue()
    bar.abandon()
    del bar  # tqdm closes (and redraws) a bar it still owns when collected
    assert out.getvalue() == drawn


def test_a_terminal_of_no_size_still_gets_a_bar(monkeypatch):
    # A pseudo-terminal nobody gave a size (os.openpty, `script`) as stderr: tqdm measured
    # it as 0 or -1 columns and rows and drew nothing there.
    import os

    master, slave = os.openpty()
    with os.fdopen(slave, "w") as tty:
        monkeypatch.setattr(sys, "stderr", tty)
        bar = ProgressBar(file=sys.stderr)
        bar(1000, 4000)
        bar(4000, 4000)
    # the kernel hands a pty's writes to its reader asynchronously: read until the bar's
    # last draw, its newline, has come (or nothing more comes for 5 s)
    drawn = b""
    while not drawn.endswith(b"\n") and select.select([master], [], [], 5.0)[0]:
        drawn += os.read(master, 65536)
    os.close(master)
    drawn = drawn.decode()
    assert "100%|" in drawn and TIMES.search(drawn), drawn


def test_tqdm_is_loaded_only_where_a_bar_is_shown(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('[render]\nwidth = 4\nheight = 2\n[[objects]]\ntype = "sphere"\n'
                     'center = [0, 0, -3]\nradius = 1\n')
    probe = ("import sys, raytrace\n"
             "from raytrace import cli\n"
             f"raytrace.render(raytrace.load_scene({str(scene)!r}))\n"
             f"assert cli.main(['render', {str(scene)!r}, '-o', {str(tmp_path / 'o.exr')!r}])"
             " == 0\n"
             "print('tqdm' in sys.modules, end=' ')\n"
             "raytrace.ProgressBar\n"
             "print('tqdm' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout  # stderr piped: no bar
    assert out == "False True\n"


def test_the_api_takes_the_bar_as_its_progress_callback():
    out = io.StringIO()
    scene = raytrace.Scene(objects=[raytrace.Sphere([0, 0, -3], 1)])
    raytrace.render(scene, width=8, height=4, threads=1, progress=raytrace.ProgressBar(
        file=out))
    assert "100%|" in out.getvalue() and "32/32" in out.getvalue()
    assert TIMES.search(out.getvalue())
