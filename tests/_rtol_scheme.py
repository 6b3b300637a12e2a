"""Test helper: a plugin scheme whose accuracy parameter is called ``rtol`` (Dormand-Prince
5(4) under another name for its tolerance), registered for one test by ``register``."""
from longtime.core import registry
from longtime.core.contract import check_registered
from longtime.core.params import Param
from longtime.integrators.embedded_rk import DormandPrince45

NAME = "test-rtol"


class RtolDormandPrince(DormandPrince45):
    name = NAME
    summary = "Dormand-Prince 5(4) whose tolerance is the parameter rtol (a test plugin)"
    parameters = {
        "rtol": Param(1e-6, "relative tolerance", float, positive=True, role="accuracy"),
        "atol": Param(None, "absolute tolerance (default: rtol)", float, positive=True),
        "controller": Param("pi", "step-size control", str, choices=("pi", "standard")),
    }
    sweep = {"rtol": (1e-4, 1e-7)}

    def prepare_work(self, problem, work):
        settings = self.settings
        self.settings = {**settings, "tol": settings["rtol"]}  # the family reads "tol"
        try:
            super().prepare_work(problem, work)
        finally:
            self.settings = settings


def register(monkeypatch) -> None:
    """Register the scheme as an entry point would (undone when the test ends)."""
    check_registered(RtolDormandPrince)
    monkeypatch.setitem(registry._load()["integrators"], NAME, RtolDormandPrince)
