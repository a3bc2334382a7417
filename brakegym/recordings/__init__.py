"""Recordings of brake applications: the format, replay against the model, and synthetic recording
sets (``brakegym synth``). The diagnosis of recordings is :mod:`brakegym.diagnosis`.

- :mod:`.format`: read and write recordings and folders of them (``docs/recording-format.md``);
  :mod:`.columns` (the channels), :mod:`.metadata` (``<stem>.json``), :mod:`.validation` (the
  rules on the samples) and :mod:`.problems` (what is wrong, where) are its parts.
- :mod:`.measurement`: what the sensors report of the simulated states.
- :mod:`.replay`: simulate a recording from its own inputs and compare every channel.
- :mod:`.synth`: synthetic campaigns with concealed effects and an answer key kept apart.
"""

from .format import Dataset, Recording, read_dataset, read_recording, write_recording
from .metadata import GradientProfile, LineGradientProfile, RecordingMetadata, read_metadata
from .problems import DatasetError, RecordingError, RecordingProblem

__all__ = [
    "Dataset",
    "DatasetError",
    "Recording",
    "RecordingError",
    "GradientProfile",
    "LineGradientProfile",
    "RecordingMetadata",
    "RecordingProblem",
    "read_dataset",
    "read_metadata",
    "read_recording",
    "write_recording",
]
