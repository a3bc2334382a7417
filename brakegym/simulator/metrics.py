"""Summaries of a stop per application, updated after each step (paper Eqs. 3 and 15)."""

from __future__ import annotations

import numpy as np

from .integrator import Simulator
from .state import MU_DISTANCE, MU_EFF_DISTANCE, POSITION, SPEED, T_DISC, T_FRIC


class StopMetrics:
    """Summaries of a stop per application (paper Eqs. 3 and 15), updated after each step.

    ``nominal_clamp_force_N`` (B, A) is the clamp force each axle is commanded to reach; the mean
    COF over distance runs from where the clamp force first reaches 95 % of it to standstill.
    Internally arrays are (axles, trains) like the simulator's.
    """

    def __init__(self, sim: Simulator, nominal_clamp_force_N: np.ndarray, threshold: float = 0.95) -> None:
        self.nominal_clamp_force_N = np.asarray(nominal_clamp_force_N, dtype=float).T.copy()  # (A, B)
        self.threshold = threshold
        axles, n = self.nominal_clamp_force_N.shape
        self.onset_position_m = np.full((axles, n), np.nan)
        self.onset_time_s = np.full((axles, n), np.nan)
        self.onset_mu_distance = np.full((axles, sim.plant.discs_per_axle, n), np.nan)
        self.train_onset_position_m = np.full(n, np.nan)
        self.train_onset_mu_eff_distance = np.full(n, np.nan)
        self.peak_friction_temperature_K = sim.disc[T_FRIC].copy()
        self.peak_disc_temperature_K = sim.disc[T_DISC].copy()

    @staticmethod
    def _crossing(start: np.ndarray, end: np.ndarray, level: np.ndarray) -> np.ndarray:
        """Fraction of the step at which a linearly varying value reaches ``level``."""
        span = end - start
        safe = np.where(span > 0, span, 1.0)
        return np.clip(np.where(span > 0, (level - start) / safe, 0.0), 0.0, 1.0)

    def update(self, sim: Simulator) -> None:
        record = sim.last_step
        assert record is not None
        np.maximum(self.peak_friction_temperature_K, sim.disc[T_FRIC], out=self.peak_friction_temperature_K)
        np.maximum(self.peak_disc_temperature_K, sim.disc[T_DISC], out=self.peak_disc_temperature_K)

        level = self.threshold * self.nominal_clamp_force_N
        force_start = record.clamp_force_start_N[:, 0, :]
        force_end = record.clamp_force_end_N[:, 0, :]
        new_axle = np.isnan(self.onset_position_m) & (self.nominal_clamp_force_N > 0) & (force_end >= level)
        if new_axle.any():
            theta = self._crossing(force_start, force_end, level)
            position = record.train_start[POSITION] + theta * (sim.train[POSITION] - record.train_start[POSITION])
            mu_distance = record.disc_start[MU_DISTANCE] + theta[:, None, :] * (
                sim.disc[MU_DISTANCE] - record.disc_start[MU_DISTANCE]
            )
            self.onset_position_m = np.where(new_axle, position, self.onset_position_m)
            self.onset_time_s = np.where(new_axle, record.time_start_s + theta * sim.step_s, self.onset_time_s)
            self.onset_mu_distance = np.where(new_axle[:, None, :], mu_distance, self.onset_mu_distance)

        total_level = level.sum(axis=0)
        total_start, total_end = force_start.sum(axis=0), force_end.sum(axis=0)
        new_train = np.isnan(self.train_onset_position_m) & (total_level > 0) & (total_end >= total_level)
        if new_train.any():
            theta = self._crossing(total_start, total_end, total_level)
            self.train_onset_position_m = np.where(
                new_train,
                record.train_start[POSITION] + theta * (sim.train[POSITION] - record.train_start[POSITION]),
                self.train_onset_position_m,
            )
            self.train_onset_mu_eff_distance = np.where(
                new_train,
                record.train_start[MU_EFF_DISTANCE]
                + theta * (sim.train[MU_EFF_DISTANCE] - record.train_start[MU_EFF_DISTANCE]),
                self.train_onset_mu_eff_distance,
            )

    def mean_mu_over_distance(self, sim: Simulator) -> np.ndarray:
        """mu_s of Eq. 3 per disc, trains x discs (B, A * k); nan where the 95 % point was never
        reached."""
        distance = sim.train[POSITION] - self.onset_position_m
        return sim.to_external((sim.disc[MU_DISTANCE] - self.onset_mu_distance) / distance[:, None, :])

    def distance_after_onset_m(self, sim: Simulator) -> np.ndarray:
        """s_2 of Eq. 3, per train: from the train's 95 % clamp-force point to standstill."""
        return sim.train[POSITION] - self.train_onset_position_m

    def effective_mu_over_distance(self, sim: Simulator) -> np.ndarray:
        """mu_s,eff: Eq. 15's mu_eff averaged over distance like Eq. 3, per train."""
        distance = sim.train[POSITION] - self.train_onset_position_m
        return (sim.train[MU_EFF_DISTANCE] - self.train_onset_mu_eff_distance) / distance


class SpeedCrossings:
    """Where and when each train's speed first falls to each of ``speeds_mps`` (S,), updated after
    each step, and its state at ``time_s`` (nan if the run never passes it): the points that split a
    stop into speed bands.

    Inside a step the deceleration is taken as constant (as the stop interpolation does), so the
    position grows linearly with the fall of v^2: a train passes speed V at the fraction
    (v_0^2 - V^2) / (v_0^2 - v_1^2) of the step's distance. Arrays are (S, B); nan until passed.
    """

    def __init__(self, n_trains: int, speeds_mps: np.ndarray, time_s: float | None = None) -> None:
        self.speeds_mps = np.asarray(speeds_mps, dtype=float)
        n = n_trains
        self.position_m = np.full((len(self.speeds_mps), n), np.nan)
        self.time_s = np.full((len(self.speeds_mps), n), np.nan)
        self.at_time_s = time_s
        self.position_at_time_m = np.full(n, np.nan)
        self.speed_at_time_mps = np.full(n, np.nan)

    def update(self, sim: Simulator) -> None:
        record = sim.last_step
        assert record is not None
        v0, v1 = record.train_start[SPEED], sim.train[SPEED]
        s0, s1 = record.train_start[POSITION], sim.train[POSITION]
        for row, speed in enumerate(self.speeds_mps):
            passed = np.isnan(self.position_m[row]) & (v0 >= speed) & (v1 < speed)
            if passed.any():
                fall = np.where(passed, v0**2 - v1**2, 1.0)
                share = np.where(passed, (v0**2 - speed**2) / fall, 0.0)
                self.position_m[row] = np.where(passed, s0 + share * (s1 - s0), self.position_m[row])
                # Constant deceleration: the speed falls linearly in time.
                time_share = np.where(passed, (v0 - speed) / np.where(passed, v0 - v1, 1.0), 0.0)
                self.time_s[row] = np.where(passed, record.time_start_s + time_share * sim.step_s, self.time_s[row])
        if self.at_time_s is not None and record.time_start_s <= self.at_time_s < record.time_start_s + sim.step_s:
            elapsed = self.at_time_s - record.time_start_s
            deceleration = (v0 - v1) / sim.step_s
            self.speed_at_time_mps = v0 - deceleration * elapsed
            self.position_at_time_m = s0 + v0 * elapsed - 0.5 * deceleration * elapsed**2
