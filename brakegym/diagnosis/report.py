"""The diagnosis report: the JSON document ``brakegym diagnose --json`` writes (its keys are a
public interface), its one-paragraph summary, and the effect set of the selected effects.

Parameters come with 95 % intervals, the wider of the Gauss-Newton interval (effective samples)
and the jackknife over recordings with Student's t: the Gauss-Newton covariance sees only the
noise of the samples, not what varies between recordings and no nuisance absorbs (each
application's running-resistance draw shifts a fitted gradient); the spread of the
leave-one-recording-out estimates does. The selected candidate's intervals are then widened to
take in a parametric bootstrap's (:mod:`.bootstrap`).

Where one recording holds a parameter alone (with it left out, the others hold less than
``one_recording_share`` of the parameter's information: a thermal fade that one stop reaches),
the report names that recording (``resting_on_one_recording``). Its jackknife then steps towards
the parameter's bounds and says where they are, not how the estimate scatters; the selected
candidate's interval of such a parameter is the bootstrap's alone, which re-draws that
recording's friction scatter and noise (``docs/diagnosis.md``, interval coverage).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy import stats

from .. import config as cfg
from ..effects import EFFECTS, effects_from_config, separating_measurement
from ..recordings.columns import DECEL, DISC_TEMPERATURE, SPEED
from ..recordings.replay import compare
from ..statistics import gauss_newton_covariance
from .fitting import FitProblem, FitResult
from .heldout import HeldOut
from .judging import Candidate, Verdict, mismatch_explained_share, not_bounded_by_data
from .rules import DiagnosisRules
from .screening import ScreenedPoint
from .weighting import CHANNEL_NAMES, Weighting


def ci95(problem: FitProblem, weighting: Weighting, fit: FitResult, heldout: HeldOut) -> dict[str, list[float]]:
    """95 % intervals of a fit's parameters (see the module documentation), inside the bounds;
    integer parameters held fixed have their value as both ends."""
    p = len(fit.free)
    out: dict[str, list[float]] = {}
    if p:
        jac = fit.jacobian
        dof = max(weighting.n_eff_total - jac.shape[1], 1.0)
        variance = weighting.chi2(fit.residual) / dof
        try:
            covariance = gauss_newton_covariance(jac * np.sqrt(weighting.weights)[:, None])[:p, :p] * variance
        except np.linalg.LinAlgError:
            covariance = np.full((p, p), np.nan)
        steps = heldout.steps
        n = problem.n
        jackknife = (n - 1) / n * np.sum((steps - steps.mean(axis=0)) ** 2, axis=0) if n > 2 else np.zeros(p)
        quantile = float(stats.t.ppf(0.975, n - 1)) if n > 2 else 1.96
        for j, parameter in enumerate(fit.free):
            half = max(1.96 * math.sqrt(max(covariance[j, j], 0.0)), quantile * math.sqrt(jackknife[j]))
            value = fit.x[j]
            out[parameter.name] = [
                round(float(max(value - half, parameter.spec.lower)), 5),
                round(float(min(value + half, parameter.spec.upper)), 5),
            ]
    for name, value in fit.fixed.items():
        out[name] = [value, value]
    return out


def resting_on_one_recording(
    problem: FitProblem, fit: FitResult, heldout: HeldOut, min_others_share: float
) -> dict[str, str]:
    """Each effect parameter that one recording holds alone (the others hold less than
    ``min_others_share`` of its information), with that recording's name."""
    out = {}
    for j, parameter in enumerate(fit.free):
        i = int(np.argmin(heldout.others_share[:, j]))
        if heldout.others_share[i, j] < min_others_share:
            out[parameter.name] = problem.recordings[i].name
    return out


def heldout_at_no_effect(problem: FitProblem, fit: FitResult, heldout: HeldOut) -> dict[str, list[str]]:
    """Each size held at its no-effect value in some recording's held-out prediction (it rests on
    that recording and the others do not see it), with those recordings' names."""
    return {
        parameter.name: [problem.recordings[i].name for i in np.flatnonzero(heldout.held_at_no_effect[:, j])]
        for j, parameter in enumerate(fit.free)
        if heldout.held_at_no_effect[:, j].any()
    }


def stop_errors(fit: FitResult) -> dict[str, float]:
    """RMS and largest stop-distance error of a fit's replays, m."""
    errors = [compare(r).stop_distance_error_m for r in fit.replays]
    errors = np.array([e for e in errors if np.isfinite(e)])
    if not errors.size:
        return {"rms_m": float("nan"), "max_abs_m": float("nan")}
    return {"rms_m": round(float(np.sqrt(np.mean(errors**2))), 2), "max_abs_m": round(float(np.max(np.abs(errors))), 2)}


def candidate_entries(
    problem: FitProblem,
    weighting: Weighting,
    baseline: FitResult,
    candidates: Sequence[Candidate],
    rules: DiagnosisRules,
) -> list[dict[str, Any]]:
    """Every candidate's report entry, best BIC first."""
    base_rms = weighting.rms(baseline.residual)
    base_stop = stop_errors(baseline)
    entries = []
    for candidate in sorted(candidates, key=lambda c: c.delta_bic):
        fit = candidate.fit
        share = mismatch_explained_share(weighting, baseline.residual, candidate.chi2_eff)
        intervals = ci95(problem, weighting, fit, candidate.heldout)
        candidate.report.update(
            {
                "effects": list(candidate.effect_ids),
                "parameters": {k: round(v, 5) for k, v in fit.parameters.items()},
                "ci95": intervals,
                "not_bounded_by_data": not_bounded_by_data(candidate.effect_ids, intervals, rules.range_end_share),
                "resting_on_one_recording": resting_on_one_recording(
                    problem, fit, candidate.heldout, rules.one_recording_share
                ),
                "heldout_at_no_effect": heldout_at_no_effect(problem, fit, candidate.heldout),
                "heldout_refitted": [problem.recordings[i].name for i in np.flatnonzero(candidate.heldout.refitted)],
                "rms_before": base_rms,
                "rms_after": weighting.rms(fit.residual),
                "heldout_rms_before": base_rms,
                "heldout_rms_after": weighting.rms(candidate.heldout.residual),
                "delta_bic": round(candidate.delta_bic, 1),
                "mismatch_explained_share": None if share is None else round(share, 3),
                "relevant_size": candidate.relevant,
                "at_search_range_end": list(candidate.at_range_end),
                "stop_distance_error_before": base_stop,
                "stop_distance_error_after": stop_errors(fit),
            }
        )
        entries.append(candidate.report)
    return entries


def build_report(
    problem: FitProblem,
    weighting: Weighting,
    noise: dict[str, float],
    mismatch: dict[str, Any],
    unexplained: dict[str, Any] | None,
    candidates: list[dict[str, Any]],
    verdict: Verdict,
    screened: dict[str, ScreenedPoint],
    fitted: set[str],
    chi2_unmodified: float,
) -> dict[str, Any]:
    """The report of a diagnosis (``brakegym diagnose --json``)."""
    selected = verdict.selected
    report = {
        "recordings": problem.n,
        "noise": {k: round(v, 5) for k, v in noise.items()},
        "mismatch": mismatch,
        "candidates": candidates,
        "selected": list(selected.effect_ids) if selected else [],
        "parameters": dict(selected.report["parameters"]) if selected else {},
        "indistinguishable": verdict.indistinguishable,
        "separating_measurements": {
            " / ".join(pair): separating_measurement(*pair) for pair in verdict.indistinguishable
        },
        "signature_correlations": verdict.signature_correlations,
        "indistinguishable_single_or_pair": [_single_or_pair_entry(a, b) for a, b in verdict.single_or_pair],
        "unconfirmed": [_unconfirmed_entry(c) for c in verdict.unconfirmed],
        "unexplained": unexplained["text"] if unexplained else None,
        "unexplained_fit": unexplained,
        "screening": {
            effect_id: {"chi2_eff_profiled": round(float(screened[effect_id].chi2), 1), "fitted": effect_id in fitted}
            for effect_id in sorted(screened, key=lambda e: screened[e].chi2)
        },
        "chi2_eff_unmodified": round(float(chi2_unmodified), 1),
        "effective_sample_share": {CHANNEL_NAMES[c]: round(v, 4) for c, v in weighting.channel_shares.items()},
        "trains_simulated": problem.simulations,
    }
    report["summary"] = _summary(report, selected)
    return report


def _single_or_pair_entry(single: Candidate, pair: Candidate) -> dict[str, Any]:
    """A pair with the selected single that the data cannot tell from the single alone, and what
    would: the measurement that separates the single's effect from the pair's second one."""
    (first,) = single.effect_ids
    (second,) = [e for e in pair.effect_ids if e != first]
    return {
        "single": list(single.effect_ids),
        "pair": list(pair.effect_ids),
        "pair_parameters": {k: round(v, 5) for k, v in pair.fit.parameters.items()},
        "delta_bic_over_single": round(pair.delta_bic - single.delta_bic, 1),
        "heldout_gain_over_single": pair.report.get("heldout_gain"),
        "heldout_t_over_single": pair.report.get("heldout_t"),
        "heldout_p_over_single": pair.report.get("heldout_p"),
        "heldout_acts_on_over_single": pair.report.get("heldout_acts_on"),
        "separating_measurement": separating_measurement(first, second),
    }


def _unconfirmed_entry(candidate: Candidate) -> dict[str, Any]:
    effect_id = candidate.effect_ids[0]
    acts_on = candidate.report["heldout_acts_on"]
    parameters = candidate.report["parameters"]
    template = EFFECTS[effect_id].confirming_measurement
    where = ", ".join(Path(name).name for name in acts_on)
    return {
        "effects": list(candidate.effect_ids),
        "parameters": parameters,
        "acts_on": acts_on,
        "heldout_gain_acting": round(candidate.acting_gain, 4),
        "delta_bic": round(candidate.delta_bic, 1),
        "to_confirm": template.format(where=where, **parameters),
    }


def _unconfirmed_text(report: dict[str, Any]) -> str:
    sentences = []
    for entry in report["unconfirmed"]:
        parameters = ", ".join(f"{name} = {value:g}" for name, value in entry["parameters"].items())
        k = len(entry["acts_on"])
        sentences.append(
            f"{' + '.join(entry['effects'])} ({parameters}) fits the {k} recording{'s' if k > 1 else ''} it acts on "
            f"({', '.join(Path(name).name for name in entry['acts_on'])}) much better "
            f"(BIC lower by {-entry['delta_bic']:.0f}; "
            f"{100 * entry['heldout_gain_acting']:.0f} % of their held-out error removed), "
            f"but {k} of {report['recordings']} "
            f"recordings are too few to confirm it on recordings held out of the fit, so it is not selected; "
            f"to confirm or reject it: {entry['to_confirm']}."
        )
    return " ".join(sentences)


def _summary(report: dict[str, Any], selected: Candidate | None) -> str:
    """The report's ``summary``: the verdict, then the effects left unconfirmed."""
    text = _verdict(report, selected)
    if report["unconfirmed"]:
        text += " Unconfirmed: " + _unconfirmed_text(report)
    return text


def _caveats(report: dict[str, Any], selected: Candidate) -> str:
    """What the summary adds to a selection: parameters the data do not bound, parameters that one
    recording holds alone, and the candidates that explain the data about as well."""
    text = ""
    unbounded = selected.report.get("not_bounded_by_data") or []
    if unbounded:
        text += (
            f" The data do not bound {', '.join(unbounded)}: the 95 % interval spans the search range, "
            f"so the value is not measured."
        )
    resting = selected.report.get("resting_on_one_recording") or {}
    for recording in sorted(set(resting.values())):
        names = [name for name, where in resting.items() if where == recording]
        one = len(names) == 1
        text += (
            f" {', '.join(names)} rest{'s' if one else ''} on {Path(recording).name} alone: no other recording "
            f"confirms {'it' if one else 'them'}."
        )
    if report["indistinguishable"]:
        pairs = "; ".join(
            f"{a} and {b} (their corrections to the model correlate "
            f"{report['signature_correlations'][a + ' / ' + b]:.2f}): "
            f"{report['separating_measurements'][a + ' / ' + b]}"
            for a, b in report["indistinguishable"]
        )
        text += f" These candidates explain the data about equally well, and would be separated by: {pairs}."
    for entry in report["indistinguishable_single_or_pair"]:
        text += " " + single_or_pair_sentence(entry)
    return text


def single_or_pair_sentence(entry: dict[str, Any]) -> str:
    """The summary's sentence on an entry of ``indistinguishable_single_or_pair``. A pair whose
    second effect changes the held-out prediction of fewer recordings than the held-out rule
    counts has no held-out t against the single; the sentence says so rather than print None."""
    single, pair = " + ".join(entry["single"]), " + ".join(entry["pair"])
    second = next(e for e in entry["pair"] if e not in entry["single"])
    t = entry["heldout_t_over_single"]
    if t is not None:
        heldout = f"held-out t {t}"
    else:
        acting = len(entry.get("heldout_acts_on_over_single") or [])
        heldout = f"no held-out t: it changes the held-out prediction of {acting} recording(s) only"
    return (
        f"The pair {pair} fits about as well (BIC {entry['delta_bic_over_single']:+.0f} and {heldout}, "
        f"against {single} alone), but not by every rule: {single} alone or with {second} would be "
        f"separated by {entry['separating_measurement']}."
    )


def _verdict(report: dict[str, Any], selected: Candidate | None) -> str:
    """The verdict in words: the selected effects with their intervals and caveats, else why
    nothing is selected (unexplained, unconfirmed, or the model fits)."""
    n = report["recordings"]
    noise = report["noise"]
    noise_text = (
        f"noise {noise.get(SPEED, float('nan')):.3f} m/s in speed, "
        f"{noise.get(DECEL, float('nan')):.3f} m/s^2 in deceleration "
        f"and {noise.get(DISC_TEMPERATURE, float('nan')):.2f} K in disc temperature"
    )
    if selected is not None:
        parameters = ", ".join(
            f"{name} = {value:g} (95 % {ci[0]:g}..{ci[1]:g})"
            for name, value in selected.report["parameters"].items()
            for ci in [selected.report["ci95"][name]]
        )
        before, after = selected.report["heldout_rms_before"], selected.report["heldout_rms_after"]
        change = "; ".join(f"{c} {before[c]:g} -> {after[c]:g}" for c in before)
        text = (
            f"Across {n} recordings ({noise_text}) the unmodified model misses the measurements beyond noise and "
            f"friction scatter. The missing physics is {' + '.join(selected.effect_ids)} with {parameters}: "
            f"it lowers the held-out residual RMS ({change}) and the BIC by {-selected.delta_bic:.0f}."
        )
        text += _caveats(report, selected)
        return text
    if report["unexplained"]:
        verdict = "is confirmed on held-out recordings" if report["unconfirmed"] else "explains it"
        return (
            f"Across {n} recordings ({noise_text}) the model misses the data, but no effect of the library "
            f"{verdict}. {report['unexplained']}"
        )
    if report["unconfirmed"]:
        return f"Across {n} recordings ({noise_text}) no effect of the library is confirmed on held-out recordings."
    return (
        f"Across {n} recordings ({noise_text}) the unmodified model fits within noise and the scatter between "
        "applications once each recording's initial speed, initial disc temperature, friction factor and running "
        "resistance are fitted; no effect of the library improves the held-out fit enough to be selected."
    )


def write_effect_set(report: dict[str, Any], path: str | Path, dataset_name: str) -> Path:
    """Write the selected effects of a diagnosis report as an effect set (``configs/effects``
    schema, validated on the way out), so that the modified model runs in the simulator:
    ``load_effects(path)``, then ``replay_batch`` or ``apply_effects``. The 95 % intervals go
    along as a comment. With nothing selected the set is empty: the nominal model."""
    path = Path(path)
    parameters = report["parameters"]
    effects = []
    for effect_id in report["selected"]:
        names = [spec.name for spec in EFFECTS[effect_id].parameters]
        effects.append({"id": effect_id, "parameters": {name: float(parameters[name]) for name in names}})
    document = {
        "name": path.stem,  # a config's name is its file's stem
        "description": f"effects selected by brakegym diagnose on {dataset_name}",
        "effects": effects,
    }
    effects_from_config(cfg.EffectSet.model_validate(document), str(path))  # what is written loads
    chosen = next((c for c in report["candidates"] if c["effects"] == report["selected"]), None)
    header = [f"# Written by brakegym diagnose from {dataset_name}: {len(report['selected'])} effect(s) selected."]
    if chosen is not None:
        header += [f"# {name}: 95 % interval {low:g} .. {high:g}" for name, (low, high) in chosen["ci95"].items()]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(header) + "\n" + yaml.safe_dump(document, sort_keys=False))
    return path
