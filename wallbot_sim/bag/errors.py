"""Errors of the bag tools: each carries a one-line message for the user.

BagError is a CliError (exit status 2), so every verb (including ``simulate --bag``) reports it
as one line without catching it itself.
"""

from wallbot_sim.cli.errors import CliError


class BagError(CliError):
    """A bag cannot be read, written or repaired (message is one line, names the path)."""


class NotABagError(BagError):
    """The path is missing or holds no rosbag2 bag."""


class UnknownTopicError(BagError):
    """A topic asked for is not in the bag (or not a graph topic)."""
