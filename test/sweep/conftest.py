"""Fixtures of the sweep tests: a real Dask scheduler and workers (test/support/dask_cluster.py)."""
from test.support.dask_cluster import dask_client  # noqa: F401 (the fixture)
