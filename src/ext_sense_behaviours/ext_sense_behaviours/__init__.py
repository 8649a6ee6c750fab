"""Behaviour nodes: Robotiq 2F gripper over Modbus RTU, Panda arm adapter, handover, food probing and tap marker."""
