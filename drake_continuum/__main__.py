"""`python -m drake_continuum ...`: the command line, as `drake-continuum ...`."""

import sys

from .console import main

__all__ = []

sys.exit(main())
