"""The one exception type of :mod:`ext_sense_bags`."""


class BagError(Exception):
    """A bag cannot be written or read: bad path, unknown type or topic, corrupt file."""
