"""A read-only folder (a read-only mount) is refused in one line before any work: asv-init's
DIR, a new store's folder."""
import subprocess

import pytest

from longtime.commands.cli import main


@pytest.fixture
def read_only(tmp_path):
    """A read-only bind mount of an empty folder (needs root and mount; else skipped)."""
    source, mount = tmp_path / "source", tmp_path / "mount"
    source.mkdir()
    mount.mkdir()
    done = subprocess.run(["mount", "--bind", str(source), str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip(f"no bind mount here: {done.stderr.decode().strip()}")
    try:
        if subprocess.run(["mount", "-o", "remount,ro,bind", str(mount)], capture_output=True).returncode != 0:
            pytest.skip("no read-only remount here")
        yield mount
    finally:
        subprocess.run(["umount", str(mount)], capture_output=True)


def _main(capsys, *args):
    capsys.readouterr()
    try:
        code = main(list(map(str, args)))
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def test_asv_init_on_a_read_only_folder_is_refused_in_one_line(read_only, capsys):
    code, err = _main(capsys, "asv-init", read_only, "-p", "harmonic", "-i", "rk4")
    assert code == 2 and "not writable" in err and "nothing was written" in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_run_with_a_new_store_on_a_read_only_folder_is_refused_before_any_cell(read_only, capsys):
    code, err = _main(capsys, "run", "-p", "harmonic", "-i", "rk4", "--t-final", "5", "--db",
                      read_only / "new.sqlite")
    assert code == 2 and "cannot write it" in err and "not writable" in err and "--no-store" in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
