"""``brakegym synth``: the command-line side of :mod:`.synth` (registered by ``brakegym.cli``)."""

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
