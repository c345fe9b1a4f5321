"""The one exception type the bag tools raise for bad input; its text is the user message."""


class BagError(Exception):
    """A bag cannot be written or read; ``str(err)`` is a complete one-line explanation."""
