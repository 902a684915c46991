"""``rod-sim compare``: a log against the full model (docs/compare.md).

:mod:`.command` (options, table, plot) on :mod:`.comparison` (the numbers: a pipeline of
:mod:`.inputs` (held forces and torques, sample times and gaps), :mod:`.runs` (the reference
re-runs), :mod:`.chaos` (twin run, gain, horizon), :mod:`.stats` (per-quantity statistics),
:mod:`.spacecraft` (per-chain and base errors) and :mod:`.verdict` (the verdict as data))."""
