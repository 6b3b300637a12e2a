"""The reference check is part of a cell: it stops at the cell's time limit on every executor,
the serial one and the API's included, and the row says so."""
import time

import longtime


def test_a_long_reference_check_ends_at_the_cells_time_limit_on_the_serial_executor():
    start = time.monotonic()
    rows = longtime.sweep("kepler", "rk4", dt=[0.5], t_final=2e6, executor="serial", time_limit=2, repeats=1)
    elapsed = time.monotonic() - start
    row = rows.iloc[0]
    assert row["status"] == "timeout" and "reference check passed the cell's time limit of 2 s" in row["message"]
    # the heyoka reference to t = 2e6 takes minutes; the cell ends within its limit plus compile and start-up
    assert elapsed < 60, elapsed
