"""Deterministic multi-case identification: fit friction (paper Eq. 4) and thermal (Eqs. 5-10)
parameters to several load cases at once, with bounds, and say how well the data fix them.

Method
------
Weighted nonlinear least squares (``scipy.optimize.least_squares``, trust-region reflective,
bounds from ``configs/identification/``) over every sample of every series of a case set; each
residual is (model - observed) / the channel's scale (the measurement noise the config expects),
so mu and temperatures weigh alike. The parameters are fitted in units of their start values.
Every residual evaluation simulates all cases in one batch, and the forward-difference Jacobian
puts one copy of the case set per perturbed parameter into the same call (``cases.plant_groups``:
copies that differ only in mu_0 or a share a batch; the simulator holds the other constants per
batch, so those copies run in batches of their own).

Uncertainty
-----------
After the fit, each channel's residual standard deviation ``s_c`` is estimated from the residuals
themselves (not from the config's scale), and their lag-1 autocorrelation ``rho_c`` within each
series: model error and noise that is not white make neighbouring residuals alike, and treating
them as independent would make the intervals far too narrow. For an AR(1) residual the variance of
an estimate grows by ``(1 + rho) / (1 - rho)``, i.e. the effective sample size is
``n (1 - rho) / (1 + rho)``. The covariance is the Gauss-Newton one,
``C = (sum_c J_c' J_c / (s_c^2 k_c))^-1`` with that inflation ``k_c`` per channel, and the 95 %
intervals use Student's t with the effective degrees of freedom. This is a linearisation: for
parameters with wide intervals the true confidence region is not an ellipse.

Identifiability
---------------
A parameter is reported **not identifiable** when (i) its 95 % half-width exceeds the configured
fraction of its estimate, or (ii) it takes part in a near-null direction of the Jacobian: the
Jacobian is weighted as above and its columns normalised to unit length (so only collinearity
counts, not units), and a singular value below the configured threshold names the combination
of parameters (its right singular vector) that the data leave free. A column of zeros (the data
do not depend on a parameter at all) is both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, stats

from .. import config as cfg
from ..execution.blas import on_one_blas_thread
from ..statistics import effective_sample_share, gauss_newton_covariance, lag1_autocorrelation
from .cases import CaseSet
from .parameters import IdentificationConfig, ParameterSpace, load_identification_config

CONFIDENCE = 0.95


@dataclass(frozen=True)
class ParameterEstimate:
    symbol: str
    field: str
    start: float
    estimate: float
    standard_error: float
    ci95: tuple[float, float]
    lower_bound: float
    upper_bound: float
    identifiable: bool
    reasons: tuple[str, ...] = ()

    @property
    def relative_ci_half_width(self) -> float:
        half = 0.5 * (self.ci95[1] - self.ci95[0])
        return abs(half / self.estimate) if self.estimate != 0 else float("inf")

    @property
    def at_bound(self) -> bool:
        span = self.upper_bound - self.lower_bound
        return min(self.estimate - self.lower_bound, self.upper_bound - self.estimate) < 1e-6 * span


@dataclass(frozen=True)
class ChannelFit:
    """Residual statistics of one channel at the estimate (residual = model - observed)."""

    channel: str
    samples: int
    rms: float
    lag1_autocorrelation: float
    variance_inflation: float
    effective_samples: float


@dataclass
class IdentificationResult:
    data: str
    parameters: list[ParameterEstimate]
    correlation: np.ndarray
    channels: list[ChannelFit]
    singular_values: np.ndarray  # of the weighted, column-normalised Jacobian, descending
    weak_combinations: list[str]
    cost_start: float
    cost_end: float
    evaluations: int
    simulations: int
    converged: bool
    message: str
    series_residual_rms: dict[str, float] = field(default_factory=dict)

    @property
    def estimates(self) -> dict[str, float]:
        return {p.symbol: p.estimate for p in self.parameters}

    @property
    def not_identifiable(self) -> list[str]:
        return [p.symbol for p in self.parameters if not p.identifiable]

    def as_dict(self) -> dict[str, Any]:
        return {
            "data": self.data,
            "parameters": [
                {
                    "symbol": p.symbol,
                    "field": p.field,
                    "start": p.start,
                    "estimate": p.estimate,
                    "standard_error": p.standard_error,
                    "ci95": list(p.ci95),
                    "relative_ci_half_width": p.relative_ci_half_width,
                    "bounds": [p.lower_bound, p.upper_bound],
                    "at_bound": p.at_bound,
                    "identifiable": p.identifiable,
                    "reasons": list(p.reasons),
                }
                for p in self.parameters
            ],
            "correlation": {
                "symbols": [p.symbol for p in self.parameters],
                "matrix": np.round(self.correlation, 6).tolist(),
            },
            "channels": [vars(c) for c in self.channels],
            "normalised_singular_values": self.singular_values.tolist(),
            "weak_combinations": self.weak_combinations,
            "not_identifiable": self.not_identifiable,
            "cost_start": self.cost_start,
            "cost_end": self.cost_end,
            "evaluations": self.evaluations,
            "simulations": self.simulations,
            "converged": self.converged,
            "message": self.message,
        }

    def table(self) -> str:
        lines = [
            f"deterministic identification: {self.data}",
            f"cost {self.cost_start:.4g} -> {self.cost_end:.4g} in {self.evaluations} evaluations "
            f"({self.simulations} simulated case sets); {self.message}",
            "",
            f"{'param':<7} {'start':>11} {'estimate':>11} {'95 % interval':>25} {'+-%':>7}  identifiable",
        ]
        for p in self.parameters:
            verdict = "yes" if p.identifiable else "NO: " + "; ".join(p.reasons)
            lines.append(
                f"{p.symbol:<7} {p.start:11.5g} {p.estimate:11.5g} {p.ci95[0]:12.5g} {p.ci95[1]:12.5g} "
                f"{100 * p.relative_ci_half_width:7.1f}  {verdict}"
            )
        lines += ["", f"{'channel':<11} {'samples':>7} {'rms':>10} {'lag-1 rho':>9} {'n_eff':>8}"]
        for c in self.channels:
            lines.append(
                f"{c.channel:<11} {c.samples:7d} {c.rms:10.4g} {c.lag1_autocorrelation:9.3f} {c.effective_samples:8.1f}"
            )
        symbols = [p.symbol for p in self.parameters]
        lines += ["", "correlation " + " ".join(f"{s:>6}" for s in symbols)]
        for s, row in zip(symbols, self.correlation):
            lines.append(f"{s:<11} " + " ".join(f"{v:6.2f}" for v in row))
        if self.weak_combinations:
            lines += ["", "directions the data leave (nearly) free:"] + [f"  {w}" for w in self.weak_combinations]
        return "\n".join(lines)


class _Evaluator:
    """Residuals and Jacobian in scaled parameters u = theta / scale, remembering the last
    evaluation (least_squares asks for residuals and Jacobian at the same point)."""

    def __init__(
        self,
        cases: CaseSet,
        space: ParameterSpace,
        channel_scales: dict[str, float],
        scale: np.ndarray,
        relative_step: float,
    ):
        self.cases, self.space, self.scale = cases, space, scale
        self.relative_step = relative_step
        self.observed = np.concatenate([s.values for s in cases.series])
        self.weights = np.concatenate([np.full(len(s.values), 1.0 / channel_scales[s.channel]) for s in cases.series])
        self.simulations = 0
        self._cache: dict[bytes, np.ndarray] = {}

    def _predict(self, rows: np.ndarray) -> np.ndarray:
        self.simulations += len(rows)
        return np.array([np.concatenate(per_row) for per_row in self.cases.predict(self.space, rows)])

    def raw_residuals(self, u: np.ndarray) -> np.ndarray:
        key = np.asarray(u, dtype=float).tobytes()
        if key not in self._cache:
            self._cache = {key: self._predict((u * self.scale)[None])[0] - self.observed}
        return self._cache[key]

    def residuals(self, u: np.ndarray) -> np.ndarray:
        return self.raw_residuals(u) * self.weights

    def raw_jacobian(self, u: np.ndarray) -> np.ndarray:
        """d(model)/d(theta) by forward differences, all perturbed copies in one call; a step
        that would leave the bounds is taken backwards."""
        theta = u * self.scale
        steps = self.relative_step * self.scale
        steps = np.where(theta + steps > self.space.upper, -steps, steps)
        rows = np.vstack([theta, theta + np.diag(steps)])
        predicted = self._predict(rows)
        self._cache = {np.asarray(u, dtype=float).tobytes(): predicted[0] - self.observed}
        return ((predicted[1:] - predicted[0]) / steps[:, None]).T

    def jacobian(self, u: np.ndarray) -> np.ndarray:
        return self.raw_jacobian(u) * self.scale[None, :] * self.weights[:, None]


def _channel_statistics(cases: CaseSet, raw: np.ndarray, n_parameters: int) -> tuple[list[ChannelFit], np.ndarray]:
    """Per channel: residual statistics and, per sample, the variance s_c^2 k_c to weight it by."""
    bounds = np.cumsum([0] + [len(s.values) for s in cases.series])
    pieces = [raw[bounds[i] : bounds[i + 1]] for i in range(len(cases.series))]
    channels = list(dict.fromkeys(s.channel for s in cases.series))
    total = len(raw)
    variance = np.empty(total)
    fits = []
    for channel in channels:
        index = [i for i, s in enumerate(cases.series) if s.channel == channel]
        values = np.concatenate([pieces[i] for i in index])
        n = len(values)
        # The p fitted parameters use up degrees of freedom; share them by sample count.
        dof = max(n - n_parameters * n / total, 1.0)
        s2 = float(np.dot(values, values)) / dof
        rho = lag1_autocorrelation([pieces[i] for i in index], centred=True)
        inflation = 1.0 / effective_sample_share(rho)
        for i in index:
            variance[bounds[i] : bounds[i + 1]] = s2 * inflation
        fits.append(ChannelFit(channel, n, float(np.sqrt(np.mean(values**2))), rho, inflation, n / inflation))
    return fits, variance


def _describe_direction(vector: np.ndarray, symbols: Sequence[str]) -> str:
    order = np.argsort(-np.abs(vector))
    sign = 1.0 if vector[order[0]] > 0 else -1.0
    terms = [f"{sign * vector[i]:+.2f}*{symbols[i]}" for i in order if abs(vector[i]) >= 0.1]
    return " ".join(terms)


@on_one_blas_thread
def identify(
    cases: CaseSet,
    parameters: Sequence[str],
    material: cfg.FrictionMaterial,
    disc: cfg.DiscThermal,
    settings: IdentificationConfig | None = None,
    start: dict[str, float] | None = None,
) -> IdentificationResult:
    """Fit ``parameters`` (symbols or set names of the identification config) to ``cases``.

    The fit starts from the values in ``material`` and ``disc`` (or ``start``, by symbol), which
    must lie strictly inside the bounds. Other parameters stay at their values in ``material``
    and ``disc``.
    """
    settings = settings or load_identification_config()
    space = ParameterSpace(tuple(settings.resolve(parameters)), material, disc)
    theta0 = space.base_values()
    for symbol, value in (start or {}).items():
        if symbol not in space.symbols:
            raise ValueError(f"start value for {symbol!r}, which is not fitted ({space.symbols})")
        theta0[space.symbols.index(symbol)] = float(value)
    space.check_inside(theta0, "start")
    space.configs(theta0)  # the start must be a valid config
    channel_scales = {s.channel: settings.channel_scale(s.channel) for s in cases.series}
    scale = np.where(theta0 != 0, np.abs(theta0), 0.1 * (space.upper - space.lower))
    evaluator = _Evaluator(cases, space, channel_scales, scale, settings.jacobian_relative_step)
    if len(evaluator.observed) <= len(theta0):
        raise ValueError(f"{len(evaluator.observed)} samples cannot determine {len(theta0)} parameters")

    u0 = theta0 / scale
    cost_start = 0.5 * float(np.sum(evaluator.residuals(u0) ** 2))
    solution = optimize.least_squares(
        evaluator.residuals,
        u0,
        jac=evaluator.jacobian,
        bounds=(space.lower / scale, space.upper / scale),
        method="trf",
        x_scale=1.0,
        max_nfev=settings.max_function_evaluations,
    )
    theta = solution.x * scale
    raw = evaluator.raw_residuals(solution.x)
    sensitivity = evaluator.raw_jacobian(solution.x)
    channels, variance = _channel_statistics(cases, raw, len(theta))
    result = _uncertainty(space, settings, theta0, theta, sensitivity, variance, channels)
    bounds = np.cumsum([0] + [len(s.values) for s in cases.series])
    per_series = {
        f"{s.case}/{s.channel}": float(np.sqrt(np.mean(raw[bounds[i] : bounds[i + 1]] ** 2)))
        for i, s in enumerate(cases.series)
    }
    return IdentificationResult(
        data=cases.describe(),
        cost_start=cost_start,
        cost_end=0.5 * float(np.sum((raw * evaluator.weights) ** 2)),
        evaluations=int(solution.nfev),
        simulations=evaluator.simulations,
        converged=bool(solution.status > 0),
        message=str(solution.message),
        series_residual_rms=per_series,
        **result,
    )


def _uncertainty(
    space: ParameterSpace,
    settings: IdentificationConfig,
    theta0: np.ndarray,
    theta: np.ndarray,
    sensitivity: np.ndarray,
    variance: np.ndarray,
    channels: list[ChannelFit],
) -> dict[str, Any]:
    """Covariance, intervals, correlation and identifiability verdicts at the estimate."""
    symbols = space.symbols
    rule = settings.identifiability
    weighted = sensitivity / np.sqrt(variance)[:, None]
    covariance = gauss_newton_covariance(weighted)
    standard_error = np.sqrt(np.abs(np.diag(covariance)))
    effective_dof = max(sum(c.effective_samples for c in channels) - len(theta), 1.0)
    t = stats.t.ppf(0.5 + CONFIDENCE / 2, effective_dof)
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(standard_error, standard_error)
    correlation = np.where(np.isfinite(correlation), correlation, np.nan)
    np.fill_diagonal(correlation, 1.0)

    norms = np.linalg.norm(weighted, axis=0)
    reasons: list[list[str]] = [[] for _ in theta]
    weak = []
    for j, norm in enumerate(norms):
        if norm == 0:
            reasons[j].append("the data do not depend on it")
    normalised = weighted / np.where(norms > 0, norms, 1.0)
    _, normalised_singular, normalised_vt = np.linalg.svd(normalised, full_matrices=False)
    for value, vector in zip(normalised_singular, normalised_vt):
        if value < rule.min_normalised_singular_value:
            combination = _describe_direction(vector, symbols)
            weak.append(f"{combination} (normalised singular value {value:.2g})")
            for j in np.flatnonzero(np.abs(vector) >= 0.1):
                if norms[j] > 0:
                    reasons[j].append(f"near-collinear: {combination}")
    estimates = []
    for j, symbol in enumerate(symbols):
        half = t * standard_error[j]
        relative = half / abs(theta[j]) if theta[j] != 0 else np.inf
        if relative > rule.max_relative_ci_half_width:
            reasons[j].append(f"95 % half-width {100 * relative:.0f} % of the estimate")
        span = space.upper[j] - space.lower[j]
        if min(theta[j] - space.lower[j], space.upper[j] - theta[j]) < 1e-6 * span:
            reasons[j].append("at a bound: the linearised interval does not hold there")
        estimates.append(
            ParameterEstimate(
                symbol=symbol,
                field=space.parameters[j].field,
                start=float(theta0[j]),
                estimate=float(theta[j]),
                standard_error=float(standard_error[j]),
                ci95=(float(theta[j] - half), float(theta[j] + half)),
                lower_bound=float(space.lower[j]),
                upper_bound=float(space.upper[j]),
                identifiable=not reasons[j],
                reasons=tuple(dict.fromkeys(reasons[j])),
            )
        )
    return {
        "parameters": estimates,
        "correlation": correlation,
        "channels": channels,
        "singular_values": normalised_singular,
        "weak_combinations": weak,
    }
