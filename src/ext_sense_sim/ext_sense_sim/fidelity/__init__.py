"""Fidelity: a scene held against real NUSkin captures at the captures' own time resolution.

Real rod-tap captures and simulated tap trials are reduced alike (:mod:`.captures`: event
times to the host's 10 ms bins), cut alike (:mod:`.taps`: the onset bin rule, a 250 ms
window) and described by the same per-window statistics; :mod:`.compare` summarises them per
real session and pooled, checks the issue's targets and runs a classifier two-sample test
whose yardstick is the real sessions against each other. Food trials get their own
statistics (:mod:`.food`). :mod:`.check` puts a run together, :mod:`.figure` draws it. No ROS.
"""
