"""Errors of run data (one-line messages; the command line maps them to its exit status)."""


class RunDataError(Exception):
    """The path is neither a readable wallbot bag nor a simulate CSV, or holds nothing to analyse."""
