"""The wheel-slide protection test of UIC 541-05 / EN 15595 as the simulator runs it
(docs/adhesion.md, "WSP test"): an emergency stop on a low-adhesion rail (or a line of sections)
with a WSP, the same stop on the dry rail for the reference distance, and what the standards judge
a WSP by: the extension of the stopping distance, the adhesion utilisation, the longest time an
axle stayed locked and the energy the treads dissipated sliding on the rail.

:func:`wsp_test` runs it; :func:`resolve_wsp` turns a WSP name, a controller YAML or a policy
folder into the controller factory :func:`~brakegym.wheel_slide.wsp_train_stops` takes;
:class:`WspTraces` records each step's speeds, pressures, creeps and adhesion used and available,
and sums the adhesion utilisation (:data:`ADHESION_UTILISATION_DEFINITION`).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import config as cfg
from .applications import MAX_STOP_TIME_S, TrainApplication
from .physics import PolachLaw
from .physics.adhesion import creep
from .plants import rail_friction_factor_for_samples, train_scatter, wheel_rail_adhesion
from .simulator import wheelset_kernel
from .simulator.state import MU, POSITION, SPEED
from .simulator.wheelsets import AdhesionSimulator, WheelRailAdhesion
from .units import STANDARD_GRAVITY_MPS2, kmh_to_mps
from .wheel_slide import (
    DEFAULT_CONTROL_STEP_S,
    LOCKED_MIN_TRAIN_SPEED_MPS,
    LOCKED_SPEED_RATIO,
    wsp_train_stops,
)

#: The rail the stopping distance is extended against.
DRY_CONDITION = "dry"
#: The reference controller's configs by the WSP names ``--wsp`` takes for them.
WSP_CONFIGS = {"reference": "wsp", "reference-true-speed": "wsp-true-speed"}
#: The WSP name for no WSP (the valves at rest).
NO_WSP = "none"
#: The WSP name of the PPO policy shipped for ``WheelSlideProtection-v0``, and its folder in
#: ``brakegym.agents``' ``policies/``.
SHIPPED_POLICY = "ppo"
SHIPPED_POLICY_FOLDER = "wheel_slide_protection_ppo"
#: The test's brake application, the emergency brake through the EP brake control.
TEST_BRAKE_MODE = "emergency"
TEST_ACTUATION = "EP"
#: The scatter set-up the friction of a seeded test is drawn in (every disc on its own).
DEFAULT_SCATTER_SETUP = "mcs-100"
# The table of available adhesion: its speeds (0 to a little above v0) and the creeps searched.
_PEAK_TABLE_POINTS = 241
_PEAK_TABLE_CREEPS = 4001

#: Where the adhesion utilisation's definition comes from, as the JSON says it.
ADHESION_UTILISATION_SOURCE = (
    "Neither UIC 541-05 nor EN 15595 was at hand: their text is sold, not public, and no public page "
    "gave their formula. Public descriptions of both say a WSP is judged by how much of the available "
    "adhesion it uses and by how far it extends the stopping distance under degraded adhesion (EN "
    "15595 scope: 'minimize the extension of the stopping distance under degraded adhesion conditions "
    "by optimizing the available adhesion between wheel and rail'; a summary of UIC 541-05 at "
    "railwaynews.net quotes an adhesion utilisation above 85 % as the pass mark). The definition "
    "below is brakegym's, written to match that description; it is not quoted from either standard."
)
#: The adhesion utilisation eta the test reports, as the JSON says it.
ADHESION_UTILISATION_DEFINITION = (
    "eta = integral of sum_i F_i ds / integral of sum_i min(F_peak,i, (M / m) F_brake,i) ds over the "
    "stop: the distance-weighted mean of the adhesion used (creep force F_i of axle i over its wheel "
    "load) over the mean of the adhesion available to it. F_peak,i = 2 Q_w max_s f(s, s v) is the "
    "peak of the rail's creep-force law at the train speed v and the wheel load Q_w; it is capped at "
    "what the brake can put on the rail with the wheels rolling, (M / m) F_brake,i, F_brake,i = sum "
    "over the axle's discs of mu F_C(p_supply) r_fric / r at the brake control's pressure (before the "
    "WSP valves), M / m the body's share of the effective mass (the rest of the brake torque "
    "decelerates the wheelsets). Where the brake asks more than the rail gives (the WSP test) the cap "
    "never acts and eta is the adhesion used over the peak; on a rail that gives more, eta is the "
    "share of the brake's demand that reached the rail (1 when nothing slides). The distance "
    "weighting makes the mean adhesion used the deceleration a test track measures from the stopping "
    "distance, v0^2 / (2 g s), less the running resistance."
)


# ------------------------------------------------------------------------------------------------
# The WSP


@dataclass(frozen=True)
class WspChoice:
    """A WSP as the test runs it: its name in the report and the controller factory
    ``make_controller(valve_of_axle, control_step_s)`` (None: no WSP)."""

    label: str
    make_controller: Callable | None


def _agents_module(wsp: str, name: str):
    """``brakegym.agents.<name>``, which a trained policy needs, or an error naming the ``--wsp``
    that asked for it."""
    try:
        return importlib.import_module(f"brakegym.agents.{name}")
    except ModuleNotFoundError as error:
        if error.name != f"brakegym.agents.{name}":
            raise
        raise cfg.ConfigError(
            f"--wsp {wsp}: read as a trained WSP policy; policies need brakegym.agents.{name}, "
            "which this installation lacks"
        ) from None


def resolve_wsp(spec: str | Path) -> WspChoice:
    """``none``, ``reference`` (``configs/agents/wsp.yaml``), ``reference-true-speed``, ``ppo``
    (the policy shipped for ``WheelSlideProtection-v0``), a YAML file of the reference controller's
    kind (:class:`brakegym.agents.wsp.WspControllerConfig`), or a trained policy folder (loaded by
    ``brakegym.agents.wsp_policy.load_wsp_controller``)."""
    text = str(spec)
    if text == NO_WSP:
        return WspChoice(NO_WSP, None)
    from .agents import wsp as reference

    if text in WSP_CONFIGS:
        config = reference.load_wsp_config(WSP_CONFIGS[text])
        return WspChoice(text, functools.partial(reference.WspController, config))
    if text == SHIPPED_POLICY:
        folder = _agents_module(text, "rl").shipped_policies().joinpath(SHIPPED_POLICY_FOLDER)
        if not folder.joinpath("training.json").is_file():
            raise cfg.ConfigError(f"--wsp {text}: this installation ships no WSP policy ({folder})")
        return WspChoice(SHIPPED_POLICY, _agents_module(text, "wsp_policy").load_wsp_controller(folder))
    path = Path(text)
    if path.is_dir():
        return WspChoice(str(path), _agents_module(text, "wsp_policy").load_wsp_controller(path))
    if path.suffix in (".yaml", ".yml"):
        if not path.is_file():
            raise cfg.ConfigError(f"--wsp {text}: no such file")
        config = reference.load_wsp_config(path)
        return WspChoice(str(path), functools.partial(reference.WspController, config))
    known = ", ".join([NO_WSP, *WSP_CONFIGS, SHIPPED_POLICY])
    raise cfg.ConfigError(f"--wsp {text!r}: not a WSP name ({known}), a controller YAML file or a policy folder")


# ------------------------------------------------------------------------------------------------
# The rail and its scatter


def load_rail(condition: str | None, line: str | None) -> cfg.RailCondition | cfg.Line:
    """The rail of the test: a rail condition (``configs/rail_conditions/``) or a line of sections
    (``configs/lines/``), exactly one of them."""
    if (condition is None) == (line is None):
        raise cfg.ConfigError("give either a rail condition or a line, not both or neither")
    return cfg.load("lines", line) if line is not None else cfg.load("rail_conditions", condition)


def seeded_adhesion(
    vehicle: cfg.Vehicle, rail: cfg.RailCondition | cfg.Line, seed: int | None, with_load_transfer: bool = False
) -> WheelRailAdhesion:
    """The adhesion option of ``vehicle`` on ``rail`` (with load transfer between its axles if
    asked, :func:`~brakegym.plants.wheel_rail_adhesion`); with a ``seed``, the rail's mu_0 scaled by
    the factor a campaign seeded so draws for its stop 0
    (:func:`~brakegym.plants.rail_friction_factor_for_samples`: lognormal, mean 1, one factor for
    a whole line, the same day's rail)."""
    adhesion = wheel_rail_adhesion(vehicle, rail, with_load_transfer)
    if seed is None:
        return adhesion
    factor = rail_friction_factor_for_samples(rail, seed, np.zeros(1, dtype=np.int64))
    return dataclasses.replace(adhesion, static_friction_factor=(float(factor[0]),))


# ------------------------------------------------------------------------------------------------
# Adhesion available


class PeakAdhesionTable:
    """The peak F / Q of each rail section's law over the train speed (0 to a little above
    ``max_speed_mps``) at one wheel load, interpolated linearly in speed; of one train's rail
    (its ``static_friction_factor`` on every section's mu_0). Under an axle whose mu_0 the rail's
    conditioning raises by g the peak at v is g times the section's at g v (Polach's law with mu_0
    times g: the creep s = g s' maps the curves, tested in tests/test_adhesion.py)."""

    def __init__(self, adhesion: WheelRailAdhesion, n_axles: int, wheel_load_N: float, max_speed_mps: float):
        starts, parameters, offsets = adhesion.rail_table(n_axles)
        factors = adhesion.static_friction_factor
        if factors is not None and len(factors) != 1:
            raise ValueError(f"static_friction_factor {factors}: the table is of one train's rail, give one factor")
        laws = parameters[:, : wheelset_kernel.N_LAW_PARAMETERS].copy()
        laws[:, 0] *= 1.0 if factors is None else factors[0]
        self.conditioning = parameters[:, wheelset_kernel.AXLE_CONDITIONING :]  # (S, A)
        self.starts_m, self.axle_offsets_m = starts, offsets
        reach = float(self.conditioning.max())
        self.speeds_mps = np.linspace(0.0, reach * (1.05 * max_speed_mps + 1.0), _PEAK_TABLE_POINTS)
        stiffness = adhesion.contact.creep_stiffness_N(wheel_load_N)
        self.peaks = np.array(
            [
                [
                    PolachLaw(*row).peak_adhesion(v, wheel_load_N, stiffness, n_creeps=_PEAK_TABLE_CREEPS)[0]
                    for v in self.speeds_mps
                ]
                for row in laws
            ]
        )

    def section_of(self, position_m: np.ndarray) -> np.ndarray:
        """The section index under each axle (A, B) for train positions (B,)."""
        axle_position = np.asarray(position_m)[None, :] - self.axle_offsets_m[:, None]
        return np.maximum(np.searchsorted(self.starts_m, axle_position, side="right") - 1, 0)

    def peak(self, speed_mps: np.ndarray, section: np.ndarray) -> np.ndarray:
        """The peak F / Q at train speeds (B,) in sections (A, B), under each axle: (A, B)."""
        factor = np.take_along_axis(self.conditioning.T, section, axis=1)  # (A, B)
        peak = np.zeros(section.shape)
        for index, row in enumerate(self.peaks):
            in_section = section == index
            scaled = factor * np.interp(factor * np.asarray(speed_mps)[None, :], self.speeds_mps, row)
            peak = np.where(in_section, scaled, peak)
        return peak


#: The ideal (perfect-WSP) stop the test reports, as the JSON says it.
IDEAL_DISTANCE_DEFINITION = (
    "the stop of a perfect WSP: every axle at every moment as much force as the rail and the brake "
    "allow, dv/dt = -min((m g mean_i peak_i(v, x) + F_R(v)) / M, (D(t) + F_R(v)) / m): the rail's "
    "peak adhesion under each axle decelerating the body (mass M = m - n J / r^2), or the brake's "
    "demand D(t) (sum over the axles of mu F_C(p_supply) r_fric / r, from the dry stop at the same "
    "time after the command, so the brake's response is in it) decelerating body and wheelsets "
    "(effective mass m), whichever is less. On a rail where the brake asks more than the rail gives "
    "it is the adhesion-limited stop after the brake's response; on the dry rail it is the dry stop."
)


def ideal_distance_m(
    table: PeakAdhesionTable,
    body_mass_kg: float,
    mass_kg: float,
    resistance: cfg.RunningResistance,
    resistance_A_N: float,
    initial_speed_mps: float,
    demand_time_s: np.ndarray,
    demand_N: np.ndarray,
    command_time_s: float = 0.0,
    time_step_s: float = 0.01,
) -> float:
    """The distance of :data:`IDEAL_DISTANCE_DEFINITION` from the brake command at
    ``command_time_s``, the train running from ``initial_speed_mps`` at time 0 (coasting on its
    running resistance until the demand rises), by the midpoint rule in time; ``demand_N``
    (steps,) the train's total demand at ``demand_time_s``, held beyond both ends; the last step
    is cut where the speed reaches zero."""
    demand_time_s, demand_N = np.asarray(demand_time_s, dtype=float), np.asarray(demand_N, dtype=float)
    weight_N = mass_kg * STANDARD_GRAVITY_MPS2

    def deceleration(t: float, x: float, v: float) -> float:
        v = max(v, 0.0)
        peak = float(table.peak(np.array([v]), table.section_of(np.array([x]))).mean())
        running = resistance_A_N + v * (resistance.B_N_per_mps + resistance.C_N_per_mps2 * v)
        brake = float(np.interp(t, demand_time_s, demand_N))
        return min((peak * weight_N + running) / body_mass_kg, (brake + running) / mass_kg)

    t, x, v = 0.0, 0.0, float(initial_speed_mps)
    position_at_command_m = 0.0 if command_time_s <= 0 else None
    while True:
        a0 = deceleration(t, x, v)
        half_v = v - 0.5 * time_step_s * a0
        a = deceleration(t + 0.5 * time_step_s, x + 0.5 * time_step_s * v, half_v)
        if position_at_command_m is None and t + time_step_s > command_time_s:
            position_at_command_m = x + (command_time_s - t) * half_v
        if a * time_step_s >= v:
            # Uniform deceleration over the rest of the last step.
            return x + 0.5 * v * v / a - position_at_command_m
        x += time_step_s * half_v
        v -= time_step_s * a
        t += time_step_s
        if t > MAX_STOP_TIME_S:
            raise RuntimeError(f"the ideal stop from {initial_speed_mps} m/s never ends: no brake demand")


# ------------------------------------------------------------------------------------------------
# Traces


class WspTraces:
    """After each step of an :class:`~brakegym.simulator.wheelsets.AdhesionSimulator` under WSP
    valves: time, position, train and wheel speeds, cylinder and supply pressures, each axle's
    creep, the adhesion it uses (creep force over its two wheels' load), the peak adhesion
    available and the brake's demand (both as F / Q); and the sums of
    :data:`ADHESION_UTILISATION_DEFINITION`. One row per step, the trains of the batch side by
    side (the test runs one)."""

    def __init__(self, table: PeakAdhesionTable) -> None:
        self.table = table
        self.rolling_share = np.ones(0)  # M / m per train: the brake force's share that reaches the rail
        self.rows: dict[str, list[np.ndarray]] = {
            name: []
            for name in (
                "time_s",
                "position_m",
                "speed_mps",
                "wheel_speed_mps",
                "pressure_bar",
                "supply_bar",
                "creep",
                "adhesion_used",
                "adhesion_available",
                "adhesion_demanded",
            )
        }

    def update(self, sim: AdhesionSimulator) -> None:
        speed, position = sim.train[SPEED].copy(), sim.train[POSITION].copy()
        wheels = sim.wheel_speed_mps.copy()  # (A, B)
        axle_load_N = 2.0 * sim.axle_wheel_load_N  # (A, B): each axle's own with load transfer
        law = sim.rail_law_at(position)
        used = sim.creep_force_N(speed, wheels, law) / axle_load_N
        available = self.table.peak(speed, self.table.section_of(position))
        supply = np.asarray(getattr(sim.pressure, "supply_bar", sim.pressure.pressure_bar), dtype=float)
        demand_N = (sim.disc[MU] * sim.clamp_force_N(supply)).sum(axis=1) * sim.plant.radius_ratio
        self.rolling_share = sim.body_mass_kg / sim.mass_kg
        rows = self.rows
        rows["time_s"].append(np.full(speed.shape, sim.time_s))
        rows["position_m"].append(position)
        rows["speed_mps"].append(speed)
        rows["wheel_speed_mps"].append(wheels.T)
        rows["pressure_bar"].append(np.array(sim.pressure.pressure_bar, dtype=float))
        rows["supply_bar"].append(supply.copy())
        rows["creep"].append(creep(speed, wheels, sim.adhesion.regularisation_speed_mps).T)
        rows["adhesion_used"].append(used.T)
        rows["adhesion_available"].append(available.T)
        rows["adhesion_demanded"].append((demand_N / axle_load_N).T)

    def arrays(self, train: int = 0) -> dict[str, np.ndarray]:
        """Train ``train``'s traces: (steps,) or (steps, axles)."""
        return {name: np.stack(values)[:, train] for name, values in self.rows.items()}

    def adhesion_utilisation(self, train: int = 0) -> float:
        """eta of :data:`ADHESION_UTILISATION_DEFINITION` from the recorded steps (trapezoid rule
        in position; the samples before the first step carry no brake force)."""
        traces = self.arrays(train)
        step_m = np.diff(traces["position_m"])
        used = traces["adhesion_used"].sum(axis=1)
        reaching_rail = self.rolling_share[train] * traces["adhesion_demanded"]
        available = np.minimum(traces["adhesion_available"], reaching_rail).sum(axis=1)
        used_m = float(np.sum(0.5 * (used[1:] + used[:-1]) * step_m))
        available_m = float(np.sum(0.5 * (available[1:] + available[:-1]) * step_m))
        return used_m / available_m if available_m > 0 else float("nan")


# ------------------------------------------------------------------------------------------------
# The test


@dataclass
class WspTestResult:
    """What :func:`wsp_test` found: :meth:`as_json` gives the command's JSON; ``traces`` the test
    stop's traces (:meth:`WspTraces.arrays`)."""

    report: dict[str, object]
    traces: dict[str, np.ndarray]

    def as_json(self) -> dict[str, object]:
        """The command's JSON: the stable keys, what was asked and the definitions used."""
        return self.report


def wsp_test(
    vehicle_name: str,
    load: str,
    v0_kmh: float,
    wsp: str | Path,
    condition: str | None = None,
    line: str | None = None,
    seed: int | None = None,
    setup: str = DEFAULT_SCATTER_SETUP,
    valves: str = "axle",
    control_step_s: float = DEFAULT_CONTROL_STEP_S,
    load_transfer: bool = False,
) -> WspTestResult:
    """The WSP test: an emergency EP stop of ``vehicle_name`` (``load``) from ``v0_kmh`` on the
    rail ``condition`` (or the ``line``) with the WSP ``wsp`` (:func:`resolve_wsp`) on the
    ``valves``, and the same stop with the same WSP on the dry rail for the reference distance.

    Without ``seed`` the nominal stop; with it, the discs' friction and the running resistance
    drawn as sample 0 of a campaign seeded ``seed`` in the set-up ``setup``
    (:meth:`~brakegym.plants.TrainScatter.draw_for_samples`) and the rail's mu_0 from the seed's
    rail stream (:func:`seeded_adhesion`); both stops share the stream. ``load_transfer``: both stops
    with the load transfer between the axles while braking (docs/adhesion.md, "Load transfer")."""
    if not (np.isfinite(v0_kmh) and v0_kmh > 0):
        raise ValueError(f"v0 = {v0_kmh} km/h: must be a positive speed")
    vehicle = cfg.load("vehicles", vehicle_name)
    mass_kg = vehicle.mass_kg(load)
    vehicle.brake_pressure_bar(TEST_BRAKE_MODE, load)
    rail = load_rail(condition, line)
    dry = cfg.load("rail_conditions", DRY_CONDITION)
    valve_set = cfg.load("wsp_valves", valves)
    choice = resolve_wsp(wsp)

    scatter_setup = cfg.load("setups", setup)  # checked even when unused: a bad name is a mistake
    if seed is None:
        draw, resistance_A_N = None, np.array([vehicle.running_resistance.A_N])
    else:
        scatter = train_scatter(vehicle, scatter_setup)
        draw, resistance_A_N = scatter.draw_for_samples(seed, np.zeros(1, dtype=np.int64))
    application = [TrainApplication(load, TEST_BRAKE_MODE, TEST_ACTUATION, float(v0_kmh))]
    command_time_s = application[0].command_time_s
    v0_mps = kmh_to_mps(v0_kmh)
    wheel_load_N = mass_kg * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)

    def stop(adhesion: WheelRailAdhesion):
        table = PeakAdhesionTable(adhesion, vehicle.n_axles, wheel_load_N, v0_mps)
        traces = WspTraces(table)
        stops = wsp_train_stops(
            vehicle,
            application,
            adhesion,
            valve_set,
            choice.make_controller,
            control_step_s,
            draw=draw,
            running_resistance_A_N=resistance_A_N,
            observers=[traces],
        )
        return stops, traces, table

    adhesion = seeded_adhesion(vehicle, rail, seed, load_transfer)
    test, traces, table = stop(adhesion)
    reference, dry_traces, _ = stop(seeded_adhesion(vehicle, dry, seed, load_transfer))
    dry_trace = dry_traces.arrays()

    distance_m = float(test.summary.braking_distance_m[0])
    dry_distance_m = float(reference.summary.braking_distance_m[0])
    body_mass_kg = mass_kg - vehicle.n_axles * adhesion.wheelset_inertia_kgm2 / vehicle.wheel_radius_m**2
    ideal_m = ideal_distance_m(
        table,
        body_mass_kg,
        mass_kg,
        vehicle.running_resistance,
        float(resistance_A_N[0]),
        v0_mps,
        dry_trace["time_s"],
        dry_trace["adhesion_demanded"].sum(axis=1) * 2.0 * wheel_load_N,
        command_time_s,
    )
    longest_s, total_s = test.locked.longest_s[0], test.locked.total_s[0]
    slip_work_J = test.summary.slip_work_J[0]
    rail_name = f"line {rail.name}" if isinstance(rail, cfg.Line) else rail.name
    report: dict[str, object] = {
        "vehicle": vehicle.name,
        "load": load,
        "condition": None if isinstance(rail, cfg.Line) else rail.name,
        "line": rail.name if isinstance(rail, cfg.Line) else None,
        "wsp": choice.label,
        "valves": valve_set.name,
        "v0_kmh": float(v0_kmh),
        "seed": seed,
        "scatter_setup": setup if seed is not None else None,
        "rail_static_friction_factor": None if seed is None else adhesion.static_friction_factor[0],
        "brake_mode": TEST_BRAKE_MODE,
        "actuation": TEST_ACTUATION,
        "control_step_s": control_step_s,
        "load_transfer": load_transfer,
        "stop_distance_m": distance_m,
        "stop_time_s": float(test.summary.braking_time_s[0]),
        "dry_stop_distance_m": dry_distance_m,
        "distance_extension_pct": 100.0 * (distance_m / dry_distance_m - 1.0),
        "ideal_distance_m": ideal_m,
        "ideal_distance_definition": IDEAL_DISTANCE_DEFINITION,
        "distance_over_ideal": distance_m / ideal_m,
        "adhesion_utilisation": traces.adhesion_utilisation(),
        "adhesion_utilisation_definition": ADHESION_UTILISATION_DEFINITION,
        "adhesion_utilisation_source": ADHESION_UTILISATION_SOURCE,
        "peak_adhesion_at_v0": float(table.peak(np.array([v0_mps]), table.section_of(np.zeros(1)))[0, 0]),
        "max_locked_time_s": float(longest_s.max()),
        "locked_time_longest_s": [float(x) for x in longest_s],
        "locked_time_total_s": [float(x) for x in total_s],
        "slide_energy_MJ": float(slip_work_J.sum()) / 1e6,
        "slide_energy_per_axle_MJ": [float(x) / 1e6 for x in slip_work_J],
        "dry_slide_energy_MJ": float(reference.summary.slip_work_J[0].sum()) / 1e6,
        "dry_max_locked_time_s": float(reference.locked.longest_s[0].max()),
        "locked_definition": f"an axle is locked while its wheel turns slower than {LOCKED_SPEED_RATIO:g} times "
        f"the train speed and the train runs faster than {LOCKED_MIN_TRAIN_SPEED_MPS:g} m/s "
        "(brakegym.wheel_slide.LockedTimeObserver)",
        "rail": rail_name,
    }
    # The traces from the brake command on, in time and position.
    arrays = traces.arrays()
    position_at_command_m = float(np.interp(command_time_s, arrays["time_s"], arrays["position_m"]))
    arrays["time_s"] = arrays["time_s"] - command_time_s
    arrays["position_m"] = arrays["position_m"] - position_at_command_m
    return WspTestResult(report, arrays)
