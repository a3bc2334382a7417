"""Effects on what the sensors report: a speed-sensor scale and a temperature-sensor lag."""

from __future__ import annotations

from collections.abc import Mapping

from .base import Effect, EffectedModel, Evidence, ParameterSpec, per_train


class SpeedSensorScale(Effect):
    """The speed sensor reports ``scale`` x the true speed (a wheel-diameter error): speed and
    odometry are scaled together, a deceleration differentiated from speed too, the accelerometer
    not."""

    id = "speed_sensor_scale"
    sensor = True
    parameters = (ParameterSpec("scale", "", 0.9, 1.1, 1.0, ((0.95, 0.99), (1.01, 1.05))),)
    RELEVANT_CHANGE = 0.007

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return abs(parameters["scale"] - 1.0) >= cls.RELEVANT_CHANGE

    def apply(self, model: EffectedModel) -> None:
        model.sensors.speed_scale = model.sensors.speed_scale * per_train(self["scale"], model.n_trains, "scale")


class TemperatureSensorLag(Effect):
    """The disc-temperature sensor lags the friction surface: tau dT_meas/dt = T_fric - T_meas,
    discretised exactly (see :func:`.measurement.first_order_lag`)."""

    id = "temperature_sensor_lag"
    sensor = True
    parameters = (ParameterSpec("tau_s", "s", 0.0, 60.0, 0.0, ((2.0, 20.0),), lower_is_physical=True),)
    RELEVANT_TAU_S = 1.0

    @classmethod
    def is_relevant(cls, parameters: Mapping[str, float], evidence: Evidence) -> bool:
        return parameters["tau_s"] >= cls.RELEVANT_TAU_S

    def apply(self, model: EffectedModel) -> None:
        model.sensors.temperature_lag_s = per_train(self["tau_s"], model.n_trains, "tau_s")
