"""Files the suite writes are replaced whole or not at all: never through a symbolic link, and
on a full disk the previous file stays, with one line and a non-zero exit."""
import errno
import os
import subprocess
import sys

import pytest

from longtime.commands.cli import main
from longtime.core import files
from longtime.core.files import NotWritten, write_atomic

QUICK = ["-p", "harmonic", "-i", "verlet", "--dt", "0.1", "--t-final", "1"]


def test_a_link_at_the_path_is_replaced_and_its_target_kept(tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("precious")
    folder = tmp_path / "out"
    folder.mkdir()
    (folder / "page.html").symlink_to(outside)
    write_atomic(folder / "page.html", "<html>new</html>")
    assert outside.read_text() == "precious"
    assert not (folder / "page.html").is_symlink() and (folder / "page.html").read_text() == "<html>new</html>"
    assert sorted(p.name for p in folder.iterdir()) == ["page.html"]  # no temporary file left


def test_a_write_that_fails_midway_keeps_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "index.html"
    path.write_text("old page")
    real = os.write
    calls = []

    def full(fd, data):
        calls.append(len(data))
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd, data[:10])

    monkeypatch.setattr(files.os, "write", full)
    with pytest.raises(NotWritten) as caught:
        write_atomic(path, "x" * 100_000)
    assert caught.value.errno == errno.ENOSPC
    assert "No space left on device" in str(caught.value) and "\n" not in str(caught.value)
    assert path.read_text() == "old page" and [p.name for p in tmp_path.iterdir()] == ["index.html"]


@pytest.fixture
def db(tmp_path):
    db = tmp_path / "r.sqlite"
    assert main(["run", *QUICK, "--db", str(db)]) == 0
    return db


def _cli(*args):
    env = {**os.environ, "LONGTIME_PROGRESS": "0"}
    return subprocess.run([sys.executable, "-m", "longtime.commands.cli", *args], capture_output=True, text=True,
                          env=env, timeout=300)


@pytest.mark.slow
def test_report_html_never_writes_through_a_linked_page(tmp_path, db):
    outside = tmp_path / "elsewhere.html"
    outside.write_text("not the suite's")
    folder = tmp_path / "site"
    folder.mkdir()
    (folder / "index.html").symlink_to(outside)
    res = _cli("report", "--html", str(folder), "--db", str(db))
    assert res.returncode == 0, res.stderr
    assert outside.read_text() == "not the suite's"
    assert not (folder / "index.html").is_symlink() and "<html" in (folder / "index.html").read_text()


@pytest.mark.slow
def test_a_full_disk_keeps_the_previous_page_with_one_line_and_exit_1(tmp_path, db):
    mount = tmp_path / "small"
    mount.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=200k", "tmpfs", str(mount)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        old = "<html>the previous complete page</html>"
        (mount / "index.html").write_text(old)
        fd = os.open(mount / "filler", os.O_WRONLY | os.O_CREAT)  # the disk full but for 8 KiB
        written = 0
        try:
            while True:
                written += os.write(fd, b"\1" * 4096)
        except OSError:
            os.ftruncate(fd, written - 8192)
        finally:
            os.close(fd)
        res = _cli("report", "--html", str(mount), "--db", str(db))
        assert res.returncode != 0
        lines = [ln for ln in res.stderr.strip().splitlines() if ln.strip()]
        assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
        assert "No space left on device" in lines[0] and "index.html" in lines[0]
        assert (mount / "index.html").read_text() == old
        assert sorted(p.name for p in mount.iterdir()) == ["filler", "index.html"]
    finally:
        subprocess.run(["umount", str(mount)], check=False)
