"""asv-init checks its input before it writes anything; --force
never writes through a symbolic link out of DIR."""
import ast

import pytest

from longtime.commands.cli import main


def _asv_init(capsys, *args):
    capsys.readouterr()
    try:
        code = main(["asv-init", *map(str, args)])
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


def test_benchmarks_a_file_is_refused_before_writing_anything(tmp_path, capsys):
    (tmp_path / "benchmarks").write_text("not a folder")
    code, err = _asv_init(capsys, tmp_path, "-p", "harmonic", "-i", "rk4")
    assert code == 2 and "benchmarks" in err and "nothing was written" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["benchmarks"]


def test_force_never_writes_through_a_symlink_out_of_dir(tmp_path, capsys):
    repo, outside = tmp_path / "repo", tmp_path / "outside"
    repo.mkdir()
    outside.mkdir()
    victim = outside / "precious.json"
    victim.write_text("keep me")
    (repo / "asv.conf.json").symlink_to(victim)
    code, err = _asv_init(capsys, repo, "-p", "harmonic", "-i", "rk4", "--force")
    assert code == 0, err
    assert victim.read_text() == "keep me"
    assert not (repo / "asv.conf.json").is_symlink() and '"benchmark_dir"' in (repo / "asv.conf.json").read_text()
    # a benchmarks folder that is a link out of DIR: refused, nothing written through it
    repo2 = tmp_path / "repo2"
    repo2.mkdir()
    (repo2 / "benchmarks").symlink_to(outside, target_is_directory=True)
    code, err = _asv_init(capsys, repo2, "-p", "harmonic", "-i", "rk4", "--force")
    assert code == 2 and "leads out of" in err, err
    assert sorted(p.name for p in outside.iterdir()) == ["precious.json"]
    assert sorted(p.name for p in repo2.iterdir()) == ["benchmarks"]


@pytest.mark.parametrize("args, text", [
    (["-p", "harmonc", "-i", "rk4"], "harmonc"),
    (["-p", "harmonic", "-i", "rk5"], "rk5"),
    (["-p", "harmonic", "-i", "rk4", "--t-final", "-5"], "--t-final"),
    (["-p", "harmonic", "-i", "rk4", "--t-final", "nan"], "--t-final"),
    (["-p", "harmonic", "-i", "rk4", "--dt", "0"], "--dt"),
    (["-p", "harmonic", "-i", "rk45", "--tol", "-1e-6"], "--tol"),
    (["-p", "harmonic", "-i", "rk4", "--dt", "5", "--t-final", "1"], "larger than the span"),
])
def test_unknown_names_and_bad_numbers_are_refused(tmp_path, capsys, args, text):
    code, err = _asv_init(capsys, tmp_path, *args)
    assert code == 2 and text in err and "Traceback" not in err, err
    assert not list(tmp_path.iterdir())


def test_a_plugin_s_own_declared_names_are_taken(tmp_path, capsys):
    (tmp_path / "pyproject.toml").write_text(
        '[project]\nname = "myplug"\n[project.entry-points."longtime.integrators"]\nmy-scheme = "myplug:Scheme"\n')
    code, err = _asv_init(capsys, tmp_path, "-p", "harmonic", "-i", "my-scheme", "--t-final", "2")
    assert code == 0, err
    text = (tmp_path / "benchmarks" / "bench_longtime.py").read_text()
    module = ast.parse(text)
    assigned = {node.targets[0].id: ast.literal_eval(node.value) for node in module.body
                if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name)}
    t_final = next(ast.literal_eval(k.value) for node in ast.walk(module) if isinstance(node, ast.Call)
                   for k in node.keywords if k.arg == "t_final")
    assert assigned["SCHEMES"] == ["my-scheme"] and assigned["PROBLEMS"] == ["harmonic"]
    assert t_final == 2.0  # the number given, written as a float the benchmarks take


@pytest.mark.parametrize("toml", [
    '[project]\nname = "p"\nentry-points = "longtime.problems"\n',
    '[project]\nname = "p"\nentry-points = ["a"]\n',
    '[project]\nname = "p"\n[project.entry-points]\n"longtime.problems" = "x:Y"\n',
    'project = 3\n',
])
def test_entry_points_not_a_table_is_a_refusal(tmp_path, capsys, toml):
    (tmp_path / "pyproject.toml").write_text(toml)
    code, err = _asv_init(capsys, tmp_path)
    assert code == 2 and "not a table" in err and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pyproject.toml"]


def test_asv_init_says_what_to_run_next_and_that_asv_needs_a_commit(tmp_path, capsys):
    import shutil
    import subprocess

    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    code, err = _asv_init(capsys, tmp_path, "-p", "harmonic", "-i", "rk4")
    assert code == 0, err
    assert "asv needs a git repository with a commit" in err and "is not in a git repository" in err
    assert "--git-commit" in err and "asv run --quick --python=same --set-commit-hash HEAD" in err
    # asked, it makes the repository and its first commit; then only the next steps are said
    code, err = _asv_init(capsys, tmp_path, "-p", "harmonic", "-i", "rk4", "--git-commit")
    assert code == 0, err
    assert "first commit made for asv" in err and "asv needs a git repository" not in err
    assert "asv machine --yes" in err
    listed = subprocess.run(["git", "-C", str(tmp_path), "ls-files"], capture_output=True, text=True).stdout.split()
    assert sorted(listed) == ["asv.conf.json", "benchmarks/__init__.py", "benchmarks/bench_longtime.py"]
    code, err = _asv_init(capsys, tmp_path, "-p", "harmonic", "-i", "rk4", "--git-commit")
    assert code == 0 and "has a git commit already" in err
