"""Fidelity: a scene held against real NUSkin captures at the captures' own time resolution.

Real captures and simulated trials are reduced alike (:mod:`.captures`, 10 ms bins), cut alike
(:mod:`.taps`, :mod:`.food`), summarised and compared (:mod:`.compare`: the issue's targets and
a classifier two-sample test); :mod:`.check` puts a run together, :mod:`.figure` draws it.
"""
