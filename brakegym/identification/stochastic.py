"""Stochastic identification: the scatter of mu_0 and a (paper Eq. 13) and the global/individual
split of each sigma (MCS-75/25, spec Section 5), from the spread a campaign shows.

Data
----
Groups of repeated applications under one condition (a dynamometer load case; one field
application of a train), each with the observed value of one summary per application (mu_s of
Eq. 3 on the rig, mu_s,eff of Eq. 15 or the braking distance on the train). Each group has a
disc count (1 on the rig, 16 for ``emu_8axle``) and either a known split (the rig's applications
are independent stops: the spec's MCS-100, global fraction 0) or the split to be fitted.

Method: method of moments with linearised sensitivities
-------------------------------------------------------
With the sigmas small against the nominal values (0.01 of 0.35, 0.001 of 0.008), a summary Y of a
stop is nearly linear in each disc's mu_0 and a. Writing g_j for dY/dtheta_j of disc j (by a
forward difference of the deterministic model, all perturbed copies in one simulator batch),
G = sum_j g_j and S = sum_j g_j^2, a set-up with global fraction f and individual fraction 1 - f
(the paper's partition of sigma) gives

    Var Y = sum over theta in {mu_0, a} of sigma_theta^2 (f^2 G_theta^2 + (1 - f)^2 S_theta)
            + sigma_A^2 H^2          (running-resistance scatter on the train, known, if present)

For one disc S = G^2, so a single-disc group sees sigma^2 (f^2 + (1 - f)^2) only: the split is not
identifiable from single-disc data. A 16-disc train sees sigma^2 G^2 (f^2 + (1 - f)^2 / 16): the
train-level spread shrinks by sqrt(16) for independent scatter (f = 0) and keeps about 3/4 of it
for MCS-75/25, but alone it fixes only that product, not sigma and f apart: the split needs
multi-disc data *and* data that fix sigma (single-disc groups with a known split).

Each group's sample variance s^2 (nu = n - 1 degrees of freedom) is, for Gaussian scatter,
Var Y * chi^2_nu / nu; the sigmas and the split are fitted by maximum likelihood under that law
(least squares on the gamma deviance residuals, bounds from the identification config). Why
moments and not a simulation-based fit: the linearised variance is exact to second order in the
small sigmas, costs one batch of sensitivity runs instead of a campaign per evaluation, and its
error is checked in the tests by recovering sigmas from campaigns simulated with the full
nonlinear model. Intervals: a parametric bootstrap of the chi-square law of every group's
variance (fixed seed), refitted each time; percentile 95 % intervals, which respect the bounds.

A parameter is not identifiable when its bootstrap half-width exceeds the configured fraction of
the estimate, when the normalised information matrix has a near-null direction through it, or
(for the split) when no group with the split free has more than one disc.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
from scipy import optimize

from .. import config as cfg
from ..applications import TrainApplication, dyno_stops, train_stops
from ..defaults import DEFAULT_STEP_S
from ..execution.blas import on_one_blas_thread
from ..observables import DYNO_OBSERVABLES, TRAIN_OBSERVABLES
from ..physics import FrictionDraw
from .parameters import IdentificationConfig, load_identification_config

SIGMAS = ("sigma_mu0", "sigma_a")
SPLIT = "global_fraction"
FIELD_KEYS = ["brake_mode", "load", "pad_set", "actuation", "v0_kmh"]


@dataclass(frozen=True)
class SpreadGroup:
    """Repeated applications under one condition and the linearised sensitivities of their
    summary: G and S per scattered parameter (mu_0, a), H for the running resistance's A."""

    name: str
    values: np.ndarray
    n_discs: int
    global_fraction: float | None  # known split of this group's data, or None: fitted
    G: np.ndarray  # (2,) sum over discs of dY/d(mu_0), dY/d(a)
    S: np.ndarray  # (2,) sum over discs of their squares
    resistance_variance: float = 0.0  # (sigma_A H)^2, known

    def __post_init__(self) -> None:
        if self.values.ndim != 1 or len(self.values) < 2:
            raise ValueError(f"group {self.name}: needs at least 2 applications, has {len(self.values)}")
        if not np.all(np.isfinite(self.values)):
            raise ValueError(f"group {self.name}: non-finite observed values")

    @property
    def dof(self) -> int:
        return len(self.values) - 1

    @property
    def sample_variance(self) -> float:
        return float(np.var(self.values, ddof=1))


def predicted_variance(groups: Sequence[SpreadGroup], sigma: np.ndarray, split: float) -> np.ndarray:
    """Var Y of every group for sigmas (mu_0, a) and the fitted global fraction ``split``."""
    return _VarianceModel(groups)(sigma, split)


class _VarianceModel:
    """:func:`predicted_variance` with the groups' sensitivities stacked once (the fit and the
    bootstrap evaluate it many thousand times)."""

    def __init__(self, groups: Sequence[SpreadGroup]) -> None:
        self.G2 = np.array([g.G**2 for g in groups])  # (groups, 2)
        self.S = np.array([g.S for g in groups])
        known = np.array([np.nan if g.global_fraction is None else g.global_fraction for g in groups])
        self.free = np.isnan(known)
        self.known = np.nan_to_num(known)
        self.resistance = np.array([g.resistance_variance for g in groups])

    def __call__(self, sigma: np.ndarray, split: float) -> np.ndarray:
        f = np.where(self.free, split, self.known)[:, None]
        return (f**2 * self.G2 + (1 - f) ** 2 * self.S) @ (np.asarray(sigma) ** 2) + self.resistance


# ------------------------------------------------------------------------------------------------
# Sensitivities


def _dyno_group_sensitivity(
    rig: cfg.Dynamometer,
    material: cfg.FrictionMaterial,
    case: cfg.LoadCase,
    observable: str,
    step: float,
    step_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    h = step * np.array([material.initial_mu, material.power_coefficient_per_s])
    mu0 = material.initial_mu + np.array([0.0, h[0], 0.0])
    a = material.power_coefficient_per_s + np.array([0.0, 0.0, h[1]])
    summary = dyno_stops(rig, [case] * 3, FrictionDraw(mu0.reshape(3, 1, 1), a.reshape(3, 1, 1)), step_s)
    y = DYNO_OBSERVABLES[observable](summary)
    g = (y[1:] - y[0]) / h
    return g, g**2


def dyno_spread_groups(
    applications: pd.DataFrame,
    rig: cfg.Dynamometer,
    observable: str = "mu_s",
    global_fraction: float | None = 0.0,
    material: cfg.FrictionMaterial | None = None,
    settings: IdentificationConfig | None = None,
    step_s: float = DEFAULT_STEP_S,
) -> list[SpreadGroup]:
    """Groups per load case of a dyno campaign's application table (``brakegym mcs --campaign
    dyno --csv``: columns ``load_case`` and the observable). ``global_fraction`` is the split of
    the data's set-up (0: independent stops, MCS-100); None fits it (not identifiable here)."""
    settings = settings or load_identification_config()
    material = material or cfg.load("materials", rig.material)
    if observable not in DYNO_OBSERVABLES:
        raise ValueError(f"unknown dyno observable {observable!r}; choose from {sorted(DYNO_OBSERVABLES)}")
    _require_columns(applications, ["load_case", observable], "dyno applications")
    groups = []
    for name, frame in applications.groupby("load_case", sort=False):
        try:
            case = rig.load_case(str(name))
        except cfg.ConfigError as exc:
            raise ValueError(f"dyno applications: {exc}") from None
        G, S = _dyno_group_sensitivity(
            rig, material, case, observable, settings.stochastic.sensitivity_relative_step, step_s
        )
        groups.append(SpreadGroup(str(name), frame[observable].to_numpy(float), 1, global_fraction, G, S))
    return groups


def _train_group_sensitivity(
    vehicle: cfg.Vehicle,
    material: cfg.FrictionMaterial,
    app: TrainApplication,
    observable: str,
    step: float,
    resistance_scatter: bool,
    step_s: float,
) -> tuple[np.ndarray, np.ndarray, float]:
    """One batch: nominal, then mu_0 and a of each disc perturbed alone, then A."""
    shape = (vehicle.n_axles, vehicle.discs_per_axle)
    n_discs = vehicle.n_discs
    rows = 2 + 2 * n_discs
    h = step * np.array([material.initial_mu, material.power_coefficient_per_s])
    mu0 = np.full((rows, n_discs), material.initial_mu)
    a = np.full((rows, n_discs), material.power_coefficient_per_s)
    mu0[1 + np.arange(n_discs), np.arange(n_discs)] += h[0]
    a[1 + n_discs + np.arange(n_discs), np.arange(n_discs)] += h[1]
    h_A = step * max(abs(vehicle.running_resistance.A_N), vehicle.running_resistance.A_sigma_N, 1.0)
    resistance = np.full(rows, vehicle.running_resistance.A_N)
    resistance[-1] += h_A
    draw = FrictionDraw(mu0.reshape(rows, *shape), a.reshape(rows, *shape))
    summary = train_stops(vehicle, [app] * rows, draw, resistance, step_s)
    y = TRAIN_OBSERVABLES[observable](summary)
    per_disc = np.stack([(y[1 : 1 + n_discs] - y[0]) / h[0], (y[1 + n_discs : 1 + 2 * n_discs] - y[0]) / h[1]])
    H = (y[-1] - y[0]) / h_A
    sigma_A = vehicle.running_resistance.A_sigma_N if resistance_scatter else 0.0
    return per_disc.sum(axis=1), (per_disc**2).sum(axis=1), float((sigma_A * H) ** 2)


def field_spread_groups(
    applications: pd.DataFrame,
    vehicle: cfg.Vehicle,
    observable: str = "mu_s_eff",
    global_fraction: float | None = None,
    resistance_scatter: bool = True,
    command_time_s: float = 1.0,
    material: cfg.FrictionMaterial | None = None,
    settings: IdentificationConfig | None = None,
    step_s: float = DEFAULT_STEP_S,
) -> list[SpreadGroup]:
    """Groups per field application of a train campaign's table (``brakegym mcs --campaign field
    --csv``: columns brake_mode, load, pad_set, actuation, v0_kmh and the observable).
    ``resistance_scatter``: whether the running resistance's A scattered (spec Section 5), a
    known variance term with the vehicle's sigma."""
    settings = settings or load_identification_config()
    material = material or cfg.load("materials", vehicle.material)
    if observable not in TRAIN_OBSERVABLES:
        raise ValueError(f"unknown train observable {observable!r}; choose from {sorted(TRAIN_OBSERVABLES)}")
    _require_columns(applications, [*FIELD_KEYS, observable], "field applications")
    groups = []
    for key, frame in applications.groupby(FIELD_KEYS, sort=False):
        mode, load, pad_set, actuation, v0 = key
        app = TrainApplication(
            load=str(load),
            brake_mode=str(mode),
            actuation=str(actuation),
            initial_speed_kmh=float(v0),
            command_time_s=command_time_s,
            pad_set=str(pad_set),
        )
        G, S, resistance = _train_group_sensitivity(
            vehicle,
            material,
            app,
            observable,
            settings.stochastic.sensitivity_relative_step,
            resistance_scatter,
            step_s,
        )
        name = f"{mode}/{load}/{pad_set}/{actuation}/{float(v0):.0f}"
        groups.append(
            SpreadGroup(name, frame[observable].to_numpy(float), vehicle.n_discs, global_fraction, G, S, resistance)
        )
    return groups


def _require_columns(frame: pd.DataFrame, columns: Sequence[str], what: str) -> None:
    missing = [c for c in columns if c not in frame.columns]
    if missing:
        raise ValueError(f"{what}: missing column(s) {missing}; has {list(frame.columns)}")


# ------------------------------------------------------------------------------------------------
# Fit


@dataclass(frozen=True)
class ScatterEstimate:
    name: str
    estimate: float
    ci95: tuple[float, float]
    identifiable: bool
    reasons: tuple[str, ...] = ()


@dataclass
class ScatterResult:
    parameters: list[ScatterEstimate]
    groups: int
    applications: int
    method: str
    bootstrap_resamples: int
    bootstrap_seed: int
    weak_combinations: list[str] = field(default_factory=list)

    @property
    def estimates(self) -> dict[str, float]:
        return {p.name: p.estimate for p in self.parameters}

    @property
    def not_identifiable(self) -> list[str]:
        return [p.name for p in self.parameters if not p.identifiable]

    def as_dict(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "groups": self.groups,
            "applications": self.applications,
            "bootstrap_resamples": self.bootstrap_resamples,
            "bootstrap_seed": self.bootstrap_seed,
            "parameters": [
                {
                    "name": p.name,
                    "estimate": p.estimate,
                    "ci95": list(p.ci95),
                    "identifiable": p.identifiable,
                    "reasons": list(p.reasons),
                }
                for p in self.parameters
            ],
            "weak_combinations": self.weak_combinations,
            "not_identifiable": self.not_identifiable,
        }

    def table(self) -> str:
        lines = [
            f"stochastic identification: {self.groups} groups, {self.applications} applications; {self.method}",
            f"95 % intervals: parametric bootstrap, {self.bootstrap_resamples} resamples, seed {self.bootstrap_seed}",
            "",
            f"{'parameter':<16} {'estimate':>11} {'95 % interval':>25}  identifiable",
        ]
        for p in self.parameters:
            verdict = "yes" if p.identifiable else "NO: " + "; ".join(p.reasons)
            lines.append(f"{p.name:<16} {p.estimate:11.5g} {p.ci95[0]:12.5g} {p.ci95[1]:12.5g}  {verdict}")
        return "\n".join(lines)


def _deviance_residuals(variance: np.ndarray, observed: np.ndarray, dof: np.ndarray) -> np.ndarray:
    """Signed square roots of the chi-square (gamma) deviance of each group's sample variance."""
    q = observed / np.maximum(variance, 1e-300)
    return np.sign(q - 1) * np.sqrt(np.maximum(dof * (q - 1 - np.log(q)), 0.0))


def _fit(
    groups: Sequence[SpreadGroup],
    observed: np.ndarray,
    start: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    scale: np.ndarray,
    fit_split: bool,
    fixed_split: float,
) -> np.ndarray:
    dof = np.array([g.dof for g in groups], dtype=float)
    model = _VarianceModel(groups)

    def residuals(u: np.ndarray) -> np.ndarray:
        theta = u * scale
        split = theta[2] if fit_split else fixed_split
        return _deviance_residuals(model(theta[:2], split), observed, dof)

    solution = optimize.least_squares(
        residuals, start / scale, bounds=(lower / scale, upper / scale), method="trf", x_scale=1.0
    )
    return solution.x * scale


@on_one_blas_thread
def identify_scatter(
    groups: Sequence[SpreadGroup],
    settings: IdentificationConfig | None = None,
    fixed_global_fraction: float = 0.0,
    start: dict[str, float] | None = None,
) -> ScatterResult:
    """Fit sigma of mu_0 and of a, and the global fraction of the split for the groups whose
    split is not given. Without such groups the split is not fitted (``fixed_global_fraction``
    only fills the model; it does not enter)."""
    if not groups:
        raise ValueError("no groups of applications to identify the scatter from")
    settings = settings or load_identification_config()
    stochastic = settings.stochastic
    free_split = [g for g in groups if g.global_fraction is None]
    fit_split = bool(free_split)
    names = [*SIGMAS, SPLIT] if fit_split else list(SIGMAS)
    intervals = [stochastic.initial_mu_sigma, stochastic.power_coefficient_sigma_per_s, stochastic.global_fraction][
        : len(names)
    ]
    lower = np.array([i.lower for i in intervals])
    upper = np.array([i.upper for i in intervals])
    theta0 = 0.5 * (lower + upper) if start is None else np.array([start[n] for n in names], dtype=float)
    if np.any(theta0 <= lower) or np.any(theta0 >= upper):
        raise ValueError(
            f"start {dict(zip(names, theta0))} must lie strictly inside the bounds "
            f"{dict(zip(names, zip(lower, upper)))}"
        )
    scale = np.where(theta0 != 0, np.abs(theta0), 1.0)
    observed = np.array([g.sample_variance for g in groups])
    theta = _fit(groups, observed, theta0, lower, upper, scale, fit_split, fixed_global_fraction)

    # Parametric bootstrap of the chi-square law of each group's sample variance.
    rng = np.random.default_rng(stochastic.bootstrap_seed)
    fitted_split = theta[2] if fit_split else fixed_global_fraction
    variance = predicted_variance(groups, theta[:2], fitted_split)
    dof = np.array([g.dof for g in groups], dtype=float)
    samples = np.empty((stochastic.bootstrap_resamples, len(theta)))
    for b in range(stochastic.bootstrap_resamples):
        resampled = variance * rng.chisquare(dof) / dof
        samples[b] = _fit(groups, resampled, theta, lower, upper, scale, fit_split, fixed_global_fraction)
    low, high = np.percentile(samples, [2.5, 97.5], axis=0)

    reasons: list[list[str]] = [[] for _ in names]
    weak = _weak_directions(groups, theta, fit_split, fixed_global_fraction, names, settings, reasons)
    if fit_split:
        if not any(g.n_discs > 1 for g in free_split):
            reasons[2].append("no multi-disc group with the split free: one disc sees only sigma^2 (f^2 + (1 - f)^2)")
        elif all(g.n_discs > 1 for g in groups):
            reasons[2].append(
                "only multi-disc groups: they fix sigma^2 (f^2 G^2 + (1 - f)^2 S), not sigma and f apart; "
                "add single-disc data"
            )
    rule = settings.identifiability.max_relative_ci_half_width
    estimates = []
    for j, name in enumerate(names):
        half = 0.5 * (high[j] - low[j])
        relative = half / abs(theta[j]) if theta[j] != 0 else np.inf
        if relative > rule:
            reasons[j].append(f"95 % half-width {100 * relative:.0f} % of the estimate")
        estimates.append(
            ScatterEstimate(
                name, float(theta[j]), (float(low[j]), float(high[j])), not reasons[j], tuple(dict.fromkeys(reasons[j]))
            )
        )
    return ScatterResult(
        parameters=estimates,
        groups=len(groups),
        applications=int(sum(len(g.values) for g in groups)),
        method="method of moments, linearised sensitivities, chi-square likelihood of the group variances",
        bootstrap_resamples=stochastic.bootstrap_resamples,
        bootstrap_seed=stochastic.bootstrap_seed,
        weak_combinations=weak,
    )


def _weak_directions(
    groups: Sequence[SpreadGroup],
    theta: np.ndarray,
    fit_split: bool,
    fixed_split: float,
    names: Sequence[str],
    settings: IdentificationConfig,
    reasons: list[list[str]],
) -> list[str]:
    """Near-null directions of the information of the log-variances, columns normalised."""
    dof = np.array([g.dof for g in groups], dtype=float)

    def log_variance(t: np.ndarray) -> np.ndarray:
        split = t[2] if fit_split else fixed_split
        return np.log(np.maximum(predicted_variance(groups, t[:2], split), 1e-300))

    steps = 1e-6 * np.maximum(np.abs(theta), 1e-3)
    base = log_variance(theta)
    jacobian = np.stack(
        [(log_variance(theta + np.eye(len(theta))[j] * steps[j]) - base) / steps[j] for j in range(len(theta))], axis=1
    )
    weighted = jacobian * np.sqrt(dof / 2)[:, None]
    norms = np.linalg.norm(weighted, axis=0)
    normalised = weighted / np.where(norms > 0, norms, 1.0)
    _, singular, vt = np.linalg.svd(normalised, full_matrices=False)
    weak = []
    for value, vector in zip(singular, vt):
        if value < settings.identifiability.min_normalised_singular_value:
            terms = " ".join(
                f"{vector[i]:+.2f}*{names[i]}" for i in np.argsort(-np.abs(vector)) if abs(vector[i]) >= 0.1
            )
            weak.append(f"{terms} (normalised singular value {value:.2g})")
            for j in np.flatnonzero(np.abs(vector) >= 0.1):
                reasons[j].append(f"near-collinear: {terms}")
    for j, norm in enumerate(norms):
        if norm == 0:
            reasons[j].append("the data do not depend on it")
    return weak
