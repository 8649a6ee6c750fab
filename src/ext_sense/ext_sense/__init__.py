"""Bringup and command line of ext_sense.

The node-graph descriptions, the launch files, and the ``ext-sense`` command.
"""
