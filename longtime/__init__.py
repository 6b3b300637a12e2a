"""longtime: a benchmark suite for time integrators on long-time dynamics.

Importing the package compiles nothing: numba kernels compile on first use.
"""
from .integrator import AdaptiveIntegrator, FixedStepIntegrator, Integrator, Trajectory
from .params import InputError, Param
from .problem import Problem

from .version import __version__
__all__ = ["AdaptiveIntegrator", "FixedStepIntegrator", "InputError", "Integrator", "Param",
           "Problem", "Trajectory", "__version__"]
