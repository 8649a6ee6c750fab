"""Device drivers: NUSkin receiver words and ACES line, BioTac serial bridge, Robotiq gripper.

Transports (serial, CAN, file) and their reconnecting reader thread are shared by all drivers;
only ``nodes/`` imports rclpy.
"""
