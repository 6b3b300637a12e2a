"""asv benchmarks of example-forest-ruth, example-heun, example-midpoint on kepler, written by `longtime asv-init`.

Integration.time_integrate times the integration alone; Accuracy.track_l2_error,
track_drift (the first invariant's maximum relative error) and track_growth (its growth
exponent) track the accuracy of each cell (see longtime.asvbench)."""
from longtime.asvbench import benchmarks

PROBLEMS = ['kepler']
SCHEMES = ['example-forest-ruth', 'example-heun', 'example-midpoint']
SETTINGS = {'dt': [0.01]}

globals().update(benchmarks(PROBLEMS, SCHEMES, t_final=None, **SETTINGS))
