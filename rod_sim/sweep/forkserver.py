"""Preloaded by the sweep's forkserver (and only there): importing it makes that process die
with the sweep that started it (:func:`rod_sim.sweep.parent_death.die_with_parent`), so the
forkserver never outlives a SIGKILLed sweep; the workers it forks die with it in turn."""
from .parent_death import die_with_parent

die_with_parent()
