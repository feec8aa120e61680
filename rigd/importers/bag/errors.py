"""The error of ``rigd import bag``: bad input named in the message (a topic, an encoding, the bag itself)."""

from rigd.errors import RigdError


class BagError(RigdError):
    """A bag that cannot be imported as asked: a missing or wrong topic (the message lists the bag's topics), an
    unknown image encoding or point layout, a truncated or corrupt file, topics that do not overlap in time, or
    no still moment. The CLI prints it as ``rigd: error: ...`` and exits 65."""
