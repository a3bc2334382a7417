"""Recordings of brake applications: the format, replay against the model, the library of
candidate effects, and synthetic recording sets (``brakegym synth``).

- :mod:`.format`: read, validate and write recordings (``shared/spec/recording-format.md``).
- :mod:`.effects`: candidate effects the nominal model leaves out, switchable in the simulator.
- :mod:`.measurement`: what the sensors report of the simulated states.
- :mod:`.replay`: simulate a recording from its own inputs and compare every channel.
- :mod:`.synth`: synthetic campaigns with concealed effects and an answer key kept apart.
"""

from .effects import EFFECTS, Effect, EffectedModel, ParameterSpec, apply_effects, load_effects, make_effect
from .format import Dataset, Recording, RecordingError, RecordingMetadata, read_dataset, read_recording, write_recording

__all__ = [
    "EFFECTS",
    "Dataset",
    "Effect",
    "EffectedModel",
    "ParameterSpec",
    "Recording",
    "RecordingError",
    "RecordingMetadata",
    "apply_effects",
    "load_effects",
    "make_effect",
    "read_dataset",
    "read_recording",
    "write_recording",
]
