"""sensorispace_ros: a ROS 2 (Jazzy) Python package."""

__version__ = "0.1.0"
