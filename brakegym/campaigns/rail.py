"""The field campaign on a rail condition: its stops with wheel-rail adhesion, each stop on its own
rail (mu_0 scattered per stop), through wheel-slide protection or none (docs/adhesion.md).

Stop ``i`` is the field campaign's stop ``i`` (:mod:`.field`: the same application, the same
friction and running-resistance draws) on a rail whose mu_0 is the condition's times a factor drawn
from the seed and ``i`` alone (:func:`brakegym.plants.rail_friction_factor_for_samples`), run by
:func:`brakegym.wheel_slide.wsp_train_stops` at the WSP controller's step. So the rows are the
same bit for bit whatever the chunks and the executor, as the field campaign's are. The rows are
the field campaign's columns and :data:`RAIL_STOP_COLUMNS`.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import config as cfg
from ..applications import TrainApplication
from ..defaults import DEFAULT_CHUNK_STOPS
from ..execution import Executor
from ..execution.base import Progress
from ..plants import load_transfer as vehicle_load_transfer
from ..plants import (
    polach_law,
    rail_conditions_of,
    rail_friction_factor_for_samples,
    train_scatter,
    wheel_rail_adhesion,
    wheel_rail_contact,
)
from ..units import STANDARD_GRAVITY_MPS2
from ..wheel_slide import DEFAULT_CONTROL_STEP_S, wsp_train_stops
from .chunks import Chunk, even_chunks, run_chunks
from .field import STOP_COLUMNS, STOPS, FieldCampaignResult, field_applications, field_manifest, field_stop_columns
from .store import CampaignStore

#: The columns a rail campaign's stops add to the field campaign's (one row per stop).
RAIL_STOP_COLUMNS = (
    "rail_friction_factor",  # the stop's rail mu_0 over the condition's (on a line: every section's)
    "rail_static_friction",  # the stop's mu_0 (on a line: of the section with the lowest peak adhesion)
    "rail_peak_adhesion",  # the peak of that rail's creep curve at the stop's wheel load, 30 m/s
    "slide_energy_MJ",  # work of the treads sliding on the rail, all axles
    "longest_locked_s",  # the longest unbroken time an axle was locked (brakegym.wheel_slide.LockedTimeObserver)
    "locked_time_s",  # the total locked time of the axle locked longest in all
)
#: The train speed at which the rows' peak adhesion is given (the configs' ``peak_adhesion`` too).
PEAK_ADHESION_SPEED_MPS = 30.0


def governing_condition(vehicle: cfg.Vehicle, rail: cfg.RailCondition | cfg.Line) -> cfg.RailCondition:
    """The condition of ``rail`` with the lowest peak adhesion at ``vehicle``'s contact: the rail
    itself, or the slipperiest section of a line (the one the WSP has to master)."""
    conditions = rail_conditions_of(rail)
    if len(conditions) == 1:
        return conditions[0]
    load = vehicle.mass_kg("empty") * STANDARD_GRAVITY_MPS2 / (2 * vehicle.n_axles)
    stiffness = wheel_rail_contact(vehicle).creep_stiffness_N(load)
    peaks = [polach_law(c).peak_adhesion(PEAK_ADHESION_SPEED_MPS, load, stiffness)[0] for c in conditions]
    return conditions[int(np.argmin(peaks))]


@dataclass(frozen=True)
class RailFieldChunkTask:
    """The stops of a chunk of a field campaign on a rail, from the seed and the stops' numbers
    alone; ``wsp`` the controller's config (:class:`brakegym.agents.wsp.WspControllerConfig`) or
    None (no WSP, the valves at rest); ``load_transfer``: the axle loads move between and within
    the bogies with the deceleration (docs/adhesion.md, "Load transfer")."""

    vehicle: cfg.Vehicle
    applications: tuple[TrainApplication, ...]
    repetitions: int
    setup: cfg.ScatterSetup
    seed: int
    rail: cfg.RailCondition | cfg.Line
    valves: cfg.WspValves
    wsp: object | None
    control_step_s: float = DEFAULT_CONTROL_STEP_S
    load_transfer: bool = False

    def __call__(self, chunk: Chunk) -> dict[str, dict[str, np.ndarray]]:
        stop = chunk.sample_index()
        application = stop // self.repetitions
        apps = [self.applications[a] for a in application]
        draw, resistance = train_scatter(self.vehicle, self.setup).draw_for_samples(self.seed, stop)
        factor = rail_friction_factor_for_samples(self.rail, self.seed, stop)
        adhesion = dataclasses.replace(
            wheel_rail_adhesion(self.vehicle, self.rail, with_load_transfer=self.load_transfer),
            static_friction_factor=tuple(factor.tolist()),
        )
        make_controller = None
        if self.wsp is not None:
            from ..agents.wsp import WspController  # the agents package only where a WSP runs

            make_controller = functools.partial(WspController, self.wsp)
        stops = wsp_train_stops(
            self.vehicle,
            apps,
            adhesion,
            self.valves,
            make_controller,
            control_step_s=self.control_step_s,
            draw=draw,
            running_resistance_A_N=resistance,
        )
        summary, locked = stops.summary, stops.locked
        static_friction, peak = self._rail_of_stops(apps, factor)
        columns = {
            **field_stop_columns(stop, self.repetitions, resistance, summary),
            "rail_friction_factor": factor,
            "rail_static_friction": static_friction,
            "rail_peak_adhesion": peak,
            "slide_energy_MJ": summary.slip_work_J.sum(axis=1) * 1e-6,
            "longest_locked_s": locked.longest_s.max(axis=1),
            "locked_time_s": locked.total_s.max(axis=1),
        }
        return {STOPS: columns}

    def _rail_of_stops(self, apps: list[TrainApplication], factor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each stop's mu_0 and peak adhesion (the governing condition's, scaled by its factor) at
        its wheel load and :data:`PEAK_ADHESION_SPEED_MPS`."""
        law = polach_law(governing_condition(self.vehicle, self.rail))
        contact = wheel_rail_contact(self.vehicle)
        static_friction = law.static_friction * factor
        peaks = np.empty(len(apps))
        for k, app in enumerate(apps):
            load = self.vehicle.mass_kg(app.load) * STANDARD_GRAVITY_MPS2 / (2 * self.vehicle.n_axles)
            scaled = dataclasses.replace(law, static_friction=float(static_friction[k]))
            peaks[k] = scaled.peak_adhesion(
                PEAK_ADHESION_SPEED_MPS, load, contact.creep_stiffness_N(load), n_creeps=4001
            )[0]
        return static_friction, peaks


def rail_field_campaign(
    campaign: cfg.FieldCampaign,
    setup: cfg.ScatterSetup,
    seed: int,
    rail: cfg.RailCondition | cfg.Line,
    valves: cfg.WspValves,
    wsp=None,
    control_step_s: float = DEFAULT_CONTROL_STEP_S,
    executor: Executor | None = None,
    progress: Progress | None = None,
    chunk_size: int = DEFAULT_CHUNK_STOPS,
    out: str | Path | None = None,
    resume: bool = False,
    load_transfer: bool = False,
) -> FieldCampaignResult:
    """:func:`~.field.field_campaign` on ``rail`` (a rail condition or a line), with wheel-rail
    adhesion, each stop's rail scattered, through the WSP ``valves`` commanded by the controller
    of config ``wsp`` (:func:`brakegym.agents.wsp.load_wsp_config`; None: no WSP), at the step
    ``control_step_s``, with the axle loads' transfer during braking where ``load_transfer``
    (the vehicle needs its ``car_geometry``). The result's rows have the field campaign's columns
    and :data:`RAIL_STOP_COLUMNS`."""
    vehicle = cfg.load("vehicles", campaign.vehicle)
    applications = field_applications(campaign)
    task = RailFieldChunkTask(
        vehicle,
        tuple(applications),
        campaign.repetitions,
        setup,
        seed,
        rail,
        valves,
        wsp,
        control_step_s,
        load_transfer,
    )
    if load_transfer:
        vehicle_load_transfer(vehicle)  # a vehicle without its car geometry fails here, not in a worker
    chunks = even_chunks(len(applications) * campaign.repetitions, chunk_size)
    store = None
    if out is not None:
        manifest = field_manifest(campaign, vehicle, setup, seed, control_step_s, chunk_size, len(chunks))
        configs = manifest["configs"]
        assert isinstance(configs, dict)
        configs["rail"] = rail.model_dump(mode="json")
        configs["rail_conditions"] = [c.model_dump(mode="json") for c in rail_conditions_of(rail)]
        configs["wsp_valves"] = valves.model_dump(mode="json")
        configs["wsp"] = None if wsp is None else wsp.model_dump(mode="json")
        configs["load_transfer"] = load_transfer
        manifest["campaign"] = "field-rail"
        manifest["tables"] = {STOPS: [*STOP_COLUMNS, *RAIL_STOP_COLUMNS]}
        store = CampaignStore.open(out, manifest, resume)
    elif resume:
        raise ValueError("resume needs the folder of the campaign to resume (out)")
    rows = run_chunks(task, chunks, executor, store, progress)
    return FieldCampaignResult(setup.name, seed, control_step_s, applications, campaign.repetitions, rows)
