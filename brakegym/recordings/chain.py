"""A measurement chain: how a train's data logger samples and degrades each channel
(``configs/measurement_chains/<name>.yaml``, ``brakegym synth --measurement-chain NAME``).

Each channel has its own sample rate with timing jitter, a start delay, a sensor resolution
(quantisation), white or AR(1) coloured noise, a constant offset per sensor and recording (an
accelerometer's bias, a pressure transducer's zero offset) and dropouts (runs of blank samples).
The chain also sets the coasting before the brake command and where the deceleration comes from.
:mod:`.logger` applies it to the true channels of a run; this module only says what it is.

Loading validates; a bad value raises :class:`~brakegym.config.ConfigError` naming the file, the
field (e.g. ``channels.decel_mps2.ar1_rho``) and the value.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from .. import config as cfg
from .columns import DECEL, DISC_TEMPERATURE, POSITION, SPEED

KIND = "measurement_chains"
PRESSURES = "p_c_bar"  # every cylinder-pressure column p_c_bar_1..N: one logger group


class ChannelChain(cfg.StrictModel):
    """What the logger does to one channel. Units of ``resolution``, ``noise_sigma`` and
    ``offset_sigma`` are the channel's own (m/s, m/s^2, bar, degC, m)."""

    rate_Hz: float = Field(gt=0, le=1000)  # nominal sample rate
    jitter_s: float = Field(default=0.0, ge=0)  # each instant moves uniformly within +-jitter_s
    start_delay_s: float = Field(default=0.0, ge=0)  # first sample this long after the recording starts
    resolution: float = Field(default=0.0, ge=0)  # quantisation step of the reported value; 0: none
    noise_sigma: float = Field(default=0.0, ge=0)  # marginal standard deviation of the noise
    ar1_rho: float = Field(default=0.0, ge=0, lt=1)  # lag-1 correlation of the noise, per sample
    offset_sigma: float = Field(default=0.0, ge=0)  # constant offset per sensor and recording ~ N(0, sigma)
    dropout_probability: float = Field(default=0.0, ge=0, lt=0.5)  # chance a dropout starts at a sample
    dropout_mean_samples: float = Field(default=1.0, ge=1)  # mean length of a dropout (geometric)

    @property
    def interval_s(self) -> float:
        return 1.0 / self.rate_Hz

    @field_validator("jitter_s")
    @classmethod
    def _jitter_keeps_order(cls, jitter_s: float, info: ValidationInfo) -> float:
        rate = info.data.get("rate_Hz")  # absent when rate_Hz itself is invalid
        if rate is not None and not jitter_s < 0.5 / rate:
            raise ValueError(
                f"jitter_s = {jitter_s} must be below half the sample interval ({0.5 / rate:g} s at {rate:g} Hz): "
                "samples of a channel must stay in order"
            )
        return jitter_s


class ChainChannels(cfg.StrictModel):
    """The chain of every channel of a synthetic recording."""

    speed_mps: ChannelChain
    p_c_bar: ChannelChain  # every axle's transducer alike, sampled together
    decel_mps2: ChannelChain
    T_disc_C: ChannelChain
    position_m: ChannelChain

    @model_validator(mode="after")
    def _speed_from_the_start(self) -> ChainChannels:
        # The replay takes the initial speed from the first speed sample (docs/recording-format.md).
        if self.speed_mps.start_delay_s != 0:
            raise ValueError(
                f"speed_mps.start_delay_s = {self.speed_mps.start_delay_s}: the speed channel must have a sample at "
                "the start of the recording (the initial speed)"
            )
        return self

    def by_column(self) -> dict[str, ChannelChain]:
        """The chains keyed by the channel's column name (``p_c_bar`` for the pressure group)."""
        return {
            SPEED: self.speed_mps,
            PRESSURES: self.p_c_bar,
            DECEL: self.decel_mps2,
            DISC_TEMPERATURE: self.T_disc_C,
            POSITION: self.position_m,
        }


class MeasurementChain(cfg.StrictModel):
    """``configs/measurement_chains/<name>.yaml``: a data logger's channels and the test procedure
    around them (see the module documentation)."""

    name: str
    description: str = ""
    clock_resolution_s: float = Field(default=0.001, gt=0, le=0.01)  # resolution of time_s
    coasting_range_s: tuple[float, float] = (4.0, 10.0)  # coasting before the brake command, uniform
    decel_source: Literal["accelerometer", "speed"] = "accelerometer"
    channels: ChainChannels

    @model_validator(mode="after")
    def _consistent(self) -> MeasurementChain:
        low, high = self.coasting_range_s
        if not 0 <= low <= high:
            raise ValueError(f"coasting_range_s = [{low}, {high}]: need 0 <= low <= high")
        for column, chain in self.channels.by_column().items():
            # Rounding each instant to the clock moves it by half a tick at most: two ticks between
            # neighbours keep the channel's times strictly increasing.
            gap = chain.interval_s - 2 * chain.jitter_s
            if gap < 2 * self.clock_resolution_s:
                raise ValueError(
                    f"channels.{column}: rate_Hz = {chain.rate_Hz:g} with jitter_s = {chain.jitter_s:g} leaves "
                    f"{gap:g} s between samples, less than two ticks of clock_resolution_s = "
                    f"{self.clock_resolution_s:g}"
                )
        return self


def load_measurement_chain(name_or_path: str | Path) -> MeasurementChain:
    """A measurement chain by name (``configs/measurement_chains/<name>.yaml`` on the config search
    path) or from a YAML file; errors name the file, the field and the value."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.is_file():
        return cfg.load_file(path, MeasurementChain)
    return cfg.load_file(cfg.find(KIND, str(name_or_path)), MeasurementChain)
