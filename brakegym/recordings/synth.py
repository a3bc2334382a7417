"""Synthetic recording sets with concealed effects (``brakegym synth``).

A set is a campaign of brake applications of ``emu_8axle``, simulated with the physics a real
train would add to the nominal model, and written as recordings (``format``) that look measured.
The answer key (which effects, their parameters, each effect's imprint on the recordings, the
per-application truth) is written apart from the recordings: a diagnosis reading the folder
cannot see it.

What varies, per application (from the seed):

- initial speed uniform 60..160 km/h; load, brake mode (emergency/service), actuation (EP/PN) and
  pad set uniform over their values; the mode's cylinder pressure for the load with a per-axle
  spread of 1 % (real axles differ; the recording measures each);
- a coasting phase of 4..10 s before the brake command (running resistance and gradient act
  alone there, which separates them from the brake), and 2..5 s of standstill after the stop;
- ambient 0..30 degC, initial disc temperature ambient + 0..60 K (earlier braking);
- friction scatter MCS-75/25 (``brakegym.physics.scatter``) and the running-resistance scatter
  A ~ N(A, sigma_A);
- per set: the deceleration source (accelerometer with probability 3/4, else differentiated
  speed); the instrumented disc is disc 1 (the front axle's first disc).

Sensors (``SENSOR_NOISE``; white Gaussian, independent per sample):

| channel | noise (1 sigma) | resolution | notes |
|---|---|---|---|
| ``speed_mps`` | 0.03 m/s | 0.001 | a pulse sensor: reports the magnitude, exactly 0 at standstill |
| ``decel_mps2`` | 0.02 (accelerometer), 0.03 (from speed) m/s^2 | 0.001 | |
| ``T_disc_C`` | 1.0 K | 0.01 | |
| ``position_m`` | 0.05 m | 0.001 | |
| ``p_c_bar_i`` | 0.02 bar | 0.001 | a 0..10 bar transducer: its output saturates at its range |

Samples at 10 Hz with +-10 ms timing jitter (uneven sampling), and 0.2 % of the cells of the
optional channels blank (dropouts; never on the first line).

The truth is integrated at ``TRUTH_STEP_S`` = 0.05 s with the cylinder pressure following the
command exactly (dead time and lag), finer than a replay's 0.1 s, so that a replay carries a small
genuine model error of its own, as against real data.

``base_offset``: the base model is moved within its own scatter for the whole set (the running
resistance: A by 0.5..1 sigma_A, B and C by up to +-20 %; or the friction: nominal mu_0 and a by
0.5..1 sigma of their scatter), which a diagnosis must not label an effect.

Everything is drawn from one seed through independent streams (campaign, scatter, effects, base
offset, noise), so the same seed writes the same files byte for byte, and a set with an effect
has the same applications and noise as the set without it.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import __version__
from .. import config as cfg
from ..applications import CommandSchedule
from ..effects import Effect, EffectedModel, RunningResistanceEffect, apply_effects, effect_class
from ..physics import BrakeCylinder, RunningResistanceLaw
from ..plants import brake_cylinder, train_plant, train_scatter
from ..simulator import BatchConditions, CommandedPressure, Plant, Simulator
from ..units import ZERO_CELSIUS_K, kmh_to_mps
from .chain import PRESSURES, MeasurementChain
from .columns import DECEL, DISC_TEMPERATURE, POSITION, SPEED, TIME, pressure_column
from .format import Recording, write_recording
from .logger import log_run
from .measurement import GridTrajectory, MeasurementModel
from .metadata import GradientProfile, LineGradientProfile, RecordingMetadata
from .model_form import DrawnModelForm, ModelForm, draw_model_form, key_entry, truth_row_entry
from .replay import add_gradient_profiles, simulate_grid

VEHICLE = "emu_8axle"
SCATTER_SETUP = "mcs-75-25"
TRUTH_STEP_S = 0.05
SAMPLE_INTERVAL_S = 0.1
SAMPLE_JITTER_S = 0.01
DROPOUT_PROBABILITY = 0.002
INSTRUMENTED_DISC = 1
SPEED_RANGE_KMH = (60.0, 160.0)
# The child of the set's seed that draws where the applications begin on the line (after the six
# of _draw_set: spawning more does not change those).
LINE_STREAM = 6
# Where a run back begins, beyond the place drawn for it: runs of the synth's middle speeds cover
# 600-900 m from their first sample to standstill (coasting and braking), so runs both ways then
# meet about the same part of the line.
RUN_BACK_OFFSET_M = 1000.0
COASTING_RANGE_S = (4.0, 10.0)
STANDSTILL_RANGE_S = (2.0, 5.0)
AMBIENT_RANGE_C = (0.0, 30.0)
INITIAL_DISC_EXCESS_RANGE_K = (0.0, 60.0)
AXLE_PRESSURE_SPREAD = 0.01
ACCELEROMETER_PROBABILITY = 0.75
PRESSURE_TRANSDUCER_RANGE_BAR = (0.0, 10.0)
SENSOR_NOISE = {
    SPEED: 0.03,
    "decel_mps2_accelerometer": 0.02,
    "decel_mps2_speed": 0.03,
    DISC_TEMPERATURE: 1.0,
    POSITION: 0.05,
    "p_c_bar": 0.02,
}
RESOLUTION = {TIME: 1e-3, SPEED: 1e-3, DECEL: 1e-3, DISC_TEMPERATURE: 1e-2, POSITION: 1e-3, "p_c_bar": 1e-3}
MAX_EFFECTS = 2
# An effect that moves no sample of any channel by this many noise sigmas is not in the data.
IMPRINT_EXPRESSED_OVER_NOISE = 1.0


@dataclass(frozen=True)
class EffectRequest:
    """An effect to switch on; parameters not given are drawn within their synth ranges."""

    id: str
    parameters: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        cls = effect_class(self.id)
        names = [p.name for p in cls.parameters]
        unknown = sorted(set(self.parameters) - set(names))
        if unknown:
            raise ValueError(f"effect {self.id!r}: unknown parameter(s) {unknown}; its parameters are {names}")
        for name, value in self.parameters.items():
            cls.spec(name).check(self.id, value)

    @classmethod
    def parse(cls, text: str) -> EffectRequest:
        """``ID`` or ``ID:name=value[,name=value...]``, e.g. ``gradient:gradient_permil=-5.8``."""
        effect_id, _, rest = text.partition(":")
        parameters: dict[str, float] = {}
        for item in filter(None, (part.strip() for part in rest.split(","))):
            name, equals, value = item.partition("=")
            if not equals:
                raise ValueError(f"effect {text!r}: expected name=value, got {item!r}")
            try:
                parameters[name.strip()] = float(value)
            except ValueError:
                raise ValueError(f"effect {text!r}: parameter {name.strip()!r} = {value!r} is not a number") from None
            if not math.isfinite(parameters[name.strip()]):
                raise ValueError(f"effect {text!r}: parameter {name.strip()!r} = {value!r} is not finite")
        return cls(effect_id.strip(), parameters)


def _draw_parameter(rng: np.random.Generator, spec) -> float:
    low, high = spec.synth_ranges[int(rng.integers(len(spec.synth_ranges)))]
    if spec.integer:
        return float(rng.integers(int(low), int(high) + 1))
    # Rounded to 4 significant digits: the key reads like a specification, not like noise.
    return float(f"{rng.uniform(low, high):.4g}")


def resolve_effects(
    requests: Sequence[EffectRequest], rng: np.random.Generator
) -> tuple[list[Effect], list[dict[str, Any]]]:
    """The effects with every parameter set (drawn where not given), and their key entries."""
    effects, entries = [], []
    for request in requests:
        cls = effect_class(request.id)
        values, drawn = {}, []
        for spec in cls.parameters:
            # Always draw, so that giving one parameter does not shift the stream for the others.
            candidate = _draw_parameter(rng, spec)
            if spec.name in request.parameters:
                values[spec.name] = float(request.parameters[spec.name])
            else:
                values[spec.name] = candidate
                drawn.append(spec.name)
        effects.append(cls(**values))
        entries.append({"id": cls.id, "parameters": values, "drawn": drawn})
    return effects, entries


#: the effects ``--random-effects`` draws from: the library of brakegym 0.2, so that a seed keeps
#: its set as the library grows (an effect added since is drawn on request, ``--effect``)
RANDOM_EFFECT_IDS = (
    "gradient",
    "friction_level",
    "wet_pads",
    "adhesion_limit",
    "thermal_fade",
    "rotating_mass",
    "brake_unit_failure",
    "running_resistance",
    "speed_sensor_scale",
    "temperature_sensor_lag",
)


#: the effects that live along the line, one of which ``--random-library along_track`` puts in every set
ALONG_TRACK_EFFECT_IDS = ("gradient_section", "adhesion_section", "gradient_sections")

#: what ``--random-effects`` draws from (:func:`random_requests`)
RANDOM_LIBRARIES = ("default", "along_track")


def random_requests(rng: np.random.Generator, library: str = "default") -> list[EffectRequest]:
    """The effects of a random set, drawn from ``library``:

    - ``default``: zero, one or two effects of ``RANDOM_EFFECT_IDS``, equally likely counts,
      distinct ids;
    - ``along_track``: one effect of ``ALONG_TRACK_EFFECT_IDS``, and in half the sets one of
      ``RANDOM_EFFECT_IDS`` beside it, for a benchmark of the effects located along position."""
    if library == "default":
        count = int(rng.integers(MAX_EFFECTS + 1))
        ids = list(RANDOM_EFFECT_IDS)
        chosen = rng.choice(len(ids), size=count, replace=False)
        return [EffectRequest(ids[int(i)]) for i in sorted(chosen)]
    if library == "along_track":
        requests = [EffectRequest(ALONG_TRACK_EFFECT_IDS[int(rng.integers(len(ALONG_TRACK_EFFECT_IDS)))])]
        if rng.random() < 0.5:
            requests.append(EffectRequest(RANDOM_EFFECT_IDS[int(rng.integers(len(RANDOM_EFFECT_IDS)))]))
        return requests
    raise ValueError(f"random library {library!r}: choose one of {', '.join(RANDOM_LIBRARIES)}")


@dataclass
class Application:
    stem: str
    initial_speed_kmh: float
    load: str
    brake_mode: str
    actuation: str
    pad_set: str
    command_time_s: float
    standstill_s: float
    ambient_C: float
    initial_disc_C: float
    axle_pressure_bar: np.ndarray
    line_position_m: float | None = None  # where along the line its first sample is (None: not said)
    line_direction: str | None = None  # "decreasing" for a run towards falling line positions (None: not said)

    @property
    def line_direction_sign(self) -> float:
        """+1 for a run towards growing line positions, -1 towards falling (as the metadata's)."""
        return -1.0 if self.line_direction == "decreasing" else 1.0


def _round(values: np.ndarray, resolution: float) -> np.ndarray:
    # Snap to the resolution and print-round, so the CSV holds short decimals.
    return np.round(np.round(values / resolution) * resolution, 6)


def draw_applications(
    rng: np.random.Generator, vehicle: cfg.Vehicle, n: int, coasting_range_s: tuple[float, float] = COASTING_RANGE_S
) -> list[Application]:
    loads = sorted(vehicle.loads)
    modes = sorted(vehicle.brake_pressures_bar)
    actuations = ["EP", "PN"]
    applications = []
    for i in range(n):
        load = loads[int(rng.integers(len(loads)))]
        mode = modes[int(rng.integers(len(modes)))]
        ambient = round(float(rng.uniform(*AMBIENT_RANGE_C)), 1)
        spread = 1.0 + AXLE_PRESSURE_SPREAD * rng.standard_normal(vehicle.n_axles)
        applications.append(
            Application(
                stem=f"rec_{i + 1:03d}",
                initial_speed_kmh=round(float(rng.uniform(*SPEED_RANGE_KMH)), 1),
                load=load,
                brake_mode=mode,
                actuation=actuations[int(rng.integers(2))],
                pad_set=str(int(rng.integers(1, 3))),
                # On the truth grid, so the command switches at a step.
                command_time_s=round(float(rng.uniform(*coasting_range_s)), 1),
                standstill_s=round(float(rng.uniform(*STANDSTILL_RANGE_S)), 1),
                ambient_C=ambient,
                initial_disc_C=round(ambient + float(rng.uniform(*INITIAL_DISC_EXCESS_RANGE_K)), 1),
                axle_pressure_bar=np.round(vehicle.brake_pressure_bar(mode, load) * spread, 4),
            )
        )
    return applications


def _placed_on_the_line(
    applications: list[Application], seed: int, spread_m: float, both_directions: bool = False
) -> list[Application]:
    """The applications, each beginning at a place on the line drawn evenly in 0..``spread_m``
    (to 0.1 m), from a stream of its own: the set's other draws stay what they are without it.
    ``both_directions``: each run goes towards growing or falling line positions, drawn evenly
    after the places (which stay what they are without it). A run back begins
    ``RUN_BACK_OFFSET_M`` further along, so that runs both ways cover the same part of the line."""
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(LINE_STREAM + 1)[LINE_STREAM])
    positions = np.round(rng.uniform(0.0, spread_m, size=len(applications)), 1)
    back = rng.integers(2, size=len(applications)).astype(bool) if both_directions else np.zeros(len(positions), bool)
    return [
        dataclasses.replace(
            app,
            line_position_m=float(x + RUN_BACK_OFFSET_M) if is_back else float(x),
            line_direction=("decreasing" if is_back else "increasing") if both_directions else None,
        )
        for app, x, is_back in zip(applications, positions, back, strict=True)
    ]


def _draw_base_offset(
    rng: np.random.Generator, vehicle: cfg.Vehicle, material: cfg.FrictionMaterial, allowed: Sequence[str]
) -> dict[str, Any]:
    # Both kinds' numbers are always drawn so the stream does not depend on the choice.
    kind_index = int(rng.integers(2))
    sign = np.where(rng.random(2) < 0.5, -1.0, 1.0)
    size = rng.uniform(0.5, 1.0, size=2)
    factors = rng.uniform(0.8, 1.2, size=2)
    kind = ("running_resistance", "friction")[kind_index]
    if kind not in allowed:
        kind = allowed[0]
    if kind == "running_resistance":
        resistance = vehicle.running_resistance
        return {
            "kind": kind,
            "A_shift_N": round(float(sign[0] * size[0] * resistance.A_sigma_N), 1),
            "B_factor": round(float(factors[0]), 4),
            "C_factor": round(float(factors[1]), 4),
        }
    scatter = material.scatter
    return {
        "kind": kind,
        "initial_mu_shift": round(float(sign[0] * size[0] * scatter.initial_mu_sigma), 5),
        "power_coefficient_shift_per_s": round(float(sign[1] * size[1] * scatter.power_coefficient_sigma_per_s), 6),
    }


@dataclass
class SynthResult:
    recordings: list[Recording]
    key: dict[str, Any]
    folder: Path
    key_path: Path


def default_key_path(out_dir: Path) -> Path:
    """``OUT_DIR/../<name>_key.json``: beside the recordings folder, not in it."""
    out_dir = Path(out_dir)
    return out_dir.resolve().parent / f"{out_dir.resolve().name}_key.json"


def synthesize(
    out_dir: str | Path,
    n_recordings: int,
    seed: int,
    effects: Sequence[EffectRequest] = (),
    random_effects: bool = False,
    base_offset: bool = False,
    key_path: str | Path | None = None,
    noise_scale: float = 1.0,
    random_library: str = "default",
    scatter_setup: str = SCATTER_SETUP,
    measurement_chain: MeasurementChain | None = None,
    model_form: ModelForm | None = None,
    gradient_profile: GradientProfile | None = None,
    declare_gradient_profile: bool = True,
    line_spread_m: float = 0.0,
    both_directions: bool = False,
) -> SynthResult:
    """Write a synthetic set of ``n_recordings`` into ``out_dir`` and its key to ``key_path``
    (default :func:`default_key_path`).

    ``random_library``: what ``random_effects`` draws from (:func:`random_requests`).
    ``noise_scale`` multiplies every sensor noise level (0: noise-free, for checking a replay;
    larger for robustness); ``scatter_setup`` names the friction scatter set-up (``ds``: none,
    and no running-resistance scatter either); ``measurement_chain`` logs each channel through
    that chain (:mod:`.logger`) instead of the clean 10 Hz table (its noise levels times
    ``noise_scale``; offsets, quantisation and dropouts as configured); ``model_form`` makes the
    truth differ from the fitted model (:mod:`.model_form`: its step and integrator, unmodelled
    forces, effects outside the library, recorded in the key); ``gradient_profile`` runs every
    application on a line of that gradient profile (from each recording's first sample; with
    ``line_spread_m``, in positions along the line, each run over its own part of it), written
    into each recording's metadata where ``declare_gradient_profile`` (a known line), else only
    into the key (a line the diagnosis has to find). ``line_spread_m`` > 0: each application
    begins at its own place on the line, drawn evenly in 0..``line_spread_m`` m and written into
    its metadata (``line_position_m``), as recordings taken along a line are; effects on part of
    the line then lie in metres along it (0: every application begins at 0, and the metadata
    say nothing). ``both_directions`` (with ``line_spread_m``): each application runs towards
    growing or falling line positions, drawn evenly and written into its metadata
    (``line_direction``); a run back begins ``RUN_BACK_OFFSET_M`` further along the line."""
    out_dir = Path(out_dir)
    key_path = Path(key_path) if key_path is not None else default_key_path(out_dir)
    _check_request(out_dir, key_path, n_recordings, effects, random_effects, noise_scale, random_library)
    if not (math.isfinite(line_spread_m) and line_spread_m >= 0):
        raise ValueError(f"line spread {line_spread_m} m: must be a non-negative finite number")
    if both_directions and not line_spread_m > 0:
        raise ValueError(
            "runs both ways along the line need a line spread of more than 0 m "
            "(line_spread_m, --line-spread-m): give one"
        )
    drawn = _draw_set(
        n_recordings,
        seed,
        effects,
        random_library if random_effects else None,
        base_offset,
        scatter_setup,
        measurement_chain,
        model_form,
    )
    if line_spread_m > 0:
        drawn.applications = _placed_on_the_line(drawn.applications, seed, line_spread_m, both_directions)
    drawn.gradient_profile, drawn.gradient_profile_declared = gradient_profile, declare_gradient_profile
    model, grid = _simulate_truth(drawn, drawn.chosen)
    recordings, truth_rows = _write_recordings(drawn, model, grid, out_dir, noise_scale)
    if drawn.chosen:
        true_channels = _sensor_channels(recordings, model, grid, drawn.decel_source)
        for effect, entry in zip(drawn.chosen, drawn.effect_entries):
            others = [e for e in drawn.chosen if e is not effect]
            without = _sensor_channels(recordings, *_simulate_truth(drawn, others), drawn.decel_source)
            entry["imprint"] = _imprint(true_channels, without, _imprint_sigmas(drawn, noise_scale))
    key = _answer_key(drawn, seed, noise_scale, truth_rows)
    key_path.parent.mkdir(parents=True, exist_ok=True)
    key_path.write_text(json.dumps(key, indent=2) + "\n")
    return SynthResult(recordings=recordings, key=key, folder=out_dir, key_path=key_path)


def _write_recordings(
    drawn: _DrawnSet, model: EffectedModel, grid: GridTrajectory, out_dir: Path, noise_scale: float
) -> tuple[list[Recording], list[dict[str, Any]]]:
    """Measure every application of the true run ``grid`` (through the set's measurement chain,
    if any), write it into ``out_dir``; the recordings and the key's truth rows."""
    recordings, truth_rows = [], []
    for b, app in enumerate(drawn.applications):
        stop = float(grid.stop_time_s[b])
        row = _truth_row(drawn, b, model, grid, stop)
        if drawn.chain is not None:
            record, row["measurement_chain"] = _measure_through_chain(drawn, b, grid, model, stop, noise_scale)
        else:
            record = _measure(
                app,
                b,
                grid,
                model,
                drawn.cylinders[b],
                drawn.decel_source,
                stop,
                drawn.noise_seeds[b],
                drawn.vehicle,
                noise_scale,
                drawn.declared_gradient_profile,
            )
        write_recording(record, out_dir)
        recordings.append(record)
        truth_rows.append(row)
    return recordings, truth_rows


def _check_request(
    out_dir: Path,
    key_path: Path,
    n_recordings: int,
    effects: Sequence[EffectRequest],
    random_effects: bool,
    noise_scale: float,
    random_library: str = "default",
) -> None:
    """Refuse a set that cannot be written as asked."""
    if random_library not in RANDOM_LIBRARIES:
        raise ValueError(f"random library {random_library!r}: choose one of {', '.join(RANDOM_LIBRARIES)}")
    if random_library != "default" and not random_effects:
        raise ValueError(f"random library {random_library!r} given without random effects, which are drawn from it")
    if not (math.isfinite(noise_scale) and noise_scale >= 0):
        raise ValueError(f"noise scale {noise_scale}: must be a non-negative finite number")
    if n_recordings < 1:
        raise ValueError(f"--recordings {n_recordings}: need at least 1")
    if len(effects) > MAX_EFFECTS:
        raise ValueError(f"{len(effects)} effects given; a set holds at most {MAX_EFFECTS}")
    if random_effects and effects:
        raise ValueError("give either effects or random effects, not both")
    ids = [e.id for e in effects]
    if len(set(ids)) != len(ids):
        raise ValueError(f"effect ids {ids} repeat")
    if out_dir.resolve() in key_path.resolve().parents:
        raise ValueError(f"the key {key_path} must not lie inside the recordings folder {out_dir}")
    if out_dir.exists() and any(p.suffix in (".csv", ".json") for p in out_dir.iterdir()):
        raise ValueError(f"{out_dir} already holds recordings; write a new set into an empty folder")


@dataclass
class _DrawnSet:
    """Everything a set's seed draws: the applications, their scatter, the effects and the base
    offset, and the truth's plant and batch built from them."""

    vehicle: cfg.Vehicle
    setup: cfg.ScatterSetup
    plant: Plant
    chosen: list[Effect]
    effect_entries: list[dict[str, Any]]
    applications: list[Application]
    decel_source: str
    conditions: BatchConditions
    scatter_A: np.ndarray  # each application's running-resistance draw less the nominal A
    offset: dict[str, Any] | None
    cylinders: list[BrakeCylinder]
    noise_seeds: list[np.random.SeedSequence]
    chain: MeasurementChain | None = None
    model_form: DrawnModelForm | None = None
    gradient_profile: GradientProfile | None = None  # the line every application runs on
    gradient_profile_declared: bool = True  # in each recording's metadata, or in the key alone
    random_library: str | None = None  # what the effects were drawn from (None: given)

    @property
    def declared_gradient_profile(self) -> GradientProfile | None:
        """The profile the recordings' metadata carry."""
        return self.gradient_profile if self.gradient_profile_declared else None

    @property
    def truth_step_s(self) -> float:
        return TRUTH_STEP_S if self.model_form is None else self.model_form.form.truth_step_s


def _draw_set(
    n: int,
    seed: int,
    effects: Sequence[EffectRequest],
    random_library: str | None,
    base_offset: bool,
    scatter_setup: str,
    chain: MeasurementChain | None = None,
    form: ModelForm | None = None,
) -> _DrawnSet:
    """The draws of a set from its seed, through independent streams (campaign, scatter, effects,
    base offset, noise, model form: a child's stream does not depend on how many are spawned).
    ``random_library``: the library random effects are drawn from (None: ``effects``)."""
    streams = np.random.SeedSequence(seed).spawn(6)
    campaign_seed, scatter_seed, effect_seed, offset_seed, noise_seed, form_seed = streams
    campaign_rng, scatter_rng, effect_rng, offset_rng = (
        np.random.default_rng(s) for s in (campaign_seed, scatter_seed, effect_seed, offset_seed)
    )
    vehicle = cfg.load("vehicles", VEHICLE)
    material = cfg.load("materials", vehicle.material)
    setup = cfg.load("setups", scatter_setup)
    plant = train_plant(vehicle)
    requests = random_requests(effect_rng, random_library) if random_library is not None else list(effects)
    chosen, effect_entries = resolve_effects(requests, effect_rng)
    applications = draw_applications(
        campaign_rng, vehicle, n, COASTING_RANGE_S if chain is None else chain.coasting_range_s
    )
    decel_source = "accelerometer" if campaign_rng.random() < ACCELEROMETER_PROBABILITY else "speed"
    if chain is not None:
        decel_source = chain.decel_source
    draw, drawn_A = train_scatter(vehicle, setup).draw(scatter_rng, n)
    initial_mu, power_coefficient, resistance_A = draw.initial_mu, draw.power_coefficient_per_s, drawn_A
    offset: dict[str, Any] | None = None
    if base_offset:
        has_resistance_effect = any(isinstance(e, RunningResistanceEffect) for e in chosen)
        allowed = ["friction"] if has_resistance_effect else ["running_resistance", "friction"]
        offset = _draw_base_offset(offset_rng, vehicle, material, allowed)
        if offset["kind"] == "running_resistance":
            nominal = vehicle.running_resistance
            resistance_A = drawn_A + offset["A_shift_N"]
            plant = dataclasses.replace(
                plant,
                running_resistance=RunningResistanceLaw(
                    A_N=nominal.A_N + offset["A_shift_N"],
                    B_N_per_mps=nominal.B_N_per_mps * offset["B_factor"],
                    C_N_per_mps2=nominal.C_N_per_mps2 * offset["C_factor"],
                ),
            )
        else:
            initial_mu = initial_mu + offset["initial_mu_shift"]
            power_coefficient = power_coefficient + offset["power_coefficient_shift_per_s"]
    disc_shape = (n, *plant.disc_shape)
    initial_K = np.array([a.initial_disc_C for a in applications]) + ZERO_CELSIUS_K
    conditions = BatchConditions(
        mass_kg=np.array([vehicle.mass_kg(a.load) for a in applications]),
        initial_speed_mps=np.array([kmh_to_mps(a.initial_speed_kmh) for a in applications]),
        initial_mu=initial_mu,
        power_coefficient_per_s=power_coefficient,
        running_resistance_A_N=resistance_A,
        initial_friction_temperature_K=np.broadcast_to(initial_K[:, None, None], disc_shape).copy(),
        initial_disc_temperature_K=np.broadcast_to(initial_K[:, None, None], disc_shape).copy(),
        ambient_temperature_K=np.array([a.ambient_C for a in applications]) + ZERO_CELSIUS_K,
    )
    return _DrawnSet(
        vehicle=vehicle,
        setup=setup,
        plant=plant,
        chosen=chosen,
        effect_entries=effect_entries,
        applications=applications,
        decel_source=decel_source,
        conditions=conditions,
        scatter_A=drawn_A - vehicle.running_resistance.A_N,
        offset=offset,
        cylinders=[brake_cylinder(cfg.load("pneumatics", a.actuation)) for a in applications],
        # One noise seed per recording and channel: sample k of a recording gets the same noise
        # whatever the length of the recording or of the others.
        noise_seeds=noise_seed.spawn(n),
        chain=chain,
        model_form=None
        if form is None
        else draw_model_form(form, np.random.default_rng(form_seed), [a.brake_mode for a in applications]),
        random_library=random_library,
    )


def _truth_row(drawn: _DrawnSet, b: int, model: EffectedModel, grid: GridTrajectory, stop: float) -> dict[str, Any]:
    """What the key records of application ``b``."""
    app = drawn.applications[b]
    position = grid.position_m[:, b]
    conditions = drawn.conditions
    return {
        "stem": app.stem,
        "initial_speed_kmh": app.initial_speed_kmh,
        "load": app.load,
        "brake_mode": app.brake_mode,
        "actuation": app.actuation,
        "command_time_s": app.command_time_s,
        "stop_time_s": round(stop, 4),
        "braking_distance_m": round(
            float(np.interp(stop, grid.time_s, position) - np.interp(app.command_time_s, grid.time_s, position)), 3
        ),
        "running_resistance_A_N": round(float(np.asarray(model.conditions.running_resistance_A_N)[b]), 2),
        "mean_initial_mu": round(float(conditions.initial_mu[b].mean()), 5),
        "mean_power_coefficient_per_s": round(float(conditions.power_coefficient_per_s[b].mean()), 6),
        "initial_disc_C": app.initial_disc_C,
        "ambient_C": app.ambient_C,
        "axle_pressure_command_bar": [float(p) for p in app.axle_pressure_bar],
        **({} if app.line_position_m is None else {"line_position_m": app.line_position_m}),
        **({} if app.line_direction is None else {"line_direction": app.line_direction}),
        **({} if drawn.model_form is None else {"model_form": truth_row_entry(drawn.model_form, b)}),
    }


def _answer_key(drawn: _DrawnSet, seed: int, noise_scale: float, truth_rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The answer key: the effects and their imprint, the base offset, the measurement chain and
    the per-application truth."""
    offset = drawn.offset
    form = drawn.model_form
    stems = [a.stem for a in drawn.applications]
    return {
        "generator": f"brakegym synth {__version__}",
        "seed": seed,
        "recordings": len(drawn.applications),
        "vehicle": VEHICLE,
        "effects": drawn.effect_entries,
        "random_library": drawn.random_library,
        "expected_selected": [entry["id"] for entry in drawn.effect_entries if entry["imprint"]["expressed"]],
        "base_offset": offset,
        "base_offset_note": None
        if offset is None
        else "the base model is moved within its own scatter: not an effect, must not be selected",
        "scatter_setup": drawn.setup.name,
        "running_resistance_scatter_sigma_N": (
            drawn.vehicle.running_resistance.A_sigma_N if drawn.setup.resistance_scatter else 0.0
        ),
        "decel_source": drawn.decel_source,
        "instrumented_disc": INSTRUMENTED_DISC,
        # The clean logger's settings; a set written through a measurement chain has those instead.
        **(
            {
                "sensor_noise": {name: sigma * noise_scale for name, sigma in SENSOR_NOISE.items()},
                "sample_interval_s": SAMPLE_INTERVAL_S,
                "sample_jitter_s": SAMPLE_JITTER_S,
                "dropout_probability": DROPOUT_PROBABILITY,
            }
            if drawn.chain is None
            else {"noise_scale": noise_scale}
        ),
        "truth_step_s": drawn.truth_step_s,
        "measurement_chain": None if drawn.chain is None else drawn.chain.model_dump(mode="json"),
        "model_form": None if form is None else key_entry(form, stems),
        # Effects outside the library: a diagnosis must leave them unexplained, not name them.
        "expected_unexplained": [] if form is None else [e["id"] for e in key_entry(form, stems)["out_of_library"]],
        **(
            {}
            if drawn.gradient_profile is None
            else {
                "gradient_profile": {
                    **drawn.gradient_profile.model_dump(mode="json"),
                    "declared": drawn.gradient_profile_declared,
                    # Placed on the line, the starts are line positions (line_gradient_profile).
                    **({"in_line_positions": True} if drawn.applications[0].line_position_m is not None else {}),
                }
            }
        ),
        "applications": truth_rows,
    }


def _simulate_truth(drawn: _DrawnSet, chosen: Sequence[Effect]) -> tuple[EffectedModel, GridTrajectory]:
    """The true runs of the set's applications with the effects ``chosen``: (model, grid)."""
    form = drawn.model_form
    applications = drawn.applications
    command_time = np.array([a.command_time_s for a in applications])
    model = apply_effects(
        drawn.plant,
        drawn.conditions,
        chosen,
        form.friction_modifiers() if form is not None else (),
        form.wheel_brake_forces(command_time) if form is not None else (),
        line_position_at_start_m=np.array([a.line_position_m or 0.0 for a in applications]),
        line_direction_sign=np.array([a.line_direction_sign for a in applications]),
    )
    add_gradient_profiles(model, [_run_profile(drawn.gradient_profile, a) for a in applications])
    if any(isinstance(e, RunningResistanceEffect) for e in chosen):
        # The effect sets the set's running resistance; each application still scatters around it.
        model.conditions = dataclasses.replace(
            model.conditions,
            running_resistance_A_N=np.asarray(model.conditions.running_resistance_A_N) + drawn.scatter_A,
        )
    command = np.stack([a.axle_pressure_bar for a in applications])
    simulator_class = Simulator
    if form is not None:
        model.extra_forces += form.extra_forces()
        simulator_class = form.form.simulator_class
    step = drawn.truth_step_s
    pressure = CommandedPressure(list(drawn.cylinders), drawn.plant.n_axles, step)
    schedule = CommandSchedule(pressure, command, command_time, step)
    end_after_stop = np.array([a.standstill_s for a in applications])

    def finished(sim) -> bool:
        return bool(not sim.moving.any() and np.all(sim.time_s >= sim.stop_time_s + end_after_stop))

    return model, simulate_grid(model, pressure, step, finished, before_step=schedule, simulator_class=simulator_class)


def _sensor_channels(recordings: Sequence[Recording], model, grid, decel_source: str) -> list[dict[str, np.ndarray]]:
    """Each recording's channels as its sensors would report the run ``grid``, noise-free, at the
    recording's own sample instants."""
    return [
        MeasurementModel(grid, b, model, decel_source, INSTRUMENTED_DISC).channels(record.data[TIME].to_numpy())
        for b, record in enumerate(recordings)
    ]


def _imprint_sigmas(drawn: _DrawnSet, noise_scale: float) -> dict[str, float]:
    """Each channel's sensor noise (1 sigma) an effect's imprint is measured in: the set's own,
    the nominal one when the set is written noise-free."""
    scale = noise_scale if noise_scale > 0 else 1.0
    if drawn.chain is not None:
        chains = drawn.chain.channels.by_column()
        # A channel logged without noise has no unit to measure an imprint in.
        return {
            channel: chains[channel].noise_sigma * scale
            for channel in (SPEED, DECEL, DISC_TEMPERATURE, POSITION)
            if chains[channel].noise_sigma > 0
        }
    return {
        SPEED: SENSOR_NOISE[SPEED] * scale,
        DECEL: SENSOR_NOISE[f"decel_mps2_{drawn.decel_source}"] * scale,
        DISC_TEMPERATURE: SENSOR_NOISE[DISC_TEMPERATURE] * scale,
        POSITION: SENSOR_NOISE[POSITION] * scale,
    }


def _imprint(
    with_effect: Sequence[dict[str, np.ndarray]],
    without_effect: Sequence[dict[str, np.ndarray]],
    sigma: Mapping[str, float],
) -> dict[str, Any]:
    """What an effect leaves in the recordings: the noise-free channels with it against those of
    the same runs without it (:func:`_sensor_channels`), in units of each channel's sensor noise
    ``sigma`` (:func:`_imprint_sigmas`).

    ``expressed`` is false when no sample of any channel moves by IMPRINT_EXPRESSED_OVER_NOISE
    noise sigmas or more: such an effect (a fade onset above every temperature the discs reached,
    an adhesion limit above every deceleration demanded) is not in the data, and no diagnosis can
    be asked to find it."""
    sum_squares = {channel: 0.0 for channel in sigma}
    largest = {channel: 0.0 for channel in sigma}
    samples = 0
    for with_channels, without_channels in zip(with_effect, without_effect):
        samples += len(with_channels[SPEED])
        for channel, s in sigma.items():
            change = (with_channels[channel] - without_channels[channel]) / s
            sum_squares[channel] += float(np.sum(change**2))
            largest[channel] = max(largest[channel], float(np.max(np.abs(change))))
    max_over_noise = max(largest.values())
    return {
        "max_change_over_noise": {channel: round(value, 3) for channel, value in largest.items()},
        "rms_change_over_noise": {
            channel: round(math.sqrt(value / samples), 4) for channel, value in sum_squares.items()
        },
        "expressed": bool(max_over_noise >= IMPRINT_EXPRESSED_OVER_NOISE),
    }


def _cylinder_pressure_bar(app: Application, cylinder: BrakeCylinder, time_s: np.ndarray) -> np.ndarray:
    """The exact cylinder response to the command: nothing before command + dead time, then the
    first-order lag towards the commanded pressure (what the truth simulation integrates)."""
    elapsed = np.maximum(time_s - app.command_time_s - cylinder.dead_time_s, 0.0)
    return app.axle_pressure_bar[None, :] * (1.0 - np.exp(-elapsed / cylinder.time_constant_s))[:, None]


def _measure(
    app: Application,
    index: int,
    grid,
    model,
    cylinder: BrakeCylinder,
    decel_source: str,
    stop_time_s: float,
    noise_seed: np.random.SeedSequence,
    vehicle: cfg.Vehicle,
    noise_scale: float,
    gradient_profile: GradientProfile | None = None,
) -> Recording:
    noise = {name: sigma * noise_scale for name, sigma in SENSOR_NOISE.items()}
    streams = [np.random.default_rng(s) for s in noise_seed.spawn(7)]
    end = stop_time_s + app.standstill_s
    n_samples = int(math.floor(end / SAMPLE_INTERVAL_S)) + 1
    jitter = streams[0].uniform(-SAMPLE_JITTER_S, SAMPLE_JITTER_S, size=n_samples)
    jitter[0] = 0.0
    time = _round(np.arange(n_samples) * SAMPLE_INTERVAL_S + jitter, RESOLUTION[TIME])
    time = time[time <= end]
    measurement = MeasurementModel(grid, index, model, decel_source, INSTRUMENTED_DISC)
    true = measurement.channels(time)
    n = len(time)
    moving = time < stop_time_s

    speed_noise = streams[1].standard_normal(n) * noise[SPEED]
    decel_noise = streams[2].standard_normal(n) * noise[f"decel_mps2_{decel_source}"]
    temperature_noise = streams[3].standard_normal(n) * noise[DISC_TEMPERATURE]
    position_noise = streams[4].standard_normal(n) * noise[POSITION]
    pressure_noise = streams[5].standard_normal((n, vehicle.n_axles)) * noise["p_c_bar"]
    dropouts = streams[6].random((n, 3)) < DROPOUT_PROBABILITY
    dropouts[0] = False

    data: dict[str, np.ndarray] = {TIME: time}
    # A pulse-counting speed sensor reports a magnitude, and nothing at all once the wheels stand.
    data[SPEED] = _round(np.where(moving, np.abs(true[SPEED] + speed_noise), 0.0), RESOLUTION[SPEED])
    low, high = PRESSURE_TRANSDUCER_RANGE_BAR
    pressures = np.clip(_cylinder_pressure_bar(app, cylinder, time) + pressure_noise, low, high)
    for axle in range(vehicle.n_axles):
        data[pressure_column(axle + 1)] = _round(pressures[:, axle], RESOLUTION["p_c_bar"])
    for column, (channel, noise) in enumerate(
        ((DECEL, decel_noise), (DISC_TEMPERATURE, temperature_noise), (POSITION, position_noise))
    ):
        values = _round(true[channel] + noise, RESOLUTION[channel])
        data[channel] = np.where(dropouts[:, column], np.nan, values)
    return Recording(stem=app.stem, metadata=_metadata(app, decel_source, gradient_profile), data=pd.DataFrame(data))


def _run_profile(profile: GradientProfile | None, app: Application) -> GradientProfile | None:
    """The gradient profile under ``app``'s run: the set's profile from its first sample, or, for
    an application placed on the line, its run's part of the profile in line positions."""
    if profile is None or app.line_position_m is None:
        return profile
    return LineGradientProfile(**profile.model_dump()).along_run(app.line_position_m, app.line_direction_sign)


def _metadata(app: Application, decel_source: str, gradient_profile: GradientProfile | None) -> RecordingMetadata:
    """What a synthetic recording says was measured (no ``initial_disc_C``: the first disc
    temperature sample, if any, gives it), and the line's gradient profile where it is known: in
    line positions for an application placed on the line."""
    on_line = app.line_position_m is not None and gradient_profile is not None
    return RecordingMetadata(
        vehicle=VEHICLE,
        load=app.load,
        brake_mode=app.brake_mode,
        actuation=app.actuation,
        instrumented_disc=INSTRUMENTED_DISC,
        ambient_C=app.ambient_C,
        decel_source=decel_source,
        pad_set=app.pad_set,
        gradient_profile=None if on_line else gradient_profile,
        line_gradient_profile=LineGradientProfile(**gradient_profile.model_dump()) if on_line else None,
        line_position_m=app.line_position_m,
        line_direction=app.line_direction,
    )


def _scaled_noise(chain: MeasurementChain, noise_scale: float) -> MeasurementChain:
    """``chain`` with every channel's noise level times ``noise_scale`` (offsets, quantisation
    and dropouts as they are)."""
    channels = {
        name: getattr(chain.channels, name).model_copy(
            update={"noise_sigma": getattr(chain.channels, name).noise_sigma * noise_scale}
        )
        for name in type(chain.channels).model_fields
    }
    return chain.model_copy(update={"channels": chain.channels.model_copy(update=channels)})


def _measure_through_chain(
    drawn: _DrawnSet, index: int, grid: GridTrajectory, model: EffectedModel, stop_time_s: float, noise_scale: float
) -> tuple[Recording, dict[str, Any]]:
    """Application ``index`` logged through the set's measurement chain (:func:`.logger.log_run`):
    the recording, and what the key records of its chain (each sensor's offset, each channel's
    first sample instant)."""
    assert drawn.chain is not None
    app, cylinder = drawn.applications[index], drawn.cylinders[index]
    measurement = MeasurementModel(grid, index, model, drawn.decel_source, INSTRUMENTED_DISC)

    def sensed(channel: str):
        return lambda time_s: measurement.channels(time_s)[channel]

    # In the clean table's column order: speed, pressures, then the optional channels.
    true_values = {SPEED: sensed(SPEED), PRESSURES: lambda time_s: _cylinder_pressure_bar(app, cylinder, time_s)}
    true_values.update({channel: sensed(channel) for channel in (DECEL, DISC_TEMPERATURE, POSITION)})
    columns = {channel: [channel] for channel in true_values}
    columns[PRESSURES] = [pressure_column(axle + 1) for axle in range(drawn.vehicle.n_axles)]
    low, high = PRESSURE_TRANSDUCER_RANGE_BAR
    outputs = {
        # A pulse-counting speed sensor reports a magnitude, and nothing at all once the wheels stand.
        SPEED: lambda time_s, reading: np.where(time_s < stop_time_s, np.abs(reading), 0.0),
        PRESSURES: lambda time_s, reading: np.clip(reading, low, high),
    }
    chain = _scaled_noise(drawn.chain, noise_scale)
    end_s = stop_time_s + app.standstill_s
    table, offsets = log_run(chain, drawn.noise_seeds[index], true_values, columns, end_s, outputs)
    chains = chain.channels.by_column()
    truth = {
        "offsets": {
            channel: [round(float(v), 6) for v in values]
            for channel, values in offsets.items()
            if chains[channel].offset_sigma > 0
        },
        "first_sample_s": {
            column: float(table[TIME][np.flatnonzero(~np.isnan(table[column]))[0]])
            for column in (SPEED, DECEL, DISC_TEMPERATURE, POSITION)
            if (~np.isnan(table[column])).any()
        },
    }
    record = Recording(
        stem=app.stem,
        metadata=_metadata(app, drawn.decel_source, drawn.declared_gradient_profile),
        data=pd.DataFrame(table),
    )
    return record, truth
