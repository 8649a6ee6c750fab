"""Emulated devices that answer on a pty like the real hardware (``ext-sense sim serve``)."""
