"""Figures and the Markdown report of ``brakegym diagnose --report DIR``."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from ..recordings.columns import DECEL, DISC_TEMPERATURE, SPEED  # noqa: E402

SHOWN_RECORDINGS = 3
UNITS = {SPEED: "m/s", DECEL: "m/s^2", DISC_TEMPERATURE: "K"}


def _residuals_figure(diagnosis, path: Path) -> Path:
    """Residuals of every recording over time and over speed, before (unmodified) and after."""
    fits = [("unmodified model", diagnosis.baseline)]
    if diagnosis.selected is not None:
        fits.append((" + ".join(diagnosis.selected.effect_ids), diagnosis.selected.fit))
    channels = [c for c in (SPEED, DECEL, DISC_TEMPERATURE) if c in diagnosis.problem.noise]
    fig, axes = plt.subplots(len(channels), 2, figsize=(11, 2.6 * len(channels)), squeeze=False)
    for _, fit in fits:
        for replayed in fit.replays:
            measured = replayed.recording
            for row, channel in enumerate(channels):
                values = measured.channel(channel)
                if values is None:
                    continue
                residual = values - replayed.simulated[channel].to_numpy()
                style = dict(lw=0.6, alpha=0.7, color="C3" if fit is diagnosis.baseline else "C0")
                axes[row, 0].plot(measured.time_s, residual, **style)
                axes[row, 1].plot(replayed.states["true_speed_mps"], residual, **style)
    for row, channel in enumerate(channels):
        axes[row, 0].set_ylabel(f"{channel} residual [{UNITS[channel]}]")
        axes[row, 0].set_xlabel("time [s]")
        axes[row, 1].set_xlabel("speed [m/s]")
    handles = [plt.Line2D([], [], color="C3", label=fits[0][0])]
    if len(fits) > 1:
        handles.append(plt.Line2D([], [], color="C0", label=f"with {fits[1][0]}"))
    axes[0, 0].legend(handles=handles, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _traces_figure(diagnosis, path: Path) -> Path:
    """Measured against simulated speed, deceleration and temperature of a few recordings."""
    shown = diagnosis.baseline.replays[:SHOWN_RECORDINGS]
    after = diagnosis.selected.fit.replays[:SHOWN_RECORDINGS] if diagnosis.selected is not None else None
    channels = [c for c in (SPEED, DECEL, DISC_TEMPERATURE) if c in diagnosis.problem.noise]
    fig, axes = plt.subplots(len(channels), len(shown), figsize=(4 * len(shown), 2.6 * len(channels)), squeeze=False)
    for column, replayed in enumerate(shown):
        recording = replayed.recording
        for row, channel in enumerate(channels):
            ax = axes[row, column]
            values = recording.channel(channel)
            if values is None:
                continue
            ax.plot(recording.time_s, values, color="0.6", lw=0.8, label="measured")
            ax.plot(recording.time_s, replayed.simulated[channel], color="C3", lw=1.0, label="unmodified")
            if after is not None:
                ax.plot(
                    recording.time_s, after[column].simulated[channel], color="C0", lw=1.0, ls="--", label="with effect"
                )
            ax.set_ylabel(f"{channel} [{UNITS[channel]}]")
            if row == 0:
                ax.set_title(recording.stem)
            if row == len(channels) - 1:
                ax.set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _table(rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(lines)


def found_lines(report: dict) -> list[str]:
    """What the data pointed the search at, as Markdown bullets: the step of the residual along
    position (and the second, found in what the first leaves), each friction level's shared
    shift, the fallback's signatures."""
    lines = []
    origin = report.get("line_origin_m")
    if origin is not None:
        lines.append(
            f"- Positions along the line (the step below, the start of a section or stretch) count from "
            f"{origin:g} m, the lowest line position the recordings reach."
        )
    counted = "from the recordings' first samples" if origin is None else "along the line"
    for key, what in (("position_step", "Step"), ("second_position_step", "Second step")):
        step = report.get(key)
        if step is not None:
            lines.append(
                f"- {what} of the residual deceleration along position (while braking): {step['start_m']:g} to "
                f"{step['end_m']:g} m {counted}, {step['decel_step_mps2']:g} m/s^2 "
                f"(a gradient of {step['gradient_permil']:g} permil), {step['explained_share']:.1%} of the "
                f"residual's variance, {step['recordings']} recordings on it."
            )
    for candidate in report["candidates"]:
        shift = candidate.get("friction_level_shift")
        if shift is not None:
            lines.append(
                f"- Friction level in {' + '.join(candidate['effects'])}: a shared shift of the recordings' "
                f"friction factors to {shift['level']:g} (their scatter {shift['scatter']:g}, standard "
                f"error {shift['standard_error']:g}, z = {shift['z']:g})."
            )
    fallback = report.get("fallback_screening")
    if fallback is not None:
        description = fallback["description"]
        lines.append(
            f'- Before the verdict "unexplained", the residual along {description["axis"]} '
            f"({description['form']}) was matched against the library's signatures:"
        )
        for signature in fallback["signatures"] or [{"signature": "none matched", "effect": "-", "verdict": "-"}]:
            lines.append(f"  - {signature['signature']} -> {signature['effect']}: {signature['verdict']}")
    return lines


def _candidate_rows(report: dict) -> list[list[str]]:
    """Every fitted candidate: its effects, parameters with their 95 % intervals and judgement."""
    rows = [
        ["effects", "parameters (95 %)", "delta BIC", "held-out gain", "relevant size", "at its search range's end"]
    ]
    for c in report["candidates"]:
        parameters = ", ".join(
            f"{k} = {v:g} [{c['ci95'][k][0]:g}, {c['ci95'][k][1]:g}]" for k, v in c["parameters"].items()
        )
        rows.append(
            [
                " + ".join(c["effects"]),
                parameters,
                f"{c['delta_bic']:g}",
                f"{c.get('heldout_gain', float('nan')):.3f}",
                str(c["relevant_size"]),
                ", ".join(c.get("at_search_range_end") or []),
            ]
        )
    return rows


def _rms_rows(report: dict, chosen: dict) -> list[list[str]]:
    """Each channel's residual RMS, fitted and held out, of the unmodified model and of ``chosen``."""
    rows = [
        ["channel", "noise", "unmodified (fitted)", "unmodified (held out)", "selected (fitted)", "selected (held out)"]
    ]
    for channel, noise in report["noise"].items():
        if channel not in chosen["rms_before"]:
            continue
        rows.append(
            [
                channel,
                f"{noise:g}",
                f"{chosen['rms_before'][channel]:g}",
                f"{chosen['heldout_rms_before'][channel]:g}",
                f"{chosen['rms_after'][channel]:g}",
                f"{chosen['heldout_rms_after'][channel]:g}",
            ]
        )
    return rows


def _attribution_rows(report: dict) -> list[list[str]]:
    """The residual's variance share along each axis (eta^2), per residual; empty without one."""
    attribution = report["mismatch"]["attribution_eta2"]
    if not attribution:
        return []
    rows = [["residual", *next(iter(attribution.values())).keys()]]
    for name, shares in attribution.items():
        rows.append([name, *(f"{v:.3f}" for v in shares.values())])
    return rows


def _indistinguishable_text(report: dict) -> str:
    """The pairs of singles named indistinguishable (with their correlation) and each single named
    indistinguishable from a pair; empty where there are none."""
    singles = [
        f"{name} (corrections correlate {report['signature_correlations'][name]:.2f})"
        for name in (" / ".join(pair) for pair in report["indistinguishable"])
    ]
    single_or_pair = [
        f"{' + '.join(entry['single'])} / {' + '.join(entry['pair'])}"
        for entry in report.get("indistinguishable_single_or_pair", [])
    ]
    return "; ".join([*singles, *single_or_pair])


def write_report(diagnosis, out_dir: str | Path, dataset_name: str) -> Path:
    """Write ``report.md``, ``diagnosis.json`` and the two figures of ``diagnosis`` into
    ``out_dir``; returns the path of ``report.md``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    report = diagnosis.report
    residuals = _residuals_figure(diagnosis, out_dir / "residuals.png")
    traces = _traces_figure(diagnosis, out_dir / "measured_vs_simulated.png")
    (out_dir / "diagnosis.json").write_text(json.dumps(report, indent=2) + "\n")
    attribution_rows = _attribution_rows(report)
    parts = [
        f"# Diagnosis of `{dataset_name}`",
        "",
        report["summary"],
        "",
        f"**Selected:** {', '.join(report['selected']) or 'nothing'}. **Indistinguishable:** "
        f"{_indistinguishable_text(report) or 'none'}. **Unconfirmed** (fits the "
        f"few recordings it acts on, too few to confirm held out): "
        f"{'; '.join(' + '.join(u['effects']) for u in report['unconfirmed']) or 'none'}.",
        "",
        "## Where the unmodified model misses (variance share of the residual along each axis, eta^2)",
        "",
        _table(attribution_rows) if attribution_rows else "(no residual channels)",
        "",
        f"Segments above {3:g} x noise: {len(report['mismatch']['segments'])} (see `diagnosis.json`).",
        "",
        "## Candidates",
        "",
        _table(_candidate_rows(report)),
        "",
    ]
    found = found_lines(report)
    if found:
        parts += ["## What the data pointed the search at", "", *found, ""]
    chosen = next((c for c in report["candidates"] if c["effects"] == report["selected"]), None)
    if chosen is not None:
        parts += [
            "## Residual RMS before and after",
            "",
            _table(_rms_rows(report, chosen)),
            "",
            f"Stop-distance error (simulated minus measured): before {chosen['stop_distance_error_before']}, "
            f"after {chosen['stop_distance_error_after']}.",
            "",
        ]
    if report["unexplained"]:
        parts += ["## Not explained by the library", "", report["unexplained"], ""]
    parts += [
        "## Figures",
        "",
        f"![residuals over time and speed]({residuals.name})",
        "",
        f"![measured and simulated]({traces.name})",
        "",
    ]
    path = out_dir / "report.md"
    path.write_text("\n".join(parts))
    return path
