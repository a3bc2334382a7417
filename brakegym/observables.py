"""Observables of a :class:`~brakegym.applications.StopSummary` by name: the summaries whose
scatter the identification fits (:mod:`brakegym.identification.stochastic`). Here, apart from
the identification, so that the command line can offer the names without importing it."""

DYNO_OBSERVABLES = {"mu_s": lambda s: s.mu_s[:, 0], "s_m": lambda s: s.stop_distance_m}
TRAIN_OBSERVABLES = {
    "mu_s_eff": lambda s: s.mu_s_eff,
    "braking_distance_m": lambda s: s.braking_distance_m,
    "stop_distance_m": lambda s: s.stop_distance_m,
}
