"""rod_sim: a ROS 2 Jazzy simulator of chains of elastic rods."""

__version__ = "0.1.0"
