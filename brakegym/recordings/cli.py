"""``brakegym synth`` and ``brakegym diagnose``: the command-line side of :mod:`.synth` and
:mod:`.diagnosis` (registered by ``brakegym.cli``)."""

from __future__ import annotations

import argparse
import math


def _count(name: str, minimum: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{name} must be at least {minimum}, got {text!r}")
        return value

    return parse


def _scale(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--noise-scale must be a number, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"--noise-scale must be a non-negative finite number, got {text!r}")
    return value


def cmd_synth(args: argparse.Namespace) -> int:
    from .synth import EffectRequest, synthesize

    requests = [EffectRequest.parse(text) for text in args.effect]
    result = synthesize(
        args.out_dir,
        args.recordings,
        args.seed,
        effects=requests,
        random_effects=args.random_effects,
        base_offset=args.base_offset,
        key_path=args.key,
        noise_scale=args.noise_scale,
    )
    print(f"wrote {len(result.recordings)} recordings to {result.folder} and the answer key to {result.key_path}")
    return 0


def add_synth_command(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "synth",
        help="synthetic recordings of emu_8axle with concealed effects; the answer key is written apart",
        description=(
            "Write a campaign of emu_8axle brake applications as recordings (MCS-75/25 friction scatter, "
            "running-resistance scatter, sensor noise) with zero, one or two effects switched on. The answer "
            "key goes to OUT_DIR/../<name>_key.json (or --key), never into OUT_DIR."
        ),
    )
    p.add_argument("out_dir", metavar="OUT_DIR", help="folder for the recordings (new or empty)")
    p.add_argument("--recordings", type=_count("--recordings", 1), required=True, help="number of brake applications")
    p.add_argument("--seed", type=_count("--seed", 0), required=True)
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="ID[:NAME=VALUE,...]",
        help="switch an effect on (at most two), e.g. gradient:gradient_permil=-5.8; parameters not given are drawn",
    )
    p.add_argument("--random-effects", action="store_true", help="zero, one or two effects drawn from the library")
    p.add_argument("--base-offset", action="store_true", help="move the base model within its scatter (not an effect)")
    p.add_argument("--noise-scale", type=_scale, default=1.0, help="factor on every sensor noise level (default 1)")
    p.add_argument("--key", help="answer key path (default OUT_DIR/../<name>_key.json; never inside OUT_DIR)")
    p.set_defaults(func=cmd_synth)


def cmd_diagnose(args: argparse.Namespace) -> int:
    import json
    from pathlib import Path

    from .diagnosis import diagnose

    result = diagnose(args.dataset_dir, top_singles=args.top_singles, pairs_from=args.pairs_from)
    report = result.report
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(report, indent=2) + "\n")
    if args.report:
        from .diagnosis_report import write_report

        path = write_report(result, args.report, Path(args.dataset_dir).name)
        print(f"report: {path}")
    if args.effects_out:
        from .diagnosis import write_effect_set

        path = write_effect_set(report, args.effects_out, Path(args.dataset_dir).name)
        print(f"effect set: {path} (simulator: brakegym.recordings.effects.load_effects; environments: config effects={str(path)!r})")
    print(f"selected: {', '.join(report['selected']) or 'nothing'}")
    print(report["summary"])
    return 0


def add_diagnose_command(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "diagnose",
        help="locate the mismatch between recordings and the model and name the missing physics",
        description=(
            "Fit the unmodified model and every effect of the library to a folder of recordings (initial speed, "
            "initial disc temperature and friction factor per recording as nuisance), rank the candidates by "
            "held-out error and an effective-sample BIC, and report the selected effects with 95 % intervals."
        ),
    )
    p.add_argument("dataset_dir", metavar="DATASET_DIR", help="folder of recordings (<stem>.csv + <stem>.json)")
    p.add_argument("--json", help="write the report as JSON (a public interface)")
    p.add_argument("--report", metavar="DIR", help="folder for the Markdown report and its figures")
    p.add_argument(
        "--effects-out", metavar="FILE.yaml",
        help="write the selected effects with their fitted parameters as an effect set (configs/effects schema)",
    )
    p.add_argument("--top-singles", type=_count("--top-singles", 1), default=3, help="screened effects fitted in full (default 3)")
    p.add_argument("--pairs-from", type=_count("--pairs-from", 0), default=2, help="pairs among this many best singles (default 2)")
    p.set_defaults(func=cmd_diagnose)
