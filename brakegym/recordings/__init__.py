"""Recordings of brake applications: the format, replay against the model, and synthetic recording
sets (``brakegym synth``). The diagnosis of recordings is :mod:`brakegym.diagnosis`.

- :mod:`.format`: read, validate and write recordings (``docs/recording-format.md``).
- :mod:`.measurement`: what the sensors report of the simulated states.
- :mod:`.replay`: simulate a recording from its own inputs and compare every channel.
- :mod:`.synth`: synthetic campaigns with concealed effects and an answer key kept apart.
"""

from .format import (
    Dataset,
    DatasetError,
    Recording,
    RecordingError,
    RecordingMetadata,
    RecordingProblem,
    read_dataset,
    read_recording,
    write_recording,
)

__all__ = [
    "Dataset",
    "DatasetError",
    "Recording",
    "RecordingError",
    "RecordingMetadata",
    "RecordingProblem",
    "read_dataset",
    "read_recording",
    "write_recording",
]
