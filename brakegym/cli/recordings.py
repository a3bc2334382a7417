"""``brakegym synth`` and ``brakegym diagnose``: the command-line side of
:mod:`brakegym.recordings.synth` and :mod:`brakegym.diagnosis`."""

from __future__ import annotations

import argparse

from .common import finite_non_negative, integer_at_least, write_json


def cmd_synth(args: argparse.Namespace) -> int:
    from ..recordings.synth import EffectRequest, synthesize

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


def _add_synth_command(sub: argparse._SubParsersAction) -> None:
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
    p.add_argument("--recordings", type=integer_at_least("--recordings", 1), required=True, help="number of brake applications")
    p.add_argument("--seed", type=integer_at_least("--seed", 0), required=True)
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="ID[:NAME=VALUE,...]",
        help="switch an effect on (at most two), e.g. gradient:gradient_permil=-5.8; parameters not given are drawn",
    )
    p.add_argument("--random-effects", action="store_true", help="zero, one or two effects drawn from the library")
    p.add_argument("--base-offset", action="store_true", help="move the base model within its scatter (not an effect)")
    p.add_argument("--noise-scale", type=finite_non_negative("--noise-scale"), default=1.0, help="factor on every sensor noise level (default 1)")
    p.add_argument("--key", help="answer key path (default OUT_DIR/../<name>_key.json; never inside OUT_DIR)")
    p.set_defaults(func=cmd_synth)


def cmd_diagnose(args: argparse.Namespace) -> int:
    from pathlib import Path

    from ..diagnosis import diagnose

    result = diagnose(args.dataset_dir, top_singles=args.top_singles, pairs_from=args.pairs_from)
    report = result.report
    write_json(args.json, report)
    if args.report:
        from ..diagnosis.markdown import write_report

        path = write_report(result, args.report, Path(args.dataset_dir).name)
        print(f"report: {path}")
    if args.effects_out:
        from ..diagnosis import write_effect_set

        path = write_effect_set(report, args.effects_out, Path(args.dataset_dir).name)
        print(f"effect set: {path} (simulator: brakegym.effects.load_effects; environments: config effects={str(path)!r})")
    print(f"selected: {', '.join(report['selected']) or 'nothing'}")
    print(report["summary"])
    return 0


def _add_diagnose_command(sub: argparse._SubParsersAction) -> None:
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
    p.add_argument("--top-singles", type=integer_at_least("--top-singles", 1), default=3, help="screened effects fitted in full (default 3)")
    p.add_argument("--pairs-from", type=integer_at_least("--pairs-from", 0), default=2, help="pairs among this many best singles (default 2)")
    p.set_defaults(func=cmd_diagnose)


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``synth`` and ``diagnose``."""
    _add_synth_command(sub)
    _add_diagnose_command(sub)
