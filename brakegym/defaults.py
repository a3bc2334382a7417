"""Defaults that the simulations and the command line share, in a module that imports nothing:
the command line shows them in its help without loading the simulator."""

# RK4 at 0.2 s reproduces the golden values within 0.04 % and 0.01 K (tests/test_golden.py), far
# inside the spec's 0.5 %; 0.1 s halves that error at twice the cost.
DEFAULT_STEP_S = 0.2

# Stops per chunk of a campaign: about 0.35 s of one core for 16-disc trains (0.35 ms a stop), well
# above the ~100 ms that makes a chunk's overhead (pickling, scheduling, a Parquet file) negligible,
# and small enough that the paper's 4400-stop field campaign makes 5 chunks to share out.
DEFAULT_CHUNK_STOPS = 1000

# Stops per task of a rare-event run on worker processes or a cluster (brakegym tail, kdry): about
# 100 ms of one core, the least that keeps a task's overhead small; smaller than a campaign's
# chunk because an estimator's batches are small (a subset simulation's step evaluates one row
# per chain, a few hundred).
DEFAULT_TAIL_CHUNK_STOPS = 250

# The tail estimators of brakegym tail and brakegym.safety.tail.tail (docs/tails.md), named here so
# that the command line offers them without importing the estimators.
TAIL_METHODS = ("subset", "is", "brute")

# The step of a WSP controller and of the stops it commands: WSP controllers run at 50-100 Hz.
DEFAULT_WSP_CONTROL_STEP_S = 0.02
