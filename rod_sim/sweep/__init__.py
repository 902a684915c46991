"""``rod-sim sweep``: batch runs over parameter grids (docs/sweep.md).

:mod:`.command` (options, local process pool or dask cluster, progress, the table) runs the
runs that :mod:`.spec` expands from a spec file, each by :mod:`.worker`; :mod:`.table` writes
CSV or Parquet, :mod:`.plot` the figure; :mod:`.forkserver` and :mod:`.parent_death` make the
local pool's processes die with the sweep."""
