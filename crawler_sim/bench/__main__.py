"""``python -m crawler_sim.bench``: the benchmark (or ``... stress``: the stress run)."""
import sys

from .runner import main

sys.exit(main())
