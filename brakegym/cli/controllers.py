"""``brakegym train | evaluate | stress``: the controller commands of the command line.

    brakegym train     train a stable-baselines3 agent (PPO, SAC) on a brakegym environment
    brakegym evaluate  success rate and task metric of a controller over scattered episodes
    brakegym stress    the stress-test table per speed band, worst episodes, figure, JSON

Agents are named ``pid`` (:mod:`brakegym.agents.pid` with ``configs/agents/pid.yaml``), ``none`` /
``wsp`` / ``wsp-true-speed`` (no WSP and the reference WSP, :mod:`brakegym.agents.wsp_policy`, on
the environments with WSP valves), ``ppo`` /
``sac`` / ``ppo-residual`` (the policy shipped in ``brakegym.agents``' ``policies/`` for the
environment; ``ppo-residual`` is a PPO policy that corrects the PID's command) or the path of an
agent folder written by ``brakegym train``. ``train`` and the learned agents need the ``rl`` extra.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .common import (
    UsageError,
    finite_positive,
    non_negative_int,
    positive_int,
    progress,
    write_json,
)


def _env_id(text: str) -> str:
    from ..envs.registry import full_env_id

    try:
        return full_env_id(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _bands(text: str) -> list[float]:
    try:
        edges = [float(part) for part in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--bands must be comma-separated speeds in km/h, got {text!r}") from None
    if len(edges) < 2 or any(b <= a for a, b in zip(edges, edges[1:])):
        raise argparse.ArgumentTypeError(f"--bands needs at least two increasing speeds, got {text!r}")
    return edges


# Agent ids of the policies shipped in agents/policies/<task>_<id with _ for ->.
SHIPPED_AGENTS = ("ppo", "sac", "ppo-residual")


def controller_factory(agent: str, env_id: str) -> tuple[str, Callable[[Any], Any]]:
    """(display name, factory env -> controller) for an agent argument."""
    from ..agents.wsp_policy import WSP_AGENTS, wsp_env_controller_factory

    if agent in WSP_AGENTS:
        try:
            return agent, wsp_env_controller_factory(agent, env_id)
        except ValueError as error:
            raise UsageError(f"--agent {error}") from None
    if agent == "pid":
        from ..agents.pid import PIDController, load_pid_config

        gains = load_pid_config()
        return "pid", lambda env: PIDController(env.config, env.observation_names, gains)
    from ..agents.rl import PolicyController, shipped_policies
    from ..envs.registry import task_class

    if agent in SHIPPED_AGENTS:
        stem = task_class(env_id).name
        folder = shipped_policies().joinpath(f"{stem}_{agent.replace('-', '_')}")
        if not (folder / "training.json").is_file():
            raise UsageError(
                f"--agent {agent}: no shipped {agent} policy for {env_id} (looked for {folder}); "
                f"train one with `brakegym train --algo {agent} --env {env_id.split('/')[1]}` and pass its folder"
            )
    else:
        folder = Path(agent)
        if not (folder / "training.json").is_file():
            raise UsageError(
                f"--agent {agent}: not pid, ppo, sac, ppo-residual or an agent folder with training.json "
                "(nor none, wsp, wsp-true-speed, the agents of an environment with WSP valves)"
            )
    controller = PolicyController(folder)
    trained_on = "brakegym/" + controller.meta["env"]
    if trained_on != env_id:
        raise UsageError(f"--agent {agent}: trained on {trained_on}, not {env_id}")
    return agent if agent in SHIPPED_AGENTS else controller.name, controller.for_env


def _default_bands(env_id: str) -> list[float]:
    from ..envs.registry import environment_config

    speeds = environment_config(env_id).initial_speed_kmh
    return [round(speeds.low + k * (speeds.high - speeds.low) / 3, 1) for k in range(4)]


def _run(args: argparse.Namespace, agent: str):
    from ..stress import run_stress

    name, factory = controller_factory(agent, args.env)
    bar = progress(args.episodes, f"{name} on {args.env.split('/')[1]}")
    try:
        result = run_stress(
            args.env,
            factory,
            name,
            setup=args.setup,
            episodes=args.episodes,
            seed=args.seed,
            batch_size=args.batch,
            keep_worst=getattr(args, "worst", 5),
            progress=bar.update,
        )
    finally:
        bar.close()
    return result


def cmd_train(args: argparse.Namespace) -> int:
    from ..agents.rl import train

    out = args.out or f"out/agents/{args.env.split('/')[1]}_{args.algo}_seed{args.seed}"
    folder = train(
        args.algo,
        args.env,
        out,
        seed=args.seed,
        total_timesteps=args.timesteps,
        time_budget_s=None if args.time_budget_min is None else 60.0 * args.time_budget_min,
        setup=args.setup,
    )
    meta = json.loads((folder / "training.json").read_text())
    print(f"trained {args.algo} on {args.env}: {meta['timesteps']} steps in {meta['wall_time_s']} s -> {folder}")
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from ..stress import report

    result = _run(args, args.agent)
    rep = report(result, _default_bands(args.env))
    overall = rep["overall"]
    metric = result.metric_name
    print(
        f"{result.agent} on {args.env} ({args.setup}, {overall['episodes']} episodes, seed {args.seed}): "
        f"success {100 * overall['success_rate']:.1f} %, {metric} mean {overall[metric + '_mean']:.3f}, "
        f"p99 |.| {overall[metric + '_abs_p99']:.3f}, peak jerk p95 {overall['peak_jerk_mps3_p95']:.2f} m/s3"
    )
    write_json(args.json, rep)
    return 0


def cmd_stress(args: argparse.Namespace) -> int:
    from ..stress import comparison_figure, report, table

    edges = args.bands or _default_bands(args.env)
    results = [_run(args, agent) for agent in args.agent]
    reports = [report(result, edges) for result in results]
    print(f"{args.env}, set-up {args.setup}, {args.episodes} episodes per agent, seed {args.seed}\n")
    print(table(reports))
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        figure = comparison_figure(results, edges, out / "stress_comparison.png")
        for result in results:
            safe = result.agent.replace("/", "_").replace(":", "_")
            (out / f"worst_{safe}.json").write_text(json.dumps(result.worst, indent=1))
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot write ({exc.strerror})") from exc
    print(f"\nfigure: {figure}; worst episodes: {out}/worst_*.json")
    write_json(
        args.json,
        {"env": args.env, "setup": args.setup, "episodes": args.episodes, "seed": args.seed, "agents": reports},
    )
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``train``, ``evaluate`` and ``stress``."""

    def common(p: argparse.ArgumentParser, default_episodes: int) -> None:
        p.add_argument(
            "--env", type=_env_id, default="brakegym/StationStop-v0", help="environment (default StationStop-v0)"
        )
        p.add_argument("--setup", default="mcs-75-25", help="friction scatter set-up (default mcs-75-25)")
        p.add_argument("--episodes", type=positive_int("--episodes"), default=default_episodes)
        p.add_argument("--seed", type=non_negative_int("--seed"), default=0)
        p.add_argument("--batch", type=positive_int("--batch"), default=500, help="trains per batch (default 500)")
        p.add_argument("--json", help="write the results as JSON")

    p = sub.add_parser("train", help="train a stable-baselines3 agent (ppo, sac, ppo-residual) on an environment")
    p.add_argument(
        "--algo",
        choices=["ppo", "sac", "ppo-residual"],
        default="ppo",
        help="ppo-residual: PPO correcting the PID's command",
    )
    p.add_argument("--env", type=_env_id, default="brakegym/StationStop-v0")
    p.add_argument("--setup", default="mcs-75-25")
    p.add_argument("--seed", type=non_negative_int("--seed"), default=0)
    p.add_argument("--timesteps", type=positive_int("--timesteps"), help="default: the hyperparameter file's")
    p.add_argument("--time-budget-min", type=finite_positive("--time-budget-min"), help="stop after this many minutes")
    p.add_argument("--out", help="agent folder (default out/agents/<env>_<algo>_seed<seed>)")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("evaluate", help="success rate and task metric of a controller")
    p.add_argument("--agent", default="pid", help="pid, ppo, sac, ppo-residual or an agent folder (default pid)")
    common(p, 500)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("stress", help="stress-test controllers under friction scatter: table, worst episodes, figure")
    p.add_argument(
        "--agent",
        action="append",
        required=True,
        help="pid, ppo, sac, ppo-residual, none, wsp, wsp-true-speed or an agent folder; repeat to compare",
    )
    p.add_argument(
        "--bands", type=_bands, help="speed band edges in km/h, e.g. 40,60,80,100 (default: thirds of the range)"
    )
    p.add_argument("--worst", type=non_negative_int("--worst"), default=5, help="worst episodes to save (default 5)")
    p.add_argument("--out", default="out/stress", help="folder for the figure and worst episodes (default out/stress)")
    common(p, 1000)
    p.set_defaults(func=cmd_stress)
