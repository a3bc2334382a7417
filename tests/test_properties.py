"""Property tests: invariants hold over the whole range of valid dynamometer load cases."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from brakegym import config as cfg
from brakegym.applications import dyno_stops

RIG = cfg.load("rigs", "dynamometer")


@settings(max_examples=20, deadline=None)
@given(
    speed_kmh=st.floats(30.0, 250.0),
    mass_kg=st.floats(3000.0, 15000.0),
    clamp_force_kN=st.floats(10.0, 60.0),
)
def test_any_dyno_stop_conserves_energy(speed_kmh, mass_kg, clamp_force_kN):
    case = RIG.load_cases[0].model_copy(
        update={"initial_speed_kmh": speed_kmh, "mass_kg": mass_kg, "clamp_force_kN": clamp_force_kN}
    )
    s = dyno_stops(RIG, [case])
    assert np.isfinite(s.stop_distance_m[0]) and s.stop_time_s[0] > 0
    assert abs(s.brake_work_J[0] / s.initial_kinetic_energy_J[0] - 1) < 0.005
    assert abs((s.stored_heat_J + s.cooling_heat_J)[0, 0] / s.friction_heat_J[0, 0] - 1) < 0.005
    assert 0.05 <= s.mu_s[0, 0] <= 0.80
