"""ROS 2 nodes of ext_sense_behaviours (the only modules here that import rclpy)."""
