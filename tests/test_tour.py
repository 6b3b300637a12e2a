"""README's tour of the commands runs in order after a run of the main command, each command
as written, and each prints an answer or a line saying why there is none.

On a small store: the main command's run is a small matrix, and the tour's matrices run two
schemes (``-i`` added) with no checks; every other command runs as README writes it (the
placeholder DIR of asv-init is a copy of the example plugin)."""
import re
import shlex
import shutil
from pathlib import Path

import pytest

from longtime.commands.cli import main

ROOT = Path(__file__).resolve().parents[1]
# a command's allowed exit codes besides 0: a question with no answer (recommend: 3), a
# comparison that finds a regression (compare: 1, on a loaded machine)
ALSO = {"recommend": {3}, "compare": {1}}
SMALL = ["-i", "verlet,rk4", "--checks", "0", "--no-ensemble", "--no-html"]


def tour() -> list[list[str]]:
    """The commands of README's tour, in order, each as its arguments after `longtime`."""
    text = (ROOT / "README.md").read_text()
    block = text.split("## A tour of the commands", 1)[1].split("```bash\n", 1)[1].split("```", 1)[0]
    out = []
    for line in block.splitlines():
        command = line.split("#", 1)[0].strip()
        if command:
            words = shlex.split(command)
            assert words[0] == "longtime", line
            out.append(words[1:])
    return out


def test_the_tour_is_stated_in_order():
    commands = [c[0] for c in tour()]
    assert commands[0] == "matrix" and "--quick" in tour()[0]  # the first answer comes first
    assert {"list", "run", "report", "recommend", "card", "compare", "history"} <= set(commands)
    # compare names run 1 (the main command's) and the tour's sub-matrix: the runs before it make it run 4
    runs = [c for c in tour()[:commands.index("compare")] if c[0] in ("matrix", "run")]
    assert tour()[commands.index("compare")][1:3] == ["1", str(1 + len(runs))]


@pytest.mark.slow
def test_the_tour_runs_in_order_on_a_small_store(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("LONGTIME_DB", str(tmp_path / "longtime.sqlite"))
    plugin = tmp_path / "plugin"
    shutil.copytree(ROOT / "examples" / "plugin", plugin)
    assert main(["matrix", "-p", "harmonic,kepler,toda", *SMALL]) == 0  # the main command's run: run 1
    capsys.readouterr()
    for argv in tour():
        if argv[0] == "matrix":
            argv = [*argv, *SMALL]
        argv = [str(plugin) if a == "DIR" else a for a in argv]
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's own refusals
            code = exc.code
        out = capsys.readouterr()
        assert code == 0 or code in ALSO.get(argv[0], set()), (argv, code, out.err[-2000:])
        assert (out.out + out.err).strip(), argv  # an answer, or the line that says why not
        assert "Traceback" not in out.err, out.err
        if code == 3:
            assert re.search(r"no answer|no pointwise answer", out.out), out.out
