"""Errors of drawing (one-line messages; the command line maps them to its exit status)."""


class PlotError(Exception):
    """Output directory unusable, or a figure cannot be written."""
