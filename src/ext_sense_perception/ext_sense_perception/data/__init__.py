"""Labelled window sets from recordings: importers, captures, datasets, bags, device streams.

Every source becomes a :class:`~ext_sense_perception.data.window_set.WindowSet` cut by the
online windowing code (:mod:`ext_sense_perception.online`), so training sees the live windows.
"""
