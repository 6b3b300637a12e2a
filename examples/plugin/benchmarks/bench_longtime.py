"""asv benchmarks of example-forest-ruth, example-heun, example-midpoint on kepler, written by `longtime asv-init`.

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

PROBLEMS = ['kepler']
SCHEMES = ['example-forest-ruth', 'example-heun', 'example-midpoint']
SETTINGS = {'dt': [0.01]}

globals().update(benchmarks(PROBLEMS, SCHEMES, t_final=None, **SETTINGS))
