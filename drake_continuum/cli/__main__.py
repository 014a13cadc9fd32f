"""`python -m drake_continuum.cli ...`: the command line."""

import sys

from ..console import main

__all__ = []

sys.exit(main())
