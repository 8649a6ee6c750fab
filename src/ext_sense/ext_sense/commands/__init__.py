"""Subcommands of ``ext-sense`` that belong to the bringup package."""
