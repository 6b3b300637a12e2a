"""One status vocabulary (longtime.core.status): the row statuses, the compiled loops' codes
and the row status each ends in, and how the messages that readers match begin."""
import re
from pathlib import Path

from longtime.core import drivers, rowschema, status
from longtime.core.status import Code, Status
from longtime.core.stepping import _status_message
from longtime.execution import budget, limits

PACKAGE = Path(__file__).resolve().parents[1] / "longtime"
# a row status written as a literal where a status is compared, assigned or stored
LITERAL = re.compile(r"""(?<!solver\.)status["')\]]*\s*(==|!=|=|\bin\b|\bnot in\b)\s*[(\[]?\s*"""
                     r"""["'](ok|diverged|failed|timeout|skipped)["']|["']status["']:\s*["'](ok|diverged|failed|"""
                     r"""timeout|skipped)["']|\bstatus, message = ["']""")


def test_the_row_declares_the_statuses_and_the_codes_end_in_them():
    assert rowschema.field("status").values == status.STATUSES == tuple(
        v for k, v in vars(Status).items() if not k.startswith("_"))
    # the drivers' codes are the vocabulary's, and every code but a full buffer ends in a row status
    assert (drivers.OK, drivers.DIVERGED, drivers.FAILED, drivers.BUFFER_FULL, drivers.TIMEOUT) == (
        Code.OK, Code.DIVERGED, Code.FAILED, Code.BUFFER_FULL, Code.TIMEOUT)
    assert set(status.STATUS_OF_CODE) == {Code.OK, Code.DIVERGED, Code.FAILED, Code.TIMEOUT}
    assert set(status.STATUS_OF_CODE.values()) <= set(status.STATUSES)


def test_the_messages_readers_match_begin_as_the_vocabulary_says():
    assert _status_message(Code.TIMEOUT, 2.5).startswith(status.TIME_LIMIT)
    assert _status_message(Code.FAILED, 2.5).startswith(status.STEP_FAILED + " at t=2.5 (")
    assert _status_message(Code.DIVERGED, 2.5) == status.blew_up_at(2.5)
    assert status.time_limit_at(None) == "time limit reached before the first step"
    assert status.step_failed_at(1.0, "the right-hand side is not finite") == (
        "step failed at t=1: the right-hand side is not finite")
    assert budget.TOO_SLOW is status.TOO_SLOW
    assert limits.MEMORY_LIMIT == status.MEMORY_LIMIT
    assert limits.hit_memory_limit({"message": f"{status.MEMORY_LIMIT}: the cell may use 1 GiB"})


def test_no_module_spells_a_row_status_as_a_literal():
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        name = path.relative_to(PACKAGE).as_posix()
        if name == "core/status.py":
            continue
        for k, line in enumerate(path.read_text().splitlines(), 1):
            if LITERAL.search(line):
                found.append(f"{name}:{k}: {line.strip()}")
    assert found == [], "read the status from longtime.core.status.Status:\n" + "\n".join(found)
