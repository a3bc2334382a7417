"""brakegym: railway friction brakes after Ehret, Hohmann & Heckmann (2022).

Dynamic, stochastic coefficient of friction per disc, two-capacity disc temperatures, the
dynamometer rig and a 16-disc multiple-unit train, integrated in batches.
"""

__version__ = "0.1.0"
