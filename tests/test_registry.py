"""Discovery of problems and schemes (longtime.core.registry), on entry points made in the test:
what loads, what is broken and why, and how name clashes resolve."""
from dataclasses import dataclass
from importlib.metadata import EntryPoint
from types import SimpleNamespace

import pytest

from longtime import InputError
from longtime.core import registry
from longtime.integrators.splitting import Verlet
from longtime.problems.harmonic import Harmonic


@dataclass
class FakeEntryPoint:
    name: str
    value: str
    target: object
    dist_name: str = "a-plugin"
    pattern = EntryPoint.pattern  # what a NAME = module:Class value must match

    @property
    def dist(self):
        return SimpleNamespace(name=self.dist_name)

    def load(self):
        if isinstance(self.target, Exception):
            raise self.target
        return self.target


class RenamedHarmonic(Harmonic):
    name = "harmonic-again"


@pytest.fixture
def fake_points(monkeypatch):
    """Replace the installed entry points with the ones a test lists, with no class
    registered from Python; restore the real registry afterwards."""
    groups = {"longtime.problems": [], "longtime.integrators": []}
    monkeypatch.setattr(registry, "entry_points", lambda group: list(groups[group]))
    monkeypatch.setattr(registry, "_session", {"problems": {}, "integrators": {}})  # nothing registered from Python
    registry.reload()
    yield groups
    monkeypatch.undo()
    registry.reload()


def test_the_installed_built_ins_load_and_none_is_broken():
    registry.reload()
    assert {"harmonic", "kepler", "toda"} <= set(registry.problems())
    assert {"rk4", "verlet", "gauss4"} <= set(registry.integrators())
    assert registry.problem_class("kepler").name == "kepler"
    assert [b for b in registry.broken() if b.target.startswith("longtime.")] == []


def test_a_plugin_that_fails_to_import_is_broken_and_the_rest_load(fake_points):
    fake_points["longtime.problems"] += [
        FakeEntryPoint("harmonic", "longtime.problems.harmonic:Harmonic", Harmonic, "longtime"),
        FakeEntryPoint("exploding", "boom:Problem", ImportError("no module named boom")),
    ]
    registry.reload()
    assert list(registry.problems()) == ["harmonic"]
    (bad,) = registry.broken()
    assert bad.name == "exploding" and "no module named boom" in bad.error
    with pytest.raises(InputError, match="'exploding' is a broken plugin: .*boom"):
        registry.problem_class("exploding")


def test_a_class_of_the_wrong_kind_or_name_is_broken(fake_points):
    fake_points["longtime.problems"] += [
        FakeEntryPoint("not-a-problem", "x:Verlet", Verlet),
        FakeEntryPoint("other-name", "x:RenamedHarmonic", RenamedHarmonic),
    ]
    registry.reload()
    assert registry.problems() == {}
    errors = {b.name: b.error for b in registry.broken()}
    assert "is not a subclass of longtime.core.problem.Problem" in errors["not-a-problem"]
    assert "is named 'harmonic-again' but registered as 'other-name'" in errors["other-name"]


def test_a_clash_with_a_built_in_keeps_the_built_in(fake_points):
    fake_points["longtime.integrators"] += [
        FakeEntryPoint("verlet", "longtime.integrators.splitting:Verlet", Verlet, "longtime"),
        FakeEntryPoint("verlet", "mine:Verlet", Verlet, "my-plugin"),
    ]
    registry.reload()
    assert registry.integrators() == {"verlet": Verlet}
    (bad,) = registry.broken()
    assert bad.target == "mine:Verlet" and "the built-in keeps it" in bad.error


def test_a_clash_between_plugins_loads_neither(fake_points):
    fake_points["longtime.integrators"] += [
        FakeEntryPoint("leap", "one:Verlet", Verlet, "plugin-one"),
        FakeEntryPoint("leap", "two:Verlet", Verlet, "plugin-two"),
    ]
    registry.reload()
    assert registry.integrators() == {}
    assert len(registry.broken()) == 2
    assert all("none of them is loaded" in b.error for b in registry.broken())


def test_unknown_names_are_reported_together_with_the_closest(fake_points):
    fake_points["longtime.problems"] += [
        FakeEntryPoint("harmonic", "longtime.problems.harmonic:Harmonic", Harmonic, "longtime")]
    registry.reload()
    with pytest.raises(InputError, match=r"'harmonik' \(did you mean harmonic\?\), 'zzz'"):
        registry.check_names("problem", ["harmonik", "zzz", "harmonic"])


def test_the_session_is_pickled_whole_by_threads_that_start_workers_together(monkeypatch):
    """A pool's threads start their workers together, each pickling the session's classes;
    numba gives a compiled function its pickling id on first use, unguarded, so two threads
    at once would fail one batch ("worker process failed: AssertionError()")."""
    import threading

    import numba

    def pickled_together(threads: int = 8) -> list[BaseException]:
        kernels = {f"k{i}": numba.njit(lambda x: x) for i in range(4)}  # fresh: no id yet
        monkeypatch.setattr(registry, "_session", {"problems": kernels, "integrators": {}})
        start, failed = threading.Barrier(threads), []

        def one():
            start.wait()
            try:
                registry.session_payload()
            except BaseException as exc:  # noqa: BLE001  (what a worker's start would turn into a failed batch)
                failed.append(exc)

        team = [threading.Thread(target=one) for _ in range(threads)]
        for t in team:
            t.start()
        for t in team:
            t.join()
        return failed

    failures = [exc for _ in range(200) for exc in pickled_together()]
    assert failures == []
