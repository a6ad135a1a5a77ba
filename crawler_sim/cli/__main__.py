"""``python -m crawler_sim.cli``: the crawler-sim command."""
import os
import sys

from . import main

os.environ.setdefault("MPLBACKEND", "Agg")
sys.exit(main())
