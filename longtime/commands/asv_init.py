"""``longtime asv-init DIR``: asv benchmarks for a plugin's repository.

Writes DIR/asv.conf.json and DIR/benchmarks/ (``__init__.py`` and ``bench_longtime.py``,
which builds its benchmarks with ``longtime.asvbench``) for the selected problems and
schemes; by default the problems and schemes DIR/pyproject.toml declares as entry points.
An existing file is left as it is unless ``--force``.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

from longtime.core import cli_args
from longtime.core.files import write_atomic
from longtime.core.params import InputError

CONF_TEMPLATE = {
    "version": 1,
    "project": "",
    "repo": ".",
    "branches": ["HEAD"],
    "dvcs": "git",
    "environment_type": "existing",
    "pythons": [f"{sys.version_info.major}.{sys.version_info.minor}"],
    "matrix": {"req": {"longtime": [""]}},
    "build_command": ["python -m pip wheel --no-deps -w {build_cache_dir} {build_dir}"],
    "install_command": ["in-dir={env_dir} python -m pip install {wheel_file}"],
    "uninstall_command": ["return-code=any python -m pip uninstall -y {project}"],
    "benchmark_dir": "benchmarks",
    "env_dir": ".asv/env",
    "results_dir": ".asv/results",
    "html_dir": ".asv/html",
    "default_benchmark_timeout": 600,
    # asv publish marks a change of a tracked value beyond 5 % by default; an instruction
    # count is deterministic (identical code agrees within 1e-4), so 1 % is the code's
    "regressions_thresholds": {r".*Cost\.track_instructions": 0.01},
}

# what to run in DIR once the files are written, on the environment that has the plugin and longtime
NEXT_STEPS = ("asv machine --yes", "asv run --quick --python=same --set-commit-hash HEAD",
              "asv publish && asv preview")
HISTORY_STEP = "asv run -E virtualenv --steps 10 ALL"
CONF_HEAD = ("// asv configuration written by `longtime asv-init`.\n"
             "// On the environment that has this package and longtime installed:\n"
             + "".join(f"//     {step}\n" for step in NEXT_STEPS)
             + f"// History, each commit built in a fresh virtualenv: {HISTORY_STEP}\n")

BENCH_TEMPLATE = '''\
"""asv benchmarks of {what}, written by `longtime asv-init`.

Judge a change of speed by Speed.track_cpu_ratio: the integration's CPU time in units of a
reference workload timed beside it, in fresh processes, so that the load and the machine's
speed between two commits' runs divide out. Integration.time_integrate and track_cpu_s
give the time in seconds (its size; asv's fixed factor 1.1 between runs minutes apart
misjudges them on a loaded machine): time_integrate the whole call (the compiled loop and
the Python work on its samples, asv's median), track_cpu_s the loop alone (the minimum of
runs spread over seconds), so on a run of a millisecond the first is several times the
second. Cost.track_instructions counts the integration's
instructions under Valgrind (deterministic: a slowdown of the scheme shows on a loaded
machine too; Debian package valgrind, else n/a); Accuracy.track_l2_error, track_drift (the
first invariant's maximum relative error) and track_growth_class (its growth class as a
number: 1 bounded, 3 linear, ...) track the accuracy of each cell (see longtime.asvbench)."""
from longtime.asvbench import benchmarks

PROBLEMS = {problems!r}
SCHEMES = {schemes!r}
SETTINGS = {settings!r}

globals().update(benchmarks(PROBLEMS, SCHEMES, t_final={t_final!r}, **SETTINGS))
'''


def declared(folder: Path) -> tuple[str, list[str], list[str]]:
    """(distribution name, problems, schemes) that folder/pyproject.toml declares."""
    path = folder / "pyproject.toml"
    if not path.is_file():
        return folder.resolve().name, [], []
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]
    try:
        project = tomllib.loads(path.read_text()).get("project", {})
    except Exception as exc:
        raise InputError(f"{path}: not readable as TOML ({exc})") from None
    points = project.get("entry-points", {}) if isinstance(project, dict) else project
    for key, value in (("project", project), ("project.entry-points", points),
                       *((f"project.entry-points.\"{g}\"", points.get(g, {}) if isinstance(points, dict) else {})
                         for g in ("longtime.problems", "longtime.integrators"))):
        if not isinstance(value, dict):  # as pip and setuptools read it: each of these is a table
            raise InputError(f"{path}: {key} is {type(value).__name__}, not a table: "
                             f"expected [{key.replace(chr(34), '')}] with name = \"module:Class\" lines")
    name = project.get("name")
    return (name if isinstance(name, str) and name else folder.resolve().name,
            sorted(points.get("longtime.problems", {})), sorted(points.get("longtime.integrators", {})))


def repo_path(folder: Path) -> str:
    """The git repository's top folder relative to ``folder`` (asv's "repo"): "." for a
    plugin at the top of its repository, "../.." for one in a subfolder (examples/plugin)."""
    import os
    import subprocess

    try:
        top = subprocess.run(["git", "-C", str(folder), "rev-parse", "--show-toplevel"], capture_output=True,
                             text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        top = ""
    return os.path.relpath(top, folder.resolve()) if top else "."


def _git(folder: Path, *args: str) -> Any:
    import subprocess

    try:
        return subprocess.run(["git", "-C", str(folder), *args], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None


def git_state(folder: Path) -> str:
    """"no git" (git is not installed), "no repository", "no commit" or "ok": whether asv,
    which clones the repository and builds a commit, can run in ``folder``."""
    found = _git(folder, "rev-parse", "--show-toplevel")
    if found is None:
        return "no git"
    if found.returncode != 0:
        return "no repository"
    head = _git(folder, "rev-parse", "--verify", "--quiet", "HEAD")
    return "ok" if head is not None and head.returncode == 0 else "no commit"


def first_commit(folder: Path) -> str:
    """Make ``folder`` a git repository with a commit (``git init`` where there is none, then
    every file committed) for asv; an identity for the commit where git has none. What was
    done, as one line; an InputError when git refuses."""
    state = git_state(folder)
    if state == "ok":
        return f"{folder} has a git commit already: nothing committed"
    if state == "no git":
        raise InputError("--git-commit: git is not installed (Debian package git)")
    steps = [("init",)] if state == "no repository" else []
    email = _git(folder, "config", "user.email")
    identity = [] if email is not None and email.stdout.strip() else [
        "-c", "user.name=longtime asv-init", "-c", "user.email=asv-init@localhost"]
    steps += [("add", "-A"), (*identity, "commit", "-q", "-m", "asv benchmarks written by longtime asv-init")]
    for step in steps:
        done = _git(folder, *step)
        if done is None or done.returncode != 0:
            why = (done.stderr or done.stdout).strip().splitlines()[-1:] if done is not None else ["git did not run"]
            raise InputError(f"--git-commit: git {' '.join(step)} failed in {folder}: {' '.join(why)}")
    return f"{folder}: {'git init, ' if state == 'no repository' else ''}first commit made for asv"


def next_steps(folder: Path, state: str) -> str:
    """What to run after asv-init, for stderr: the git repository asv needs where it is
    missing, then asv's commands."""
    lines = []
    if state != "ok":
        what = {"no git": "git is not installed (Debian package git)",
                "no repository": f"{folder} is not in a git repository",
                "no commit": f"{folder}'s git repository has no commit"}[state]
        lines += [f"asv needs a git repository with a commit (it clones the repository and builds a commit): {what}.",
                  f"  make one: cd {folder} && git init && git add -A && git commit -m 'asv benchmarks'",
                  f"  or let asv-init make it: longtime asv-init {folder} --git-commit"]
    lines.append(f"next, in {folder}, on the environment that has longtime and the plugin installed:")
    lines += [f"  {step}" for step in NEXT_STEPS]
    lines.append(f"  history, each commit built in a fresh virtualenv: {HISTORY_STEP}")
    return "\n".join(lines)


def write(folder: Path, problems: list[str], schemes: list[str], settings: dict, t_final: float | None,
          force: bool = False, own: tuple[str, list[str], list[str]] | None = None) -> list[Path]:
    """Write DIR's asv.conf.json and benchmarks/ (``own``: ``declared(folder)``, read once by
    the caller, else here); the paths written."""
    name, found_p, found_s = own or declared(folder)
    problems, schemes = problems or found_p, schemes or found_s
    if not problems or not schemes:
        raise InputError(f"{folder}: no problems or schemes to benchmark: pass -p and -i (its pyproject.toml "
                         f"declares problems {found_p or 'none'}, schemes {found_s or 'none'})")
    conf = {**CONF_TEMPLATE, "project": name, "repo": repo_path(folder)}
    files = {folder / "asv.conf.json": CONF_HEAD + json.dumps(conf, indent=4) + "\n",
             folder / "benchmarks" / "__init__.py": "",
             folder / "benchmarks" / "bench_longtime.py": BENCH_TEMPLATE.format(
                 what=", ".join(schemes) + " on " + ", ".join(problems), problems=problems, schemes=schemes,
                 settings=settings, t_final=t_final)}
    _check_targets(folder, list(files))  # every refusal before the first file is written
    written = []
    for path, text in files.items():
        if path.exists() and not force:
            print(f"kept {path} (exists; --force replaces it)", file=sys.stderr)
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, text)  # replaces a link itself, never the file it points to
        written.append(path)
    return written


def _check_targets(folder: Path, paths: list[Path]) -> None:
    """Refuse, before anything is written, a target that cannot be written whole: a folder
    where a file goes or a file where a folder goes, or a path whose folder leads out of
    DIR through a symbolic link (a link as the file itself is replaced, not written through)."""
    root = folder.resolve()
    if not os.access(root, os.W_OK):  # a read-only mount, or no permission: before any file
        raise InputError(f"DIR {folder}: not writable (a read-only file system or no permission): asv-init "
                         f"writes asv.conf.json and benchmarks/ there; nothing was written")
    for path in paths:
        parent = path.parent
        if parent.exists() and not parent.is_dir():
            raise InputError(f"{parent} is a file, not a folder: asv-init writes {path.name} there "
                             f"(move the file away); nothing was written")
        if parent.exists() and root not in (parent.resolve(), *parent.resolve().parents):
            raise InputError(f"{parent} leads out of {folder} (to {parent.resolve()}): asv-init writes only "
                             f"inside DIR; nothing was written")
        if path.is_dir():
            raise InputError(f"{path} is a folder, not a file; nothing was written")


def _check_names(own_p: list[str], own_s: list[str], problems: list[str], schemes: list[str]) -> None:
    """-p and -i name problems and schemes that are installed, or that DIR's pyproject.toml
    declares (``own_p``, ``own_s``: the plugin's own, perhaps not installed yet): one error for
    the unknown ones."""
    from longtime.core import registry

    registry.check_names("problem", [n for n in problems if n not in own_p])
    registry.check_names("integrator", [n for n in schemes if n not in own_s])


def _check_steps(own_p: list[str], own_s: list[str], problems: list[str], schemes: list[str], steps,
                 t_final: float | None) -> None:
    """Each installed problem x fixed-step scheme is refused a step larger than its span, as
    ``longtime run`` refuses it, so that the suite written holds no cell ``run`` would refuse
    (the plugin's own names, perhaps not installed yet, are checked when asv runs them)."""
    from longtime.core import registry
    from longtime.execution.sizes import check_step

    problems, schemes = problems or own_p, schemes or own_s
    known_p = [n for n in problems if n in registry.problems()]
    known_s = [n for n in schemes if n in registry.integrators()]
    for problem in known_p:
        span_end = registry.problem_class(problem).default_t_final if t_final is None else t_final
        for scheme in known_s:
            for dt in steps or [None]:
                check_step(problem, scheme, {} if dt is None else {"dt": dt}, span_end)


def _check_numbers(flag: str, values) -> None:
    for v in values or ():
        if not (0 < v < float("inf")):
            raise InputError(f"{flag} {v:g}: expected finite numbers > 0")


def cmd_asv_init(args) -> int:
    folder = Path(args.dir)
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder (the plugin's repository)")
    _check_numbers("--dt", args.dt)
    _check_numbers("--tol", args.tol)
    _check_numbers("--t-final", [args.t_final] if args.t_final is not None else [])
    own = _, own_p, own_s = declared(folder)  # DIR's pyproject.toml, read once
    _check_names(own_p, own_s, args.problem or [], args.integrator or [])
    _check_steps(own_p, own_s, args.problem or [], args.integrator or [], args.dt, args.t_final)
    settings = {k: v for k, v in (("dt", args.dt), ("tol", args.tol)) if v}
    for key, value in args.set:
        settings[key] = value
    for path in write(folder, args.problem or [], args.integrator or [], settings, args.t_final, args.force, own):
        print(path)
    if args.git_commit:
        print(first_commit(folder), file=sys.stderr)
    print(next_steps(folder, git_state(folder)), file=sys.stderr)
    return 0


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("asv-init", help="asv.conf.json and benchmarks/ for a plugin's repository",
                              description=__doc__.splitlines()[0])
    p.add_argument("dir", metavar="DIR", help="the plugin's repository")
    p.add_argument("-p", "--problem", type=cli_args.names, default=None, metavar="PROBLEM[,..]",
                   help="problems (default: those DIR/pyproject.toml declares)")
    p.add_argument("-i", "--integrator", type=cli_args.names, default=None, metavar="SCHEME[,..]",
                   help="schemes (default: those DIR/pyproject.toml declares)")
    p.add_argument("--dt", type=cli_args.floats("--dt"), default=None, metavar="X[,..]", help="time steps")
    p.add_argument("--tol", type=cli_args.floats("--tol"), default=None, metavar="X[,..]", help="tolerances")
    p.add_argument("--t-final", type=float, default=None, metavar="T", help="final time (default: the problem's)")
    p.add_argument("--set", type=cli_args.key_value, action="append", default=[], metavar="KEY=VALUE",
                   help="any other parameter (repeatable)")
    p.add_argument("--force", action="store_true", help="replace existing files")
    p.add_argument("--git-commit", action="store_true",
                   help="where DIR is not a git repository with a commit (asv needs one), make it: git init "
                        "if needed, then commit every file")
    p.set_defaults(func=cmd_asv_init)
