"""Task composites of iTaSC-ROS2: virtual kinematic chains, constraint outputs, constraint controllers, setpoint
generators."""
