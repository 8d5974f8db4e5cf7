"""sweep_ros: the ROS 2 side of the project (the node comes with its own issue)."""
