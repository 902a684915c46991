"""What every ``rod-sim`` subcommand shares, below them all: exit statuses, the usage error and
argument types (:mod:`.common`), Ctrl-C / SIGTERM handling (:mod:`.signals`) and the command
line's resource limits (:mod:`.limits`). Imports only ``rod_sim.core`` and ``rod_sim.io``, so
the subcommand packages (``rod_sim.tools``, ``rod_sim.compare``, ``rod_sim.sweep``,
``rod_sim.bench``) and the ROS processes can all use it without an import cycle."""
