"""Drivers and Sensors of iTaSC-ROS2: simulated robot, adapters to existing ROS 2 drivers (ros2_control,
JointTrajectory), pose sensors."""
