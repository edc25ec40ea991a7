"""Bootstrap (root Composer) of iTaSC-ROS2 applications, the application models under config/, and the plot and graph
tools."""
