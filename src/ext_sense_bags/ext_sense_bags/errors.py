"""The one exception type of :mod:`ext_sense_bags`, and how library errors are worded in it."""


class BagError(Exception):
    """A bag cannot be written or read: bad path, unknown type or topic, corrupt file."""


def why(err: BaseException) -> str:
    """A library's error in one line of at most 200 characters (parsers quote whole texts)."""
    text = " ".join(str(err).split()) or type(err).__name__
    if isinstance(err, KeyError):
        text = f"its message definitions name an unknown type {text}"
    return text if len(text) <= 200 else text[:197] + "..."
