import importlib.util
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

GOLDEN = Path(__file__).resolve().parent / "golden"
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture(scope="session")
def golden_dir() -> Path:
    """The golden reference values (``tests/golden/PROVENANCE.md`` says where they come from)."""
    return GOLDEN


@pytest.fixture(scope="session")
def naming_rules():
    """The diagnosis's rules without its bootstrap, for tests of what it names and fits rather
    than of its intervals: the bootstrap runs after the verdict and changes no name, and with
    its interval ends tested it costs up to three times a fade's diagnosis. The intervals have
    tests of their own (``test_diagnosis_bootstrap.py``, and the diagnoses that check ``ci95``)."""
    from brakegym.diagnosis import DiagnosisRules

    return DiagnosisRules(bootstrap_replicates=0)


@pytest.fixture(scope="session")
def load_benchmark() -> Callable[[str], ModuleType]:
    """Imports a script of ``benchmarks/`` (not a package) by name, for tests of its bookkeeping."""

    def load(name: str) -> ModuleType:
        if name not in sys.modules:
            spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{name}.py")
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            spec.loader.exec_module(module)
        return sys.modules[name]

    return load


@pytest.fixture(scope="session")
def simulate_one_stop() -> Callable[..., tuple]:
    """One emu_8axle application, empty, from 25 m/s at a constant 3.3 bar from t = 0 to
    standstill with 50 degC discs, under ``effects`` and any extra hooks, beginning
    ``line_position_at_start_m`` along the line and running ``line_direction_sign`` along it:
    returns the effected model and the simulated grid (tests of effects on part of the line)."""
    from brakegym import config as cfg
    from brakegym.effects import apply_effects
    from brakegym.plants import train_plant
    from brakegym.recordings.replay import simulate_grid
    from brakegym.simulator import BatchConditions, PrescribedPressure

    vehicle = cfg.load("vehicles", "emu_8axle")
    material = cfg.load("materials", vehicle.material)
    plant = train_plant(vehicle)
    shape = (1, *plant.disc_shape)

    def run(
        effects=(),
        extra_forces=(),
        friction_modifiers=(),
        pressure_bar: float = 3.3,
        wheel_brake_forces=(),
        line_position_at_start_m: float = 0.0,
        line_direction_sign: float = 1.0,
    ):
        conditions = BatchConditions(
            mass_kg=np.full(1, vehicle.mass_kg("empty")),
            initial_speed_mps=np.full(1, 25.0),
            initial_mu=np.full(shape, material.initial_mu),
            power_coefficient_per_s=np.full(shape, material.power_coefficient_per_s),
            running_resistance_A_N=np.full(1, vehicle.running_resistance.A_N),
            initial_friction_temperature_K=np.full(shape, 323.15),
            initial_disc_temperature_K=np.full(shape, 323.15),
            ambient_temperature_K=np.full(1, 293.15),
        )
        model = apply_effects(
            plant,
            conditions,
            list(effects),
            wheel_brake_forces=wheel_brake_forces,
            line_position_at_start_m=np.full(1, line_position_at_start_m),
            line_direction_sign=np.full(1, line_direction_sign),
        )
        model.extra_forces.extend(extra_forces)
        model.friction_modifiers.extend(friction_modifiers)
        trace = np.full((2, 1, vehicle.n_axles), pressure_bar)
        grid = simulate_grid(
            model, PrescribedPressure(np.array([0.0, 1.0]), trace, 0.1), 0.1, lambda sim: not sim.moving.any()
        )
        return model, grid

    return run


@pytest.fixture(scope="session")
def synth_train_like() -> Callable[..., object]:
    """Writes a set of the diagnosis's train-like blind benchmark to ``folder``: 8 recordings of
    set ``seed`` through the measurement chain ``real`` with the model form ``real_train``, its
    effects drawn (``random_effects``) as ``brakegym synth --random-effects`` draws them; returns
    the :class:`~brakegym.recordings.synth.SynthResult`."""
    from brakegym.recordings.chain import load_measurement_chain
    from brakegym.recordings.model_form import load_model_form
    from brakegym.recordings.synth import synthesize

    def synth(folder: Path, seed: int, random_effects: bool = True):
        return synthesize(
            folder,
            8,
            seed=seed,
            random_effects=random_effects,
            measurement_chain=load_measurement_chain("real"),
            model_form=load_model_form("real_train"),
        )

    return synth
