"""The table of ``rod-sim`` subcommands, read by the command line (:mod:`rod_sim.tools.cli`)
and by the console script's first signal handler (:mod:`rod_sim.tools.launch`): plain data,
no imports, so that both can load it at once."""

COMMANDS = {
    # rod-sim NAME: module (in the order of `rod-sim --help`)
    "simulate": "simulate",                     # offline run -> MCAP log
    "table1": "table1",                         # Table 1 of the paper
    "node": "node",                             # the ROS 2 node (rod_sim.ros.node)
    "advise": "advise",                         # cheapest model/integrator for a tolerance
    "bench": "rod_sim.bench.command",           # speed against error (docs/bench.md)
    "compare": "rod_sim.compare.command",       # a log against the full model
    "ctl": "ctl",                               # the node's services, parameters, topics
    "deployment-figure": "deployment_figure",   # snapshots of a logged chain
    "repair": "repair",                         # rewrite a damaged log
    "replay": "replay",                         # republish a log on a ROS graph
    "sweep": "rod_sim.sweep.command",           # batch runs over parameter grids
    "urdf": "urdf",                             # a scene's chain as URDF
}
"""``rod-sim`` subcommand -> the module that implements it (of ``rod_sim.tools`` unless a full
name: compare, sweep and bench are packages of their own)."""
NEVER_COMPILES = frozenset({"ctl", "repair", "replay", "urdf"})
"""Subcommands that run no compiled code (the others say what numba compiles when it does:
:func:`rod_sim.app.common.watch_compiles`; the node installs its own)."""
