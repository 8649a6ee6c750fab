"""Node plumbing shared by every ext_sense node.

QoS profiles, executor choice, parameter descriptors, the diagnostics updater.
"""
