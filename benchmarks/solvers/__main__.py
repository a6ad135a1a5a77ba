"""``python -m benchmarks.solvers``: the benchmark (or ``... stress``: the stress run)."""
import sys

from .runner import main

sys.exit(main())
