"""``python -m solver``: the solver's command line (model files only)."""

import sys

from .cli import main

sys.exit(main())
