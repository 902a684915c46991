"""The rod_sim log format's fixed names (docs/interface.md section 4) and the one error of
opening and reading logs.

A rod_sim log is an MCAP file in the ROS 2 profile, as rosbag2 Jazzy writes it: header
(profile ``ros2``), a metadata record ``rod_sim`` (written first, so that even a truncated log
can be replayed), zstd-compressed chunks of CDR messages, then the summary and message indexes.
Writing: :mod:`rod_sim.io.log_writer`; reading one MCAP file with its integrity checks:
:mod:`rod_sim.io.log_reader`; opening any supported log (a file or a rosbag2 bag):
:mod:`rod_sim.io.log_open`.
"""
from __future__ import annotations

METADATA_NAME = "rod_sim"
"""Name of the MCAP metadata record holding the run's scene, model and integrator."""
REQUIRED_METADATA = ("scene", "model", "integrator")
CHUNK_SIZE = 256 * 1024
"""[bytes] uncompressed size at which a chunk is closed and written (rosbag2's is 768 KiB)."""
MAGIC = b"\x89MCAP0\r\n"
"""The 8 bytes an MCAP file starts and ends with."""
PROFILE = "ros2"


class LogFormatError(ValueError):
    """A log (MCAP file or rosbag2 bag) that cannot be opened or read, or a topic it does not
    have; ``str(err)`` is one line naming the file or topic. The one error type of
    :mod:`rod_sim.io.log_open` and the modules reading on top of it (compare, replay, repair,
    the series readers)."""
