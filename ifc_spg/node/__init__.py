"""The SPG node: its configuration, its ROS-free core, and the ROS shells."""
