"""Nodes of the bringup package."""
