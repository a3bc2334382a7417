"""Stress-test a brake controller under friction scatter: many scattered trains, batched.

Runs a controller on N episodes of an environment at once (a :class:`BrakeVectorEnv` without
autoreset: each train drives one episode), collects per-episode outcomes, tabulates them per
initial-speed band, keeps the worst episodes' traces and draws a comparison figure.

A controller is anything with ``reset(info)`` (the batched info of the reset, whose ``mass_kg`` is
the load-weighing signal) and ``act(observations) -> actions`` over the batch.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from .envs import BrakeVectorEnv, task_class
from .units import mps_to_kmh

TRACE_CHANNELS = ("time_s", "speed_mps", "position_m", "deceleration_mps2", "mean_command_bar", "hottest_disc_C")


class BatchController(Protocol):
    def reset(self, info: dict[str, Any]) -> None: ...

    def act(self, observation: np.ndarray) -> np.ndarray: ...


@dataclass
class StressResult:
    """Per-episode outcomes (arrays of length episodes) and the worst episodes' traces."""

    env_id: str
    setup: str
    agent: str
    initial_speed_kmh: np.ndarray
    load: np.ndarray  # load names
    success: np.ndarray
    metric: np.ndarray  # the task's metric (signed stop error for StationStop)
    metric_name: str
    peak_jerk_mps3: np.ndarray
    peak_disc_temperature_C: np.ndarray
    ended_by_time_limit: np.ndarray
    worst: list[dict[str, Any]]  # the worst episodes: conditions and traces
    # The task's further per-episode quantities (its stress_quantities), by info key.
    quantities: dict[str, np.ndarray] = field(default_factory=dict)


def make_vector_env(
    env_id: str, n_trains: int, setup: str, config: dict[str, Any] | None = None, autoreset: bool = False
) -> BrakeVectorEnv:
    """The batched environment ``env_id`` with ``setup`` as its friction scatter."""
    return BrakeVectorEnv(env_id, num_envs=n_trains, config={**(config or {}), "setup": setup}, autoreset=autoreset)


def run_stress(
    env_id: str,
    make_controller: Callable[[BrakeVectorEnv], BatchController],
    agent_name: str,
    setup: str = "mcs-75-25",
    episodes: int = 1000,
    seed: int = 0,
    batch_size: int = 500,
    keep_worst: int = 5,
    config: dict[str, Any] | None = None,
    progress: Callable[[int], None] | None = None,
) -> StressResult:
    """Run ``episodes`` episodes in batches of ``batch_size`` trains; batch ``k`` is seeded with
    ``seed + k``, so results do not depend on anything but the seed and the batch size."""
    if episodes < 1:
        raise ValueError(f"episodes = {episodes}: need at least one")
    columns: dict[str, list[np.ndarray]] = {
        name: [] for name in ("speed", "load", "success", "metric", "jerk", "temperature", "time_limit")
    }
    worst: list[dict[str, Any]] = []
    metric_name = None
    quantity_names = task_class(env_id).stress_quantities
    quantities: dict[str, list[np.ndarray]] = {name: [] for name in quantity_names}
    for batch, start in enumerate(range(0, episodes, batch_size)):
        n = min(batch_size, episodes - start)
        env = make_vector_env(env_id, n, setup, config)
        metric_name = task_class(env.config.name).metric[0]
        controller = make_controller(env)
        observation, info = env.reset(seed=seed + batch)
        controller.reset(info)
        vehicle_loads = env.core.fleet.vehicle_loads
        loads = np.array([vehicle_loads[i] for i in env.core.fleet.episodes.load_index])
        initial_speed = mps_to_kmh(info["initial_speed_mps"])
        # What each train's episode ended with, kept from the step it ended.
        ended_with = (metric_name, "peak_jerk_mps3", "peak_friction_temperature_C", *quantity_names)
        final = {key: np.zeros_like(info[key]) for key in ended_with}
        final["is_success"] = np.zeros(n, dtype=bool)
        final["time_limit"] = np.zeros(n, dtype=bool)
        ended = np.zeros(n, dtype=bool)
        traces: list[np.ndarray] = []
        trace_end = np.zeros(n, dtype=np.int64)
        while not ended.all():
            observation, _, terminated, truncated, info = env.step(controller.act(observation))
            newly = (terminated | truncated) & ~ended
            for key in (*ended_with, "is_success"):
                final[key][newly] = info[key][newly]
            final["time_limit"][newly] = truncated[newly] & ~terminated[newly]
            traces.append(
                np.stack(
                    [
                        info["time_s"],
                        info["speed_mps"],
                        info["position_m"],
                        info["deceleration_mps2"],
                        info["command_bar"].mean(axis=1),
                        info["friction_temperature_C"].max(axis=1),
                    ]
                ).astype(np.float32)
            )
            trace_end[newly] = len(traces)
            ended |= newly
        trace_array = np.stack(traces)  # (steps, channels, n)
        order = np.lexsort((-np.abs(final[metric_name]), final["is_success"]))  # failures first, then the largest error
        for i in order[:keep_worst]:
            worst.append(
                {
                    "batch_seed": seed + batch,
                    "train": int(i),
                    "initial_speed_kmh": float(initial_speed[i]),
                    "load": str(loads[i]),
                    "success": bool(final["is_success"][i]),
                    metric_name: float(final[metric_name][i]),
                    "trace": {
                        name: trace_array[: trace_end[i], k, i].tolist() for k, name in enumerate(TRACE_CHANNELS)
                    },
                }
            )
        columns["speed"].append(initial_speed)
        columns["load"].append(loads)
        columns["success"].append(final["is_success"])
        columns["metric"].append(final[metric_name])
        columns["jerk"].append(final["peak_jerk_mps3"])
        columns["temperature"].append(final["peak_friction_temperature_C"])
        columns["time_limit"].append(final["time_limit"])
        for name in quantity_names:
            quantities[name].append(final[name])
        if progress is not None:
            progress(n)
    assert metric_name is not None
    result = StressResult(
        env_id=env_id,
        setup=setup,
        agent=agent_name,
        initial_speed_kmh=np.concatenate(columns["speed"]),
        load=np.concatenate(columns["load"]),
        success=np.concatenate(columns["success"]),
        metric=np.concatenate(columns["metric"]),
        metric_name=metric_name,
        peak_jerk_mps3=np.concatenate(columns["jerk"]),
        peak_disc_temperature_C=np.concatenate(columns["temperature"]),
        ended_by_time_limit=np.concatenate(columns["time_limit"]),
        worst=[],
        quantities={name: np.concatenate(values) for name, values in quantities.items()},
    )
    result.worst = sorted(worst, key=lambda w: (w["success"], -abs(w[metric_name])))[:keep_worst]
    return result


def speed_bands(result: StressResult, edges_kmh: Sequence[float]) -> list[tuple[float, float, np.ndarray]]:
    """(low, high, mask) per band; the last band includes its upper edge."""
    bands = []
    for k, (low, high) in enumerate(zip(edges_kmh[:-1], edges_kmh[1:])):
        upper = result.initial_speed_kmh <= high if k == len(edges_kmh) - 2 else result.initial_speed_kmh < high
        bands.append((low, high, (result.initial_speed_kmh >= low) & upper))
    return bands


def summarise(result: StressResult, mask: np.ndarray | None = None) -> dict[str, Any]:
    """The table row of a set of episodes: metric statistics, success rate, jerk, temperature."""
    mask = np.ones(len(result.success), dtype=bool) if mask is None else mask
    count = int(mask.sum())
    if count == 0:
        return {"episodes": 0}
    metric = result.metric[mask]
    judged = np.abs(metric)
    return {
        "episodes": count,
        "success_rate": float(result.success[mask].mean()),
        f"{result.metric_name}_mean": float(metric.mean()),
        f"{result.metric_name}_std": float(metric.std(ddof=1)) if count > 1 else 0.0,
        f"{result.metric_name}_abs_p95": float(np.percentile(judged, 95)),
        f"{result.metric_name}_abs_p99": float(np.percentile(judged, 99)),
        f"{result.metric_name}_abs_worst": float(judged.max()),
        "peak_jerk_mps3_p95": float(np.percentile(result.peak_jerk_mps3[mask], 95)),
        "peak_jerk_mps3_max": float(result.peak_jerk_mps3[mask].max()),
        "peak_disc_temperature_C_max": float(result.peak_disc_temperature_C[mask].max()),
        "ended_by_time_limit": int(result.ended_by_time_limit[mask].sum()),
        **{
            f"{name}_{statistic}": float(function(values[mask]))
            for name, values in result.quantities.items()
            for statistic, function in (
                ("mean", np.mean),
                ("p95", lambda v: np.percentile(v, 95)),
                ("max", np.max),
            )
        },
    }


def report(result: StressResult, edges_kmh: Sequence[float]) -> dict[str, Any]:
    return {
        "env": result.env_id,
        "setup": result.setup,
        "agent": result.agent,
        "metric": result.metric_name,
        "overall": summarise(result),
        "bands": [
            {"initial_speed_kmh": [low, high], **summarise(result, mask)}
            for low, high, mask in speed_bands(result, edges_kmh)
        ],
    }


def table(reports: Sequence[dict[str, Any]]) -> str:
    """A Markdown table: one row per agent and speed band (and overall)."""
    metric = reports[0]["metric"]
    unit = task_class(reports[0]["env"]).metric[1]
    quantity_names = task_class(reports[0]["env"]).stress_quantities
    header = (
        f"| agent | speed band (km/h) | episodes | success | {metric} mean | std | p95 abs | p99 abs | worst abs "
        f"| peak jerk p95 / max (m/s3) | peak disc T max (C) |"
    )
    header += "".join(f" {name} mean / p95 / max |" for name in quantity_names)
    lines = [f"({metric} in {unit})", "", header, "|" + "---|" * (11 + len(quantity_names))]
    for rep in reports:
        for label, row in [
            (f"{b['initial_speed_kmh'][0]:.0f}-{b['initial_speed_kmh'][1]:.0f}", b) for b in rep["bands"]
        ] + [("all", rep["overall"])]:
            if row["episodes"] == 0:
                continue
            lines.append(
                f"| {rep['agent']} | {label} | {row['episodes']} | {100 * row['success_rate']:.1f} % "
                f"| {row[metric + '_mean']:.3f} | {row[metric + '_std']:.3f} | {row[metric + '_abs_p95']:.3f} "
                f"| {row[metric + '_abs_p99']:.3f} | {row[metric + '_abs_worst']:.3f} "
                f"| {row['peak_jerk_mps3_p95']:.2f} / {row['peak_jerk_mps3_max']:.2f} "
                f"| {row['peak_disc_temperature_C_max']:.0f} |"
                + "".join(
                    f" {row[name + '_mean']:.2f} / {row[name + '_p95']:.2f} / {row[name + '_max']:.2f} |"
                    for name in quantity_names
                )
            )
    return "\n".join(lines)


def comparison_figure(results: Sequence[StressResult], edges_kmh: Sequence[float], path: Path) -> Path:
    """Box plots of the judged metric per speed band for each agent, and their peak jerk."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (metric_axis, jerk_axis) = plt.subplots(1, 2, figsize=(11, 4.2))
    width = 0.8 / len(results)
    for k, result in enumerate(results):
        bands = speed_bands(result, edges_kmh)
        positions = np.arange(len(bands)) + (k - (len(results) - 1) / 2) * width
        metric_axis.boxplot(
            [result.metric[mask] for _, _, mask in bands],
            positions=positions,
            widths=width * 0.9,
            patch_artist=True,
            boxprops={"facecolor": f"C{k}", "alpha": 0.6},
            flierprops={"markersize": 2},
        )
        jerk_axis.boxplot(
            [result.peak_jerk_mps3[mask] for _, _, mask in bands],
            positions=positions,
            widths=width * 0.9,
            patch_artist=True,
            boxprops={"facecolor": f"C{k}", "alpha": 0.6},
            flierprops={"markersize": 2},
        )
        metric_axis.plot([], [], color=f"C{k}", linewidth=6, alpha=0.6, label=result.agent)
    labels = [f"{low:.0f}-{high:.0f}" for low, high, _ in speed_bands(results[0], edges_kmh)]
    for axis in (metric_axis, jerk_axis):
        axis.set_xticks(np.arange(len(labels)), labels)
        axis.set_xlabel("initial speed (km/h)")
    metric_axis.set_ylabel(results[0].metric_name)
    if results[0].metric_name == "stop_error_m":
        metric_axis.axhspan(-0.5, 0.5, color="0.9", zorder=0, label="success band")
    metric_axis.legend()
    jerk_axis.set_ylabel("peak jerk (m/s$^3$)")
    figure.suptitle(f"{results[0].env_id}, {results[0].setup}: {len(results[0].success)} episodes per agent")
    figure.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
