"""The reference check is part of a cell: it stops at the cell's time limit on every executor,
the serial one and the API's included, and the row says so."""
import time

import pytest

import longtime


@pytest.mark.slow  # runs to its hard limit: 2 s + 10 s of grace, and heyoka's compile
def test_a_long_reference_check_ends_at_the_cells_time_limit_on_the_serial_executor():
    start = time.monotonic()
    rows = longtime.sweep("kepler", "rk4", dt=[0.5], t_final=2e6, executor="serial", time_limit=2, repeats=1)
    elapsed = time.monotonic() - start
    row = rows.iloc[0]
    assert row["status"] == "timeout"
    assert "the reference check passed the cell's hard time limit of 12.2 s" in row["message"]
    # the heyoka reference to t = 2e6 takes minutes; the cell ends at its hard limit (2 s + grace)
    assert elapsed < 60, elapsed
