"""Errors of bag I/O: each carries a one-line message naming the path (the command line maps
them to its exit status)."""


class BagError(Exception):
    """A bag cannot be read, written or repaired."""


class NotABagError(BagError):
    """The path is missing or holds no rosbag2 bag."""


class UnknownTopicError(BagError):
    """A topic asked for is not in the bag (or not a graph topic)."""
