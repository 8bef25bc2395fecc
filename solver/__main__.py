"""``python -m solver``: the solver's command line (model files only)."""

import sys

from hyperstat.solver.cli import main

sys.exit(main())
