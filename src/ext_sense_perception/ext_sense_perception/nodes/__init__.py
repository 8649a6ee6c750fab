"""The window and inference nodes (rclpy), and the message-level pipeline they share (no rclpy)."""
