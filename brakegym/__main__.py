"""``python -m brakegym``: the command line (:mod:`brakegym.cli`)."""

import sys

from .cli import main

sys.exit(main())
