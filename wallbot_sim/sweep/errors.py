"""Errors of a sweep (one-line messages; the command line maps them to its exit status)."""


class SweepError(Exception):
    """A sweep spec that cannot be run, or an output directory that belongs to another sweep."""
