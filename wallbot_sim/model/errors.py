"""Errors raised by the model core."""


class ModelError(Exception):
    """Base class of every error the model core raises."""


class ParameterError(ModelError, ValueError):
    """A robot or scenario parameter is missing, unknown, of the wrong type or out of range."""


class DivergedError(ModelError):
    """The state stopped being finite."""
