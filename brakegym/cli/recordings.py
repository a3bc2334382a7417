"""``brakegym synth`` and ``brakegym diagnose``: the command-line side of
:mod:`brakegym.recordings.synth` and :mod:`brakegym.diagnosis`; and what every command that reads
a folder of recordings shares: ``--skip-bad-recordings``, the list of bad recordings on stderr and
the ``recordings_left_out`` key of its JSON output."""

from __future__ import annotations

import argparse
import sys
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .common import finite_non_negative, integer_at_least, write_json

if TYPE_CHECKING:
    from ..recordings import Dataset

SKIP_BAD_RECORDINGS = "--skip-bad-recordings"
LEFT_OUT_KEY = "recordings_left_out"


def add_skip_bad_recordings_option(parser: argparse.ArgumentParser) -> None:
    """The option of every command that reads a folder of recordings: go on without the bad ones."""
    parser.add_argument(
        SKIP_BAD_RECORDINGS,
        action="store_true",
        help=(
            "go on with the good recordings when some are bad: the bad ones are listed on stderr and under "
            f"'{LEFT_OUT_KEY}' in the JSON (without it, a bad recording ends the command with status 2 and a "
            "list of every bad recording and its problems)"
        ),
    )


def read_recordings(folder: str | Path, skip_bad: bool, command: str) -> Dataset:
    """The recordings a command works on, every bad one listed.

    Without ``skip_bad`` a bad recording raises the :class:`~brakegym.recordings.DatasetError`
    that lists them all (the command ends with status 2), with a hint at the option when some
    recordings are good; with it, the recordings left out are printed on stderr, each with its
    problems, and the good ones returned. A folder without a good recording raises in both modes.
    """
    from ..recordings import DatasetError, read_dataset

    try:
        dataset = read_dataset(folder, skip_bad=skip_bad)
    except DatasetError as exc:
        if skip_bad or exc.n_good == 0:
            raise
        hint = f"({SKIP_BAD_RECORDINGS} goes on with the {exc.n_good} good recording(s) and leaves these out)"
        raise DatasetError(exc.folder, exc.errors, exc.n_recordings, note=hint) from None
    if dataset.errors:
        total = len(dataset) + len(dataset.errors)
        print(f"brakegym {command}: left out {len(dataset.errors)} of the {total} recordings:", file=sys.stderr)
        for error in dataset.errors:
            print(textwrap.indent(str(error), "  "), file=sys.stderr)
    return dataset


def recordings_left_out(dataset: Dataset) -> list[dict[str, Any]]:
    """What the JSON output says of the recordings left out: ``[{"file": ..., "problems": [...]}]``."""
    return [error.as_dict() for error in dataset.errors]


def cmd_synth(args: argparse.Namespace) -> int:
    from ..recordings.chain import load_measurement_chain
    from ..recordings.model_form import load_model_form
    from ..recordings.synth import EffectRequest, synthesize

    requests = [EffectRequest.parse(text) for text in args.effect]
    chain = load_measurement_chain(args.measurement_chain) if args.measurement_chain else None
    form = load_model_form(args.model_form) if args.model_form else None
    result = synthesize(
        args.out_dir,
        args.recordings,
        args.seed,
        effects=requests,
        random_effects=args.random_effects,
        random_library=args.random_library,
        base_offset=args.base_offset,
        key_path=args.key,
        noise_scale=args.noise_scale,
        measurement_chain=chain,
        model_form=form,
        gradient_profile=args.gradient_profile,
        declare_gradient_profile=not args.conceal_gradient_profile,
        line_spread_m=args.line_spread_m,
        both_directions=args.both_directions,
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
    p.add_argument(
        "--recordings", type=integer_at_least("--recordings", 1), required=True, help="number of brake applications"
    )
    p.add_argument("--seed", type=integer_at_least("--seed", 0), required=True)
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="ID[:NAME=VALUE,...]",
        help="switch an effect on (at most two), e.g. gradient:gradient_permil=-5.8; parameters not given are drawn",
    )
    p.add_argument("--random-effects", action="store_true", help="zero, one or two effects drawn from the library")
    p.add_argument(
        "--random-library",
        default="default",
        metavar="NAME",
        help="what --random-effects draws from: default, the ten effects of brakegym 0.2 (zero, one or two); "
        "along_track, one effect located along the line (a gradient section, a profile of two, a stretch of "
        "low adhesion) and in half the sets one of the ten beside it",
    )
    p.add_argument("--base-offset", action="store_true", help="move the base model within its scatter (not an effect)")
    p.add_argument(
        "--noise-scale",
        type=finite_non_negative("--noise-scale"),
        default=1.0,
        help="factor on every sensor noise level (default 1)",
    )
    p.add_argument(
        "--measurement-chain",
        metavar="NAME|FILE.yaml",
        help=(
            "log every channel through a measurement chain (configs/measurement_chains, e.g. 'real': mixed and "
            "uneven sample rates, quantisation, dropouts, accelerometer bias and AR(1) noise, transducer offsets, "
            "a late disc thermometer) instead of the clean 10 Hz table"
        ),
    )
    p.add_argument(
        "--model-form",
        metavar="NAME|FILE.yaml",
        help=(
            "make the truth differ from the fitted model (configs/model_forms, e.g. 'real_train': a fine step and "
            "the numpy reference integrator, a slow unmodelled resistance, effects outside the library named in "
            "the key under 'out_of_library')"
        ),
    )
    p.add_argument(
        "--gradient-profile",
        type=_gradient_profile,
        metavar="START_M:PERMIL,...",
        help=(
            "run every application on a line of this gradient profile, sections from metres travelled since the "
            "recording's first sample, e.g. 0:0,400:-6 (level, then 6 permil downhill from 400 m), or with "
            "--line-spread-m in positions along the line; written into each recording's metadata as the line's "
            "known gradient (gradient_profile, or line_gradient_profile)"
        ),
    )
    p.add_argument(
        "--conceal-gradient-profile",
        action="store_true",
        help="keep the gradient profile out of the recordings (in the answer key only): a line to be found",
    )
    p.add_argument(
        "--line-spread-m",
        type=float,
        default=0.0,
        metavar="M",
        help=(
            "each application begins at its own place on the line, drawn in 0..M metres and written into its "
            "metadata (line_position_m); effects on part of the line then lie in metres along it (default 0: "
            "every application begins at the same place)"
        ),
    )
    p.add_argument(
        "--both-directions",
        action="store_true",
        help=(
            "with --line-spread-m: each application runs towards growing or falling line positions, drawn evenly "
            "and written into its metadata (line_direction); a run back begins further along the line, so that runs "
            "both ways meet about the same part of it"
        ),
    )
    p.add_argument("--key", help="answer key path (default OUT_DIR/../<name>_key.json; never inside OUT_DIR)")
    p.set_defaults(func=cmd_synth)


def _gradient_profile(text: str):
    """``START_M:PERMIL,...`` as a :class:`~brakegym.recordings.GradientProfile`; a clear error
    naming the option and the part that is wrong."""
    from pydantic import ValidationError

    from ..recordings import GradientProfile

    starts, gradients = [], []
    for part in text.split(","):
        start, sep, gradient = part.partition(":")
        try:
            if not sep:
                raise ValueError
            starts.append(float(start))
            gradients.append(float(gradient))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"--gradient-profile {text!r}: {part!r} is not START_M:PERMIL (e.g. 0:0,400:-6)"
            ) from None
    try:
        return GradientProfile(start_m=starts, gradient_permil=gradients)
    except ValidationError as error:
        reasons = "; ".join(item["msg"].removeprefix("Value error, ") for item in error.errors())
        raise argparse.ArgumentTypeError(f"--gradient-profile {text!r}: {reasons}") from None


def cmd_diagnose(args: argparse.Namespace) -> int:
    dataset = read_recordings(args.dataset_dir, args.skip_bad_recordings, args.command)
    from ..diagnosis.pipeline import Diagnoser  # after reading: a bad folder is refused at once

    result = Diagnoser(dataset.recordings, top_singles=args.top_singles, pairs_from=args.pairs_from).run()
    report = result.report
    write_json(args.json, {**report, LEFT_OUT_KEY: recordings_left_out(dataset)})
    if args.report:
        from ..diagnosis.markdown import write_report

        path = write_report(result, args.report, Path(args.dataset_dir).name)
        print(f"report: {path}")
    if args.effects_out:
        from ..diagnosis import write_effect_set

        path = write_effect_set(report, args.effects_out, Path(args.dataset_dir).name)
        print(
            f"effect set: {path} (simulator: brakegym.effects.load_effects; environments: config effects={str(path)!r})"
        )
    if dataset.errors:
        print(f"left out {len(dataset.errors)} bad recording(s) (listed on stderr); diagnosed {len(dataset)}")
    print(f"selected: {', '.join(report['selected']) or 'nothing'}")
    print(report["summary"])
    return 0


def _add_diagnose_command(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "diagnose",
        help="locate the mismatch between recordings and the model and name the missing physics",
        description=(
            "Fit the unmodified model and every effect of the library to a folder of recordings (initial speed, "
            "initial disc temperature, friction factor and running resistance per recording as nuisance), rank the "
            "candidates by "
            "held-out error and an effective-sample BIC, and report the selected effects with 95 % intervals."
        ),
    )
    p.add_argument("dataset_dir", metavar="DATASET_DIR", help="folder of recordings (<stem>.csv + <stem>.json)")
    p.add_argument("--json", help="write the report as JSON (a public interface)")
    p.add_argument("--report", metavar="DIR", help="folder for the Markdown report and its figures")
    p.add_argument(
        "--effects-out",
        metavar="FILE.yaml",
        help="write the selected effects with their fitted parameters as an effect set (configs/effects schema)",
    )
    p.add_argument(
        "--top-singles",
        type=integer_at_least("--top-singles", 1),
        default=3,
        help="screened effects fitted in full (default 3)",
    )
    p.add_argument(
        "--pairs-from",
        type=integer_at_least("--pairs-from", 0),
        default=2,
        help="pairs among this many best singles (default 2)",
    )
    add_skip_bad_recordings_option(p)
    p.set_defaults(func=cmd_diagnose)


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``synth`` and ``diagnose``."""
    _add_synth_command(sub)
    _add_diagnose_command(sub)
