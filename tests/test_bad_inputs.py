"""Bad and extreme inputs end in one line or a picture, never a traceback, a hang or runaway
memory: the cases of ``tests/bad_inputs.py``, each in its own process under an 8 GiB
address-space limit and 60 s. A sample of every group runs by default, every case with
``-m slow``."""

from __future__ import annotations

import bad_inputs
import pytest

CASES = bad_inputs.cases()
#: The default run's sample: the first case of each group and those that once hung, grew
#: without end or ended in a traceback.
SAMPLE = {("value", "camera.position.2=1e+200"), ("structure", "json-deep-list"),
          ("structure", "huge-normal"), ("file", "scene-utf16"), ("file", "mesh-truncated-face"),
          ("flag", "frames-function-raises"), ("api", "string-material-appended"),
          ("api", "radius-negative"), ("api", "from-exr-corrupt")}


def ident(case: bad_inputs.Case) -> str:
    return f"{case.group}/{case.name}"


def check(case: bad_inputs.Case) -> None:
    outcome = bad_inputs.run(case)
    assert outcome.verdict in bad_inputs.GOOD, (
        f"{outcome.verdict} (exit {outcome.status}, {outcome.seconds:.1f} s): {outcome.line}")


def test_the_sample_names_cases_that_exist():
    assert SAMPLE <= {(c.group, c.name) for c in CASES}


@pytest.mark.parametrize("case", [c for c in CASES if (c.group, c.name) in SAMPLE], ids=ident)
def test_a_bad_input_ends_in_one_line_or_a_picture(case):
    check(case)


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=ident)
def test_every_bad_input_ends_in_one_line_or_a_picture(case):
    check(case)
