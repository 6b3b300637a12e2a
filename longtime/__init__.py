"""longtime: a benchmark suite for time integrators on long-time dynamics.

Importing the package compiles nothing: numba kernels compile on first use.
"""
from longtime.core.version import __version__

__all__ = ["AdaptiveIntegrator", "FixedStepIntegrator", "InputError", "Integrator", "MainJobSpec", "Order", "Param",
           "Problem", "Result", "Trajectory", "__version__", "card", "convergence", "main_job", "plot", "recommend",
           "solve", "sweep", "testing", "work_precision"]

# the Python API (docs/api.md), imported on first use: `import longtime` stays light
_API = ("Order", "Result", "card", "convergence", "main_job", "recommend", "solve", "sweep", "work_precision")
# the main job's specification, from its home in the execution layer, on first use too
_EXECUTION = {"MainJobSpec": "main_job"}
# the base classes, imported on first use too (numpy and numba load with them): the command's
# entry point (longtime.commands.entry) is running, and catches Ctrl-C, before they load
_CORE = {"AdaptiveIntegrator": "stepping", "FixedStepIntegrator": "stepping", "Integrator": "integrator",
         "Trajectory": "trajectory", "InputError": "params", "Param": "params", "Problem": "problem"}
# submodules on top of the API, imported on first use as longtime.plot, longtime.testing
_SUBMODULES = ("plot", "testing", "api", "asvbench")


def __getattr__(name: str):
    if name in _API:
        from longtime import api

        return getattr(api, name)
    if name in _CORE:
        import importlib

        return getattr(importlib.import_module(f"longtime.core.{_CORE[name]}"), name)
    if name in _EXECUTION:
        import importlib

        return getattr(importlib.import_module(f"longtime.execution.{_EXECUTION[name]}"), name)
    if name in _SUBMODULES:
        import importlib

        return importlib.import_module(f"longtime.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
