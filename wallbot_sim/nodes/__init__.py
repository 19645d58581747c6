"""The ROS 2 nodes of the wallbot graph (dynamics, trajectory, constraint_config): thin shells
around the model; messages and QoS come from wallbot_msgs_py."""
