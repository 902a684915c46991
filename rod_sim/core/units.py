"""Unit constants shared by every layer (core, io, ros, tools): the one definition of each."""

NS_PER_S = 1_000_000_000
"""Nanoseconds per second: simulated time, ROS stamps and log times are integer ns."""
