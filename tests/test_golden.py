"""The golden file of public calls (tests/golden.py): every number of about sixty public calls, bit
for bit, on the machine and JAX build that recorded it; to OTHER_MACHINE_RTOL elsewhere."""

import json

import numpy as np
import pytest

from golden import CALLS, GOLDEN, OTHER_MACHINE_RTOL, bits, machine

RECORDED = json.loads(GOLDEN.read_text())
SAME_MACHINE = RECORDED["machine"] == machine()

pytestmark = pytest.mark.slow  # sixty programs to compile: the slow tier


def test_the_golden_file_covers_every_call():
    assert sorted(RECORDED["calls"]) == sorted(CALLS)


@pytest.mark.parametrize("name", sorted(CALLS))
def test_public_call_matches_the_golden_file(name):
    got, want = bits(CALLS[name]()), RECORDED["calls"][name]
    assert len(got) == len(want), (name, len(got), len(want))
    if SAME_MACHINE:
        assert got == want, name
        return
    as_numbers = [float.fromhex(x) if "x" in x or x in ("nan", "inf", "-inf") else float(x)
                  for x in (*got, *want)]
    np.testing.assert_allclose(as_numbers[:len(got)], as_numbers[len(got):], rtol=OTHER_MACHINE_RTOL,
                               atol=0.0, equal_nan=True, err_msg=name)
