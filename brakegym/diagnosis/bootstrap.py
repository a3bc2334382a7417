"""A parametric bootstrap of the selected model's parameters: re-simulate the recordings from the
fit with fresh friction scatter and fresh noise, refit, and read the 95 % interval off the spread
of the refitted values.

Each replicate

- simulates every recording from the fitted model: the fitted effect parameters (a fitted friction
  level as every recording's friction factor), each recording's fitted initial speed and initial
  disc temperature, and a fresh draw of the scatter between applications as a campaign draws it
  (:func:`brakegym.plants.train_scatter` in the scatter set-up ``scatter_setup``: every disc's
  mu_0 and power coefficient a, and the running resistance A, in place of the fitted friction
  factors and resistance deviations). The fit's friction-factor prior is a scalar summary of
  that scatter; a scalar draw leaves out what the fit cannot absorb (a scatter of a changes the
  friction's course over a stop, which a thermal fade reads), which is what moves the estimates;
- adds fresh noise to each channel on the recording's own samples (the rows the fit uses, in time
  order), drawn from the channel's estimated AR(1) noise model (:mod:`.noise`: level sigma,
  lag-1 autocorrelation rho per sample of the channel's own sampling), and to each accelerometer
  a fresh bias, one constant per recording, from the scatter of the biases between recordings
  that the standstill readings show (:func:`.inputs.accelerometer_bias_sigma`; none where they
  show none). The biases come from a stream of their own, so a set without bias draws the same
  noise as before;
- refits the selected model only (not the whole selection: the cost stays bounded) with
  :meth:`.fitting.FitProblem.fit`, from the fitted values, with the set's inputs (pressures) and
  noise levels as they are. Integer parameters stay at their selected value.

The interval is the hull of two normal intervals of half-width Student's t (0.975, B - 1) times the
replicates' standard deviation: one centred on the bias-corrected estimate theta - (mean of the
replicates - theta), one on theta. The basic (pivotal) bootstrap's bias correction is kept (an
estimator that the fit biases one way is moved back the other way, where a percentile interval
would move it further: a thermal fade's onset and loss need it), but not alone: a dozen
replicates read the bias of a weakly identified parameter (a rotating mass, which the friction
factors' prior all but decides) as far off as the estimate itself is, and the corrected interval
alone then misses a truth that the one on theta holds. The bootstrap's quantiles are not used:
with a few tens of replicates the 2.5 % and 97.5 % percentiles are the one or two most extreme
replicates, while the standard deviation uses all of them.

The replicates are drawn around the estimate, and the interval then assumes that the estimator
scatters and is biased at the truth as it is at the estimate. A thermal fade's is not: a fade
fitted short of its truth (a late onset, a small loss) is one whose stops reach less of it, and
its replicates scatter less than a set at the truth would. So the interval's ends are tested
(``end_replicates``, the rule ``bootstrap_end_replicates``): at each end of each parameter's
interval, with the other parameters along the replicates' regression on it, a second set of
replicates is drawn, and the end moves out to the truth at which the fitted value would be the
2.5 % (97.5 %) point of the replicates there, their bias and spread read at that end (one step
of a test inversion). An end only moves outwards: the interval is the hull of both.

The random stream is seeded from the bytes of the recordings' samples and the selected effects,
so the same data give the same intervals bit for bit.
"""

from __future__ import annotations

import copy
import hashlib
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from .. import config as cfg
from ..effects import FrictionLevel
from ..plants import train_scatter
from ..recordings.columns import DECEL
from ..recordings.logger import ar1_noise
from .fitting import FRICTION_FACTOR, RESISTANCE_DEVIATION, FitProblem, FitResult, FreeParameter, Samples
from .judging import Candidate, not_bounded_by_data
from .noise import ChannelNoise
from .rules import DiagnosisRules

__all__ = ["BootstrapResult", "EndDraw", "add_bootstrap_intervals", "bootstrap", "bootstrap_seed", "merged_intervals"]


@dataclass
class BootstrapResult:
    """The refitted effect parameters of every replicate and the interval they give.

    ``estimates``: (replicates, free parameters), in the order of the fit's free parameters;
    ``ci95``: per free parameter, the hull of the bias-corrected normal interval and the one on
    the estimate, inside the bounds;
    ``seed``: the seed of the random stream;
    ``ends``: the replicates drawn at the interval's ends, in the order they were drawn;
    ``ci95_at_fit``: the interval from the replicates at the fit alone (``ci95`` where no end
    was drawn)."""

    names: list[str]
    estimates: np.ndarray
    ci95: dict[str, list[float]]
    seed: int
    ends: list[EndDraw] = field(default_factory=list)
    ci95_at_fit: dict[str, list[float]] = field(default_factory=dict)


@dataclass
class EndDraw:
    """Replicates drawn at one end of one parameter's interval: ``parameter`` (its name),
    ``point`` (the effect parameters they were simulated with, in the fit's order) and
    ``estimates`` (end replicates, free parameters)."""

    parameter: str
    point: np.ndarray
    estimates: np.ndarray


def bootstrap_seed(recordings: Sequence, effect_ids: Sequence[str]) -> int:
    """A seed from the bytes of the recordings' samples (every column, in file order) and the
    effect ids: the same data and selection give the same stream."""
    digest = hashlib.sha256()
    for recording in recordings:
        for column in recording.data.columns:
            values = recording.data[column].to_numpy()
            digest.update(str(column).encode())
            digest.update(values.tobytes() if values.dtype.kind == "f" else str(values.tolist()).encode())
    digest.update(",".join(effect_ids).encode())
    return int.from_bytes(digest.digest()[:8], "little")


def _replica_noise(
    problem: FitProblem,
    noise_models: Mapping[str, ChannelNoise],
    rng: np.random.Generator,
    replicates: int,
    decel_bias_sigma: float,
    bias_rng: np.random.Generator,
) -> np.ndarray:
    """(replicates, data rows): AR(1) noise, normalised by each channel's noise level, on every
    recording's fit rows in the problem's row order. The noise runs along each channel's own
    samples (its non-blank cells), then is taken at the rows the fit uses. An accelerometer's
    rows get one bias per recording and replicate, N(0, ``decel_bias_sigma``) from ``bias_rng``."""
    parts = []
    for recording, samples in zip(problem.recordings, problem.samples):
        for channel, rows in samples.rows.items():
            model = noise_models.get(channel)
            rho = model.rho if model is not None and np.isfinite(model.rho) else 0.0
            sigma = model.sigma if model is not None and np.isfinite(model.sigma) else problem.noise[channel]
            present = np.flatnonzero(~np.isnan(recording.channel(channel)))
            noise = ar1_noise(rng, (len(present), replicates), sigma, float(np.clip(rho, -0.99, 0.99)))
            noise = noise[np.searchsorted(present, rows)]
            accelerometer = channel == DECEL and recording.metadata.decel_source == "accelerometer"
            if accelerometer and decel_bias_sigma > 0.0:
                noise = noise + bias_rng.normal(0.0, decel_bias_sigma, replicates)[None, :]
            parts.append(noise.T / problem.noise[channel])
    return np.concatenate(parts, axis=1)


def _replica(problem: FitProblem, normalised_measured: np.ndarray) -> FitProblem:
    """A copy of ``problem`` whose measured values are ``normalised_measured`` (data rows, in
    noise units) times each channel's noise level; recordings, inputs and noise levels shared."""
    replica = copy.copy(problem)
    replica.simulations = 0
    samples, start = [], 0
    for original in problem.samples:
        measured = {}
        for channel, rows in original.rows.items():
            measured[channel] = normalised_measured[start : start + len(rows)] * problem.noise[channel]
            start += len(rows)
        samples.append(Samples(original.rows, measured))
    replica.samples = samples
    return replica


def _replicate_estimates(
    problem: FitProblem,
    fit: FitResult,
    centre: np.ndarray,
    noise_models: Mapping[str, ChannelNoise],
    replicates: int,
    fit_iterations: int,
    rng: np.random.Generator,
    bias_rng: np.random.Generator,
    scatter_setup: str,
    decel_bias_sigma: float,
) -> np.ndarray:
    """(replicates, free parameters): the refitted effect parameters of ``replicates`` sets
    simulated with the effect parameters ``centre`` and the fit's nuisance (its initial speeds
    and disc temperatures; the friction and running resistance drawn), each refitted from its
    own truth."""
    p, n = len(fit.free), problem.n
    start = fit.x.copy()
    start[:p] = centre
    level = 1.0
    for j, parameter in enumerate(fit.free):
        if parameter.effect_id == FrictionLevel.id:
            level = float(centre[j])
    truths = np.tile(start, (replicates, 1))
    truths[:, problem.nuisance_block(FRICTION_FACTOR, p)] = level
    truths[:, problem.nuisance_block(RESISTANCE_DEVIATION, p)] = 0.0
    vehicle = problem.recordings[0].vehicle
    friction, resistance_A_N = train_scatter(vehicle, cfg.load("setups", scatter_setup)).draw(rng, replicates * n)
    drawn_deviation_N = resistance_A_N - vehicle.running_resistance.A_N
    residuals, _ = problem.simulate(fit.effect_ids, fit.fixed, fit.free, truths, scatter=(friction, drawn_deviation_N))
    data_rows = problem.channel_of >= 0
    measured = np.concatenate(
        [s.measured[c] / problem.noise[c] for s in problem.samples for c in s.rows]
    )  # the rows' order of FitProblem._residual
    simulated = measured[None, :] - residuals[:, data_rows]
    noisy = simulated + _replica_noise(problem, noise_models, rng, replicates, decel_bias_sigma, bias_rng)
    estimates = np.empty((replicates, p))
    for b in range(replicates):
        replica = _replica(problem, noisy[b])
        refit = replica.fit(list(fit.effect_ids), start, fixed=fit.fixed, max_iterations=fit_iterations)
        estimates[b] = refit.x[:p]
        problem.simulations += replica.simulations
    problem.simulations += replicates * n
    return estimates


def _interval_ends(
    fit: FitResult, estimates: np.ndarray, ci95: Mapping[str, Sequence[float]]
) -> list[tuple[int, np.ndarray]]:
    """Where to draw the replicates that test the interval's ends: per free parameter j and
    side, the point whose j-th value is that end of ``ci95`` and whose other values follow the
    replicates' regression on parameter j (the normal approximation's profile), inside the
    bounds. A parameter the replicates do not move, or an end on a bound, has no point."""
    p = len(fit.free)
    theta = fit.x[:p]
    lower = np.array([f.spec.lower for f in fit.free])
    upper = np.array([f.spec.upper for f in fit.free])
    covariance = np.atleast_2d(np.cov(estimates, rowvar=False))
    points = []
    for j, parameter in enumerate(fit.free):
        if not covariance[j, j] > 0.0:
            continue
        for end in ci95[parameter.name]:
            if end in (parameter.spec.lower, parameter.spec.upper):
                continue
            point = theta + covariance[:, j] / covariance[j, j] * (end - theta[j])
            point[j] = end
            points.append((j, np.clip(point, lower, upper)))
    return points


def _inside_bounds(low: float, high: float, parameter: FreeParameter) -> list[float]:
    """``low``..``high`` cut to the parameter's bounds."""
    return [float(max(low, parameter.spec.lower)), float(min(high, parameter.spec.upper))]


def bootstrap(
    problem: FitProblem,
    fit: FitResult,
    noise_models: Mapping[str, ChannelNoise],
    replicates: int,
    fit_iterations: int,
    seed: int,
    scatter_setup: str = "mcs-75-25",
    decel_bias_sigma: float = 0.0,
    end_replicates: int = 0,
) -> BootstrapResult | None:
    """The parametric bootstrap of ``fit`` (see the module documentation); None when the fit has
    no continuous parameter or fewer than 3 replicates are asked for. ``decel_bias_sigma``: the
    scatter of the accelerometer bias between recordings, m/s^2. ``end_replicates`` (3 or more):
    replicates drawn at each end of each parameter's interval, which widen it where the
    estimate scatters more or is biased more there than at the fit."""
    p = len(fit.free)
    if p == 0 or replicates < 3:
        return None
    rng = np.random.default_rng(seed)
    bias_rng = np.random.default_rng([seed, 1])
    theta = fit.x[:p]
    estimates = _replicate_estimates(
        problem, fit, theta, noise_models, replicates, fit_iterations, rng, bias_rng, scatter_setup, decel_bias_sigma
    )
    bias = estimates.mean(axis=0) - theta
    spread = estimates.std(axis=0, ddof=1)
    quantile = float(stats.t.ppf(0.975, replicates - 1))
    ci95 = {}
    for j, parameter in enumerate(fit.free):
        corrected = theta[j] - bias[j]
        half = quantile * spread[j]
        ci95[parameter.name] = _inside_bounds(
            min(corrected, theta[j]) - half, max(corrected, theta[j]) + half, parameter
        )
    at_fit = _rounded(ci95)
    ends = []
    if end_replicates >= 3:
        for k, (j, point) in enumerate(_interval_ends(fit, estimates, ci95)):
            drawn = _replicate_estimates(
                problem,
                fit,
                point,
                noise_models,
                end_replicates,
                fit_iterations,
                np.random.default_rng([seed, 2 + k]),
                np.random.default_rng([seed, 2 + k, 1]),
                scatter_setup,
                decel_bias_sigma,
            )
            ends.append(EndDraw(fit.free[j].name, point, drawn))
            limit = _inverted_end(float(theta[j]), float(point[j]), drawn[:, j])
            low, high = ci95[fit.free[j].name]
            ci95[fit.free[j].name] = _inside_bounds(min(low, limit), max(high, limit), fit.free[j])
    return BootstrapResult([f.name for f in fit.free], estimates, _rounded(ci95), seed, ends, at_fit)


def _rounded(intervals: Mapping[str, Sequence[float]]) -> dict[str, list[float]]:
    """Intervals as reported: each end to 5 decimals."""
    return {name: [round(low, 5), round(high, 5)] for name, (low, high) in intervals.items()}


def _inverted_end(fitted: float, end: float, drawn: np.ndarray) -> float:
    """The truth at which ``fitted`` is the 2.5 % point (an upper ``end``) or the 97.5 % point (a
    lower one) of replicates drawn at ``end``: their bias and spread read there, not at the fit."""
    side = 1.0 if end > fitted else -1.0
    quantile = float(stats.t.ppf(0.975, len(drawn) - 1))
    return fitted - (drawn.mean() - end) + side * quantile * drawn.std(ddof=1)


def merged_intervals(
    gauss_newton_jackknife: Mapping[str, Sequence[float]],
    bootstrapped: Mapping[str, Sequence[float]],
    resting_on_one_recording: Collection[str] = (),
) -> dict[str, list[float]]:
    """Per parameter, the hull of the Gauss-Newton/jackknife interval and the bootstrap's; a
    parameter that rests on one recording (``resting_on_one_recording``) takes the bootstrap's
    alone, and one the bootstrap does not cover keeps its interval.

    The jackknife of a parameter one recording holds alone is no spread between recordings: with
    that recording left out the others hold nothing of the parameter, and the refit steps to
    wherever its bounds let it, so the interval is anywhere from the estimate's own point to the
    whole search range. The bootstrap re-draws that recording's friction scatter and noise,
    which is what moves such an estimate."""
    out = {}
    for name, (low, high) in gauss_newton_jackknife.items():
        if name in bootstrapped:
            b_low, b_high = bootstrapped[name]
            if name in resting_on_one_recording:
                low, high = b_low, b_high
            else:
                low, high = min(low, b_low), max(high, b_high)
        out[name] = [low, high]
    return out


def add_bootstrap_intervals(
    problem: FitProblem,
    selected: Candidate,
    noise_models: Mapping[str, ChannelNoise],
    rules: DiagnosisRules,
    decel_bias_sigma: float = 0.0,
) -> BootstrapResult | None:
    """Bootstrap the selected candidate's fit and write its intervals into its report entry:
    ``ci95`` becomes the hull of the Gauss-Newton/jackknife interval (kept as
    ``ci95_gauss_newton_jackknife``) and the bootstrap's (``ci95_bootstrap``, from
    ``bootstrap_replicates`` replicates at the fit, its ends tested by ``bootstrap_end_replicates``
    at each, ``ci95_bootstrap_at_fit`` without them; ``decel_bias_sigma`` as for :func:`bootstrap`), the
    bootstrap's alone for a parameter the entry's ``resting_on_one_recording`` names (see
    :func:`merged_intervals`)."""
    fit = selected.fit
    seed = bootstrap_seed(problem.recordings, selected.effect_ids)
    result = bootstrap(
        problem,
        fit,
        noise_models,
        rules.bootstrap_replicates,
        rules.fit_iterations,
        seed,
        rules.bootstrap_scatter_setup,
        decel_bias_sigma,
        rules.bootstrap_end_replicates,
    )
    if result is None:
        return None
    report = selected.report
    report["ci95_gauss_newton_jackknife"] = report["ci95"]
    report["ci95_bootstrap"] = result.ci95
    report["ci95_bootstrap_at_fit"] = result.ci95_at_fit
    report["bootstrap_replicates"] = int(len(result.estimates))
    report["bootstrap_end_replicates"] = int(len(result.ends[0].estimates)) if result.ends else 0
    # The replicates' mean and spread, from which any other bootstrap interval can be read.
    report["bootstrap_mean"] = {n: round(float(v), 6) for n, v in zip(result.names, result.estimates.mean(axis=0))}
    report["bootstrap_std"] = {
        n: round(float(v), 6) for n, v in zip(result.names, result.estimates.std(axis=0, ddof=1))
    }
    report["ci95"] = merged_intervals(
        report["ci95_gauss_newton_jackknife"], result.ci95, report.get("resting_on_one_recording") or {}
    )
    report["not_bounded_by_data"] = not_bounded_by_data(selected.effect_ids, report["ci95"], rules.range_end_share)
    return result
