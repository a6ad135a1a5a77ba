"""Sweeps over scene and gait parameters, gait optimisation, and tables of runs.

Layer ``sweep`` (docs/ARCHITECTURE.md): imports ``core`` and ``bag`` only; ``cli`` imports it.

- `sweep(spec, client=None, ...)`: one row per scene as a pandas DataFrame (`runner`).
- `load_spec` / `spec_from_dict`: grid or random sample over scene and gait parameters (`spec`).
- `write_table` / `read_table`: Parquet or CSV with the spec and package version (`tables`).
- `trajectory_frames` / `run_frames`: a `Trajectory` or a loaded bag as DataFrames (`tables`).
- `optimize(...)`: the stroke that maximises speed or minimises cost of transport (`optimize`).
Heavy parts (Dask, scipy.optimize, matplotlib) are imported where they are used.
"""
from .metrics import FIGURES, run_figures, scene_figures
from .runner import sweep
from .spec import SpecError, SweepSpec, load_spec, spec_from_dict

__all__ = ['FIGURES', 'SpecError', 'SweepSpec', 'load_spec', 'run_figures', 'scene_figures',
           'spec_from_dict', 'sweep']
