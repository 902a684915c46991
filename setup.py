"""Packaging for rod_sim: an ament_python package that also installs with plain pip."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE_NAME = "rod_sim"

setup(
    name=PACKAGE_NAME,
    version="0.1.0",
    description=("Plane chain of elastic rods with visco-elastic hinges: full, reduced and "
                 "rigid models, a ROS 2 Jazzy node and MCAP logs"),
    maintainer="rod_sim developers",
    maintainer_email="dev@rod-sim.invalid",
    license="Apache-2.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE_NAME]),
        ("share/" + PACKAGE_NAME, ["package.xml"]),
        ("share/" + PACKAGE_NAME + "/config", sorted(glob("config/*.yaml"))),
    ],
    python_requires=">=3.10",
    install_requires=[
        "numpy",
        "scipy",
        "numba",
        "PyYAML",
        "mcap",
        "mcap-ros2-support",
    ],
    extras_require={
        "ros": ["ros-jazzy-rclpy[fastrtps]", "ros-jazzy-common-interfaces"],
        "view": ["foxglove-sdk"],               # the live view (live_view_port, --live-view)
        "test": ["pytest", "pytest-timeout", "rosbags", "sympy", "yourdfpy", "websockets",
                 "foxglove-sdk"],
        "plot": ["matplotlib"],
        "peer": ["mujoco", "pin", "bsk"],       # bench + tests; bsk pins matplotlib<=3.10.9
        "sweep": ["dask[distributed]", "pyarrow", "tqdm"],      # rod-sim sweep on a cluster
    },
    zip_safe=True,
    entry_points={
        "console_scripts": [
            "rod-sim = rod_sim.tools.launch:main",
            "sim_node = rod_sim.ros.node:main",
            "pd_controller = rod_sim.ros.controller:main",
        ],
    },
)
