"""Labelled window sets from every data source, cut by the live graph's own windowing code."""
