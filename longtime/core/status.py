"""What became of a run, in one vocabulary: the statuses a row ends in (``Status``), the codes
the compiled loops and steps return (``Code``) and the row status each ends in
(``STATUS_OF_CODE``), and how the messages begin that readers match (``TIME_LIMIT``,
``STEP_FAILED``, ``MEMORY_LIMIT``, ``TOO_SLOW``) with the texts that write them.

The values are plain strings and integers (a row stores its status as JSON text; a compiled
loop returns an integer): compare ``row["status"] == Status.OK``, return ``Code.OK``
(``longtime.core.drivers`` re-exports the codes for the step contracts)."""
from __future__ import annotations


class Status:
    """The statuses of a row (the values of its ``status`` field, longtime.core.rowschema)."""

    OK = "ok"  # the run reached its final time
    DIVERGED = "diverged"  # the state blew up (non-finite or beyond the problem's bound)
    FAILED = "failed"  # a step failed, the scheme raised, the cell's process died or ran out of memory
    TIMEOUT = "timeout"  # the run passed its time limit
    SKIPPED = "skipped"  # the cell did not run: the scheme does not apply, a package is missing, ...


STATUSES = (Status.OK, Status.DIVERGED, Status.FAILED, Status.TIMEOUT, Status.SKIPPED)


class Code:
    """The integer codes the compiled loops (longtime.core.drivers) and a scheme's step return."""

    OK = 0
    DIVERGED = 1
    FAILED = 2
    BUFFER_FULL = 3  # an adaptive loop's sample buffers are full: the caller goes on with fresh ones
    TIMEOUT = 4


# the row status a loop's code ends in
STATUS_OF_CODE = {Code.OK: Status.OK, Code.DIVERGED: Status.DIVERGED, Code.FAILED: Status.FAILED,
                  Code.TIMEOUT: Status.TIMEOUT}

# how the messages begin: a timeout's, a failed step's, a cell's stopped by its memory limit
# (longtime.execution.limits), a cell the default matrix's budget skips (longtime.execution.budget),
# a library peer's run stopped at its chain's CPU bound (a timeout that is no failure: a
# cheaper setting of its library keeps the target; longtime.execution.batches), a run the
# budget estimated too slow stopped once its pace put its end far past its time limit
# (longtime.integrators.peer_common.Pace)
TIME_LIMIT = "time limit reached"
STEP_FAILED = "step failed"
MEMORY_LIMIT = "memory limit"
TOO_SLOW = "too slow for the default matrix:"
BOUNDED = "stopped at its library's bound:"
PACED = "stopped on its pace:"
# a diverged run's message at t (longtime.core.problem.BLOWUP_MESSAGE, as the library peers read it)
BLOWUP = "state blew up (non-finite or beyond the problem's bound) at t={t:.6g}"


def time_limit_at(t: float | None) -> str:
    """A timeout's message: where the run got (None: before its first step)."""
    return f"{TIME_LIMIT} before the first step" if t is None else f"{TIME_LIMIT} at t={t:.6g}"


def bounded(row: dict) -> bool:
    """Whether ``row`` is a library peer's run stopped at its chain's CPU bound (BOUNDED): a
    costlier setting than one of its library that keeps the target, not a failure."""
    return row.get("status") == Status.TIMEOUT and str(row.get("message") or "").startswith(BOUNDED)


def step_failed_at(t: float, why: str) -> str:
    """A failed step's message at ``t``: ``why`` after a colon, or in parentheses where it
    begins with '('."""
    return f"{STEP_FAILED} at t={t:.6g}" + (f" {why}" if why.startswith("(") else f": {why}")


def blew_up_at(t: float) -> str:
    """A diverged run's message at ``t``."""
    return BLOWUP.format(t=t)
