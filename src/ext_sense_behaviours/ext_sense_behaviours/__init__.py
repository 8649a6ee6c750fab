"""Behaviours: Robotiq 2F gripper node, Panda arm adapters, handover, food probing, tap marker.

State machines, adapters and records are plain Python; only ``nodes/`` imports rclpy.
"""
