"""The ROS 2 layer: sim_node, gait_node, replay_node, their message builders and the demo.

Everything that imports rclpy or a message package at module level lives here (the bag layer
uses message classes too, but nothing from this package)."""
