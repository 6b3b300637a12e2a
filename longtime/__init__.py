"""longtime: a benchmark suite for time integrators on long-time dynamics.

Importing the package compiles nothing: numba kernels compile on first use.
"""
from .integrator import AdaptiveIntegrator, FixedStepIntegrator, Integrator, Trajectory
from .params import InputError, Param
from .problem import Problem
from .api import Order, Result, convergence, solve, sweep, work_precision

__version__ = "0.1.0"
__all__ = ["AdaptiveIntegrator", "FixedStepIntegrator", "InputError", "Integrator", "Order", "Param",
           "Problem", "Result", "Trajectory", "__version__", "convergence", "solve", "sweep", "work_precision"]
