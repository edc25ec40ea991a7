"""Kinds registered from outside iTaSC-ROS2's source tree, through entry points only (a test package)."""
