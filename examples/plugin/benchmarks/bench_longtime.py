"""asv benchmarks of example-forest-ruth, example-heun, example-midpoint on kepler, written by `longtime asv-init`.

Integration.time_integrate times the integration alone; Cost.track_instructions counts
its instructions under Valgrind (deterministic: a slowdown of the scheme shows on a loaded
machine too; Debian package valgrind, else n/a); Accuracy.track_l2_error, track_drift (the
first invariant's maximum relative error) and track_growth_class (its growth class as a
number: 1 bounded, 3 linear, ...) track the accuracy of each cell (see longtime.asvbench)."""
from longtime.asvbench import benchmarks

PROBLEMS = ['kepler']
SCHEMES = ['example-forest-ruth', 'example-heun', 'example-midpoint']
SETTINGS = {'dt': [0.01]}

globals().update(benchmarks(PROBLEMS, SCHEMES, t_final=None, **SETTINGS))
