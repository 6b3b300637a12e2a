"""longtime: a benchmark suite for time integrators on long-time dynamics.

Importing the package compiles nothing: numba kernels compile on first use.
"""
from longtime.core.integrator import AdaptiveIntegrator, FixedStepIntegrator, Integrator, Trajectory
from longtime.core.params import InputError, Param
from longtime.core.problem import Problem
from longtime.core.version import __version__

__all__ = ["AdaptiveIntegrator", "FixedStepIntegrator", "InputError", "Integrator", "Order", "Param",
           "Problem", "Result", "Trajectory", "__version__", "convergence", "recommend", "solve", "sweep",
           "work_precision"]

# the Python API (docs/api.md), imported on first use: `import longtime` stays light
_API = ("Order", "Result", "convergence", "recommend", "solve", "sweep", "work_precision")


def __getattr__(name: str):
    if name in _API:
        from longtime import api

        return getattr(api, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
